"""anafi_control.mpc_tracking: the mpc_controller cycle (inputs, staleness, solver failure, hover and
recovery, counters; the contract's shared cases are in test_contract.py), the twist frame option, the yaw PID
(Table 2 via the PID framework config), live reconfiguration, and a closed loop on a simple attitude-driven
point mass (sign chain end to end)."""
import math

import numpy as np
import pytest

from anafi_control.frames import euler_to_quaternion, wrap_angle
from anafi_control.contract import HOVER
from anafi_control.mpc_tracking import MpcTracking, mpc_params_from_flat, predicted_positions, reference_positions
from anafi_control.pid import PidController
from anafi_control.pid_framework import DEFAULT_CONFIG

LEVEL = euler_to_quaternion(0.0, 0.0, 0.0)
WP = (3.0, 2.0, 5.0, 0.0, 0.0, 0.0, 0.0)


def _q(yaw_deg, roll=0.0, pitch=0.0):
    return euler_to_quaternion(roll, pitch, math.radians(yaw_deg))


def _ready(tr, t=0.0, pos=(0.0, 0.0, 1.0), yaw_deg=0.0, vel=(0.0, 0.0, 0.0), wp=WP):
    assert tr.on_waypoint(t, wp)
    assert tr.on_state(t, pos, _q(yaw_deg), vel)


# ----------------------------------------------------------------------------- odometry

def test_twist_frame_option():
    body = MpcTracking()
    world = MpcTracking(twist_in_child_frame=False)
    for tr in (body, world):
        assert tr.on_state(0.0, (1, 2, 3), [2 * c for c in _q(90.0)], (1.0, 0.0, 0.0))
    np.testing.assert_allclose(body.state.velocity, (0.0, 1.0, 0.0), atol=1e-12)   # forward at 90 deg = +y
    np.testing.assert_allclose(world.state.velocity, (1.0, 0.0, 0.0))
    assert body.state.yaw == world.state.yaw == pytest.approx(math.pi / 2, abs=1e-12)
    np.testing.assert_allclose(body.state.position, (1, 2, 3))


# ----------------------------------------------------------------------------- cycle

def test_no_inputs_no_command_with_reason_and_counters():
    tr = MpcTracking()
    out = tr.cycle(0.0)
    assert out.command is None and not out.ok and out.key == 'no_state'
    tr.on_state(0.0, (0, 0, 1), LEVEL, (0, 0, 0))
    out = tr.cycle(0.05)
    assert out.command is None and out.key == 'no_waypoint' and 'waypoint' in out.reason
    assert tr.counters['no_state'] == 1 and tr.counters['no_waypoint'] == 1 and tr.counters['hover'] == 2
    assert tr.counters['cycles'] == 2 and tr.counters['ok'] == 0


def test_good_cycle_signs_at_heading_0_and_180():
    tr = MpcTracking()
    _ready(tr)
    out = tr.cycle(0.0)
    assert out.ok and out.key == 'ok'
    roll, pitch, yaw_rate, gaz = out.command
    assert pitch > 5.0          # waypoint ahead (+x): nose down
    assert roll < -2.0          # waypoint to the left (+y): roll left = negative
    assert gaz > 0.5            # waypoint above
    assert out.result.ok and out.result.iterations > 0
    # same waypoint, drone facing -x: +x is behind (pitch up), +y is to the right (roll right)
    tr = MpcTracking()
    _ready(tr, yaw_deg=180.0, wp=(3.0, 2.0, 5.0, 0.0, 0.0, 0.0, 180.0))
    roll, pitch, _, _ = tr.cycle(0.0).command
    assert pitch < -5.0 and roll > 2.0


