"""anafi_sim.mission.trajectory: trajectory formulas, periods, per-axis combinations, scenarios and the generator.

Velocities are checked against central finite differences of the positions
(independent of the closed forms in the code); periods by p(t + T) = p(t);
formulas against the paper's definitions written out here.
"""
import math
import re

import pytest
import yaml

from anafi_sim.mission import trajectory as tr
from anafi_sim.mission.trajectory import (Circle, Constant, PerAxis, Ramp, Sine, StaticWaypoint, StraightLine,
                                          VerticalPeriodic, load_scenario, list_scenarios, scenario_from_dict,
                                          trajectory_from_dict)
from anafi_sim.mission.generator import DONE, TrajectoryGenerator

TIMES = [0.0, 0.37, 1.0, 2.5, 4.2, 7.77, 13.1, 29.9]


def finite_difference(traj, t, h=1e-5):
    a, b = traj.sample(t - h), traj.sample(t + h)
    return ((b.x - a.x) / (2 * h), (b.y - a.y) / (2 * h), (b.z - a.z) / (2 * h))


def assert_consistent(traj, times=TIMES, tol=1e-6):
    for t in times:
        s = traj.sample(t)
        fd = finite_difference(traj, t)
        assert (s.vx, s.vy, s.vz) == pytest.approx(fd, abs=tol), 't = %g' % t


SHAPES = [
    StaticWaypoint(3.0, 2.0, 5.0, 180.0),
    StraightLine((0.0, 0.0, 7.0), (1.0, 0.0, 0.0), 3.0),
    StraightLine((1.0, -2.0, 4.0), (1.0, 2.0, -0.5), 2.5),
    Circle((0.0, 0.0, 5.0), 2.0, 1.0),
    Circle((1.0, -1.0, 3.0), 3.0, 3.0, phase=0.7, clockwise=True),
    VerticalPeriodic((0.0, 0.0, 5.0), 2.0, 2.0),
    PerAxis(Ramp(0.0, 1.5), Sine(0.0, 2.0, 0.5, 0.3), Sine(5.0, 1.0, 1.0), Constant(30.0)),
]


@pytest.mark.parametrize('traj', SHAPES, ids=lambda t: repr(t)[:40])
def test_velocity_is_the_derivative_of_the_position(traj):
    assert_consistent(traj)


def test_static_waypoint_is_wp0_with_zero_velocity():
    s = StaticWaypoint(3.0, 2.0, 5.0, 180.0).sample(12.0)
    assert tuple(s) == (3.0, 2.0, 5.0, 0.0, 0.0, 0.0, 180.0)
    assert StaticWaypoint(3, 2, 5).period() is None


def test_straight_line_formula_and_direction_normalised():
    line = StraightLine((1.0, 2.0, 7.0), (0.0, 3.0, 4.0), 5.0, yaw=10.0)   # |d| = 5
    s = line.sample(2.0)
    assert (s.x, s.y, s.z) == pytest.approx((1.0, 2.0 + 5.0 * 2.0 * 0.6, 7.0 + 5.0 * 2.0 * 0.8))
    assert (s.vx, s.vy, s.vz) == pytest.approx((0.0, 3.0, 4.0))
    assert math.hypot(s.vy, s.vz) == pytest.approx(5.0)
    assert s.yaw == 10.0
    assert line.period() is None
    with pytest.raises(ValueError, match='non-zero'):
        StraightLine((0, 0, 0), (0, 0, 0), 1.0)
    with pytest.raises(ValueError, match='speed'):
        StraightLine((0, 0, 0), (1, 0, 0), -1.0)


@pytest.mark.parametrize('r,v', [(1, 1), (2, 1), (2, 2), (3, 1), (3, 2), (3, 3)])
def test_circle_radius_speed_period_and_yaw(r, v):
    c = Circle((1.0, -2.0, 5.0), r, v)
    period = 2 * math.pi * r / v
    assert c.period() == pytest.approx(period)
    for t in TIMES:
        s = c.sample(t)
        assert math.hypot(s.x - 1.0, s.y + 2.0) == pytest.approx(r)
        assert s.z == 5.0 and s.vz == 0.0 and s.yaw == 0.0
        assert math.hypot(s.vx, s.vy) == pytest.approx(v)
        # velocity tangent to the circle, counter-clockwise: (p - c) x v has +z
        assert (s.x - 1.0) * s.vy - (s.y + 2.0) * s.vx == pytest.approx(r * v)
        s2 = c.sample(t + period)
        assert (s2.x, s2.y) == pytest.approx((s.x, s.y), abs=1e-9)
    # angular rate v / r: a quarter period is a quarter turn from (cx + r, cy)
    assert (c.sample(0).x, c.sample(0).y) == pytest.approx((1.0 + r, -2.0))
    q = c.sample(period / 4)
    assert (q.x, q.y) == pytest.approx((1.0, -2.0 + r), abs=1e-9)


