"""Calibration sections (c-e): the firmware loops from replayed commands, and the translation replay.

Stage: offline, reference logs -> the commands the paper's controllers sent (``reconstruct_pid_commands``,
``reconstruct_mpc_commands``: they are not logged), the first-order fits of the attitude, vertical-speed and
yaw-rate loops to them (``fit_command_responses``) and the translational model integrated on a log
(``replay_translation``). Pure numpy/scipy, no ROS.
"""
import collections
import math

import numpy as np

from anafi_lab.calibration.logs import is_clean, measured_yaw_rate, thrust_axis
from anafi_lab.calibration.responses import evaluate_first_order_delay, first_order_response, fit_first_order_delay

STEP_LEAD = 0.5                    # s of a static step's fit window before the waypoint step

# --------------------------------------------------------------------------- (c-e) command responses
CommandTrace = collections.namedtuple('CommandTrace', ['t', 'roll', 'pitch', 'yaw_rate', 'vertical_speed',
                                                       'start_index'])
CommandTrace.__doc__ = ('Reconstructed firmware setpoints at the command instants t [s, log time]: roll, pitch '
                        '[rad, FLU], yaw_rate [rad/s, ENU, + = counter-clockwise], vertical_speed [m/s]; '
                        'start_index = first log sample with the waypoint set (hover command before).')


def reconstruct_pid_commands(log, cycle_rate=30.0, output_rate=10.0, framework=None, mapping=None, from_start=False):
    """Replay the paper's PID framework on the logged estimate and waypoint; ``CommandTrace``.

    The loops (``anafi_control.pid_framework.PidFramework``, Table 2 gains)
    run at ``cycle_rate`` on the latest logged sample (zero-order hold) from
    the first sample whose waypoint differs from the first row (the logs start
    in hover before the waypoint is published), or with ``from_start`` from the
    first sample on (a real flight's log has its waypoint from its start); the
    command is sampled at ``output_rate`` and quantised to whole PCMD percents as
    the bridge does (``anafi_sim.sim.bridge.PilotingMapping``). Only meaningful for
    the *_pid logs.
    """
    if framework is None:
        from anafi_control.pid_framework import PidFramework
        framework = PidFramework()
    if mapping is None:
        from anafi_sim.sim.bridge import PilotingMapping
        mapping = PilotingMapping()
    wp = log.waypoint()
    changed = np.any(wp != wp[0], axis=1)
    start = int(np.argmax(changed)) if changed.any() else 0
    begin = 0 if from_start else start
    cycles = np.arange(log.t[begin], log.t[-1], 1.0 / cycle_rate)
    index = np.searchsorted(log.t, cycles, side='right') - 1
    every = max(1, int(round(cycle_rate / output_rate)))
    times = [log.t[0]] if begin > 0 else []
    setpoints = [(0.0, 0.0, 0.0, 0.0)] if begin > 0 else []
    for k, (tc, i) in enumerate(zip(cycles, index)):
        framework.update(float(tc), (log.x_anafi[i], log.y_anafi[i], log.z_anafi[i]),
                         (log.vx_anafi[i], log.vy_anafi[i], log.vz_anafi[i]), float(log.yaw_anafi[i]),
                         tuple(float(v) for v in wp[i]))
        if k % every == 0:
            times.append(float(tc))
            setpoints.append(mapping.command_to_setpoints(*framework.command()))
    sp = np.array(setpoints, dtype=np.float64)
    return CommandTrace(np.array(times), sp[:, 0], sp[:, 1], sp[:, 2], sp[:, 3], start)


