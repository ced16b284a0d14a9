"""anafi_control.pid_framework: stability-axes relative state, loop wiring, command signs, safety, closed loop."""
import math
import os

import pytest
import yaml

from anafi_control.contract import HOVER, LIMIT_DEFAULTS
from anafi_control.pid_framework import (DEFAULT_CONFIG, LOOP_NAMES, PidFramework,
                                         make_config, relative_state)
from anafi_sim.sim.bridge import PilotingMapping
from conftest import ROOT

S = math.sqrt(0.5)
DT = 1.0 / 30.0


# -- relative state -------------------------------------------------------------------
@pytest.mark.parametrize('heading_deg,rel_xy,vel_xy', [
    (0.0, (1.0, 0.0), (0.0, 2.0)),
    (90.0, (0.0, -1.0), (2.0, 0.0)),         # facing +y: world +x is to the right
    (180.0, (-1.0, 0.0), (0.0, -2.0)),       # facing -x: world +x is behind
    (-135.0, (-S, S), (-2 * S, -2 * S)),     # facing south-west
])
def test_relative_state_in_stability_axes(heading_deg, rel_xy, vel_xy):
    # waypoint 1 m east and 1 m above the drone; drone flying north at 2 m/s, climbing 0.5 m/s
    rel = relative_state((1.0, 2.0, 3.0), (0.0, 2.0, 0.5), math.radians(heading_deg),
                         (2.0, 2.0, 4.0, 0.0, 2.0, -0.3, 45.0))
    assert (rel.wp_x, rel.wp_y) == pytest.approx(rel_xy, abs=1e-12)
    assert rel.wp_z == pytest.approx(1.0)
    assert (rel.vx, rel.vy) == pytest.approx(vel_xy, abs=1e-12)
    assert (rel.wp_vx, rel.wp_vy) == pytest.approx(vel_xy, abs=1e-12)   # same world velocity
    assert rel.vz == 0.5 and rel.wp_vz == -0.3
    assert rel.yaw_deg == pytest.approx(heading_deg) and rel.wp_yaw_deg == 45.0


@pytest.mark.parametrize('bad', [
    ((float('nan'), 0, 0), (0, 0, 0), 0.0, (1, 0, 0, 0, 0, 0, 0)),
    ((0, 0, 0), (0, float('inf'), 0), 0.0, (1, 0, 0, 0, 0, 0, 0)),
    ((0, 0, 0), (0, 0, 0), float('nan'), (1, 0, 0, 0, 0, 0, 0)),
    ((0, 0, 0), (0, 0, 0), 0.0, (1, 0, 0, 0, 0, 0, float('nan'))),
    ((0, 0, 0), (0, 0, 0), 0.0, None),
    ((0, 0, 0), (0, 0, 0), 0.0, (1, 0, 0)),
    (None, (0, 0, 0), 0.0, (1, 0, 0, 0, 0, 0, 0)),
])
def test_relative_state_refuses_missing_or_non_finite(bad):
    assert relative_state(*bad) is None


# -- configuration ------------------------------------------------------------------------
def test_yaml_matches_default_config():
    with open(os.path.join(ROOT, 'anafi_sim', 'config', 'pid.yaml')) as f:
        data = yaml.safe_load(f)
    limits = dict((k, data.pop(k)) for k in LIMIT_DEFAULTS if k in data)
    assert limits == dict(LIMIT_DEFAULTS)      # the flight envelope (anafi_control.envelope), = the code defaults
    assert sorted(data) == sorted(LOOP_NAMES)
    for loop in LOOP_NAMES:
        assert sorted(data[loop]) == sorted(DEFAULT_CONFIG[loop])
        for name, value in DEFAULT_CONFIG[loop].items():
            assert data[loop][name] == pytest.approx(value, rel=1e-12), (loop, name)


