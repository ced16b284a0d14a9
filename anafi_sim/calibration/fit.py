"""Calibration of the simulated Anafi: fit its parameters to reference logs (pure numpy/scipy, no ROS).

Stage: offline, reference logs -> model parameters (``calibrate``), written to
``anafi_sim/config/anafi_model.yaml`` (read by ``anafi_sim/sim/drone_model.py`` and
``anafi_sim/sim/state_estimate.py``) by ``report.format_model_yaml``; ``report`` also writes the
Markdown report, ``plot`` the replay figure. The fits follow the model's equations exactly:

- attitude: roll/pitch (FLU Euler, R = Rz(yaw) Ry(pitch) Rx(roll), + pitch =
  nose down -> +x acceleration at yaw 0, + roll -> -y) track the setpoint
  first-order (``attitude_time_constant`` [s]) after ``attitude_delay`` [s],
  which delays the whole piloting command; yaw rate and vertical speed are
  first order too (``yaw_rate_time_constant``, ``vertical_speed_time_constant``);
- translation (world ENU): a = T z_body - g e_z - drag, with the specific
  thrust T chosen so that the vertical acceleration is what the vertical loop
  wants, horizontal drag (drag_linear + drag_quadratic |v_h|) v_h [1/s, 1/m],
  vertical drag drag_vertical v_z [1/s]; no wind in the logs (airspeed =
  ground speed);
- estimate: pure delay, first-order smoothing, sample-and-hold at
  ``estimate_rate`` [Hz], optional float16 quantisation.

Ground truth (``*_sphinx``) is the plant, ``*_anafi`` the estimate. Every fit
returns its values with the residual RMS (and R^2 where meaningful).
Units: SI (s, m, m/s, m/s^2, rad, rad/s) unless a name says otherwise.
"""
import collections
import math

import numpy as np
from scipy.optimize import minimize
from scipy.signal import lfilter, savgol_filter

from anafi_sim.experiments.reference_log import STATE_NAMES, detect_garbage, tracking_error
from anafi_sim.experiments.report import PAPER_TABLE3

GRAVITY = 9.81

# The keys of anafi_model.yaml, in file order (drone_model.MODEL_KEYS must be the same set).
MODEL_KEYS = (
    'gravity', 'attitude_time_constant', 'attitude_delay', 'yaw_rate_time_constant',
    'vertical_speed_time_constant', 'drag_linear', 'drag_quadratic', 'drag_vertical',
    'estimate_delay', 'estimate_time_constant', 'estimate_rate', 'estimate_float16',
)

SIM_STEP = 0.002                   # s, integration step of the first-order responses in the fits
ESTIMATE_STEP = 0.005              # s, the same for the (long, many-channel) estimate fits
DRAG_WINDOW = 7                    # samples of the Savitzky-Golay window (0.35 s at 20 Hz)
ESTIMATE_CHANNELS = ('x', 'y', 'z', 'vx', 'vy', 'vz', 'roll', 'pitch')   # yaw has a drifting bias

FirstOrderFit = collections.namedtuple(
    'FirstOrderFit', ['time_constant', 'delay', 'gains', 'offsets', 'rms', 'r2', 'n'])
FirstOrderFit.__doc__ = ('First order + delay fit: time_constant [s], delay [s], per-series gain and offset '
                         '(1 / 0 when not fitted), residual RMS (units of the measurement), R^2, samples used.')


# --------------------------------------------------------------------------- first order + delay
def _held_means(t_u, u, a, b):
    """Exact mean over [a, b] (arrays) of u held after each sample (constant outside the sampled span)."""
    U = np.concatenate(([0.0], np.cumsum(u[:-1] * np.diff(t_u))))
    t0, t1 = t_u[0], t_u[-1]

    def integral(x):
        return (np.interp(x, t_u, U) + np.where(x < t0, (x - t0) * u[0], 0.0)
                + np.where(x > t1, (x - t1) * u[-1], 0.0))

    return (integral(b) - integral(a)) / (b - a)


