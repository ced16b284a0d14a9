"""Calibration section (f): the fidelity effects of the firmware's loops (pure numpy/scipy, no ROS).

Stage: offline, reference logs -> the tilt attenuation (constant: ``fit_tilt_attenuation``; speed-gated:
``fit_tilt_attenuation_speed``), the descent limit (``fit_descent``), the tilt-rate and vertical acceleration
limits (``fit_tilt_rate_limit``, ``fit_vertical_acceleration_limit``) and the roll/pitch loop's coupling to the
yaw rate (``fit_gyroscopic_coupling``). Each effect has keys in anafi_model.yaml whose shipped values switch it
off; ``fit.fit_effects`` puts them together. The estimate's effects are in ``estimate``.
"""
import collections
import math

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from anafi_lab.calibration.commands import (STEP_LEAD, measured_yaw_rate, reconstruct_mpc_commands,
                                            reconstruct_pid_commands)
from anafi_lab.calibration.logs import is_clean
from anafi_lab.calibration.responses import (first_order_response, gyroscopic_tilt_response, rate_limited_response,
                                             rate_limited_tilt_response)

TiltFit = collections.namedtuple('TiltFit', [
    'attenuation', 'rms_before', 'rms', 'n', 'per_file', 'joint', 'saturation', 'airspeed', 'straight', 'files'])
TiltFit.__doc__ = (
    'Tilt attenuation a (delivered = (1 - a) x commanded roll/pitch) fitted with the attitude loop\'s time '
    'constant and delay fixed: residual rms [rad] without / with it, samples, {file: {axis: (rms before, rms '
    'after)}}; alternatives on the same data: joint (tau, delay, a, rms) refit, saturation (S, rms) of '
    'S tanh(u / S), airspeed (c, rms) of u / (1 + c |v|) (tau, delay fitted with each); {file: (speed, '
    'commanded, delivered + trim offset, ratio)} steady means of the straight-line PID logs (a check: their '
    'replayed command depends on the waypoint timing); files fitted.')


def _attitude_data(logs, window=20.0, turn_rate=0.1):
    """(t_cmd, u, t, measured, mask, speed at t_cmd, file, axis) of the static PID logs (turns excluded)."""
    data = []
    used = [log for log in logs if is_clean(log) and log.name.endswith('_pid') and 'static' in log.name]
    for log in used:
        tr = reconstruct_pid_commands(log)
        t0 = log.t[tr.start_index]
        calm = ((log.t >= t0 - STEP_LEAD) & (log.t <= t0 + window)
                & (np.abs(measured_yaw_rate(log)) <= turn_rate))
        speed = np.interp(tr.t, log.t, np.hypot(log.vx_sphinx, log.vy_sphinx))
        for axis in ('pitch', 'roll'):
            data.append((tr.t, getattr(tr, axis), log.t, log.columns[axis + '_sphinx'], calm, speed, log.name, axis))
    return data, tuple(log.name for log in used)


def _tilt_residuals(data, tau, delay, transform):
    """Per series residual (offset removed: the trim) of the first-order loop fed transform(u, speed)."""
    out = []
    for t_u, u, t_y, y, mask, speed, _, _ in data:
        model = first_order_response(t_u, transform(u, speed), tau, delay, t_y)[mask]
        r = y[mask] - model
        out.append(r - np.mean(r))
    return out


def _rms(parts):
    r = np.concatenate(parts)
    return float(np.sqrt(np.mean(r ** 2)))


def _minimise(cost, starts):
    best = None
    for x0 in starts:
        result = minimize(cost, x0, method='Nelder-Mead', options={'xatol': 1e-5, 'fatol': 1e-14, 'maxiter': 2000})
        if best is None or result.fun < best.fun:
            best = result
    return best