def test_circle_clockwise_turns_the_other_way():
    s = Circle((0, 0, 5), 2.0, 1.0, clockwise=True).sample(0.3)
    assert s.x * s.vy - s.y * s.vx == pytest.approx(-2.0)


@pytest.mark.parametrize('r,v', [(1, 1), (2, 1), (2, 2)])
def test_vertical_periodic_is_the_papers_formula(r, v):
    vp = VerticalPeriodic((0.5, -0.5, 5.0), r, v)
    assert vp.period() == pytest.approx(2 * math.pi * r / v)
    for t in TIMES:
        s = vp.sample(t)
        assert s.z == pytest.approx(5.0 + r * math.sin(v * t / r))
        assert s.vz == pytest.approx(v * math.cos(v * t / r))
        assert (s.x, s.y, s.vx, s.vy, s.yaw) == (0.5, -0.5, 0.0, 0.0, 0.0)


def test_per_axis_combination_and_common_period():
    p = PerAxis(x=Sine(0.0, 1.0, 1.0), y=Sine(0.0, 1.0, 2.0), z=Constant(4.0))
    assert p.period() == pytest.approx(2 * math.pi)          # lcm of 2 pi and pi
    p3 = PerAxis(x=Sine(0.0, 1.0, 2.0), y=Sine(0.0, 1.0, 3.0))
    assert p3.period() == pytest.approx(2 * math.pi)          # lcm of pi and 2 pi / 3
    assert PerAxis(x=Sine(0, 1, 1.0), y=Sine(0, 1, math.sqrt(2))).period() is None   # incommensurate
    assert PerAxis(x=Ramp(0.0, 1.0), y=Sine(0, 1, 1.0)).period() is None            # drifts away
    assert PerAxis(x=Ramp(2.0, 0.0)).period() is None
    s = PerAxis(x=Ramp(1.0, 2.0), yaw=Constant(45.0)).sample(3.0)
    assert tuple(s) == (7.0, 0.0, 0.0, 2.0, 0.0, 0.0, 45.0)
    with pytest.raises(ValueError):
        PerAxis(x=3.0)


def test_per_axis_from_dict_equals_circle():
    d = {'type': 'per_axis',
         'x': {'type': 'sine', 'offset': 0.0, 'amplitude': 2.0, 'omega': 0.5, 'phase': math.pi / 2},
         'y': {'type': 'sine', 'offset': 0.0, 'amplitude': 2.0, 'omega': 0.5},
         'z': 5.0}
    a = trajectory_from_dict(d)
    b = Circle((0.0, 0.0, 5.0), 2.0, 1.0)
    for t in TIMES:
        assert tuple(a.sample(t)) == pytest.approx(tuple(b.sample(t)), abs=1e-12)
    assert a.period() == pytest.approx(b.period())


@pytest.mark.parametrize('bad,match', [
    ({'type': 'circle', 'centre': [0, 0, 5], 'radius': 0, 'speed': 1}, 'radius'),
    ({'type': 'circle', 'centre': [0, 0], 'radius': 1, 'speed': 1}, 'centre'),
    ({'type': 'circle', 'centre': [0, 0, 5], 'radius': 1, 'speed': 'fast'}, 'speed'),
    ({'type': 'circle', 'centre': [0, 0, 5], 'radius': 1, 'speed': 1, 'colour': 'red'}, 'colour'),
    ({'type': 'vertical', 'centre': [0, 0, 5], 'radius': 1, 'speed': float('nan')}, 'finite'),
    ({'type': 'line', 'start': [0, 0, 7], 'speed': 1}, 'direction'),
    ({'type': 'spiral'}, 'type must be one of'),
    ({'type': 'per_axis', 'x': {'type': 'sine', 'amplitude': 1, 'frequency': 2}}, 'frequency'),
    ({'type': 'static', 'position': [1, 2, 3], 'yaw': True}, 'yaw'),
])
def test_trajectory_validation_errors_are_clear(bad, match):
    with pytest.raises(ValueError, match=match):
        trajectory_from_dict(bad)


