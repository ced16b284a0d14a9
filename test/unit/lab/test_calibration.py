"""anafi_lab.calibration: each fit recovers known parameters from synthetic data; real-log fit is sane;
the texts (report) and the figure (plot) are written from it.

Synthetic data are produced by small independent simulators written here (explicit Euler at a fine step),
not by the module's own response functions, so a wrong fit or a wrong response function fails.
"""
import math
import os
import re

import numpy as np
import pytest
import yaml
from scipy.signal import lfilter

from anafi_control import frames
from anafi_sim import paths
from anafi_lab.calibration.commands import reconstruct_mpc_commands, reconstruct_pid_commands, replay_translation
from anafi_lab.calibration.drag import fit_drag, steady_state_pitch
from anafi_lab.calibration.estimate import (estimate_change_rate, estimate_grid, estimate_model_response,
                                            estimate_quantum, fit_estimate, fit_position_fusion, fit_velocity_error,
                                            float16_fraction, fused_position_response, fusion_profile,
                                            grid_concentration, lag_along_motion, quantum_fraction)
from anafi_lab.calibration.fit import MODEL_KEYS, SHIPPED_EFFECTS, calibrate
from anafi_lab.calibration.logs import is_clean, thrust_axis
from anafi_lab.calibration.responses import (evaluate_first_order_delay, first_order_response, fit_attitude_response,
                                             fit_first_order_delay, gyroscopic_tilt_response, rate_limited_response,
                                             rate_limited_tilt_response)
from anafi_lab.reports import calibration_plot as plot
from anafi_lab.reports import calibration_report as report
from anafi_sim.mission.reference_log import COLUMNS, STATE_NAMES, ReferenceLog, read_log
from anafi_sim.sim.drone_model import EFFECT_GROUPS

REPO = paths.checkout()
LOG_DIR = paths.reference_logs_dir()     # shipped with the package
G = 9.81


# ----------------------------------------------------------------------------------------- helpers
def euler_first_order(t_cmd, u_cmd, tau, delay, t_out, h=2e-4):
    """tau y' = u(t - delay) - y by explicit Euler; u held between command instants; y starts at u[0]."""
    t0 = min(t_out[0], t_cmd[0])
    grid = t0 + h * np.arange(int((t_out[-1] - t0) / h) + 2)
    index = np.clip(np.searchsorted(t_cmd, grid - delay, side='right') - 1, 0, len(u_cmd) - 1)
    u = u_cmd[index].tolist()
    y = np.empty(len(grid))
    value = float(u_cmd[0])
    c = h / tau
    for i in range(len(grid)):
        y[i] = value
        value += c * (u[i] - value)
    return np.interp(t_out, grid, y)


def make_log(t_abs, truth, estimate=None, name='synthetic', waypoint=None):
    """ReferenceLog from absolute times [s] and {state name: array} of truth (and estimate, default truth)."""
    estimate = truth if estimate is None else estimate
    n = len(t_abs)
    columns = {}
    for s in STATE_NAMES:
        columns[s + '_sphinx'] = np.asarray(truth[s], dtype=np.float64)
        columns[s + '_anafi'] = np.asarray(estimate[s], dtype=np.float64)
    for c in COLUMNS:
        if c.startswith('wp_'):
            columns[c] = np.zeros(n) if waypoint is None else np.asarray(waypoint[c], dtype=np.float64)
    time_ns = np.round(np.asarray(t_abs) * 1e9).astype(np.int64) + 1700000000 * 10 ** 9
    return ReferenceLog(columns, time_ns, path='/synthetic/%s.csv' % name)


def smooth_signal(rng, t, amplitude, n=4):
    out = np.zeros_like(t)
    for _ in range(n):
        f = rng.uniform(0.1, 2.5)
        out += amplitude / n * np.sin(2 * math.pi * f * t + rng.uniform(0, 2 * math.pi))
    return out