def reconstruct_mpc_commands(log, rate=10.0, mpc=None, mapping=None):
    """Replay the paper's MPC on the logged estimate and waypoint; ``CommandTrace`` (yaw rate 0).

    With eq. (15) (zero cumulative errors at every solve) the MPC's command is a function of the state
    estimate and the waypoint alone, so it can be recomputed from a log: one solve every 1/``rate`` [s] on the
    latest logged sample, roll/pitch from the accelerations at the logged estimated yaw, quantised to whole
    PCMD percents as the bridge does. Only meaningful for the *_mpc logs.
    """
    from anafi_control.mpc import CumulativeErrorMpc, attitude_from_acceleration
    if mpc is None:
        mpc = CumulativeErrorMpc()
    if mapping is None:
        from anafi_sim.sim.bridge import PilotingMapping
        mapping = PilotingMapping()
    wp = log.waypoint()
    changed = np.any(wp != wp[0], axis=1)
    start = int(np.argmax(changed)) if changed.any() else 0
    cycles = np.arange(log.t[0], log.t[-1], 1.0 / rate)
    index = np.searchsorted(log.t, cycles, side='right') - 1
    times, setpoints = [], []
    for tc, i in zip(cycles, index):
        state = (log.x_anafi[i], log.y_anafi[i], log.z_anafi[i], log.vx_anafi[i], log.vy_anafi[i], log.vz_anafi[i])
        if not (np.all(np.isfinite(state)) and np.all(np.isfinite(wp[i])) and np.isfinite(log.yaw_anafi[i])):
            continue
        result = mpc.solve(np.array(state[:3]), np.array(state[3:]), wp[i][:3], wp[i][3:6])
        if not result.ok:
            continue
        roll, pitch = attitude_from_acceleration(result.u0[0], result.u0[1], float(log.yaw_anafi[i]), mpc.gravity)
        times.append(float(tc))
        setpoints.append(mapping.command_to_setpoints(roll, pitch, 0.0, result.vz_command))
    sp = np.array(setpoints, dtype=np.float64).reshape(-1, 4)
    return CommandTrace(np.array(times), sp[:, 0], sp[:, 1], sp[:, 2], sp[:, 3], start)


CommandFits = collections.namedtuple('CommandFits', [
    'attitude', 'attitude_turns', 'vertical', 'vertical_free', 'yaw', 'yaw_free', 'per_file', 'files'])
CommandFits.__doc__ = ('Fits of the firmware loops against PID command replays: attitude (FirstOrderFit, '
                       'turns excluded), attitude_turns (same delay/tau evaluated during the yaw turns), vertical '
                       'and yaw with the attitude delay (the model delays the whole command), *_free with their '
                       'own delay, {file: {loop: rms}}, files.')


def fit_command_responses(logs, window=20.0, turn_rate=0.1):
    """Attitude, vertical-speed and yaw-rate first-order fits from PID replays of the *_pid logs.

    For each clean PID log the commands are reconstructed
    (``reconstruct_pid_commands``) and compared with the truth from ``STEP_LEAD`` s
    before the waypoint step to ``window`` s after it. The attitude fit
    excludes samples where |yaw rate| > ``turn_rate`` (the turn couples the
    axes in a way a first-order model does not capture: reported separately).
    The vertical and yaw fits use the attitude delay because the model
    delays the whole piloting command; their free-delay fits are reported.
    Returns ``CommandFits`` (None entries when a log kind is missing).
    """
    used = [log for log in logs if is_clean(log) and log.name.endswith('_pid') and 'static' in log.name]
    if not used:
        raise ValueError('fit_command_responses: no clean static-waypoint PID log')
    traces = [(log, reconstruct_pid_commands(log)) for log in used]
    att, att_turn, vert, yaw = [], [], [], []
    for log, tr in traces:
        t0 = log.t[tr.start_index]
        win = (log.t >= t0 - STEP_LEAD) & (log.t <= t0 + window)
        yaw_rate = measured_yaw_rate(log)
        calm = win & (np.abs(yaw_rate) <= turn_rate)
        turning = win & (np.abs(yaw_rate) > turn_rate)
        att.append((tr.t, tr.pitch, log.t, log.pitch_sphinx, calm))
        att.append((tr.t, tr.roll, log.t, log.roll_sphinx, calm))
        if turning.sum() > 10:
            att_turn.append((tr.t, tr.pitch, log.t, log.pitch_sphinx, turning))
            att_turn.append((tr.t, tr.roll, log.t, log.roll_sphinx, turning))
            yaw.append((tr.t, tr.yaw_rate, log.t, yaw_rate, win))
        vert.append((tr.t, tr.vertical_speed, log.t, log.vz_sphinx, win))
    attitude = fit_first_order_delay(att, hold=True, fit_offset=True)
    d = attitude.delay
    attitude_turns = None
    if att_turn:
        attitude_turns = evaluate_first_order_delay(att_turn, attitude.time_constant, d, hold=True,
                                                    fit_offset=True)
    vertical = fit_first_order_delay(vert, hold=True, fit_offset=False, delay=d)
    vertical_free = fit_first_order_delay(vert, hold=True, fit_offset=False)
    yaw_fit = yaw_free = None
    if yaw:
        yaw_fit = fit_first_order_delay(yaw, hold=True, fit_offset=False, delay=d)
        yaw_free = fit_first_order_delay(yaw, hold=True, fit_offset=False)
    per_file = collections.OrderedDict()
    for log, tr in traces:
        t0 = log.t[tr.start_index]
        win = (log.t >= t0 - STEP_LEAD) & (log.t <= t0 + window)
        rms = collections.OrderedDict()
        for name, u, y, fit in (('pitch', tr.pitch, log.pitch_sphinx, attitude),
                                ('roll', tr.roll, log.roll_sphinx, attitude),
                                ('vertical_speed', tr.vertical_speed, log.vz_sphinx, vertical),
                                ('yaw_rate', tr.yaw_rate, measured_yaw_rate(log), yaw_fit)):
            if fit is None:
                continue
            m = first_order_response(tr.t, u, fit.time_constant, fit.delay, log.t, hold=True)
            r = (y - m)[win]
            if name in ('pitch', 'roll'):
                r = r - np.mean(r)
            rms[name] = float(np.sqrt(np.mean(r ** 2)))
        per_file[log.name] = rms
    return CommandFits(attitude, attitude_turns, vertical, vertical_free, yaw_fit, yaw_free, per_file,
                       tuple(log.name for log in used))