def _scenario(**over):
    d = {'name': 'test', 'trajectory': {'type': 'circle', 'centre': [0, 0, 5], 'radius': 2, 'speed': 1},
         'phases': [{'name': 'approach', 'duration': 4.0, 'hold': 'start'},
                    {'name': 'settle', 'periods': 1},
                    {'name': 'measure', 'periods': 1, 'measure': True},
                    {'name': 'tail', 'duration': 1.0}]}
    d.update(over)
    return d


def test_scenario_phases_times_and_waypoints():
    sc = scenario_from_dict(_scenario())
    T = 4 * math.pi
    assert sc.period() == pytest.approx(T)
    assert sc.duration == pytest.approx(4.0 + 2 * T + 1.0)
    assert sc.measure_window == pytest.approx((4.0 + T, 4.0 + 2 * T))
    assert tuple(sc.start) == pytest.approx((2.0, 0.0, 5.0, 0.0, 0.0, 0.0, 0.0))   # start: trajectory(0)
    assert sc.waypoint(1.0) == sc.start                                               # holding the start
    assert sc.trajectory_time(1.0) is None
    assert sc.trajectory_time(4.0 + T + 0.5) == pytest.approx(T + 0.5)               # runs on across phases
    assert tuple(sc.waypoint(4.0 + 3.0)) == pytest.approx(tuple(sc.trajectory.sample(3.0)))
    end = sc.waypoint(sc.duration + 5.0)                                              # after the end: hold
    last = sc.trajectory.sample(2 * T + 1.0)
    assert (end.x, end.y, end.z, end.vx, end.vy, end.vz) == pytest.approx((last.x, last.y, last.z, 0, 0, 0))


@pytest.mark.parametrize('over,match', [
    ({'phases': []}, 'phases'),
    ({'phases': [{'name': 'a', 'duration': 1.0}]}, 'exactly one phase'),
    ({'phases': [{'name': 'a', 'duration': 1.0, 'measure': True}, {'name': 'b', 'duration': 1, 'measure': True}]},
     'exactly one phase'),
    ({'phases': [{'name': 'a', 'duration': -1.0, 'measure': True}]}, 'duration'),
    ({'phases': [{'name': 'a', 'duration': 1.0, 'periods': 1, 'measure': True}]}, 'exactly one of'),
    ({'phases': [{'name': 'a', 'duration': 1.0, 'hold': 'end', 'measure': True}]}, 'hold'),
    ({'phases': [{'name': 'a', 'duration': 1.0, 'measure': 'yes'}]}, 'measure'),
    ({'phases': [{'name': 'a', 'duration': 1.0, 'measure': True}, {'name': 'a', 'duration': 1.0}]}, 'unique'),
    ({'trajectory': {'type': 'static', 'position': [3, 2, 5]},
      'phases': [{'name': 'a', 'periods': 1, 'measure': True}]}, 'not periodic'),
    ({'start': [1, 2]}, 'start'),
    ({'extra': 1}, 'extra'),
])
def test_scenario_validation_errors_are_clear(over, match):
    with pytest.raises(ValueError, match=match):
        scenario_from_dict(_scenario(**over))


def test_load_scenario_reports_file_and_field(tmp_path):
    p = tmp_path / 'bad.yaml'
    d = _scenario()
    d['trajectory']['radius'] = -2
    p.write_text(yaml.safe_dump(d))
    with pytest.raises(ValueError) as err:
        load_scenario(str(p))
    assert 'bad.yaml' in str(err.value) and 'radius' in str(err.value)
    (tmp_path / 'broken.yaml').write_text('phases: [unclosed\n')
    with pytest.raises(ValueError, match='not valid YAML'):
        load_scenario(str(tmp_path / 'broken.yaml'))
    with pytest.raises(ValueError, match='no scenario file'):
        load_scenario('no_such_scenario')


EXPECTED_SCENARIOS = (['static_wp0', 'static_wp1'] + ['straight_%d' % v for v in range(1, 6)]
                      + ['circle_r%d_v%d' % rv for rv in [(1, 1), (2, 1), (2, 2), (3, 1), (3, 2), (3, 3)]]
                      + ['vertical_r%d_v%d' % rv for rv in [(1, 1), (2, 1), (2, 2)]])


def test_every_paper_scenario_is_shipped_and_loads():
    shipped = list_scenarios()
    assert set(EXPECTED_SCENARIOS) <= set(shipped)
    for name in shipped:
        sc = load_scenario(name)
        assert sc.name == name
        assert 0.0 < sc.measure_window[0] < sc.measure_window[1] <= sc.duration
        assert_consistent(sc.trajectory, times=[0.5, 3.0, 11.0])


