"""The in-process engine (anafi_lab.engine.engine): determinism, the graph's schedule as the controller
sees it, the distributed PID's message hops, a run against a hand computation, the run files."""
import math
import os

import pytest
import yaml

from anafi_control.contract import OK, Controller, CycleOutput
from anafi_lab.engine.engine import DEFAULT_SCHEDULE, Engine, make_schedule, run
from anafi_lab.engine.runs import make_task, result_line, run_task
from anafi_sim.sim.drone_model import load_model_params

SHORT = """
name: short_circle
start: trajectory
trajectory: {type: circle, centre: [0.0, 0.0, 1.5], radius: 0.5, speed: 0.5, yaw: 0.0}
phases:
  - {name: approach, duration: 1.0, hold: start}
  - {name: measure, duration: 2.0, measure: true}
"""

HOVER = """
name: hover
start: {x: 0.0, y: 0.0, z: 1.0, yaw: 0.0}
trajectory: {type: static, position: [0.0, 0.0, 1.0], yaw: 0.0}
phases:
  - {name: hold, duration: 30.0, hold: start}
  - {name: measure, duration: 1.0, measure: true}
"""


@pytest.fixture
def short(tmp_path):
    path = tmp_path / 'short_circle.yaml'
    path.write_text(SHORT)
    return str(path)


def test_a_short_run_gives_the_evaluators_summary(short):
    result = run(short, 'mpc')
    assert result.ok and result.error == ''
    s = result.summary
    assert s['state'] == 'final' and s['name'] == 'short_circle_mpc'
    assert list(s)[:10] == ['name', 'samples', 'window', 'duration', 'estimate', 'truth', 'garbage',
                          'garbage_samples', 'truth_missing', 'warnings']
    assert 55 <= s['samples'] <= 62                        # 2 s of the 30 Hz estimate
    assert s['window'][1] - s['window'][0] == pytest.approx(2.0, abs=1e-3)
    assert 0.0 < s['estimate']['e_mu'] < 0.5 and 0.0 < s['truth']['e_mu'] < 0.5
    assert result.info['achieved_rtf'] > 0.0 and result.info['scenario_sim_s'] == pytest.approx(3.0, abs=0.11)


def test_same_seed_same_summary_bit_for_bit_wind_gusts_included(short):
    wind = {'wind_x': 0.5, 'wind_y': -0.3, 'gust_std_horizontal': 0.8, 'gust_std_vertical': 0.2}
    for controller in ('mpc', 'pid'):
        a = run(short, controller, seed=7, wind=wind).summary
        b = run(short, controller, seed=7, wind=wind).summary
        assert yaml.safe_dump(a) == yaml.safe_dump(b), controller
        c = run(short, controller, seed=8, wind=wind).summary
        assert c['estimate'] != a['estimate'], 'the gusts depend on the seed'


class Recorder(Controller):
    """Records what a controller node sees: state receipt times, cycle times, and hovers."""
    RATE = 10.0

    def __init__(self):
        Controller.__init__(self)
        self.states, self.cycles = [], []

    def on_state(self, t, position, orientation, twist_linear):
        self.states.append(round(t * 1000.0, 3))
        return Controller.on_state(self, t, position, orientation, twist_linear)

    def _compute(self, t, inputs):
        self.cycles.append((round(t * 1000.0, 3), self.states[-1]))
        return CycleOutput((0.0, 0.0, 0.0, 0.0), True, OK, OK, None)


@pytest.mark.parametrize('latency, shift', [(0.0005, 0), (0.006, 10)])
def test_the_controller_sees_the_estimate_of_the_right_period_with_the_delay(short, latency, shift):
    """drone/odom goes out at 30 Hz on the 200 Hz physics ticks (5, 35, 70, 100, 135, ... ms); the node
    receives it message_latency x ros_rtf later and stamps the receipt with its /clock (the tick it has):
    1 ms -> the same tick, 12 ms -> two ticks later. The 10 Hz cycle (phase 30 ms) holds the newest."""
    recorder = Recorder()
    engine = Engine(short, lambda: recorder, schedule={'message_latency': latency}, max_sim_time=2.0)
    engine.run()
    ticks = sorted(set([5] + [int(math.ceil(20.0 * k / 3.0)) * 5 for k in range(1, 61)]))  # ceil(k/30 s) on 5 ms
    expected = [t + shift for t in ticks if t + shift < 2000]
    assert recorder.states[:len(expected)] == expected
    cycles = [c for c, _ in recorder.cycles]
    assert cycles[:3] == [c for c in cycles[:3] if (c - 30) % 100 == 0] and len(cycles) >= 15
    for cycle, state in recorder.cycles:
        newest = max(t for t in expected if t + (latency * 2000 if shift == 0 else shift) <= cycle + 1e-9)
        assert state == (newest if shift else max(t for t in ticks if t < cycle)), cycle


def test_distributed_pid_inner_loops_compute_on_the_state_and_again_on_the_outer_effort(short):
    """One message hop: an inner loop computes when its state arrives (with the last outer effort) and
    again when the new outer effort arrives, one tick later (1 ms hop + 2 ms coalescing: the node's clock
    has moved to the next 5 ms tick). When the hops take no time, the second computation falls on the same
    tick: dt = 0, skipped as the pid package skips it (after shifting its error history)."""
    def counts(engine):
        return dict((node.effort.name.split('/')[1], node) for node in engine.loops)
    engine = Engine(short, 'pid')
    engine.run()
    loops = counts(engine)
    cycles = engine.relative_state.published_cycles
    assert loops['x_outer'].computations == pytest.approx(cycles, abs=1)
    assert loops['vertical'].computations == pytest.approx(cycles, abs=1)
    for inner in ('x_inner', 'y_inner'):
        assert loops[inner].computations == pytest.approx(2 * cycles, abs=3)
        assert loops[inner].pid.skipped_dt_zero == 0
    instant = Engine(short, 'pid', schedule={'message_latency': 0.0, 'pid_coalesce': 0.0})
    instant.run()
    loops = counts(instant)
    cycles = instant.relative_state.published_cycles
    for inner in ('x_inner', 'y_inner'):
        assert loops[inner].pid.skipped_dt_zero == pytest.approx(cycles, abs=3)
    assert loops['x_outer'].pid.skipped_dt_zero <= 1