def test_command_matches_mpc_core_output():
    tr = MpcTracking()
    _ready(tr, pos=(0.5, -0.2, 2.0), vel=(0.3, 0.1, -0.2), yaw_deg=30.0)
    out = tr.cycle(0.0)
    from anafi_control.mpc import CumulativeErrorMpc, piloting_from_result
    ref = CumulativeErrorMpc().solve((0.5, -0.2, 2.0), tr.state.velocity, WP[:3], WP[3:6])
    roll, pitch, gaz = piloting_from_result(ref, math.radians(30.0))
    np.testing.assert_allclose(out.command[0], roll, atol=1e-6)
    np.testing.assert_allclose(out.command[1], pitch, atol=1e-6)
    np.testing.assert_allclose(out.command[3], gaz, atol=1e-6)
    assert out.command[3] == out.result.vz_command == pytest.approx(np.clip(out.result.x_pred[5, 11], -2, 2))


def test_stale_state_then_recovery():
    tr = MpcTracking(state_timeout=0.5, waypoint_timeout=10.0)
    _ready(tr)
    assert tr.cycle(0.4).ok
    out = tr.cycle(0.6)
    assert not out.ok and out.key == 'stale_state' and out.command is None and 'stale state' in out.reason
    tr.on_state(0.7, (0, 0, 1), LEVEL, (0, 0, 0))
    assert tr.cycle(0.7).ok
    assert tr.counters['stale_state'] == 1 and tr.counters['ok'] == 2


def test_stale_waypoint_then_recovery():
    tr = MpcTracking(state_timeout=10.0, waypoint_timeout=1.0)
    _ready(tr)
    out = tr.cycle(1.2)
    assert out.key == 'stale_waypoint' and not out.ok          # holds where it is: (0, 0, 1), at rest
    assert out.command[1] == pytest.approx(0.0, abs=1e-3) and out.result.ok
    tr.on_waypoint(1.3, WP)
    assert tr.cycle(1.3).ok


def test_clock_jumping_back_drops_the_inputs():
    tr = MpcTracking()
    _ready(tr, t=100.0)
    assert tr.cycle(100.1).ok
    assert tr.cycle(3.0).key == 'clock_jump'
    assert tr.counters['clock_jumps'] == 1


def test_state_arriving_just_after_the_cycle_time_is_fresh():
    # the node reads the clock, then a state callback stamped a few ms later wins the lock first
    tr = MpcTracking()
    _ready(tr, t=10.005)
    assert tr.cycle(10.0).ok


@pytest.mark.parametrize('which', ['state', 'waypoint'])
def test_non_finite_input_hovers_then_recovers(which):
    tr = MpcTracking()
    _ready(tr)
    assert tr.cycle(0.0).ok
    if which == 'state':
        assert not tr.on_state(0.05, (float('nan'), 0, 1), LEVEL, (0, 0, 0))
    else:
        assert not tr.on_waypoint(0.05, (3, 2, float('inf'), 0, 0, 0, 0))
    out = tr.cycle(0.1)
    assert not out.ok and out.key == 'bad_' + which
    if which == 'state':
        assert out.command is None                       # silent: the firmware brakes
    else:                                                # hold at (0, 0, 1), at rest: nearly nothing to do
        assert max(abs(v) for v in out.command) < 0.1
    assert tr.counters['rejected_%ss' % which] == 1
    # the last good value of the other input is still there; a good message restores the command
    if which == 'state':
        tr.on_state(0.15, (0, 0, 1), LEVEL, (0, 0, 0))
    else:
        tr.on_waypoint(0.15, WP)
    assert tr.cycle(0.2).ok


def test_solver_failure_hovers_then_recovers():
    tr = MpcTracking({'max_iter': 1})          # OSQP stops unsolved
    _ready(tr)
    out = tr.cycle(0.0)
    assert not out.ok and out.key == 'solver_failed' and out.command is None
    assert out.reason.startswith('solver: ') and out.result is not None and not out.result.ok
    tr.reconfigure({'max_iter': 4000})          # live, as dynamic_reconfigure does it (no rebuild)
    tr.on_state(0.05, (0, 0, 1), LEVEL, (0, 0, 0))
    assert tr.cycle(0.1).ok and tr.counters['solver_failed'] == 1