def fit_tilt_attenuation(logs, attitude):
    """``TiltFit`` from the PID replays of the static-waypoint logs (the attitude loop ``attitude`` fixed).

    The model scales the commanded roll/pitch by (1 - a) before the first-order loop; a is the least-squares
    value with the loop's time constant and delay as fitted without it (the model delays every channel of
    the PCMD alike, so the delay stays that of the other loops). Reported besides: the same with tau and
    delay refitted, a saturation and an airspeed-dependent attenuation, and the steady straight-line PID
    logs (commanded from the replay vs delivered).
    """
    data, files = _attitude_data(logs)
    if not data:
        raise ValueError('fit_tilt_attenuation: no clean static-waypoint PID log')
    tau, delay = attitude.time_constant, attitude.delay

    def gain_cost(p, tau=tau, delay=delay):
        if not 0.3 <= p[0] <= 1.5:
            return 1e12
        return _rms(_tilt_residuals(data, tau, delay, lambda u, s: p[0] * u)) ** 2

    gain = float(_minimise(gain_cost, ([0.85],)).x[0])
    before = _tilt_residuals(data, tau, delay, lambda u, s: u)
    after = _tilt_residuals(data, tau, delay, lambda u, s: gain * u)
    per_file = collections.OrderedDict()
    for item, rb, ra in zip(data, before, after):
        per_file.setdefault(item[6], collections.OrderedDict())[item[7]] = (
            float(np.sqrt(np.mean(rb ** 2))), float(np.sqrt(np.mean(ra ** 2))))

    def joint_cost(p, kind):
        tau_, delay_, a = p
        if not (0.0 <= tau_ <= 1.0 and 0.0 <= delay_ <= 0.5):
            return 1e12
        if kind == 'gain':
            if not 0.3 <= a <= 1.5:
                return 1e12
            transform = lambda u, s: a * u                      # noqa: E731
        elif kind == 'tanh':
            if not 0.05 <= a <= 5.0:
                return 1e12
            transform = lambda u, s: a * np.tanh(u / a)         # noqa: E731
        else:
            if not 0.0 <= a <= 2.0:
                return 1e12
            transform = lambda u, s: u / (1.0 + a * s)          # noqa: E731
        return _rms(_tilt_residuals(data, tau_, delay_, transform)) ** 2

    out = {}
    for kind, a0 in (('gain', 0.85), ('tanh', 0.4), ('speed', 0.1)):
        best = _minimise(lambda p: joint_cost(p, kind), ([tau, delay, a0], [0.1, 0.18, a0], [0.25, 0.1, a0]))
        out[kind] = tuple(float(v) for v in best.x) + (math.sqrt(best.fun),)
    offsets = [float(np.mean(y[m] - first_order_response(tu, u, tau, delay, ty)[m]))
               for tu, u, ty, y, m, _, _, _ in data]
    trim = float(np.mean(offsets[0::2]))                 # the pitch offset of the static runs (hover trim)
    straight = collections.OrderedDict()
    for log in logs:
        if log.name.startswith('x_straight') and log.name.endswith('_pid'):
            tr = reconstruct_pid_commands(log)
            steady_cmd = tr.t > log.t[0] + 1.0
            steady = log.t > log.t[0] + 1.3
            commanded = float(np.mean(tr.pitch[steady_cmd]))
            delivered = float(np.mean(log.pitch_sphinx[steady])) - trim
            straight[log.name] = (float(np.mean(np.hypot(log.vx_sphinx, log.vy_sphinx))), commanded, delivered,
                                  delivered / commanded)
    return TiltFit(1.0 - gain, _rms(before), _rms(after), int(sum(r.size for r in after)), per_file,
                   (out['gain'][0], out['gain'][1], 1.0 - out['gain'][2], out['gain'][3]),
                   (out['tanh'][2], out['tanh'][3]), (out['speed'][2], out['speed'][3]), straight, files)


TiltSpeedFit = collections.namedtuple('TiltSpeedFit', ['attenuation', 'speed', 'speed_full', 'tolerance', 'trim',
                                                     'rows', 'files'])
TiltSpeedFit.__doc__ = (
    'Speed-gated tilt attenuation from the straight-line MPC logs: attenuation a, speed v0 [m/s] below which '
    'there is none, speed_full v1 [m/s] from which it is a (model keys tilt_attenuation, tilt_attenuation_speed, '
    'tilt_attenuation_speed_full); tolerance of "none" on the relative gain; pitch trim [rad] added to the logged '
    'pitch; {file: (speed [m/s], Sphinx commanded, Sphinx delivered + trim, stand-in commanded, stand-in '
    'delivered, relative gain)} (pitch means [rad]); files.')