def test_default_config_is_the_paper():
    c = DEFAULT_CONFIG
    gains = dict((k, (c[k]['Kp'], c[k]['Ki'], c[k]['Kd'])) for k in LOOP_NAMES)
    assert gains == {'x_outer': (0.875, 0.0001, 0), 'x_inner': (10, 1, 0),
                     'y_outer': (0.875, 0.001, 0), 'y_inner': (-10, -1, 0),
                     'vertical': (1, 0, 0.001), 'yaw': (0.6, 0.2, 0.003)}
    limits = dict((k, (c[k]['lower_limit'], c[k]['upper_limit'])) for k in LOOP_NAMES)
    assert limits == {'x_outer': (-10, 10), 'x_inner': (-30.64, 30.64), 'y_outer': (-10, 10),
                      'y_inner': (-30.64, 30.64), 'vertical': (-2, 2), 'yaw': (-180, 180)}
    windup = dict((k, c[k]['windup_limit']) for k in LOOP_NAMES)
    assert windup == {'x_outer': 0.11, 'x_inner': 0, 'y_outer': 5, 'y_inner': 10,
                      'vertical': 0.5, 'yaw': 0.5}
    assert [k for k in LOOP_NAMES if c[k]['angle_error']] == ['yaw']
    assert c['yaw']['angle_wrap'] == 360.0
    assert all(c[k]['cutoff_frequency'] == -1 for k in LOOP_NAMES)


@pytest.mark.parametrize('overrides', [
    {'z_outer': {'Kp': 1.0}}, {'yaw': {'kp': 1.0}}, {'yaw': 3.0}, [1, 2],
])
def test_unknown_config_names_are_refused(overrides):
    with pytest.raises(ValueError):
        make_config(overrides)


@pytest.mark.parametrize('overrides', [
    {'x_inner': {'lower_limit': 40.0}}, {'vertical': {'Kd': float('nan')}},
])
def test_bad_config_values_are_refused_at_construction(overrides):
    with pytest.raises(ValueError):
        PidFramework(overrides)


def test_partial_override_keeps_other_defaults():
    fw = PidFramework({'x_outer': {'Kp': 2.0}})
    assert fw.loops['x_outer'].Kp == 2.0
    assert fw.loops['x_outer'].windup_limit == 0.11
    assert fw.loops['yaw'].Kp == 0.6
    assert DEFAULT_CONFIG['x_outer']['Kp'] == 0.875      # defaults not mutated


# -- command sign conventions (after the bridge mapping) -----------------------------
def drive(drone_pos, yaw_deg, waypoint, cycles=6, vel=(0.0, 0.0, 0.0), fw=None):
    fw = fw or PidFramework()
    for k in range(cycles):
        assert fw.update(k * DT, drone_pos, vel, math.radians(yaw_deg), waypoint)
    return fw, fw.command(), PilotingMapping().to_pcmd(*fw.command())


def test_target_ahead_pitches_nose_down():
    _, cmd, pcmd = drive((0, 0, 5), 0.0, (4, 0, 5, 0, 0, 0, 0))
    assert cmd[1] > 0 and pcmd[1] > 0
    assert pcmd[0] == 0 and pcmd[2] == 0 and pcmd[3] == 0


def test_target_left_rolls_left():
    _, cmd, pcmd = drive((0, 0, 5), 0.0, (0, 4, 5, 0, 0, 0, 0))
    assert cmd[0] < 0 and pcmd[0] < 0
    assert pcmd[1] == 0


def test_target_left_at_heading_90_is_world_minus_x():
    _, cmd, pcmd = drive((0, 0, 5), 90.0, (-4, 0, 5, 0, 0, 0, 90))
    assert pcmd[0] < 0 and pcmd[1] == 0 and pcmd[2] == 0


def test_target_above_climbs():
    _, cmd, pcmd = drive((0, 0, 5), 0.0, (0, 0, 6, 0, 0, 0, 0))
    assert cmd[3] > 0 and pcmd[3] > 0
    assert pcmd[:3] == (0, 0, 0)


def test_counter_clockwise_yaw_target_gives_positive_ros_rate_negative_pcmd():
    _, cmd, pcmd = drive((0, 0, 5), 0.0, (0, 0, 5, 0, 0, 0, 30.0))
    assert cmd[2] > 0 and pcmd[2] < 0