# ----------------------------------------------------------------------------------------- first order
def test_first_order_delay_fit_recovers_time_constant_delay_and_offset():
    rng = np.random.default_rng(3)
    t_cmd = np.arange(0.0, 20.0, 0.1)                          # a 10 Hz command stream
    u = np.repeat(rng.uniform(-0.4, 0.4, len(t_cmd) // 10), 10)  # steps held for 1 s
    t_y = np.arange(0.0, 20.0, 0.05) + 0.013                   # 20 Hz measurements, other phase
    y = euler_first_order(t_cmd, u, 0.18, 0.12, t_y) + 0.004 + rng.normal(0, 0.002, len(t_y))
    fit = fit_attitude_response(t_cmd, u, y, t_measured=t_y)
    assert fit.time_constant == pytest.approx(0.18, abs=0.01)
    assert fit.delay == pytest.approx(0.12, abs=0.01)
    assert fit.offsets[0] == pytest.approx(0.004, abs=0.001)
    assert fit.rms < 0.004 and fit.r2 > 0.99
    # A wrong fixed delay leaves a clearly larger residual (the fit is sensitive to what it claims).
    worse = evaluate_first_order_delay([(t_cmd, u, t_y, y)], 0.18, 0.0)
    assert worse.rms > 5 * fit.rms


def test_first_order_fit_with_gain_and_shared_parameters():
    rng = np.random.default_rng(4)
    t_cmd = np.arange(0.0, 15.0, 0.1)
    series = []
    for gain in (0.8, 1.3):
        u = np.repeat(rng.uniform(-2, 2, len(t_cmd) // 5), 5)
        t_y = np.arange(0.0, 15.0, 0.05)
        y = gain * euler_first_order(t_cmd, u, 0.3, 0.2, t_y)
        series.append((t_cmd, u, t_y, y))
    fit = fit_first_order_delay(series, fit_gain=True, fit_offset=False)
    assert fit.time_constant == pytest.approx(0.3, abs=0.01)
    assert fit.delay == pytest.approx(0.2, abs=0.01)
    assert fit.gains == pytest.approx((0.8, 1.3), abs=0.01)
    fixed = fit_first_order_delay(series, fit_gain=True, fit_offset=False, delay=0.2)
    assert fixed.delay == 0.2 and fixed.time_constant == pytest.approx(0.3, abs=0.01)


def test_first_order_response_matches_independent_integration():
    t_cmd = np.array([0.0, 1.0, 2.5])
    u = np.array([0.0, 1.0, -0.5])
    t_out = np.linspace(0.0, 4.0, 81)
    ours = first_order_response(t_cmd, u, 0.25, 0.1, t_out, hold=True, step=0.001)
    ref = euler_first_order(t_cmd, u, 0.25, 0.1, t_out, h=1e-4)
    assert np.max(np.abs(ours - ref)) < 0.01
    assert ours[-1] == pytest.approx(-0.5, abs=0.01)


# ----------------------------------------------------------------------------------------- drag
def test_rate_limited_response_is_the_simulators_vertical_loop():
    """fit.rate_limited_response (the vertical fit's model) against AnafiModel's vertical speed for a climb step
    that ramps at the limit and a small one that does not; limit 0 is the first order."""
    from anafi_sim.sim.bridge import PilotingMapping
    from anafi_sim.sim.drone_model import AnafiModel
    params = dict(gravity=9.81, attitude_time_constant=0.2, attitude_delay=0.0, yaw_rate_time_constant=0.1,
                  vertical_speed_time_constant=0.1, drag_linear=0.2, drag_quadratic=0.02, drag_vertical=0.2,
                  estimate_delay=0.0, estimate_time_constant=0.0, estimate_rate=20.0, estimate_float16=False,
                  vertical_acceleration_limit=3.0)
    dt = 0.005
    for gaz_pct in (100, 10):
        drone = AnafiModel(params, mapping=PilotingMapping())
        drone.reset(0.0, 0.0, 20.0, 0.0, flying=True)
        t_out, vz = [], []
        t = 0.0
        for k in range(200):
            if k % 20 == 0:
                drone.set_command(0, 0, 0, gaz_pct, t)
            drone.step(dt, t)
            t += dt
            t_out.append(t)
            vz.append(drone.vz)
        u = gaz_pct / 100.0 * 2.0
        model = rate_limited_response([0.0, 1.0], [u, u], 0.1, 3.0, 0.0, np.array(t_out), step=dt)
        assert np.max(np.abs(model - np.array(vz))) < 0.01 * u + 1e-3, gaz_pct
    t = np.linspace(0.0, 2.0, 81)
    first = first_order_response([0.0, 0.5, 1.0], [1.0, -0.5, 0.3], 0.15, 0.1, t, hold=True, initial=0.0)
    assert np.max(np.abs(rate_limited_response([0.0, 0.5, 1.0], [1.0, -0.5, 0.3], 0.15, 0.0, 0.1, t,
                                                   step=0.002) - first)) < 0.01


def test_rate_limited_tilt_response_is_the_simulators_attitude_loop():
    """fit.rate_limited_tilt_response (the tilt-rate fit's model) against AnafiModel's roll/pitch for a step that
    ramps at the limit and one that does not."""
    from anafi_sim.sim.bridge import PilotingMapping
    from anafi_sim.sim.drone_model import AnafiModel
    params = dict(gravity=9.81, attitude_time_constant=0.12, attitude_delay=0.0, yaw_rate_time_constant=0.1,
                  vertical_speed_time_constant=0.1, drag_linear=0.2, drag_quadratic=0.02, drag_vertical=0.2,
                  estimate_delay=0.0, estimate_time_constant=0.0, estimate_rate=20.0, estimate_float16=False,
                  tilt_rate_limit=1.2)
    mapping = PilotingMapping()
    dt = 0.005
    for pcmd in ((-70, 90), (5, -3)):
        drone = AnafiModel(params, mapping=mapping)
        drone.reset(0.0, 0.0, 20.0, 0.0, flying=True)
        t_out, att = [], []
        t = 0.0
        for k in range(160):
            if k % 20 == 0:
                drone.set_command(pcmd[0], pcmd[1], 0, 0, t)
            drone.step(dt, t)
            t += dt
            t_out.append(t)
            att.append((drone.roll, drone.pitch))
        roll_sp, pitch_sp = mapping.pcmd_to_setpoints(pcmd[0], pcmd[1], 0, 0)[:2]
        r, p = rate_limited_tilt_response([0.0, 1.0], [roll_sp] * 2, [pitch_sp] * 2, 0.12, 1.2, 0.0,
                                              np.array(t_out), step=dt)
        err = np.max(np.hypot(r - np.array(att)[:, 0], p - np.array(att)[:, 1]))
        assert err < 0.01 * math.hypot(roll_sp, pitch_sp) + 1e-4, pcmd


@pytest.mark.parametrize('terms', [{}, {'yaw_tilt_authority': 2.0, 'yaw_tilt_precession': 1.2}])
def test_gyroscopic_tilt_response_is_the_simulators_attitude_loop(terms):
    """fit.gyroscopic_tilt_response (the coupling fit's model) against AnafiModel's roll/pitch for a tilt step
    while the drone yaws (its own yaw rate fed in), with G (and the loss of authority and the precession) and
    with the opposite signs (which must not match)."""
    from anafi_sim.sim.bridge import PilotingMapping
    from anafi_sim.sim.drone_model import AnafiModel
    base = dict(gravity=9.81, attitude_time_constant=0.18, attitude_delay=0.0, yaw_rate_time_constant=0.1,
                vertical_speed_time_constant=0.1, drag_linear=0.2, drag_quadratic=0.02, drag_vertical=0.2,
                estimate_delay=0.0, estimate_time_constant=0.0, estimate_rate=20.0, estimate_float16=False)
    mapping = PilotingMapping()
    dt = 0.005
    drone = AnafiModel(dict(base, gyroscopic_coupling=-1.0, **terms), mapping=mapping)
    drone.reset(0.0, 0.0, 20.0, 0.0, flying=True)
    t_out, att, rate = [], [], []
    t = 0.0
    for k in range(300):
        pcmd = (0, 0, -60, 0) if k < 100 else (40, 70, -60, 0)      # yaw counter-clockwise, then a tilt step
        if k % 20 == 0:
            drone.set_command(pcmd[0], pcmd[1], pcmd[2], pcmd[3], t)
        rate.append(drone.yaw_rate)                               # the rate the step uses: before its update
        drone.step(dt, t)
        t += dt
        t_out.append(t)
        att.append((drone.roll, drone.pitch))
    roll_sp, pitch_sp = mapping.pcmd_to_setpoints(40, 70, -60, 0)[:2]
    t_r = np.array(t_out) - dt                                       # rate[k] holds over the step from t_out - dt
    c, w = terms.get('yaw_tilt_authority', 0.0), terms.get('yaw_tilt_precession', 0.0)
    for g, close in ((-1.0, True), (1.0, False)):
        r, p = gyroscopic_tilt_response([0.0, 0.5, 2.0], [0.0, roll_sp, roll_sp], [0.0, pitch_sp, pitch_sp],
                                            t_r, np.array(rate), 0.18, g, 0.0, np.array(t_out), step=dt,
                                            authority=c, precession=w * math.copysign(1.0, -g))
        err = np.max(np.hypot(r - np.array(att)[:, 0], p - np.array(att)[:, 1]))
        if close:
            assert err < 0.02 * math.hypot(roll_sp, pitch_sp), err
        else:
            assert err > 0.2 * math.hypot(roll_sp, pitch_sp), err


def simulate_drag_log(dl, dq, dv, trim_pitch, duration=80.0, h=1e-3, rate=20.0):
    """Model translation (a = T z - g e_z - drag, T from the vertical profile) driven by set attitudes."""
    n = int(duration / h)
    vx = vy = 0.0
    x = y = 0.0
    every = int(round(1.0 / (rate * h)))
    rows = []
    for k in range(n):
        t = k * h
        roll = 0.06 * math.sin(0.31 * t + 1.0) + 0.03 * math.sin(1.1 * t)
        pitch = 0.12 * math.sin(0.23 * t) + 0.04 * math.sin(0.9 * t + 0.5)
        yaw = 0.8 * math.sin(0.05 * t)
        vz = 0.6 * math.sin(0.4 * t)
        az = 0.24 * math.cos(0.4 * t)
        if k % every == 0:
            rows.append((t, x, y, 5.0 + 1.5 * (1 - math.cos(0.4 * t)), vx, vy, vz, roll, pitch, yaw))
        p = pitch + trim_pitch                      # body z axis of Rz(yaw) Ry(p) Rx(roll)
        zb = (math.cos(yaw) * math.sin(p) * math.cos(roll) + math.sin(yaw) * math.sin(roll),
              math.sin(yaw) * math.sin(p) * math.cos(roll) - math.cos(yaw) * math.sin(roll),
              math.cos(p) * math.cos(roll))
        thrust = (az + G + dv * vz) / zb[2]
        k_drag = dl + dq * math.hypot(vx, vy)
        ax = thrust * zb[0] - k_drag * vx
        ay = thrust * zb[1] - k_drag * vy
        x += vx * h
        y += vy * h
        vx += ax * h
        vy += ay * h
    data = np.array(rows)
    truth = dict((s, data[:, i + 1]) for i, s in enumerate(STATE_NAMES))
    return make_log(data[:, 0], truth, name='x_straight_synthetic')


@pytest.fixture(scope='module')
def drag_log():
    return simulate_drag_log(0.2, 0.025, 0.3, 0.005)


def test_drag_fit_recovers_drag_and_trim(drag_log):
    speed = np.hypot(drag_log.vx_sphinx, drag_log.vy_sphinx)
    assert speed.max() > 3.0                                # the data span a useful speed range
    fit = fit_drag([drag_log])
    assert fit.drag_linear == pytest.approx(0.2, rel=0.03)
    assert fit.drag_quadratic == pytest.approx(0.025, rel=0.05)
    assert fit.trim_pitch == pytest.approx(0.005, abs=0.0005)
    assert fit.trim_roll == pytest.approx(0.0, abs=0.0005)
    assert fit.r2 > 0.99 and fit.rms < 0.02
    assert fit.files == ('x_straight_synthetic',)


def test_replay_of_synthetic_log_follows_truth(drag_log):
    params = {'gravity': G, 'drag_linear': 0.2, 'drag_quadratic': 0.025, 'drag_vertical': 0.3,
              'vertical_speed_time_constant': 0.1, 'attitude_delay': 0.0}
    replay = replay_translation(drag_log, params, trim=(0.005, 0.0))
    assert np.sqrt(np.mean((replay['vx'] - drag_log.vx_sphinx) ** 2)) < 0.03
    assert np.sqrt(np.mean((replay['vy'] - drag_log.vy_sphinx) ** 2)) < 0.03
    wrong = replay_translation(drag_log, dict(params, drag_linear=0.4))
    assert np.sqrt(np.mean((wrong['vx'] - drag_log.vx_sphinx) ** 2)) > 0.1


def test_thrust_axis_is_third_column_of_shared_rotation():
    for rpy in ((0.1, -0.2, 0.3), (-0.4, 0.3, 2.5)):
        assert np.array(thrust_axis(*rpy)) == pytest.approx(frames.rotation_matrix(*rpy)[:, 2])
    assert steady_state_pitch(0.0, 0.2, 0.02) == 0.0
    assert steady_state_pitch(3.0, 0.2, 0.02) == pytest.approx(math.atan((0.2 + 0.06) * 3.0 / G))


# ----------------------------------------------------------------------------------------- estimate
def synthetic_estimate_log(delay, tau, rate, log_phase, half_float_estimate=True, seed=5, duration=60.0):
    """Truth at 20 Hz (+ log_phase) and its estimate: delay, first order, hold at multiples of 1/rate."""
    rng = np.random.default_rng(seed)
    h = 1e-3
    tf = np.arange(0.0, duration, h)
    t_log = np.arange(1.0, duration - 1.0, 0.05) + log_phase
    truth, est = {}, {}
    scale = {'x': 3.0, 'y': 3.0, 'z': 2.0, 'vx': 2.0, 'vy': 2.0, 'vz': 1.0, 'roll': 0.2, 'pitch': 0.2, 'yaw': 1.0}
    for s in STATE_NAMES:
        fine = smooth_signal(rng, tf, scale[s]) + (5.0 if s == 'z' else 0.0)
        shift = int(round(delay / h))
        delayed = np.concatenate((np.full(shift, fine[0]), fine[:len(fine) - shift]))
        c = h / tau                              # explicit Euler of tau y' = u - y: y += c (u - y)
        smooth = lfilter([c], [1.0, -(1.0 - c)], delayed, zi=[(1.0 - c) * delayed[0]])[0]
        held_at = np.floor(t_log * rate + 1e-9) / rate
        truth[s] = np.interp(t_log, tf, fine)
        e = np.interp(held_at, tf, smooth)
        est[s] = np.float16(e).astype(np.float64) if half_float_estimate else e
    return make_log(t_log, truth, est, name='static_synthetic')


def test_estimate_fit_recovers_delay_smoothing_rate_and_float16():
    log = synthetic_estimate_log(delay=0.06, tau=0.03, rate=20.0, log_phase=0.025)
    fit = fit_estimate([log])
    # The logger sees the held value 0.025 s after it was taken: effective lag = delay + 0.025.
    assert fit.effective_delay == pytest.approx(0.085, abs=0.01)
    assert fit.delay == pytest.approx(0.06, abs=0.01)
    assert fit.time_constant == pytest.approx(0.03, abs=0.01)
    assert fit.rate == pytest.approx(20.0)
    assert fit.change_rate == pytest.approx(20.0, abs=0.5)
    assert fit.float16 is True                   # estimate half floats, truth not
    assert fit.fit.r2 > 0.99
    for group in ('position', 'velocity', 'attitude'):
        assert fit.groups[group].delay == pytest.approx(0.085, abs=0.015)


def test_estimate_change_rate_sees_slower_updates():
    log = synthetic_estimate_log(delay=0.0, tau=0.01, rate=10.0, log_phase=0.025, duration=30.0)
    rate, fraction, samples = estimate_change_rate([log])
    assert samples > 100
    assert rate == pytest.approx(10.0, abs=1.0) and fraction == pytest.approx(0.5, abs=0.05)


def test_float16_detection():
    values = np.array([0.123456, 1.0 / 3.0, 48.81, -2.7182818, 65280.0])
    assert float16_fraction(values) == pytest.approx(0.2)     # only 65280 is a half float as written
    halves = np.array([float(str(np.float16(v))) for v in values])
    assert float16_fraction(halves) == 1.0
    assert quantum_fraction(np.array([1 / 256.0, 3 / 256.0, 0.1]), 1 / 256.0) == pytest.approx(2 / 3.0)


def test_estimate_model_response_holds_and_delays():
    t = np.arange(0.0, 2.0, 0.001)
    truth = t.copy()                                            # a ramp
    out = estimate_model_response(t, truth, 0.1, 0.0, 10.0, t_out=np.array([0.55, 0.65, 0.99]))
    # Held at 0.5 / 0.6 / 0.9 s, delayed by 0.1 s.
    assert out == pytest.approx([0.4, 0.5, 0.8], abs=1e-3)


# ----------------------------------------------------------------------------------------- fidelity effects
def fused_by_euler(t, truth, velocity, fix_delay, gain, initial, h=1e-3):
    """p' = v + k (truth(t - D) - p) by explicit Euler at a fine step (independent of the module)."""
    grid = np.arange(t[0], t[-1] + h, h)
    fix = np.interp(grid - fix_delay, t, truth)
    v = np.interp(grid, t, velocity)
    p = np.empty(len(grid))
    value = initial
    for i in range(len(grid)):
        p[i] = value
        value += (v[i] + gain * (fix[i] - value)) * h
    return np.interp(t, grid, p)


def synthetic_fusion_log(name, fix_delay, gain, seed, cruise=0.0, duration=30.0):
    """Truth moving (smooth manoeuvres + ``cruise`` m/s along x), estimate = the fusion of the truth velocity."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 0.05)
    truth = dict((s, np.zeros_like(t)) for s in STATE_NAMES)
    est = dict((s, np.zeros_like(t)) for s in STATE_NAMES)
    fine = np.arange(-5.0, duration, 0.001)
    for axis, amplitude in (('x', 2.0), ('y', 2.0), ('z', 1.0)):
        # manoeuvres: velocity steps held for 4 s (smoothed by 0.3 s), so the lag has time to build up
        steps = np.repeat(rng.uniform(-amplitude, amplitude, int(duration / 4.0) + 3), 4000)[:len(fine)]
        speed = lfilter([0.001 / 0.3], [1.0, 0.001 / 0.3 - 1.0], steps) + (cruise if axis == 'x' else 0.0)
        position = np.cumsum(speed) * 0.001 + (5.0 if axis == 'z' else 0.0)
        truth[axis] = np.interp(t, fine, position)
        truth['v' + axis] = np.interp(t, fine, speed)
        start = fine >= -3.0
        fused = fused_by_euler(fine[start], position[start], speed[start], fix_delay, gain,
                               position[start][0] - cruise * fix_delay * (axis == 'x'))
        est[axis] = np.interp(t, fine[start], fused)
        est['v' + axis] = truth['v' + axis]
    return make_log(t, truth, est, name=name)


def test_position_fusion_fit_recovers_gain_and_delay():
    logs = [synthetic_fusion_log('static_fusion_a', 0.2, 0.4, seed=11),
            synthetic_fusion_log('x_straight_fusion', 0.2, 0.4, seed=12, cruise=3.0)]
    fit = fit_position_fusion(logs, 20.0, 0.01, 0.01)
    assert fit.effective_delay == pytest.approx(0.2, abs=0.01)
    assert fit.fix_delay == pytest.approx(0.2 - 0.5 / 20.0, abs=0.01)
    assert fit.fix_gain == pytest.approx(0.4, rel=0.1)
    assert fit.rms < 0.01
    assert fit.rms < 0.2 * np.sqrt(np.mean(np.square(list(fit.baseline.values()))))   # the delay model fits worse
    # a pure delay of the truth fits the steady flight at the fusion's delay, not the transients
    assert fit.pure_delay['steady position lag'][2] < fit.pure_delay['velocity/attitude lag'][2]
    assert fit.groups['static'][3] < fit.pure_delay['steady position lag'][1]


def test_fusion_profile_holds_the_gain_and_refits_the_delay():
    logs = [synthetic_fusion_log('static_fusion_a', 0.2, 0.4, seed=11),
            synthetic_fusion_log('x_straight_fusion', 0.2, 0.4, seed=12, cruise=3.0)]
    rows = fusion_profile(logs, (0.1, 0.4, 1.6), 20.0)
    assert [r.fix_gain for r in rows] == [0.1, 0.4, 1.6]
    true = rows[1]
    # at the true gain: the true delay and a residual as small as the free fit's
    assert true.effective_delay == pytest.approx(0.2, abs=0.01)
    assert true.fix_delay == pytest.approx(true.effective_delay - 0.5 / 20.0)
    assert true.rms < 0.01 and true.rms_static < 0.01 and true.rms_straight < 0.01
    # a gain away from the truth fits worse, on the transients and in steady flight
    for other in (rows[0], rows[2]):
        assert other.rms > 3.0 * true.rms
        assert other.rms_static > true.rms_static and other.rms_straight > true.rms_straight
    # the delay is refitted for a wrong gain: better than the true delay at that gain; or held when given
    held = fusion_profile(logs, (1.6, 1.6), 20.0, (None, 0.2))
    assert held[1].effective_delay == 0.2 and abs(held[0].effective_delay - 0.2) > 0.005
    assert held[0].rms < held[1].rms
    with pytest.raises(ValueError):
        fusion_profile([], (0.4,), 20.0)
    with pytest.raises(ValueError):
        fusion_profile(logs, (0.4, 0.5), 20.0, (None,))


def test_fused_position_response_matches_independent_integration():
    t = np.arange(0.0, 10.0, 0.05)
    truth = 2.0 * t + np.sin(t)
    velocity = 2.0 + np.cos(t)
    ours = fused_position_response(t, truth, velocity, 0.25, 0.5, 0.3, step=0.001)
    ref = fused_by_euler(t, truth, velocity, 0.25, 0.5, 0.3, h=1e-4)
    assert np.max(np.abs(ours - ref)) < 2e-3
    ramp = fused_position_response(t, 2.0 * t, np.full_like(t, 2.0), 0.25, 0.5, 0.3)
    assert ramp[-1] == pytest.approx(2.0 * t[-1] - 0.25 * 2.0, abs=0.01)          # steady: D x speed behind


def test_velocity_error_fit_recovers_the_decay():
    """Straight-line logs whose velocity estimate starts off the truth by b0 and decays with T = 3 s (plus a
    1/256 m/s quantisation): the fit finds T and b0; a static log does not enter it."""
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 12.0, 0.05)
    logs = []
    for name, b0 in (('x_straight_a_mpc', (-0.05, 0.03)), ('x_straight_b_pid', (0.02, -0.10)),
                     ('static_waypoint_c_pid', (0.3, 0.3))):
        truth = dict((s, np.zeros_like(t)) for s in STATE_NAMES)
        truth['vx'] = 3.0 + 0.01 * rng.standard_normal(len(t))
        est = dict(truth)
        for axis, b in zip(('vx', 'vy'), b0):
            est[axis] = np.round((truth[axis] + b * np.exp(-t / 3.0)) * 256.0) / 256.0
        logs.append(make_log(t + 10.0, truth, est, name=name))
    fit = fit_velocity_error(logs)
    assert fit.time_constant == pytest.approx(3.0, rel=0.05)
    assert fit.files == ('x_straight_a_mpc', 'x_straight_b_pid')
    assert fit.per_series[('x_straight_b_pid', 'y')][0] == pytest.approx(-0.10, abs=0.005)
    assert fit.rms < 0.2 * fit.rms_zero
    assert fit_velocity_error(logs[2:]).time_constant == 0.0           # no straight line: not identified


def test_lag_along_motion():
    t = np.arange(0.0, 5.0, 0.05)
    v = np.column_stack((np.full_like(t, 2.0), np.zeros_like(t)))
    truth = np.column_stack((2.0 * t, np.zeros_like(t)))
    assert lag_along_motion(t, truth, truth - 0.3 * v, v) == pytest.approx(0.3)
    assert math.isnan(lag_along_motion(t, truth, truth, 0.0 * v))


def test_quantum_detection_finds_the_grid_and_not_float16_noise():
    rng = np.random.default_rng(9)
    raw = rng.uniform(-1.9, 1.9, 2000)
    quantised = np.round(raw * 256.0) / 256.0
    as_logged = np.array([float(str(v)) for v in np.float16(quantised)])        # as logged: shortest repr
    assert estimate_quantum(as_logged) == 1.0 / 256.0
    assert estimate_quantum(np.float16(np.round(raw * 64.0) / 64.0).astype(float)) == 1.0 / 64.0
    assert estimate_quantum(np.float16(raw).astype(float)) == 0.0            # float16 alone: no grid
    assert estimate_quantum(np.float16(raw[:20]).astype(float)) == 0.0       # too few values to tell


def test_estimate_grid_finds_a_grid_of_any_step_and_offset_and_not_in_noise():
    rng = np.random.default_rng(4)
    step = 0.0213
    series = [offset + step * np.round(rng.uniform(-1.5, 2.5, 400) / step) for offset in (0.0, 0.0071, -0.013)]
    found, conc = estimate_grid(series)
    assert found == pytest.approx(step, abs=2e-5) and conc > 0.99          # the coarsest, not step / 2
    noise = [rng.uniform(-1.5, 2.5, 400) for _ in range(3)]
    assert estimate_grid(noise)[0] == 0.0
    assert grid_concentration(noise, step) < 0.3


# ----------------------------------------------------------------------------------------- PID replay
def test_reconstructed_pid_commands_have_the_bridge_signs():
    t = np.arange(0.0, 6.0, 0.05)
    n = len(t)
    truth = dict((s, np.zeros(n)) for s in STATE_NAMES)
    truth['z'] = np.ones(n)
    wp = dict((c, np.zeros(n)) for c in COLUMNS if c.startswith('wp_'))
    step = t >= 1.0
    wp['wp_x'][step], wp['wp_y'][step], wp['wp_z'][step] = 3.0, 2.0, 5.0
    log = make_log(t, truth, waypoint=wp, name='static_waypoint_synthetic_pid')
    trace = reconstruct_pid_commands(log)
    assert trace.start_index == int(np.argmax(step))
    before = trace.t < 1.0
    assert np.all(trace.pitch[before] == 0.0) and np.all(trace.vertical_speed[before] == 0.0)
    late = trace.t > 1.5
    assert np.all(trace.pitch[late] > 0.0)                     # waypoint ahead: nose down
    assert np.all(trace.roll[late] < 0.0)                      # waypoint to the left (+y): roll left
    assert np.all(trace.vertical_speed[late] == pytest.approx(2.0))   # saturated climb (100 %)
    assert np.all(np.abs(trace.pitch) <= math.radians(30.64) + 1e-9)
    assert np.all(np.diff(trace.t[1:]) == pytest.approx(0.1))  # 10 Hz output


def test_reconstructed_mpc_commands_have_the_bridge_signs_and_none_at_the_waypoint():
    t = np.arange(0.0, 4.0, 0.05)
    n = len(t)
    truth = dict((s, np.zeros(n)) for s in STATE_NAMES)
    truth['z'] = np.ones(n)
    wp = dict((c, np.zeros(n)) for c in COLUMNS if c.startswith('wp_'))
    wp['wp_z'][:] = 1.0
    step = t >= 1.0
    wp['wp_x'][step], wp['wp_y'][step] = 3.0, 2.0
    log = make_log(t, truth, waypoint=wp, name='static_waypoint_synthetic_mpc')
    trace = reconstruct_mpc_commands(log)
    assert trace.start_index == int(np.argmax(step))
    assert np.all(np.diff(trace.t) == pytest.approx(0.1))      # one solve per 10 Hz cycle
    before, late = trace.t < 0.95, trace.t > 1.05
    assert np.all(np.abs(trace.pitch[before]) < 1e-3) and np.all(np.abs(trace.roll[before]) < 1e-3)
    assert np.all(trace.pitch[late] > 0.05)                    # waypoint ahead: nose down
    assert np.all(trace.roll[late] < -0.03)                    # waypoint to the left (+y): roll left
    from anafi_sim.sim.bridge import PilotingMapping
    step_pct = math.radians(PilotingMapping().max_tilt_deg) / 100.0   # whole PCMD percents
    assert np.allclose(trace.pitch / step_pct, np.round(trace.pitch / step_pct), atol=1e-9)


# ----------------------------------------------------------------------------------------- real logs
@pytest.fixture(scope='module')
def real():
    logs = [read_log(os.path.join(LOG_DIR, name)) for name in sorted(os.listdir(LOG_DIR)) if name.endswith('.csv')]
    return logs, calibrate(logs)


def test_real_logs_give_plausible_parameters(real):
    _, result = real
    p = result.params
    assert list(p) == list(MODEL_KEYS)
    for key, value in p.items():
        assert isinstance(value, bool) if key == 'estimate_float16' else math.isfinite(value), key
    assert p['gravity'] == 9.81
    assert 0.05 < p['attitude_time_constant'] < 0.5 and 0.0 <= p['attitude_delay'] < 0.3
    assert 0.05 < p['yaw_rate_time_constant'] < 1.0
    assert 0.05 < p['vertical_speed_time_constant'] < 0.5
    assert 0.05 < p['drag_linear'] < 0.5 and 0.0 < p['drag_quadratic'] < 0.1 and p['drag_vertical'] >= 0.0
    assert 0.0 <= p['estimate_delay'] < 0.15 and 0.0 <= p['estimate_time_constant'] < 0.1
    assert p['estimate_rate'] == pytest.approx(20.0, abs=0.5)
    assert p['estimate_float16'] is False        # every column of the logs (truth too) is float16: storage
    # The two garbage files never enter a fit.
    assert 'x_straight_2_pid' not in result.drag.files and 'x_straight_3_pid' not in result.drag.files


def test_real_log_residuals_within_bounds(real):
    _, result = real
    d, e, c = result.drag, result.estimate, result.commands
    # Drag: 0.05 m/s^2 is 0.005 rad of tilt, about one PCMD percent (0.0053 rad) - the command resolution.
    assert d.rms < 0.05 and d.r2 > 0.98
    assert max(d.per_file_rms.values()) < 0.1
    # Steady straight flight: the fitted drag predicts the logged mean tilt (+ trim) to 0.003 rad.
    logs, _ = real
    for log in logs:
        if log.name.startswith('x_straight') and is_clean(log):
            speed = float(np.mean(np.hypot(log.vx_sphinx, log.vy_sphinx)))
            tilt = float(np.mean(log.pitch_sphinx)) + d.trim_pitch
            assert steady_state_pitch(speed, d.drag_linear, d.drag_quadratic) == pytest.approx(tilt, abs=0.003)
    # Estimate: the delay/smoothing model explains > 99 % of the variance; attitude to 0.005 rad.
    assert e.fit.r2 > 0.99 and e.groups['attitude'].rms < 0.005 and e.groups['velocity'].rms < 0.05
    # Firmware loops: attitude within 0.02 rad (~4 PCMD percents), vertical speed within 4 % of the 2 m/s
    # command, yaw rate within 4.5 % of the 1.9 rad/s peak command.
    assert c.attitude.rms < 0.02 and c.attitude.r2 > 0.9
    assert c.vertical.rms < 0.08 and c.vertical.r2 > 0.98
    assert c.yaw.rms < 0.085 and c.yaw.r2 > 0.97


def test_yaml_text_has_exactly_the_model_keys_and_validates(real):
    logs, result = real
    from anafi_sim.sim.drone_model import EFFECTS_OFF, MODEL_KEYS, validate_model_params
    names = [log.name + '.csv' for log in logs]
    for fitted in (False, True):
        text = report.format_model_yaml(result, names, fitted=fitted)
        data = yaml.safe_load(text)
        assert set(data) == set(MODEL_KEYS) and list(data) == list(MODEL_KEYS)
        expected = result.fitted if fitted else result.params
        clean = validate_model_params(data)
        for key in MODEL_KEYS:
            assert clean[key] == pytest.approx(expected[key], rel=1e-5), key
        assert 'Generated by anafi_lab/cli/calibrate_model.py' in text
        assert not re.search(r'\d{4}-\d{2}-\d{2}', text)          # date-free: reruns are reproducible
        comments = dict(line.split(':', 1)[0:1] + line.split('#', 1)[1:] for line in text.splitlines()
                        if not line.startswith('#'))
        for key in EFFECTS_OFF:                                     # every effect says how it was fitted
            assert len(comments[key].strip()) > 20, key
    shipped = yaml.safe_load(report.format_model_yaml(result, names))
    on_own_loop = {'gyroscopic_coupling': result.effects.gyroscopic}     # refitted on the fitted file's loop
    for name, keys in EFFECT_GROUPS.items():       # the shipped groups have the fitted values, the others are off
        for key in keys:
            if name in on_own_loop and 'tilt_rate_limit' not in result.effects_on:
                value = on_own_loop[name][keys.index(key)]          # (G, c, w): the first-order loop's fit
                assert shipped[key] == pytest.approx(value, rel=1e-5), (name, key)
            elif name in result.effects_on:
                assert shipped[key] == pytest.approx(result.fitted[key], rel=1e-5), (name, key)
            elif key in EFFECTS_OFF:
                assert shipped[key] == EFFECTS_OFF[key], (name, key)


def test_committed_config_is_this_fit(real):
    """The committed anafi_model.yaml / anafi_model_fitted.yaml must be regenerated when the fit changes."""
    _, result = real
    for name, expected in (('anafi_model.yaml', result.params), ('anafi_model_fitted.yaml', result.fitted)):
        with open(os.path.join(REPO, 'anafi_sim', 'config', name)) as stream:
            committed = yaml.safe_load(stream)
        for key in MODEL_KEYS:
            if isinstance(expected[key], bool):
                assert committed[key] is expected[key], (name, key)
            else:
                assert committed[key] == pytest.approx(expected[key], rel=1e-3, abs=1e-4), (name, key)


def test_real_log_effects(real):
    """Every effect is found in the shared logs with its documented value and helps where it should."""
    logs, result = real
    f, p = result.effects, result.fitted
    assert result.effects_on == tuple(SHIPPED_EFFECTS)
    # fusion: steady lag of the replayed estimate within 0.03 s of the logged one, transients well below it
    fusion = f.fusion
    assert 0.15 < fusion.fix_delay < 0.3 and 0.05 < fusion.fix_gain < 1.0
    assert fusion.rms < 0.6 * np.sqrt(np.mean(np.square(list(fusion.baseline.values()))))
    for name, (logged, before, after) in f.replay.steady_lag.items():
        if name in fusion.files:
            assert after == pytest.approx(logged, abs=0.03), name
            assert before < 0.5 * logged
    for name, (logged, before, after) in f.replay.transient_lag.items():
        assert after < 0.5 * fusion.effective_delay and after == pytest.approx(logged, abs=0.035), name
    # no single delay explains both steady flight and transients as well as the fusion
    for delay, rms_static, rms_straight in fusion.pure_delay.values():
        assert max(rms_static, rms_straight) > 1.4 * max(fusion.groups['static'][3], fusion.groups['straight'][3])
    # tilt, constant fit on the static PID logs (reported): it lowers their attitude residual
    assert 0.05 < f.tilt.attenuation < 0.3 and f.tilt.rms < 0.85 * f.tilt.rms_before
    # tilt, speed-gated (the model's): the straight MPC logs deliver what the stand-in delivers up to 4 m/s
    # (relative gain within 5 % at 2-4 m/s) and about a fifth less at 5 m/s
    ts = f.tilt_speed
    assert set(ts.rows) == {'x_straight_%d_mpc' % v for v in range(1, 6)}
    for name, row in ts.rows.items():
        if 1.5 < row[0] < 4.5:
            assert row[5] == pytest.approx(1.0, abs=0.05), name
    assert 3.5 < p['tilt_attenuation_speed'] < 4.5 and 4.8 < p['tilt_attenuation_speed_full'] < 5.2
    assert 0.1 < p['tilt_attenuation'] < 0.35 and p['tilt_attenuation'] == pytest.approx(1.0 - ts.rows[
        'x_straight_5_mpc'][5])
    assert ts.trim == pytest.approx(result.drag.trim_pitch)
    # descent: only the two saturated descents; climbs reach the commanded 2 m/s
    assert set(f.descent.files) == {'x_straight_2_pid', 'x_straight_3_pid'}
    assert 1.3 < p['max_descent_speed'] < 1.7 and min(f.descent.climb.values()) > 1.9
    for name in f.descent.files:
        before, after = f.descent.replay[name]
        assert after < 0.2 * before
    # vertical acceleration limit: the climbs ramp at ~6 m/s^2; the limited loop fits every static step better
    # (the MPC ones are a check: not in the fit) with a shorter small-signal lag than the single first order
    ve = f.vertical
    assert set(ve.files) == {'static_waypoint_yaw_0_pid', 'static_waypoint_yaw_180_pid'}
    assert 4.0 < p['vertical_acceleration_limit'] == ve.limit < 9.0 and 3.0 < ve.all_static[0] < 9.0
    assert p['vertical_speed_time_constant'] == ve.time_constant < 0.6 * ve.first_order[0]
    assert ve.first_order[0] == result.commands.vertical.time_constant      # section (c)'s fit is the baseline
    assert ve.rms < 0.85 * ve.first_order[1]
    assert set(ve.per_file) == {'static_waypoint_yaw_%d_%s' % (y, c) for y in (0, 180) for c in ('pid', 'mpc')}
    for name, (before, after) in ve.per_file.items():
        assert after < 0.9 * before, name
    # tilt-rate limit: the static steps turn the tilt at ~85 deg/s at most; the limited loop fits every static
    # log better outside the turns (the MPC ones a check) with a shorter small-signal lag
    tr = f.tilt_rate
    assert set(tr.files) == {'static_waypoint_yaw_0_pid', 'static_waypoint_yaw_180_pid'}
    assert math.radians(60) < p['tilt_rate_limit'] == tr.rate < math.radians(120)
    assert math.radians(60) < tr.all_static[0] < math.radians(120)
    assert p['attitude_time_constant'] == tr.time_constant < 0.8 * tr.first_order[0]
    assert tr.first_order[0] == result.commands.attitude.time_constant
    assert tr.rms < 0.8 * tr.first_order[1]
    for name, (before, after) in tr.per_file.items():
        assert after < before, name
    # coupling to the yaw rate: one set (G < 0, the loss of authority c > 0, the precession w > 0 with the yaw) from
    # both turn senses (MPC counter-clockwise, PID clockwise); G alone (~ -1.1 s) halves the roll/pitch residual of
    # both yaw-180 steps, the three terms take another third off each; the yaw-0 steps stay as they were
    gy = f.gyroscopic
    assert set(gy.files) == {'static_waypoint_yaw_%d_%s' % (y, c) for y in (0, 180) for c in ('pid', 'mpc')}
    assert -1.5 < gy.alone[0] < -0.7 and gy.alone[1] < 0.7 * gy.rms_off
    shipped = result.params
    assert -1.2 < shipped['gyroscopic_coupling'] == gy.coupling < -0.3
    assert 2.0 < shipped['yaw_tilt_authority'] == gy.authority < 5.0
    assert 0.8 < shipped['yaw_tilt_precession'] == gy.precession < 1.6
    assert gy.rms < 0.75 * gy.alone[1]
    # the fitted file's loop (tilt-rate limited) has the terms refitted on it: the first order's would fit it
    # half as well
    gl = f.gyroscopic_limited
    assert (p['gyroscopic_coupling'], p['yaw_tilt_authority'], p['yaw_tilt_precession']) == gl[:3]
    assert gl.coupling < 0.0 and gl.authority > 0.0 and gl.precession > 0.0
    assert gl.rms < 0.6 * gl.compared and gl.rms < 0.75 * gl.alone[1]
    for fit_ in (gy, gl):
        for name, (before, alone, after) in fit_.per_file.items():
            if 'yaw_180' in name:
                assert alone < 0.65 * before and after < 0.8 * alone, name
            else:
                assert alone == pytest.approx(before, rel=0.03) and after == pytest.approx(before, rel=0.03), name
    # quantisation: z and the velocities of the estimate on a 1/256 grid, the truth not
    assert p['estimate_quantum_z'] == p['estimate_quantum_velocity'] == 1.0 / 256.0
    for column in ('z', 'vx', 'vy', 'vz'):
        assert f.quanta.on_grid[column] > 0.98 and f.quanta.truth_on_grid[column] < 0.3
    assert all(value == 1.0 for value in f.replay.on_grid.values())
    # the horizontal position estimate: on grids of no power of two (0.0175 m east, 0.0265 m north), the truth not
    assert p['estimate_quantum_x'] == pytest.approx(0.01749, abs=2e-5)
    assert p['estimate_quantum_y'] == pytest.approx(0.02651, abs=2e-5)
    for column in ('x', 'y'):
        step, conc, conc_truth = f.quanta.grids[column]
        assert conc > 0.98 and conc_truth < 0.3, column
    # yaw bias: between the per-log extremes
    assert f.yaw.spread[0] <= p['estimate_yaw_bias'] <= f.yaw.spread[1]
    # the velocity estimate's own error: decays in ~4 s; the decay explains most of it where it is large
    ve = f.velocity_error
    assert 2.0 < p['estimate_velocity_error_time_constant'] == ve.time_constant < 8.0
    assert ve.rms < 0.6 * ve.rms_zero
    b0, zero, fitted = ve.per_series[('x_straight_4_pid', 'y')]
    assert -0.15 < b0 < -0.07 and fitted < 0.3 * zero


def test_report_has_a_section_per_effect(real):
    logs, result = real
    text = report.format_report(result, logs)
    for title in ('### Position estimate: fusion', '### Velocity estimate: an error', '### Tilt attenuation', '### Vertical asymmetry: descent limit',
                  '### Vertical speed: acceleration limit', '### Attitude: tilt-rate limit',
                  '### Yaw estimate bias', '### Estimate quantisation'):
        assert title in text
    assert 'anafi_model_fitted.yaml' in text and 'cannot identify' in text


def test_report_contains_table3_and_flags(real):
    logs, result = real
    text = report.format_report(result, logs, plot_name='calibration_replay.png')
    assert 'x_straight_2_pid z_anafi: 270 of 270 samples (16-bit wrap: 270)' in text
    assert '| PID | 2 | 2.67 | n/a (all 270 samples excluded) | 2.573 |' in text
    assert '| MPC | 5 | 1.41 | 1.420 | 1.420 | - |' in text
    assert '![model replaying a reference log](calibration_replay.png)' in text


def test_replay_figure_is_written(real, tmp_path):
    pytest.importorskip('matplotlib')
    logs, result = real
    path = str(tmp_path / 'replay.png')
    plot.plot_replay(result, logs, path)
    with open(path, 'rb') as stream:
        assert stream.read(8) == b'\x89PNG\r\n\x1a\n'


def test_summary_lists_every_model_key(real):
    _, result = real
    text = report.format_summary(result)
    assert all(key in text for key in MODEL_KEYS) and 'Residuals:' in text