def test_reconfigured_iteration_limit_fails_the_solver_in_flight():
    """The fault matrix's solver failure: max_iter lowered to 1 while flying -> 'maximum iterations reached',
    no command (the firmware brake), key solver_failed; back to 4000 -> commands again. Bad values refused."""
    tr = MpcTracking()
    _ready(tr)
    solver = tr.mpc._solver
    assert tr.cycle(0.0).ok
    assert tr.reconfigure({'max_iter': 1})['max_iter'] == 1 and tr.mpc._solver is solver
    tr.on_waypoint(0.05, (-4.0, 3.0, 2.0, 1.0, 0.0, 0.0, 0.0))
    tr.on_state(0.05, (0.1, 0, 1), LEVEL, (0.5, 0, 0))
    out = tr.cycle(0.1)
    assert out.key == 'solver_failed' and out.command is None
    assert 'maximum iterations' in out.result.status.lower()
    for bad in (0, 2.5, -3):
        with pytest.raises(ValueError):
            tr.reconfigure({'max_iter': bad})
        assert tr.config()['max_iter'] == 1
    tr.reconfigure({'max_iter': 4000})
    tr.on_state(0.15, (0.1, 0, 1), LEVEL, (0.5, 0, 0))
    assert tr.cycle(0.2).ok and tr.counters['solver_failed'] == 1


def test_fast_start_gives_a_real_command_not_hover():
    tr = MpcTracking()
    _ready(tr, vel=(0.0, 0.0, 4.0))             # |v_z| = 4 m/s > 2 m/s: clipped into x_0, not infeasible
    out = tr.cycle(0.0)
    assert out.ok and out.command is not None and out.result.velocity_clipped
    assert tr.counters['velocity_clipped'] == 1 and tr.counters['hover'] == 0
    assert out.command[1] > 5.0                 # still flies towards the waypoint ahead


def test_paper_timing_commands_come_from_the_previous_cycle():
    paper, now = MpcTracking({'paper_timing': True}), MpcTracking({'paper_timing': False})
    states = [((0, 0, 1), (0, 0, 0)), ((0.2, 0.1, 1.2), (1.0, 0.5, 0.5)), ((0.5, 0.2, 1.5), (2.0, 0.8, 1.0))]
    wps = [WP, WP, (-3.0, 4.0, 6.0, 0.0, 0.0, 0.0, 0.0)]
    prev = None
    for k, ((pos, vel), wp) in enumerate(zip(states, wps)):
        t = 0.1 * k
        for tr in (paper, now):
            tr.on_waypoint(t, wp)
            tr.on_state(t, pos, LEVEL, vel)
        op, on = paper.cycle(t), now.cycle(t)
        assert op.ok and on.ok
        if prev is not None:     # state and waypoint given before cycle k-1, not the newest ones
            assert op.result.delayed
            np.testing.assert_allclose(op.result.inputs[0], states[k - 1][0])
            np.testing.assert_allclose(op.command, prev.command, atol=0.05)
            assert abs(op.command[1] - on.command[1]) > 0.5
        prev = on
    paper.cycle(10.0)            # stale -> silent: the held inputs are dropped
    paper.on_waypoint(10.1, WP)
    paper.on_state(10.1, (0, 0, 1), LEVEL, (0, 0, 0))
    assert not paper.cycle(10.1).result.delayed


# ----------------------------------------------------------------------------- yaw

def test_yaw_pid_is_the_frameworks_yaw_loop():
    tr = MpcTracking()
    assert tr.yaw_config == DEFAULT_CONFIG['yaw']
    ref = PidController(**DEFAULT_CONFIG['yaw'])
    wp = (3.0, 2.0, 5.0, 0.0, 0.0, 0.0, 90.0)
    tr.on_waypoint(0.0, wp)
    expected = 0.0
    for k, yaw in enumerate((0.0, 5.0, 12.0, 20.0)):
        t = k / 30.0
        tr.on_state(t, (0, 0, 1), _q(yaw), (0, 0, 0))
        e = ref.update(90.0, yaw, t)
        if e is not None:
            expected = e
        assert tr.yaw_rate == pytest.approx(expected, abs=1e-9)
    assert expected > 30.0   # counter-clockwise towards +90 deg
    assert tr.cycle(0.1).command[2] == pytest.approx(expected, abs=1e-9)