def _steady_pitch(log, trim=0.0, skip=1.0):
    """(speed [m/s], reconstructed MPC pitch command, delivered pitch + ``trim``) means after ``skip`` s."""
    trace = reconstruct_mpc_commands(log)
    t0 = log.t[0] + skip
    pitch = np.asarray(log.pitch_sphinx, dtype=np.float64)
    keep = (log.t >= t0) & np.isfinite(pitch)
    speed = np.hypot(np.asarray(log.vx_sphinx, dtype=np.float64), np.asarray(log.vy_sphinx, dtype=np.float64))
    return (float(np.nanmean(speed[keep])), float(np.mean(trace.pitch[trace.t >= t0])),
            float(np.mean(pitch[keep])) + trim)


def fit_tilt_attenuation_speed(logs, model, trim=0.0, tolerance=0.05):
    """``TiltSpeedFit``: how much of a commanded pitch the firmware delivers, per speed, from the straight MPC logs.

    Per log: the mean MPC pitch command recomputed on the log (``reconstruct_mpc_commands``) against the mean
    delivered pitch (+ ``trim``, the drag fit's offset of the thrust axis), divided by the same ratio on the
    stand-in's closed-loop replay of that log (``anafi_lab.engine.replay``) with ``model`` (a model dict
    without the attenuation, which delivers exactly what is commanded). The recomputation's own bias (the
    10 Hz waypoint's sawtooth at the log's sample phase) is the same in both and cancels; what remains is the
    firmware's gain relative to the stand-in's 1. v1 = the speed of the fastest log, a = 1 - its relative gain,
    v0 = the speed of the fastest slower log whose relative gain is within ``tolerance`` of 1 (or above).
    Between v0 and v1 the model ramps linearly: the logs have no speed in between to tell the shape.
    """
    from anafi_lab.engine import replay as fidelity
    rows = collections.OrderedDict()
    variant = fidelity.Variant('no_attenuation', 'no attenuation', dict(model))
    for log in sorted((log for log in logs if log.name.startswith('x_straight') and log.name.endswith('_mpc')
                       and is_clean(log)), key=lambda log: float(np.nanmean(log.vx_sphinx))):
        replay = fidelity.run_replay(fidelity.replay_plan(log), variant)
        if not replay.ok:
            raise ValueError('fit_tilt_attenuation_speed: the replay of %s failed: %s' % (log.name, replay.error))
        speed, commanded, delivered = _steady_pitch(log, trim)
        _, commanded_s, delivered_s = _steady_pitch(replay.standin)
        rows[log.name] = (speed, commanded, delivered, commanded_s, delivered_s,
                          (delivered / commanded) / (delivered_s / commanded_s))
    if len(rows) < 2:
        raise ValueError('fit_tilt_attenuation_speed: needs straight-line MPC logs at two speeds at least')
    ordered = list(rows.values())
    top = ordered[-1]
    attenuation = max(0.0, 1.0 - top[5])
    below = [row[0] for row in ordered[:-1] if row[5] >= 1.0 - tolerance]
    # no slower log delivers the full tilt: a governor from (almost) standstill (v0 = 0 would mean the constant,
    # whole-tilt attenuation in the model)
    speed = max(below) if below else GATE_FLOOR
    return TiltSpeedFit(attenuation, speed, top[0], tolerance, trim, rows, tuple(rows))


GATE_FLOOR = 0.01                   # m/s, v0 of a speed governor acting from standstill (0 = constant attenuation)


DescentFit = collections.namedtuple('DescentFit', [
    'max_descent_speed', 'per_file', 'commanded', 'climb', 'replay', 'files'])
DescentFit.__doc__ = (
    'Descent limit [m/s]: mean descent speed of the truth under a saturated descent command, {file: (mean, '
    'std, samples)}, the commanded descent [m/s], {file: climb speed [m/s] reached under the saturated climb '
    'command}, {file: (vz rms before, after)} [m/s] of the vertical loop replays, files.')