# --------------------------------------------------------------------------- replay
def replay_translation(log, params, trim=(0.0, 0.0), vertical_command=None, step=0.005):
    """Integrate the model's translation with the logged truth attitude; dict of arrays at ``log.t``.

    Horizontal: a_h = T z_h - (drag_linear + drag_quadratic |v_h|) v_h with the
    logged roll/pitch (+ ``trim`` = (pitch, roll) offset of the thrust axis) and
    yaw. Vertical: with ``vertical_command`` = (t, vz setpoint) the model's
    vertical loop (delay ``attitude_delay``, ``vertical_speed_time_constant``),
    else the logged vertical velocity is followed. Starts from the logged
    truth position/velocity. Keys: t, x, y, z, vx, vy, vz.
    """
    g = params['gravity']
    dl, dq, dv = params['drag_linear'], params['drag_quadratic'], params['drag_vertical']
    t = log.t
    grid = np.arange(t[0], t[-1] + step, step)
    roll = np.interp(grid, t, log.roll_sphinx) + trim[1]
    pitch = np.interp(grid, t, log.pitch_sphinx) + trim[0]
    yaw = np.interp(grid, t, np.unwrap(log.yaw_sphinx))
    zx, zy, zz = thrust_axis(roll, pitch, yaw)
    if vertical_command is not None:
        vz_ref = first_order_response(vertical_command[0], vertical_command[1],
                                      params['vertical_speed_time_constant'], params['attitude_delay'],
                                      grid, hold=True, initial=log.vz_sphinx[0])
    else:
        vz_ref = np.interp(grid, t, log.vz_sphinx)
    az = np.gradient(vz_ref, step)
    vx, vy = float(log.vx_sphinx[0]), float(log.vy_sphinx[0])
    x, y = float(log.x_sphinx[0]), float(log.y_sphinx[0])
    z = float(log.z_sphinx[0])
    out = np.empty((len(grid), 6))
    for k in range(len(grid)):
        out[k] = (x, y, z, vx, vy, vz_ref[k])
        thrust = (az[k] + g + dv * vz_ref[k]) / zz[k]
        k_drag = dl + dq * math.hypot(vx, vy)
        vx += (thrust * zx[k] - k_drag * vx) * step
        vy += (thrust * zy[k] - k_drag * vy) * step
        x += vx * step
        y += vy * step
        z += vz_ref[k] * step
    result = {'t': t}
    for j, name in enumerate(('x', 'y', 'z', 'vx', 'vy', 'vz')):
        result[name] = np.interp(t, grid, out[:, j])
    return result