def test_heading_180_target_at_world_plus_x_is_behind():
    _, cmd, pcmd = drive((0, 0, 5), 180.0, (4, 0, 5, 0, 0, 0, 180.0))
    assert cmd[1] < 0 and pcmd[1] < 0 and pcmd[0] == 0


@pytest.mark.parametrize('target,drone,sign', [(179.0, -179.0, -1), (-179.0, 179.0, +1),
                                               (-170.0, 175.0, +1), (170.0, -175.0, -1)])
def test_yaw_error_wraps_across_180(target, drone, sign):
    fw, cmd, pcmd = drive((0, 0, 5), drone, (0, 0, 5, 0, 0, 0, target))
    assert sign * cmd[2] > 0
    assert abs(cmd[2]) < 0.6 * 20 + 1     # a small error (<= 15 deg), not ~350 deg
    assert abs(fw.loops['yaw'].error[0]) <= 15.0


def test_moving_target_lag_has_no_velocity_feed_forward():
    # waypoint on top of the drone but moving at 3 m/s: no feed-forward -> no command
    _, cmd, _ = drive((0, 0, 5), 0.0, (0, 0, 5, 3.0, 0, 0, 0))
    assert cmd == (0.0, 0.0, 0.0, 0.0)


def test_inner_loops_track_outer_effort_against_own_velocity():
    # already flying forward faster than the outer loop asks -> pitch back
    _, cmd, _ = drive((0, 0, 5), 0.0, (1, 0, 5, 0, 0, 0, 0), vel=(5.0, 0, 0))
    assert cmd[1] < 0


# -- safety -------------------------------------------------------------------------------
def test_hover_before_any_good_cycle_and_on_first_cycle():
    fw = PidFramework()
    assert fw.command() == HOVER
    fw.update(0.0, (0, 0, 0), (0, 0, 0), 0.0, (5, 5, 5, 0, 0, 0, 90))
    assert fw.command() == HOVER         # first computation of every loop publishes nothing
    fw.update(DT, (0, 0, 0), (0, 0, 0), 0.0, (5, 5, 5, 0, 0, 0, 90))
    assert all(v != 0.0 for v in fw.command())


@pytest.mark.parametrize('where', ['pos', 'vel', 'yaw', 'wp', 'wp_missing', 't'])
def test_non_finite_or_missing_input_gives_hover_and_restarts_loops(where):
    fw, cmd, _ = drive((0, 0, 0), 0.0, (5, 5, 5, 0, 0, 0, 90))
    assert cmd != HOVER
    args = dict(t=10 * DT, pos=(0, 0, 0), vel=(0, 0, 0), yaw=0.0, wp=(5, 5, 5, 0, 0, 0, 90))
    nan = float('nan')
    args.update({'pos': {'pos': (0, nan, 0)}, 'vel': {'vel': (0, 0, float('inf'))},
                 'yaw': {'yaw': nan}, 'wp': {'wp': (5, 5, 5, 0, 0, 0, nan)},
                 'wp_missing': {'wp': None}, 't': {'t': nan}}[where])
    assert not fw.update(args['t'], args['pos'], args['vel'], args['yaw'], args['wp'])
    assert fw.command() == HOVER
    assert fw.rejected_inputs == 1
    # recovery: the loops restart cleanly (one first-computation cycle, then commands again)
    fw.update(11 * DT, (0, 0, 0), (0, 0, 0), 0.0, (5, 5, 5, 0, 0, 0, 90))
    assert fw.command() == HOVER
    fw.update(12 * DT, (0, 0, 0), (0, 0, 0), 0.0, (5, 5, 5, 0, 0, 0, 90))
    assert all(math.isfinite(v) and v != 0.0 for v in fw.command())


def test_disable_gives_hover():
    fw, cmd, _ = drive((0, 0, 0), 0.0, (5, 5, 5, 0, 0, 0, 90))
    fw.set_enabled(False)
    fw.update(7 * DT, (0, 0, 0), (0, 0, 0), 0.0, (5, 5, 5, 0, 0, 0, 90))
    assert fw.command() == HOVER
    fw.set_enabled(True)
    fw.update(8 * DT, (0, 0, 0), (0, 0, 0), 0.0, (5, 5, 5, 0, 0, 0, 90))
    assert fw.command() != HOVER