def fit_descent(logs, vertical_time_constant, delay, saturated=0.99, settle=1.0):
    """``DescentFit``: the firmware's descent speed under a saturated descent command.

    The only saturated descents in the reference logs are those of x_straight_2_pid and x_straight_3_pid:
    their z estimate is garbage (a 16-bit wrap, so they are excluded from every other fit), which makes
    the PID command the full -2 m/s for the whole log, while their ground truth is valid. The limit is the
    mean truth vertical speed over the samples where the replayed command has been saturated for ``settle`` s.
    The climbs of the static PID logs show no such limit (reported). ``vertical_time_constant``, ``delay``:
    the vertical loop for the replay check (before: no limit, after: with it).
    """
    from anafi_sim.sim.bridge import MAX_VERTICAL_SPEED
    per_file = collections.OrderedDict()
    climb = collections.OrderedDict()
    traces = {}
    for log in logs:
        if not log.name.endswith('_pid'):
            continue
        tr = traces[log.name] = reconstruct_pid_commands(log)
        held = tr.vertical_speed[np.clip(np.searchsorted(tr.t, log.t, side='right') - 1, 0, None)]
        for sign, store in ((-1.0, per_file), (1.0, climb)):
            full = sign * held >= saturated * MAX_VERTICAL_SPEED
            settled = np.zeros_like(full)
            for i in np.flatnonzero(full):
                settled[i] = (np.all(full[(log.t >= log.t[i] - settle) & (log.t <= log.t[i])])
                              and log.t[i] - settle >= tr.t[0])
            if settled.sum() >= 10:
                vz = log.vz_sphinx[settled]
                if sign < 0:
                    store[log.name] = (float(-np.mean(vz)), float(np.std(vz)), int(settled.sum()))
                else:
                    store[log.name] = float(np.mean(vz[-10:]))
    if not per_file:
        return DescentFit(0.0, per_file, -MAX_VERTICAL_SPEED, climb, collections.OrderedDict(), ())
    limit = float(np.mean([v[0] for v in per_file.values()]))
    replay = collections.OrderedDict()
    for name, tr in traces.items():
        log = [lg for lg in logs if lg.name == name][0]
        t0 = log.t[tr.start_index]
        win = log.t >= t0 + 0.5 if name in per_file else (log.t >= t0 - STEP_LEAD) & (log.t <= t0 + 20.0)
        out = []
        for cap in (None, limit):
            u = tr.vertical_speed if cap is None else np.maximum(tr.vertical_speed, -cap)
            model = first_order_response(tr.t, u, vertical_time_constant, delay, log.t, hold=True,
                                         initial=log.vz_sphinx[0])
            out.append(float(np.sqrt(np.mean((model - log.vz_sphinx)[win] ** 2))))
        replay[name] = tuple(out)
    return DescentFit(limit, per_file, -MAX_VERTICAL_SPEED, climb, replay, tuple(per_file))


TiltRateFit = collections.namedtuple('TiltRateFit', [
    'rate', 'time_constant', 'rms', 'first_order', 'per_file', 'all_static', 'files'])
TiltRateFit.__doc__ = (
    'Roll/pitch loop with a tilt-rate limit: rate [rad/s], time_constant [s] (with the attitude delay), rms '
    '[rad] (outside the yaw turns, a constant offset per log and axis removed: the trim); first_order (time '
    'constant [s], rms [rad]) of the same data without the limit; {file: (rms first order, rms limited)} for '
    'every static log (the MPC ones: a check, not fitted); all_static (rate, time constant, rms) of the fit on '
    'all four; files (the fit\'s).')


def fit_tilt_rate_limit(logs, delay, baseline_time_constant, window=20.0, turn_rate=0.1):
    """``TiltRateFit``: the firmware's roll/pitch response as a first order whose tilt vector turns at most at a
    fitted rate, against the PID replays of the static steps (``fit_command_responses``' windows and calm
    samples, |yaw rate| <= ``turn_rate``), delay = the attitude ``delay``; ``baseline_time_constant`` [s]: the
    first order it is compared with (section (c)'s). A single first order has to fit the 30 deg steps (Sphinx's
    tilt ramps) and the small corrections at once; the MPC static logs (commands recomputed, eq. 15) are the
    check."""
    series = [(log.name, pid, tr, log.t[m], log.roll_sphinx[m], log.pitch_sphinx[m])
              for log, pid, tr, m in _static_steps(logs, window, turn_rate)]

    def cost(group, tau, rate):
        if tau <= 0.01 or tau > 1.0 or (rate is not None and rate <= 0.05):
            return 1e9
        parts = []
        for _, _, tr, t, roll, pitch in group:
            r, p = rate_limited_tilt_response(tr.t, tr.roll, tr.pitch, tau, rate or 0.0, delay, t)
            for e in (roll - r, pitch - p):
                parts.append(e - np.mean(e))
        return float(np.sqrt(np.mean(np.concatenate(parts) ** 2)))

    return TiltRateFit(*_fit_limited_loop('fit_tilt_rate_limit', series, cost, (0.12, 1.4), 1e-7,
                                          baseline_time_constant))