def test_yaw_takes_the_short_way_across_180():
    tr = MpcTracking()
    tr.on_waypoint(0.0, (0, 0, 1, 0, 0, 0, -170.0))
    tr.on_state(0.0, (0, 0, 1), _q(170.0), (0, 0, 0))
    tr.on_state(1.0 / 30, (0, 0, 1), _q(170.0), (0, 0, 0))
    assert 0.0 < tr.yaw_rate < 20.0   # +20 deg CCW, not -340 deg


def test_hover_resets_yaw_loop():
    tr = MpcTracking()
    _ready(tr, wp=(3, 2, 5, 0, 0, 0, 90.0))
    tr.on_state(0.033, (0, 0, 1), _q(0.0), (0, 0, 0))
    assert tr.yaw_rate > 0
    tr.cycle(5.0)  # stale -> hover
    assert tr.yaw_rate == 0.0 and tr.yaw_pid.prev_time is None


# ----------------------------------------------------------------------------- configuration

def test_parameters_flat_and_bad_ones_raise():
    p = mpc_params_from_flat({'v_max_z': 1.0, 'a_max': 4.0, 'N': 20})
    assert p['v_max'] == (10.0, 10.0, 1.0) and p['a_max'] == 4.0 and p['N'] == 20
    with pytest.raises(ValueError):
        mpc_params_from_flat({'q_cumm': 1.0})
    with pytest.raises(ValueError):
        MpcTracking(state_timeout=0.0)
    with pytest.raises(ValueError):
        MpcTracking(waypoint_timeout=float('nan'))
    with pytest.raises(ValueError):
        MpcTracking(yaw_config={'Kpp': 1.0})
    with pytest.raises(ValueError):
        MpcTracking({'r': -1.0})


def test_reconfigure_weight_changes_command():
    a, b = MpcTracking(), MpcTracking()
    _ready(a, pos=(1.0, 1.0, 4.0))
    _ready(b, pos=(1.0, 1.0, 4.0))
    solver = a.mpc._solver
    cfg = a.reconfigure({'r': 1000.0, 'unrelated': 1})
    assert cfg['r'] == 1000.0 and a.mpc._solver is solver and a.counters['reconfigurations'] == 1
    pa, pb = a.cycle(0.0).command[1], b.cycle(0.0).command[1]
    assert 0.0 < pa < 0.5 * pb     # heavier input weight -> gentler pitch
    # an unchanged config is not counted
    a.reconfigure(a.config())
    assert a.counters['reconfigurations'] == 1


def test_reconfigure_limits_horizon_and_invalid_values():
    tr = MpcTracking()
    _ready(tr)
    tr.reconfigure({'v_max_z': 0.5, 'N': 20})
    out = tr.cycle(0.0)
    assert out.ok and out.result.x_pred.shape == (21, 18) and 0.0 < out.command[3] <= 0.5
    before = tr.config()
    with pytest.raises(ValueError):
        tr.reconfigure({'r': 0.0, 'q_cum': 2.0})
    assert tr.config() == before
    with pytest.raises(ValueError):
        tr.reconfigure({'N': 3})   # shorter than vz_step 5
    assert tr.config() == before and tr.cycle(0.05).ok