def test_same_time_twice_keeps_last_command():
    fw, cmd, _ = drive((0, 0, 0), 0.0, (5, 5, 5, 0, 0, 0, 90))
    fw.update(5 * DT, (1, 1, 1), (0, 0, 0), 0.0, (5, 5, 5, 0, 0, 0, 90))   # dt == 0 for every loop
    assert fw.command() == cmd
    assert fw.loops['x_outer'].skipped_dt_zero == 1


def test_outputs_respect_table1_limits():
    _, cmd, pcmd = drive((0, 0, 0), 0.0, (500, -500, 100, 0, 0, 0, 179), cycles=60)
    roll, pitch, yaw_rate, gaz = cmd
    assert abs(roll) <= 30.64 and abs(pitch) <= 30.64
    assert abs(yaw_rate) <= 180.0 and abs(gaz) <= 2.0
    assert gaz == 2.0 and pitch == 30.64 and roll == 30.64   # saturated (right = -y target)


# -- closed loop sanity check ------------------------------------------------------------
def simulate(wp_yaw_deg, seconds=40.0):
    """Crude Anafi: point mass, first-order attitude/vertical-speed response, linear drag.

    Controller at 30 Hz, command sampled and quantised through the bridge at 10 Hz,
    plant integrated at 150 Hz. Returns the list of (t, x, y, z, yaw_deg).
    """
    g, tau_att, tau_vz, drag = 9.81, 0.2, 0.3, 0.3
    mapping = PilotingMapping()
    fw = PidFramework()
    wp = (3.0, 2.0, 5.0, 0.0, 0.0, 0.0, wp_yaw_deg)
    p, v = [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]
    roll = pitch = yaw = 0.0
    setp = (0.0, 0.0, 0.0, 0.0)
    out = []
    steps = int(round(seconds * 30))
    for k in range(steps):
        t = k * DT
        fw.update(t, tuple(p), tuple(v), yaw, wp)
        if k % 3 == 0:
            setp = mapping.command_to_setpoints(*fw.command())
        roll_sp, pitch_sp, yaw_rate, vz_sp = setp
        h = DT / 5.0
        for _ in range(5):
            roll += (roll_sp - roll) * h / tau_att
            pitch += (pitch_sp - pitch) * h / tau_att
            yaw = math.atan2(math.sin(yaw + yaw_rate * h), math.cos(yaw + yaw_rate * h))
            a_fwd, a_left = g * math.tan(pitch), -g * math.tan(roll)
            ax = math.cos(yaw) * a_fwd - math.sin(yaw) * a_left - drag * v[0]
            ay = math.sin(yaw) * a_fwd + math.cos(yaw) * a_left - drag * v[1]
            v[0] += ax * h
            v[1] += ay * h
            v[2] += (vz_sp - v[2]) * h / tau_vz
            for i in range(3):
                p[i] += v[i] * h
        out.append((t, p[0], p[1], p[2], math.degrees(yaw)))
    return out


@pytest.mark.parametrize('wp_yaw_deg', [0.0, 180.0])
def test_closed_loop_reaches_static_waypoint(wp_yaw_deg):
    traj = simulate(wp_yaw_deg)
    settled = [s for s in traj if s[0] >= 30.0]
    dist = [math.sqrt((x - 3) ** 2 + (y - 2) ** 2 + (z - 5) ** 2) for _, x, y, z, _ in settled]
    yaw_err = [abs((yd - wp_yaw_deg + 180.0) % 360.0 - 180.0) for *_, yd in settled]
    assert max(dist) < 0.3
    # yaw stops inside the PCMD dead band: |0.6 e| < 1.8 deg/s (1 %) -> e < 3 deg (+ tiny Ki term)
    assert max(yaw_err) < 3.5
    # and it did not get there by flying off first
    assert max(math.sqrt((x - 3) ** 2 + (y - 2) ** 2) for _, x, y, _, _ in traj) < 6.0