VerticalLimitFit = collections.namedtuple('VerticalLimitFit', [
    'limit', 'time_constant', 'rms', 'first_order', 'per_file', 'all_static', 'files'])
VerticalLimitFit.__doc__ = (
    'Vertical-speed loop with an acceleration limit: limit [m/s^2], time_constant [s] (with the attitude '
    'delay), rms [m/s]; first_order (time constant [s], rms [m/s]) of the same data without the limit; '
    '{file: (rms first order, rms limited)} [m/s] for every static log (PID and MPC: the MPC\'s commands are '
    'recomputed, eq. 15); all_static (limit, time constant, rms) of the same fit on all four static logs (a '
    'check); files (the fit\'s).')


def _static_steps(logs, window, turn_rate=None):
    """[(name, is_pid, CommandTrace, mask over the log's samples)] of the clean static-waypoint logs: the replayed
    commands (PID framework, or the MPC's by eq. 15) and the window from 0.5 s before the step to ``window`` s
    after it (without the yaw turns, |yaw rate| > ``turn_rate`` [rad/s], when given)."""
    out = []
    for log in logs:
        if not (is_clean(log) and log.name.startswith('static')):
            continue
        pid = log.name.endswith('_pid')
        tr = reconstruct_pid_commands(log) if pid else reconstruct_mpc_commands(log)
        t0 = log.t[tr.start_index]
        mask = (log.t >= t0 - STEP_LEAD) & (log.t <= t0 + window)
        if turn_rate is not None:
            mask &= np.abs(measured_yaw_rate(log)) <= turn_rate
        out.append((log, pid, tr, mask))
    return out


def fit_vertical_acceleration_limit(logs, delay, baseline_time_constant, window=20.0):
    """``VerticalLimitFit``: the firmware's vertical-speed step response as a first order whose acceleration is
    limited, against the PID replays of the static climbs (1 m -> 5 m, the 2 m/s command saturated).

    A single first order fits the climb's ramp and its end at once and so averages them: Sphinx's vertical
    speed rises along a straight line (~5-6 m/s^2), stops sharply at ~94 %% of the command and creeps to it;
    the limited loop separates the ramp (limit) from the small-signal lag (time constant), which is what a
    slow periodic vertical motion sees. Same windows as ``fit_command_responses`` (0.5 s before the step to
    ``window`` s after), the attitude ``delay`` (the model delays the whole PCMD); ``baseline_time_constant``
    [s]: the first order it is compared with (section (c)'s). The MPC static logs, whose commands can be
    recomputed (eq. 15), are a check: they climb faster than commanded (2.4 m/s under 2.0), which neither
    model explains (reported, not fitted)."""
    series = [(log.name, pid, tr, log.t[m], log.vz_sphinx[m]) for log, pid, tr, m in _static_steps(logs, window)]

    def cost(group, tau, limit):
        if tau <= 0.005 or tau > 1.0 or (limit is not None and limit <= 0.5):
            return 1e9
        r = [y - rate_limited_response(tr.t, tr.vertical_speed, tau, limit or 0.0, delay, t, initial=y[0])
             for _, _, tr, t, y in group]
        return float(np.sqrt(np.mean(np.concatenate(r) ** 2)))

    return VerticalLimitFit(*_fit_limited_loop('fit_vertical_acceleration_limit', series, cost, (0.08, 5.0), 1e-6,
                                               baseline_time_constant))


def _fit_limited_loop(name, series, cost, start, fatol, baseline_time_constant):
    """The fit of a first-order loop with a limit, shared by the tilt-rate and the vertical fits: ``series``
    [(log name, is_pid, ...)], ``cost(group, tau, limit)`` its rms (limit None: the plain first order), ``start``
    (tau, limit) of the Nelder-Mead. Fitted on the PID series, checked per series and on all of them. Returns
    (limit, tau, rms, (baseline tau, its rms), {log: (rms baseline, rms limited)}, (limit, tau, rms) on all,
    the fit's log names)."""
    used = [s for s in series if s[1]]
    if not used:
        raise ValueError('%s: no clean static-waypoint PID log' % name)

    def fit(group):
        res = minimize(lambda q: cost(group, q[0], q[1]), list(start), method='Nelder-Mead',
                       options={'xatol': 1e-4, 'fatol': fatol, 'maxiter': 400})
        return float(res.x[1]), float(res.x[0]), float(res.fun)

    limit, tau, rms = fit(used)
    first = (float(baseline_time_constant), cost(used, float(baseline_time_constant), None))
    per_file = collections.OrderedDict((s[0], (cost([s], first[0], None), cost([s], tau, limit))) for s in series)
    return limit, tau, rms, first, per_file, fit(series), tuple(s[0] for s in used)