def test_carry_option_and_waypoint_jump_reset():
    tr = MpcTracking({'carry_cumulative_errors': False})
    tr.reconfigure({'carry_cumulative_errors': True})
    assert tr.mpc.carry_cumulative_errors
    # a waypoint moving at its own velocity is no jump
    for k in range(5):
        t = 0.1 * k
        tr.on_waypoint(t, (1.0 * t, 0, 5, 1.0, 0, 0, 0))
        tr.on_state(t, (0, 0, 5), LEVEL, (0, 0, 0))
        assert tr.cycle(t).ok
    assert tr.mpc.cumulative_errors[0] > 0.5 and tr.counters['waypoint_jumps'] == 0
    tr.on_waypoint(0.5, (10.0, 0, 5, 0, 0, 0, 0))
    assert tr.counters['waypoint_jumps'] == 1 and not tr.mpc.cumulative_errors.any()
    # a clock jump (simulation restart) resets them too
    for t in (0.6, 0.7):
        tr.on_waypoint(t, (10.0, 0, 5, 0, 0, 0, 0))
        tr.on_state(t, (0, 0, 5), LEVEL, (0, 0, 0))
        assert tr.cycle(t).ok
    assert tr.mpc.cumulative_errors.any()
    tr.on_state(0.0, (0, 0, 5), LEVEL, (0, 0, 0))
    assert tr.counters['clock_jumps'] == 1 and not tr.mpc.cumulative_errors.any()


def test_paths():
    tr = MpcTracking()
    _ready(tr, wp=(3.0, 2.0, 5.0, 1.0, 0.0, 0.0, 0.0))
    out = tr.cycle(0.0)
    pred, ref = predicted_positions(out.result), reference_positions(out.result)
    assert pred.shape == ref.shape == (31, 3)
    np.testing.assert_allclose(pred[0], (0, 0, 1), atol=1e-4)
    np.testing.assert_allclose(ref[0], (3, 2, 5))
    np.testing.assert_allclose(ref[30], (6, 2, 5))   # 3 s at 1 m/s (constant-velocity model)
    assert predicted_positions(None) is None and reference_positions(tr.cycle(99.0).result) is None


# ----------------------------------------------------------------------------- closed loop

def _fly(wp, seconds=20.0, yaw0=0.0):
    """Attitude-driven point mass: a_fwd = g sin(pitch), a_left = -g sin(roll), v_z first order to gaz,
    yaw integrates the yaw rate; states at 30 Hz, cycles at 10 Hz. Returns the position track."""
    tr = MpcTracking()
    g, dt = 9.81, 1.0 / 30.0
    p, v, yaw = np.array([0.0, 0.0, 1.0]), np.zeros(3), math.radians(yaw0)
    cmd = HOVER
    track = []
    for k in range(int(seconds / dt)):
        t = k * dt
        tr.on_waypoint(t, wp)
        body_v = (math.cos(yaw) * v[0] + math.sin(yaw) * v[1], -math.sin(yaw) * v[0] + math.cos(yaw) * v[1], v[2])
        tr.on_state(t, p, _q(math.degrees(yaw)), body_v)
        if k % 3 == 0:
            cmd = tr.cycle(t).command
        roll, pitch, yaw_rate, gaz = cmd
        a_fwd, a_left = g * math.sin(math.radians(pitch)), -g * math.sin(math.radians(roll))
        a = np.array([math.cos(yaw) * a_fwd - math.sin(yaw) * a_left,
                      math.sin(yaw) * a_fwd + math.cos(yaw) * a_left, 0.0])
        v[:2] += a[:2] * dt
        v[2] += (gaz - v[2]) * dt / 0.3
        p += v * dt
        yaw = wrap_angle(yaw + math.radians(yaw_rate) * dt)
        track.append(p.copy())
    return np.array(track), yaw, tr


@pytest.mark.parametrize('wp_yaw', [0.0, 180.0])
def test_closed_loop_reaches_static_waypoint(wp_yaw):
    track, yaw, tr = _fly((3.0, 2.0, 5.0, 0.0, 0.0, 0.0, wp_yaw))
    assert np.linalg.norm(track[-1] - (3.0, 2.0, 5.0)) < 0.15
    assert abs(wrap_angle(yaw - math.radians(wp_yaw))) < math.radians(3.0)
    assert tr.counters['hover'] == 0