def test_shipped_scenarios_match_the_paper():
    wp0, wp1 = load_scenario('static_wp0'), load_scenario('static_wp1')
    assert tuple(wp0.waypoint(wp0.measure_window[0] + 1.0)) == (3.0, 2.0, 5.0, 0.0, 0.0, 0.0, 0.0)
    assert tuple(wp1.waypoint(wp1.measure_window[0] + 1.0)) == (3.0, 2.0, 5.0, 0.0, 0.0, 0.0, 180.0)
    assert (wp0.start.z, wp0.start.yaw) == (1.0, 0.0)                      # from hover after take-off
    for v in range(1, 6):
        sc = load_scenario('straight_%d' % v)
        s = sc.waypoint(sum(sc.measure_window) / 2)
        assert (s.vx, s.vy, s.vz, s.z, s.y, s.yaw) == (float(v), 0.0, 0.0, 7.0, 0.0, 0.0)
    for name in EXPECTED_SCENARIOS[7:]:
        sc = load_scenario(name)
        kind, r, v = name.split('_')[0], float(name.split('_')[1][1:]), float(name.split('_')[2][1:])
        period = 2 * math.pi * r / v
        assert sc.period() == pytest.approx(period)
        t0, t1 = sc.measure_window
        assert t1 - t0 == pytest.approx(period)                    # one full period measured
        settle = [p for p in sc.phases if p.name == 'settle'][0].duration
        assert settle >= 10.0 - 1e-9 and settle - period < 10.0    # documented rule: fewest periods >= 10 s
        assert sc.trajectory_time(t0) == pytest.approx(round(sc.trajectory_time(t0) / period) * period)
        s = sc.waypoint(t0 + 0.3 * period)
        if kind == 'circle':
            assert math.hypot(s.x, s.y) == pytest.approx(r) and math.hypot(s.vx, s.vy) == pytest.approx(v)
            assert s.yaw == 0.0 and s.z == 5.0
        else:
            assert abs(s.z - 5.0) <= r and (s.x, s.y) == (0.0, 0.0)


def test_generator_events_carry_exact_boundary_times():
    sc = scenario_from_dict(_scenario())
    gen = TrajectoryGenerator(sc)
    assert gen.update(5.0) == (None, [])                    # idle: nothing published
    gen.start(100.0)
    wp, events = gen.update(100.0)
    assert wp == sc.start
    assert [e.kind for e in events] == ['start', 'phase']
    t0, t1 = sc.measure_window
    _, events = gen.update(100.0 + t0 + 0.05)               # tick after the boundary
    kinds = [(e.kind, e.phase) for e in events]
    assert kinds == [('phase', 'settle'), ('phase', 'measure'), ('begin', 'measure')]
    assert events[-1].time == pytest.approx(100.0 + t0)     # exact boundary, not the tick
    wp, events = gen.update(100.0 + sc.duration + 3.0)
    assert [e.kind for e in events] == ['end', 'phase', 'done']
    assert events[0].time == pytest.approx(100.0 + t1)
    assert gen.state == DONE
    assert (wp.vx, wp.vy, wp.vz) == (0.0, 0.0, 0.0)         # holds the final position
    assert gen.update(200.0) == (wp, [])


def test_generator_stop_switch_and_abort():
    sc = scenario_from_dict(_scenario())
    gen = TrajectoryGenerator(sc)
    gen.start(0.0)
    t0 = sc.measure_window[0]
    gen.update(t0 + 1.0)
    gen.stop(t0 + 2.0)
    wp, events = gen.update(t0 + 2.5)
    assert [e.kind for e in events] == ['abort', 'stop']
    here = sc.waypoint(t0 + 2.0)
    assert (wp.x, wp.y, wp.vx, wp.vy) == pytest.approx((here.x, here.y, 0.0, 0.0))
    other = load_scenario('static_wp0')
    gen.switch(other, 50.0)
    wp, events = gen.update(50.0)
    assert wp == other.start and gen.scenario is other
    assert [e.kind for e in events] == ['start', 'phase']
    gen2 = TrajectoryGenerator(sc, hold_when_idle=False)
    gen2.start(0.0)
    gen2.stop(1.0)
    assert gen2.update(2.0)[0] is None


def test_generator_emits_every_event_when_ticks_skip_phases():
    sc = scenario_from_dict(_scenario())
    gen = TrajectoryGenerator(sc)
    gen.start(0.0)
    _, events = gen.update(1000.0)
    assert [e.kind for e in events] == ['start', 'phase', 'phase', 'phase', 'begin', 'end', 'phase', 'done']