class Climb(Controller):
    """Open loop: zero commands, then gaz +1 m/s from ``t0`` [s] on."""
    RATE = 10.0

    def __init__(self, t0):
        Controller.__init__(self)
        self.t0 = t0

    def _compute(self, t, inputs):
        return CycleOutput((0.0, 0.0, 0.0, 1.0 if t >= self.t0 - 1e-9 else 0.0), True, OK, OK, None)


def test_an_open_loop_climb_matches_the_hand_computation(tmp_path):
    """Hover under zero commands, then gaz = 1 m/s from the first cycle at or after 8 s (8.03 s: phase 30 ms).
    The command reaches the simulator within the same 5 ms tick (1 ms), the step from 8.030 s applies it (PCMD
    50 % of 2 m/s), the firmware starts after attitude_delay at the first step from >= 8.030 + 0.1246 s, i.e.
    8.155 s; then per 5 ms step v_z += clip(c (1 - v_z), -A dt, A dt), c = 1 - exp(-dt / tau_vz), A the
    vertical_acceleration_limit (none when 0), and z += dt v_z (semi-implicit Euler)."""
    path = tmp_path / 'hover.yaml'
    path.write_text(HOVER)
    engine = Engine(str(path), lambda: Climb(8.0), max_sim_time=9.5)
    engine.run()
    truth = dict((round(t * 1e-6), row) for t, row in engine.evaluator.streams['truth'])     # ms -> state
    params = load_model_params()
    dt = 0.005
    start_ms = int(round(1000 * (8.030 + math.ceil((params['attitude_delay'] - 1e-9) / dt) * dt)))
    assert start_ms == 8155
    c = 1.0 - math.exp(-dt / params['vertical_speed_time_constant'])
    cap = params.get('vertical_acceleration_limit', 0.0) * dt or float('inf')
    z0 = truth[8150][2]
    for ms in range(6000, 8160, 10):                      # hovering: nothing moves
        assert truth[ms][2] == pytest.approx(z0, abs=1e-9) and abs(truth[ms][0]) < 1e-9 and abs(truth[ms][1]) < 1e-9
    vz, climbed, n = 0.0, 0.0, 0
    limited = 0
    for ms in range(8160, 9500, 10):
        while n < (ms - start_ms) // 5:
            step = c * (1.0 - vz)
            limited += step > cap
            vz += min(cap, step)
            climbed += dt * vz
            n += 1
        assert truth[ms][2] - z0 == pytest.approx(climbed, abs=1e-9), ms
        assert truth[ms][5] == pytest.approx(vz, abs=1e-9), ms
    if params.get('vertical_acceleration_limit', 0.0) > 0.0:
        assert limited > 0        # the shipped limit (~6 m/s^2) binds on a 1 m/s step of tau ~0.08 s


def test_controllers_by_name_and_import_path(short):
    for controller in ('pid_single', 'anafi_control.pid_framework:PidTracking'):
        result = run(short, controller)
        assert result.ok, controller
        assert result.summary['estimate']['e_mu'] < 1.0
    with pytest.raises(ValueError):
        run(short, 'nonsense')


def test_schedule_parameters_are_checked():
    assert make_schedule() == DEFAULT_SCHEDULE
    assert make_schedule({'generator_phase': 0.05})['generator_phase'] == 0.05
    for bad in ({'no_such_key': 1.0}, {'physics_rate': 0.0}, {'message_latency': -1.0}, {'ros_rtf': 'fast'}):
        with pytest.raises(ValueError):
            make_schedule(bad)


def test_a_run_that_never_ends_is_reported(short):
    result = run(short, 'mpc', max_sim_time=2.0)
    assert not result.ok and 'did not end' in result.error and result.summary['state'] == 'incomplete'


def test_run_task_writes_the_summary_and_the_csv(short, tmp_path):
    out = str(tmp_path / 'out')
    record = run_task(make_task(short, 'pid', out_dir=out, seed=1))
    assert record['ok'] and record['scenario'] == 'short_circle'
    assert sorted(os.listdir(out)) == ['short_circle_pid.csv', 'short_circle_pid.yaml']
    with open(os.path.join(out, 'short_circle_pid.yaml')) as f:
        assert yaml.safe_load(f) == record['summary']
    line = result_line(record)
    assert line.startswith('RESULT short_circle_pid  ok  e_mu ') and '\n' not in line
    bad = run_task(make_task('no_such_scenario', 'pid'))
    assert not bad['ok'] and 'no_such_scenario' in bad['error']


def test_actions_run_once_at_their_time_after_the_start(short):
    from anafi_lab.engine.event_loop import to_ns
    seen = []
    engine = Engine(short, 'mpc', actions=[(0.5, lambda e: seen.append((e.world.loop.now, e.started_at,
                                                                       e.sim.model.position())))])
    assert engine.run().ok
    assert len(seen) == 1
    now, started, position = seen[0]
    assert now == to_ns(started + 0.5) and position[2] > 1.0
    for bad in ([(-1.0, lambda e: None)], [(0.0, lambda e: None)], [(0.5, 'not callable')],
                [(float('nan'), lambda e: None)]):
        with pytest.raises(ValueError):
            Engine(short, 'mpc', actions=bad)