GyroscopicFit = collections.namedtuple('GyroscopicFit', ['coupling', 'authority', 'precession', 'rms', 'rms_off',
                                                           'per_file', 'files', 'alone', 'compared'])
GyroscopicFit.__doc__ = (
    'The roll/pitch loop\'s coupling to the yaw rate (``AnafiModel``\'s gyroscopic_coupling effect): coupling G [s], '
    'authority c [1/rad] and precession w [-] (``frames.tilt_loop_step``), rms [rad] of roll/pitch over the static '
    'steps with them, rms_off without them, {file: (rms off, rms with G alone, rms with all three)} [rad], files '
    '(the fit\'s: every clean static log, PID and MPC), alone: (G, rms) of G fitted alone (the model before the '
    'authority and the precession), compared: rms [rad] of the ``compare`` terms (G, c, w) on this loop (NaN: '
    'none given).')


def fit_gyroscopic_coupling(logs, time_constant, delay, window=20.0, bounds=(-3.0, 3.0), rate_limit=0.0,
                            compare=None):
    """``GyroscopicFit``: the roll/pitch loop's coupling to the yaw rate (``gyroscopic_tilt_response``), least
    squares on the roll and pitch of every clean static step (PID commands replayed, the MPC's recomputed by
    eq. 15; 0.5 s before the step to ``window`` s after it, the yaw turns included: only they inform it) with the
    model's loop (``time_constant``, ``delay`` [s], ``rate_limit`` [rad/s]: 0 = the first order, as shipped; the
    tilt-rate limited loop for the fitted file) and the truth's yaw rate. Through Sphinx's 180 deg turns the
    tilt keeps its magnitude and swings round the long way in the sense of the yaw, where a plain first order
    cuts through level (docs/calibration.md). First G alone (bounded
    scalar search in ``bounds``), then G, the authority c >= 0 and the precession w together (Nelder-Mead from
    G alone and from a held tilt). ``compare``: terms (G, c, w) fitted elsewhere, whose rms on this loop is
    reported."""
    series = [(log.name, tr, log.t[m], log.roll_sphinx[m], log.pitch_sphinx[m], log.t, measured_yaw_rate(log))
              for log, pid, tr, m in _static_steps(logs, window)]
    if not series:
        raise ValueError('fit_gyroscopic_coupling: no clean static-waypoint log')

    def cost(group, g, c=0.0, w=0.0):
        if c < 0.0:
            return 1.0 + c * c
        parts = []
        for _, tr, t, roll, pitch, t_r, rate in group:
            r, p = gyroscopic_tilt_response(tr.t, tr.roll, tr.pitch, t_r, rate, time_constant, g, delay, t,
                                            authority=c, precession=w, rate_limit=rate_limit)
            parts += [roll - r, pitch - p]
        return float(np.sqrt(np.mean(np.concatenate(parts) ** 2)))

    res = minimize_scalar(lambda g: cost(series, g), bounds=bounds, method='bounded', options={'xatol': 1e-3})
    alone = float(res.x)
    best = None
    for start in ((alone, 0.0, 0.0), (alone, 3.0, 1.2), (0.0, 3.5, 1.2)):
        res = minimize(lambda q: cost(series, *q), start, method='Nelder-Mead',
                       options={'maxiter': 400, 'xatol': 1e-3, 'fatol': 1e-6})
        if best is None or res.fun < best.fun:
            best = res
    g, c, w = (float(v) for v in best.x)
    per_file = collections.OrderedDict((s[0], (cost([s], 0.0), cost([s], alone), cost([s], g, c, w)))
                                       for s in series)
    return GyroscopicFit(g, c, w, cost(series, g, c, w), cost(series, 0.0), per_file, tuple(s[0] for s in series),
                         (alone, cost(series, alone)), cost(series, *compare) if compare else float('nan'))