def test_airship_target_is_the_followers_waypoint_of_the_scripted_airship():
    """The in-process airship scenario: the waypoint model_follower.py makes from the airship's pose and twist
    (airship.yaml's path), a pure function of time whose velocity is the derivative of its position."""
    import math as _m
    from anafi_sim.mission.model_following import ModelFollower
    from anafi_sim.mission.trajectory import FollowedTarget, airship_defaults, load_scenario
    from anafi_sim.gazebo.airship_path import AirshipPath
    scenario = load_scenario('airship_follow')
    target = scenario.trajectory
    assert isinstance(target, FollowedTarget) and target.period() == 120.0
    assert scenario.measure_window == (30.0, 150.0)
    path = AirshipPath(**airship_defaults())
    follower = ModelFollower((-6.0, 0.0, -2.0), 'heading', 'heading', velocity_source='twist')
    for t in (0.0, 7.5, 33.0, 91.2):
        st = path.state(t)
        q = (0.0, 0.0, _m.sin(st.yaw / 2), _m.cos(st.yaw / 2))
        expected = follower.update(t, st.position, q, st.velocity, st.yaw_rate)
        got = target.sample(t)
        assert got == pytest.approx(expected)
        # 6 m behind the airship along its heading, 2 m below; facing its heading
        back = (st.position[0] - 6.0 * _m.cos(st.yaw), st.position[1] - 6.0 * _m.sin(st.yaw), st.position[2] - 2.0)
        assert (got.x, got.y, got.z) == pytest.approx(back)
        assert got.yaw == pytest.approx(_m.degrees(st.yaw))
        h = 1e-5
        a, b = target.sample(t - h), target.sample(t + h)
        assert ((b.x - a.x) / (2 * h), (b.y - a.y) / (2 * h), (b.z - a.z) / (2 * h)) == \
            pytest.approx((got.vx, got.vy, got.vz), abs=1e-4)
    assert target.sample(12.0) == target.sample(12.0)         # no history: the same answer every time
    with pytest.raises(ValueError):
        load_scenario_from = __import__('anafi_sim.mission.trajectory', fromlist=['trajectory_from_dict'])
        load_scenario_from.trajectory_from_dict({'type': 'airship', 'path': {'wingspan': 3}})


# ---------------------------------------------------------------- scenario limits
def _limited(trajectory=None, phases=None, start='trajectory'):
    from anafi_sim.mission import trajectory as tr
    d = {'name': 'x', 'start': start,
         'trajectory': dict({'type': 'circle', 'centre': [0, 0, 5], 'radius': 2, 'speed': 1}, **(trajectory or {})),
         'phases': phases or [{'name': 'm', 'periods': 1, 'measure': True}]}
    return tr.scenario_from_dict(d)


@pytest.mark.parametrize('trajectory,phases,words', [
    ({'centre': [1e300, 0, 5]}, None, 'x 1e+300 outside the limits'),
    ({'radius': 1e-300}, [{'name': 'm', 'duration': 10, 'measure': True}], 'acceleration'),
    ({'speed': 1e6}, [{'name': 'm', 'duration': 10, 'measure': True}], 'speed 1e+06 outside the limits'),
    ({'type': 'line', 'start': [0, 0, 5], 'direction': [1, 0, 0], 'speed': 1e6, 'centre': None, 'radius': None},
     [{'name': 'm', 'duration': 10, 'measure': True}], 'outside the limits'),
    (None, [{'name': 'm', 'duration': 1e6, 'measure': True}], 'duration 1e+06 s > 3600 s'),
    ({'radius': 1e-300}, None, 'measured phase m lasts'),
    ({'centre': [0, 0, -50]}, None, 'z -50 outside the limits'),
])
def test_scenario_values_beyond_the_limits_are_refused_with_the_value_named(trajectory, phases, words):
    trajectory = dict((k, v) for k, v in (trajectory or {}).items() if v is not None)
    if trajectory.get('type') == 'line':
        trajectory = {'type': 'line', 'start': [0, 0, 5], 'direction': [1, 0, 0], 'speed': 1e6}
        with pytest.raises(ValueError, match=re.escape(words)):
            from anafi_sim.mission import trajectory as tr
            tr.scenario_from_dict({'name': 'x', 'trajectory': trajectory, 'phases': phases})
        return
    with pytest.raises(ValueError, match=re.escape(words)):
        _limited(trajectory, phases)


def test_every_shipped_scenario_is_within_the_limits():
    from anafi_sim.mission import trajectory as tr
    for name in tr.list_scenarios():
        tr.load_scenario(name)
    assert _limited().duration > 0