def first_order_response(t_u, u, time_constant, delay, t_out, hold=True, step=SIM_STEP, initial=None):
    """Response y(t_out) of tau y' = u(t - delay) - y to the input samples (t_u, u).

    ``hold``: u is piecewise constant after each sample (a command stream),
    else linear between samples (a measured signal). A held input is averaged
    over a centred window of one integration step at each grid point (so the
    response is continuous in ``delay``); the grid samples are integrated
    exactly for an input linear between them (no lag bias for any time constant).
    Starts at ``initial`` (default: the input at the first instant, i.e. at rest).
    """
    t_u = np.asarray(t_u, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    t_out = np.asarray(t_out, dtype=np.float64)
    start = min(t_u[0], t_out[0])
    grid = np.arange(start, t_out[-1] + 2.0 * step, step)
    if hold:      # mean over a centred step: continuous in the delay despite the jumps
        samples = _held_means(t_u, u, grid - 0.5 * step - delay, grid + 0.5 * step - delay)
    else:
        samples = np.interp(grid - delay, t_u, u)
    y0 = samples[0] if initial is None else float(initial)
    if time_constant > 1e-6:
        a = math.exp(-step / time_constant)
        k = time_constant / step * (1.0 - a)
        b0, b1 = 1.0 - k, k - a                # exact for a linear input over the step
        body, _ = lfilter([b0, b1], [1.0, -a], samples[1:], zi=[a * y0 + b1 * samples[0]])
        y = np.concatenate(([y0], body))
    else:
        y = samples.copy()
        y[0] = y0
    return np.interp(t_out, grid, y)


SERIES_LEAD = 3.0                  # s of input kept before the first used measurement (response start-up)


def _as_series(series):
    """Arrays of each (t_u, u, t_y, y[, mask]), cropped to the used measurements (+ SERIES_LEAD of input)."""
    out = []
    for item in series:
        if len(item) == 4:
            t_u, u, t_y, y = item
            mask = None
        else:
            t_u, u, t_y, y, mask = item
        t_u = np.asarray(t_u, dtype=np.float64)
        u = np.asarray(u, dtype=np.float64)
        t_y = np.asarray(t_y, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        mask = np.ones(len(y), dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        mask = mask & np.isfinite(y)
        used = np.flatnonzero(mask)
        if used.size:
            lo, hi = used[0], used[-1] + 1
            t_y, y, mask = t_y[lo:hi], y[lo:hi], mask[lo:hi]
            first = max(0, int(np.searchsorted(t_u, t_y[0] - SERIES_LEAD, side='right')) - 1)
            if len(t_u) - first >= 2:
                t_u, u = t_u[first:], u[first:]
        out.append((t_u, u, t_y, y, mask))
    return out


def _residual_parts(data, scales, tau, d, hold, fit_gain, fit_offset, step=SIM_STEP):
    """Per series: (residual, measurement, scale, gain, offset) for time constant ``tau`` and delay ``d``."""
    out = []
    for (t_u, u, t_y, y, mask), scale in zip(data, scales):
        s = first_order_response(t_u, u, tau, d, t_y, hold=hold, step=step)[mask]
        yy = y[mask]
        columns = []
        if fit_gain:
            columns.append(s)
        if fit_offset:
            columns.append(np.ones_like(s))
        target = yy if fit_gain else yy - s
        if columns and yy.size:
            A = np.column_stack(columns)
            coef = np.linalg.lstsq(A, target, rcond=None)[0]
            model = A.dot(coef)
        else:
            coef = np.zeros(len(columns))
            model = np.zeros_like(target)
        gain = coef[0] if fit_gain else 1.0
        offset = coef[-1] if fit_offset else 0.0
        out.append((target - model, yy, scale, gain, offset))
    return out


def evaluate_first_order_delay(series, time_constant, delay, hold=True, fit_gain=False, fit_offset=True):
    """``FirstOrderFit`` of given time constant and delay on ``series`` (only gains/offsets are solved)."""
    data = _as_series(series)
    parts = _residual_parts(data, [1.0] * len(data), time_constant, delay, hold, fit_gain, fit_offset)
    return _summary(parts, time_constant, delay)


def _summary(parts, tau, d):
    res = np.concatenate([p[0] for p in parts])
    ss_tot = sum(float(np.sum((p[1] - p[1].mean()) ** 2)) for p in parts if p[1].size)
    rms = float(np.sqrt(np.mean(res ** 2))) if res.size else float('nan')
    r2 = 1.0 - float(np.sum(res ** 2)) / ss_tot if ss_tot > 0 else float('nan')
    return FirstOrderFit(float(tau), float(d), tuple(float(p[3]) for p in parts),
                         tuple(float(p[4]) for p in parts), rms, r2, int(res.size))


def fit_first_order_delay(series, hold=True, fit_gain=False, fit_offset=True, delay=None,
                          scales=None, tau_range=(0.0, 2.0), delay_range=(0.0, 0.5), step=SIM_STEP):
    """Least-squares first order + delay shared by several series; returns ``FirstOrderFit``.

    ``series``: list of (t_u, u, t_y, y[, mask]) (input samples, measured
    samples, samples used). Time constant and delay are common; each series
    gets its own offset (``fit_offset``) and gain (``fit_gain``, else 1),
    solved linearly for every candidate (variable projection). ``delay``
    fixes the delay instead of fitting it. ``scales`` divides each series'
    residual in the cost (joint fits of quantities in different units; the
    reported RMS is unscaled). Grid search, then Nelder-Mead within the ranges.
    ``step`` [s] is the integration step of the responses.
    """
    data = _as_series(series)
    scales = [1.0] * len(data) if scales is None else [float(s) for s in scales]
    lo_tau, hi_tau = tau_range
    lo_d, hi_d = delay_range

    def cost(params):
        tau = params[0]
        d = delay if delay is not None else params[1]
        if not (lo_tau <= tau <= hi_tau and lo_d <= d <= hi_d):
            return 1e12
        total = 0.0
        count = 0
        for r, _, scale, _, _ in _residual_parts(data, scales, tau, d, hold, fit_gain, fit_offset, step):
            total += float(np.sum((r / scale) ** 2))
            count += r.size
        return total / max(count, 1)

    taus = [t for t in (0.0, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 0.8, 1.2) if lo_tau <= t <= hi_tau] or [lo_tau]
    if delay is None:
        delays = [float(d) for d in np.arange(lo_d, hi_d + 1e-9, 0.05)]
        start = min(((cost((t, d)), t, d) for t in taus for d in delays))
        x0 = [start[1], start[2]]
    else:
        start = min(((cost((t,)), t) for t in taus))
        x0 = [start[1]]
    steps = [0.02] * len(x0)
    simplex = [list(x0)]
    for i in range(len(x0)):                 # step into the allowed range from the grid point
        vertex = list(x0)
        upper = hi_tau if i == 0 else hi_d
        vertex[i] = x0[i] + steps[i] if x0[i] + steps[i] <= upper else x0[i] - steps[i]
        simplex.append(vertex)
    result = minimize(cost, x0, method='Nelder-Mead',
                      options={'xatol': 1e-4, 'fatol': 1e-12, 'maxiter': 400, 'initial_simplex': simplex})
    best = result.x if result.fun <= start[0] else np.asarray(x0, dtype=np.float64)
    tau = float(best[0])
    d = float(delay) if delay is not None else float(best[1])
    return _summary(_residual_parts(data, [1.0] * len(data), tau, d, hold, fit_gain, fit_offset, step), tau, d)


def fit_attitude_response(t, commanded, measured, mask=None, fit_offset=True, delay=None, t_measured=None):
    """First order + delay from a commanded to a measured angle (same units, gain 1); ``FirstOrderFit``.

    ``t`` [s] are the command instants (the command is held between them);
    ``measured`` is sampled at ``t_measured`` (default ``t``). ``fit_offset``
    allows a constant trim between setpoint and measured attitude.
    """
    t_y = t if t_measured is None else t_measured
    return fit_first_order_delay([(t, commanded, t_y, measured, mask)], hold=True, fit_gain=False,
                                 fit_offset=fit_offset, delay=delay)


# --------------------------------------------------------------------------- helpers on logs
def log_rate(log):
    """Median sample rate of a log [Hz]."""
    return 1.0 / float(np.median(np.diff(log.t)))


def is_clean(log):
    """True when ``detect_garbage`` finds nothing in the log."""
    return not detect_garbage(log)


def thrust_axis(roll, pitch, yaw):
    """Body z axis in the world (third column of Rz(yaw) Ry(pitch) Rx(roll)), vectorised: (zx, zy, zz)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    return cy * sp * cr + sy * sr, sy * sp * cr - cy * sr, cp * cr


def _smoothed_log(log, window=DRAG_WINDOW, source='sphinx'):
    """Uniformly resampled, Savitzky-Golay smoothed truth + accelerations (edges dropped)."""
    rate = log_rate(log)
    tu = np.arange(log.t[0], log.t[-1] + 1e-9, 1.0 / rate)

    def col(name):
        values = log.columns['%s_%s' % (name, source)]
        if name == 'yaw':
            values = np.unwrap(values)
        return np.interp(tu, log.t, values)

    out = {'t': tu}
    for name in ('vx', 'vy', 'vz'):
        raw = col(name)
        out[name] = savgol_filter(raw, window, 2, deriv=0, mode='interp')
        out['a' + name[1]] = savgol_filter(raw, window, 2, deriv=1, delta=1.0 / rate, mode='interp')
    for name in ('roll', 'pitch', 'yaw'):
        out[name] = savgol_filter(col(name), window, 2, deriv=0, mode='interp')
    half = window // 2
    keep = slice(half, len(tu) - half)
    return dict((k, v[keep]) for k, v in out.items())


# --------------------------------------------------------------------------- (a) drag
DragFit = collections.namedtuple('DragFit', [
    'drag_linear', 'drag_quadratic', 'drag_vertical', 'drag_vertical_identified', 'trim_pitch', 'trim_roll',
    'stderr', 'rms', 'r2', 'n', 'per_file_rms', 'window', 'files', 'vertical_by_window'])
DragFit.__doc__ = ('Drag fit: drag_linear [1/s], drag_quadratic [1/m], drag_vertical [1/s] (fitted value, '
                   'see drag_vertical_identified), body trim of the thrust axis vs the logged attitude '
                   '(pitch, roll) [rad], standard errors {name: value}, residual RMS [m/s^2] of the horizontal '
                   'acceleration, R^2, samples, {file: rms}, Savitzky-Golay window, files, '
                   '{window: drag_vertical} (its sensitivity to smoothing).')

_DRAG_NAMES = ('drag_linear', 'drag_quadratic', 'drag_vertical', 'trim_pitch', 'trim_roll')


def _drag_system(smoothed, gravity):
    """Linear system A p = b for p = (drag_linear, drag_quadratic, drag_vertical, trim_pitch, trim_roll).

    Horizontal acceleration a_h = T z_h - (dl + dq |v_h|) v_h with T z_z = a_z + g + dv v_z (the thrust
    the vertical loop needs), a small trim (dp, dr) of the thrust axis linearised around level.
    """
    s = smoothed
    zx, zy, zz = thrust_axis(s['roll'], s['pitch'], s['yaw'])
    speed = np.hypot(s['vx'], s['vy'])
    base = (s['az'] + gravity) / zz
    cy, sy = np.cos(s['yaw']), np.sin(s['yaw'])
    rows = []
    rhs = []
    for acc, z_h, v, c_pitch, c_roll in ((s['ax'], zx, s['vx'], cy, sy), (s['ay'], zy, s['vy'], sy, -cy)):
        rows.append(np.column_stack((-v, -speed * v, s['vz'] * z_h / zz, gravity * c_pitch, gravity * c_roll)))
        rhs.append(acc - base * z_h)
    return np.vstack(rows), np.concatenate(rhs)


def fit_drag(logs, window=DRAG_WINDOW, gravity=GRAVITY, vertical_windows=(5, 7, 9, 13)):
    """Horizontal drag from truth attitude -> acceleration over all clean logs; ``DragFit``.

    Accelerations are Savitzky-Golay derivatives of the truth velocity
    (window ``window`` samples, quadratic); the regressors are smoothed by
    the same filter so both have the same phase. Logs with garbage are
    skipped. ``drag_vertical`` only enters through v_z tan(tilt) and is
    reported as identified only if its estimate is stable over
    ``vertical_windows`` (spread < 3 standard errors and < 50 %).
    """
    used = [log for log in logs if is_clean(log)]
    if not used:
        raise ValueError('fit_drag: no clean log to fit')

    def solve(win):
        systems = [_drag_system(_smoothed_log(log, win), gravity) for log in used]
        A = np.vstack([s[0] for s in systems])
        b = np.concatenate([s[1] for s in systems])
        p = np.linalg.lstsq(A, b, rcond=None)[0]
        return systems, A, b, p

    systems, A, b, p = solve(window)
    res = b - A.dot(p)
    dof = max(len(b) - len(p), 1)
    cov = np.linalg.inv(A.T.dot(A)) * float(res.dot(res)) / dof
    stderr = dict((name, float(math.sqrt(cov[i, i]))) for i, name in enumerate(_DRAG_NAMES))
    per_file = collections.OrderedDict()
    for log, (Ai, bi) in zip(used, systems):
        per_file[log.name] = float(np.sqrt(np.mean((bi - Ai.dot(p)) ** 2)))
    by_window = collections.OrderedDict()
    for win in vertical_windows:
        by_window[win] = float(solve(win)[3][2]) if win != window else float(p[2])
    spread = max(by_window.values()) - min(by_window.values())
    identified = spread < 3.0 * stderr['drag_vertical'] and spread < 0.5 * abs(p[2])
    return DragFit(float(p[0]), float(p[1]), float(p[2]), bool(identified), float(p[3]), float(p[4]), stderr,
                   float(np.sqrt(np.mean(res ** 2))), 1.0 - float(np.var(res)) / float(np.var(b)), int(len(b)),
                   per_file, window, tuple(log.name for log in used), by_window)


def steady_state_pitch(speed, drag_linear, drag_quadratic, gravity=GRAVITY):
    """Tilt [rad] that holds a level straight flight at ``speed`` [m/s] against the drag (no trim)."""
    return math.atan((drag_linear + drag_quadratic * speed) * speed / gravity)


# --------------------------------------------------------------------------- (b) estimate
def float16_fraction(values):
    """Fraction of finite ``values`` that are IEEE half floats: exactly, or as their shortest decimal repr.

    1.0 means the numbers were stored as float16 (as every column of the paper's logs is: the CSV holds
    the shortest repr, e.g. 48.8 for 48.8125).
    """
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return float('nan')
    halves = np.float16(values)
    hits = sum(1 for v, h in zip(values.tolist(), halves.tolist()) if h == v or float(str(np.float16(h))) == v)
    return hits / float(values.size)


def quantum_fraction(values, quantum):
    """Fraction of finite ``values`` (after float16 round-trip) that are whole multiples of ``quantum``."""
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return float('nan')
    v = np.float16(values).astype(np.float64) / quantum
    return float(np.mean(np.abs(v - np.round(v)) < 1e-6))


def estimate_change_rate(logs, channels=ESTIMATE_CHANNELS, thresholds=None):
    """Rate [Hz] at which the estimate's values change while the truth moves; (rate, fraction, samples).

    Only sample pairs where the truth changed by more than a threshold (well
    above the estimate's quantisation) count; the change fraction times the
    log rate is the estimate's update rate as far as the log can show it
    (it cannot show more than the log rate).
    """
    thresholds = thresholds or {'x': 0.06, 'y': 0.06, 'z': 0.02, 'vx': 0.02, 'vy': 0.02, 'vz': 0.02,
                                'roll': 0.002, 'pitch': 0.002, 'yaw': 0.002}
    changed = 0
    total = 0
    rates = []
    for log in logs:
        rates.append(log_rate(log))
        for name in channels:
            truth = log.columns[name + '_sphinx']
            est = log.columns[name + '_anafi']
            moving = np.abs(np.diff(truth)) > thresholds[name]
            changed += int(np.sum(np.diff(est)[moving] != 0))
            total += int(np.sum(moving))
    if total == 0:
        return float('nan'), float('nan'), 0
    fraction = changed / float(total)
    return fraction * float(np.median(rates)), fraction, total


def estimate_model_response(t, truth, delay, time_constant, rate, t_out=None, phase=0.0, step=SIM_STEP):
    """The model's estimate of a truth signal: delay, first order, then held at multiples of 1/rate (+phase).

    ``t``, ``truth``: truth samples (linear in between); returns the estimate at ``t_out`` (default ``t``).
    Same chain as ``anafi_sim.sim.state_estimate.StateEstimate`` (without float16).
    """
    t = np.asarray(t, dtype=np.float64)
    t_out = t if t_out is None else np.asarray(t_out, dtype=np.float64)
    grid = np.arange(t[0], t_out[-1] + step, step)
    smooth = first_order_response(t, truth, time_constant, delay, grid, hold=False, step=step)
    held_at = np.floor((t_out - phase) * rate + 1e-9) / rate + phase
    return np.interp(np.maximum(held_at, grid[0]), grid, smooth)


EstimateFit = collections.namedtuple('EstimateFit', [
    'delay', 'time_constant', 'effective_delay', 'rate', 'float16', 'fit', 'groups', 'change_rate',
    'change_fraction', 'float16_fractions', 'quanta', 'steady_position_lag', 'yaw_bias', 'files'])
EstimateFit.__doc__ = (
    'Estimate fit: model delay [s] (= effective_delay - 0.5/rate, the hold adds half a period on average), '
    'time_constant [s], effective (logged) delay [s], rate [Hz], float16 flag, the joint FirstOrderFit, '
    '{group: FirstOrderFit} per channel group, measured change rate [Hz] and fraction, '
    '{column: float16 fraction}, {column: fraction on a 1/256 grid}, {file: steady position lag [s]} of the '
    'straight-line logs, {file: mean yaw_anafi - yaw_sphinx [rad]}, files used.')

_GROUPS = collections.OrderedDict((('position', ('x', 'y', 'z')), ('velocity', ('vx', 'vy', 'vz')),
                                   ('attitude', ('roll', 'pitch'))))


def _estimate_series(logs, channels):
    series = []
    scales = []
    for log in logs:
        for name in channels:
            truth = log.columns[name + '_sphinx']
            est = log.columns[name + '_anafi']
            mask = np.ones(len(truth), dtype=bool)
            mask[:10] = False                     # let the response forget its initial state
            series.append((log.t, truth, log.t, est, mask))
            scales.append(max(float(np.std(np.diff(truth))), 1e-4))   # residual in "samples of motion"
    return series, scales


def fit_estimate(logs, dynamic_prefix='static', channels=ESTIMATE_CHANNELS):
    """Delay, smoothing, rate and float16-ness of the drone's estimate vs the truth; ``EstimateFit``.

    The delay/smoothing fit uses the clean logs whose name starts with
    ``dynamic_prefix`` (the static-waypoint runs: large transients; the
    straight-line runs hardly move but in x, where delay and a position
    bias cannot be told apart) with a free offset per file and channel
    (estimate bias) and each residual scaled by the truth's per-sample
    change. float16: the estimate counts as half-float quantised only if
    its columns are and the truth's are not (else it is the log's storage).
    """
    clean = [log for log in logs if is_clean(log)]
    dynamic = [log for log in clean if log.name.startswith(dynamic_prefix)] or clean
    if not dynamic:
        raise ValueError('fit_estimate: no clean log to fit')
    series, scales = _estimate_series(dynamic, channels)
    joint = fit_first_order_delay(series, hold=False, fit_offset=True, scales=scales,
                                  tau_range=(0.0, 0.5), delay_range=(0.0, 0.4), step=ESTIMATE_STEP)
    groups = collections.OrderedDict()
    for group, names in _GROUPS.items():
        names = [n for n in names if n in channels]
        if names:
            s, sc = _estimate_series(dynamic, names)
            groups[group] = fit_first_order_delay(s, hold=False, fit_offset=True, scales=sc,
                                                  tau_range=(0.0, 0.5), delay_range=(0.0, 0.4),
                                                  step=ESTIMATE_STEP)
    change_rate, change_fraction, _ = estimate_change_rate(clean, channels)
    rate = round(float(np.median([log_rate(log) for log in clean])), 1)
    f16 = collections.OrderedDict()
    quanta = collections.OrderedDict()
    for source in ('sphinx', 'anafi'):
        for name in STATE_NAMES:
            column = '%s_%s' % (name, source)
            values = np.concatenate([log.columns[column] for log in clean])
            f16[column] = float16_fraction(values)
            quanta[column] = quantum_fraction(values, 1.0 / 256.0)
    anafi_f16 = min(f16['%s_anafi' % n] for n in STATE_NAMES)
    sphinx_f16 = max(f16['%s_sphinx' % n] for n in STATE_NAMES)
    is_float16 = bool(anafi_f16 > 0.999 and sphinx_f16 < 0.5)
    lags = collections.OrderedDict()
    for log in clean:
        speed = float(np.mean(np.hypot(log.vx_sphinx, log.vy_sphinx)))
        if not log.name.startswith(dynamic_prefix) and speed > 0.5:
            ex = log.x_sphinx - log.x_anafi
            ey = log.y_sphinx - log.y_anafi
            along = (ex * log.vx_sphinx + ey * log.vy_sphinx) / np.hypot(log.vx_sphinx, log.vy_sphinx)
            lags[log.name] = float(np.mean(along) / speed)
    yaw_bias = collections.OrderedDict(
        (log.name, float(np.mean(np.angle(np.exp(1j * (log.yaw_anafi - log.yaw_sphinx)))))) for log in clean)
    delay = max(0.0, joint.delay - 0.5 / rate)
    return EstimateFit(delay, joint.time_constant, joint.delay, rate, is_float16, joint, groups, change_rate,
                       change_fraction, f16, quanta, lags, yaw_bias, tuple(log.name for log in dynamic))


# --------------------------------------------------------------------------- (c-e) command responses
CommandTrace = collections.namedtuple('CommandTrace', ['t', 'roll', 'pitch', 'yaw_rate', 'vertical_speed',
                                                       'start_index'])
CommandTrace.__doc__ = ('Reconstructed firmware setpoints at the command instants t [s, log time]: roll, pitch '
                        '[rad, FLU], yaw_rate [rad/s, ENU, + = counter-clockwise], vertical_speed [m/s]; '
                        'start_index = first log sample with the waypoint set (hover command before).')


def reconstruct_pid_commands(log, cycle_rate=30.0, output_rate=10.0, framework=None, mapping=None):
    """Replay the paper's PID framework on the logged estimate and waypoint; ``CommandTrace``.

    The loops (``anafi_control.pid_framework.PidFramework``, Table 2 gains)
    run at ``cycle_rate`` on the latest logged sample (zero-order hold) from
    the first sample whose waypoint differs from the first row (the logs start
    in hover before the waypoint is published); the command is sampled at
    ``output_rate`` and quantised to whole PCMD percents as the bridge does
    (``anafi_sim.sim.bridge.PilotingMapping``). Only meaningful for the *_pid logs.
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
    cycles = np.arange(log.t[start], log.t[-1], 1.0 / cycle_rate)
    index = np.searchsorted(log.t, cycles, side='right') - 1
    every = max(1, int(round(cycle_rate / output_rate)))
    times = [log.t[0]] if start > 0 else []
    setpoints = [(0.0, 0.0, 0.0, 0.0)] if start > 0 else []
    for k, (tc, i) in enumerate(zip(cycles, index)):
        framework.update(float(tc), (log.x_anafi[i], log.y_anafi[i], log.z_anafi[i]),
                         (log.vx_anafi[i], log.vy_anafi[i], log.vz_anafi[i]), float(log.yaw_anafi[i]),
                         tuple(float(v) for v in wp[i]))
        if k % every == 0:
            times.append(float(tc))
            setpoints.append(mapping.command_to_setpoints(*framework.command()))
    sp = np.array(setpoints, dtype=np.float64)
    return CommandTrace(np.array(times), sp[:, 0], sp[:, 1], sp[:, 2], sp[:, 3], start)


def measured_yaw_rate(log, window=5):
    """Yaw rate [rad/s] of the truth (Savitzky-Golay derivative of the unwrapped yaw)."""
    rate = log_rate(log)
    tu = np.arange(log.t[0], log.t[-1] + 1e-9, 1.0 / rate)
    yaw = np.interp(tu, log.t, np.unwrap(log.yaw_sphinx))
    return np.interp(log.t, tu, savgol_filter(yaw, window, 2, deriv=1, delta=1.0 / rate, mode='interp'))


CommandFits = collections.namedtuple('CommandFits', [
    'attitude', 'attitude_turns', 'vertical', 'vertical_free', 'yaw', 'yaw_free', 'per_file', 'files'])
CommandFits.__doc__ = ('Fits of the firmware loops against PID command replays: attitude (FirstOrderFit, '
                       'turns excluded), attitude_turns (same delay/tau evaluated during the yaw turns), vertical '
                       'and yaw with the attitude delay (the model delays the whole command), *_free with their '
                       'own delay, {file: {loop: rms}}, files.')


def fit_command_responses(logs, window=20.0, turn_rate=0.1):
    """Attitude, vertical-speed and yaw-rate first-order fits from PID replays of the *_pid logs.

    For each clean PID log the commands are reconstructed
    (``reconstruct_pid_commands``) and compared with the truth from 0.5 s
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
        win = (log.t >= t0 - 0.5) & (log.t <= t0 + window)
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
        win = (log.t >= t0 - 0.5) & (log.t <= t0 + window)
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


# --------------------------------------------------------------------------- everything
Calibration = collections.namedtuple('Calibration', ['params', 'drag', 'estimate', 'commands', 'garbage',
                                                     'notes'])
Calibration.__doc__ = ('Result of ``calibrate``: params {MODEL_KEYS: value}, DragFit, EstimateFit, CommandFits, '
                       '{file: GarbageReport}, [notes on what is not identified / not modelled].')


def calibrate(logs, gravity=GRAVITY):
    """Run every fit on ``logs`` (ReferenceLog list) and assemble the model parameters; ``Calibration``."""
    garbage = collections.OrderedDict((log.name, detect_garbage(log)) for log in logs)
    drag = fit_drag(logs, gravity=gravity)
    estimate = fit_estimate(logs)
    commands = fit_command_responses(logs)
    notes = []
    drag_vertical = drag.drag_vertical
    if not drag.drag_vertical_identified or drag_vertical < 0.0:
        drag_vertical = drag.drag_linear
        notes.append('drag_vertical is not identifiable from these logs (fit %s 1/s over Savitzky-Golay windows '
                     '%s); set to drag_linear (isotropic linear drag assumption). The model\'s vertical loop '
                     'compensates it, so it only matters through v_z tan(tilt).'
                     % (', '.join('%.3f' % v for v in drag.vertical_by_window.values()),
                        ', '.join(str(w) for w in drag.vertical_by_window)))
    params = collections.OrderedDict()
    params['gravity'] = float(gravity)
    params['attitude_time_constant'] = commands.attitude.time_constant
    params['attitude_delay'] = commands.attitude.delay
    params['yaw_rate_time_constant'] = commands.yaw.time_constant if commands.yaw else float('nan')
    params['vertical_speed_time_constant'] = commands.vertical.time_constant
    params['drag_linear'] = drag.drag_linear
    params['drag_quadratic'] = drag.drag_quadratic
    params['drag_vertical'] = float(drag_vertical)
    params['estimate_delay'] = estimate.delay
    params['estimate_time_constant'] = estimate.time_constant
    params['estimate_rate'] = estimate.rate
    params['estimate_float16'] = estimate.float16
    if commands.yaw is None:
        notes.append('yaw_rate_time_constant: no PID log with a yaw turn; not identified.')
    return Calibration(params, drag, estimate, commands, garbage, notes)


# --------------------------------------------------------------------------- Table 3 recomputed
Table3Row = collections.namedtuple('Table3Row', ['controller', 'speed', 'file', 'paper', 'mean_e', 'mean_e_h',
                                                 'n_excluded', 'garbage'])
Table3Row.__doc__ = ('One Table-3 cell recomputed: controller, speed [m/s], file, paper mean e [m], mean e [m] '
                     '(garbage excluded; NaN if nothing valid), mean horizontal e [m], samples excluded, '
                     'garbage summary lines.')


def table3(logs):
    """Recompute the paper's Table 3 from the x_straight_<speed>_<controller> logs; list of ``Table3Row``."""
    by_name = dict((log.name, log) for log in logs)
    rows = []
    for controller in ('mpc', 'pid'):
        for k, paper in enumerate(PAPER_TABLE3[controller]):
            name = 'x_straight_%d_%s' % (k + 1, controller)
            log = by_name.get(name)
            if log is None:
                continue
            te = tracking_error(log, 'anafi', exclude_garbage=True)
            rows.append(Table3Row(controller, k + 1, name, paper, te.stats.mean, te.stats_h.mean,
                                  te.stats.n_excluded, te.garbage.summary()))
    return rows
