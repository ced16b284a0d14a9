"""Calibration section (b) and the estimate's fidelity effects: the drone's state estimate against the truth.

Stage: offline, reference logs -> the estimate's delay, smoothing and rate (``fit_estimate``), the position
fusion (``fit_position_fusion``, ``fusion_profile``), the velocity error's decay (``fit_velocity_error``), the
quantisation (``fit_quantisation``), the yaw bias (``fit_yaw_bias``) and the open-loop replays of the
simulator's ``StateEstimate`` (``replay_estimates``). Pure numpy/scipy, no ROS.
"""
import collections
import math

import numpy as np
from scipy.optimize import minimize, minimize_scalar
from scipy.signal import lfilter

from anafi_lab.calibration.logs import is_clean, log_rate
from anafi_lab.calibration.responses import ESTIMATE_STEP, SIM_STEP, first_order_response, fit_first_order_delay
from anafi_lab.paper import CONTROLLERS
from anafi_sim.mission.reference_log import (INITIAL_WINDOW, STATE_NAMES, VELOCITY_ERROR_AXES, detect_garbage,
                                             initial_velocity_error, velocity_error)

ESTIMATE_CHANNELS = ('x', 'y', 'z', 'vx', 'vy', 'vz', 'roll', 'pitch')   # yaw has a drifting bias
PROBE_STEP = 1.0 / 256.0           # the grid of the on-grid fractions where no quantum is found


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


def estimate_series(logs, channels):
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
    series, scales = estimate_series(dynamic, channels)
    joint = fit_first_order_delay(series, hold=False, fit_offset=True, scales=scales,
                                  tau_range=(0.0, 0.5), delay_range=(0.0, 0.4), step=ESTIMATE_STEP)
    groups = collections.OrderedDict()
    for group, names in _GROUPS.items():
        names = [n for n in names if n in channels]
        if names:
            s, sc = estimate_series(dynamic, names)
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
            quanta[column] = quantum_fraction(values, PROBE_STEP)
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


# --------------------------------------------------------------------------- position fusion


def fused_position_response(t, truth, velocity, fix_delay, fix_gain, initial, t_out=None, step=ESTIMATE_STEP):
    """The position fusion of ``StateEstimate`` on one axis: p' = v + k (p_truth(t - D) - p), p(t[0]) = initial.

    ``truth`` (position) and ``velocity`` (the velocity the estimator integrates) are samples at ``t``
    (linear in between; the fix before t[0] is truth[0]); integrated on a ``step`` grid exactly as the
    simulator's estimate does (integrate, then correct with c = 1 - exp(-k step)); returns the fused
    position at ``t_out`` (default ``t``), not held.
    """
    t = np.asarray(t, dtype=np.float64)
    t_out = t if t_out is None else np.asarray(t_out, dtype=np.float64)
    grid = np.arange(t[0], t_out[-1] + step, step)
    fix = np.interp(grid - fix_delay, t, np.asarray(truth, dtype=np.float64))
    v = np.interp(grid, t, np.asarray(velocity, dtype=np.float64))
    a = math.exp(-fix_gain * step)
    u = a * v * step + (1.0 - a) * fix
    body, _ = lfilter([1.0], [1.0, -a], u[1:], zi=[a * float(initial)])
    return np.interp(t_out, grid, np.concatenate(([float(initial)], body)))


def lag_along_motion(t, truth_p, estimate_p, velocity, min_speed=0.5):
    """Least-squares lag L [s] of an estimate behind the truth along the motion: (p - p_est) ~ L v.

    ``truth_p``, ``estimate_p``, ``velocity``: (n, k) arrays (k axes); samples with |v| > ``min_speed``
    [m/s]. NaN when there are none.
    """
    e = np.asarray(truth_p, dtype=np.float64) - np.asarray(estimate_p, dtype=np.float64)
    v = np.asarray(velocity, dtype=np.float64)
    moving = np.sqrt(np.sum(v * v, axis=1)) > min_speed
    if not moving.any():
        return float('nan')
    return float(np.sum(e[moving] * v[moving]) / np.sum(v[moving] * v[moving]))


PositionFusionFit = collections.namedtuple('PositionFusionFit', [
    'fix_delay', 'effective_delay', 'fix_gain', 'rms', 'groups', 'per_series', 'baseline', 'files',
    'excluded_z', 'pure_delay'])
PositionFusionFit.__doc__ = (
    'Position fusion fit: model fix delay D [s] (= effective_delay - 0.5/rate: the hold adds half a period), '
    'effective (logged) delay [s], fix gain k [1/s], rms [m] (mean square over series, each series weighted '
    'equally), {group: (k, D_effective, rms with its own k and D, rms with the common ones)} for horizontal '
    '(x, y), vertical (z), static (the static-waypoint transients) and straight (steady flight) alone, '
    '{(file, axis): rms} of the fit, {(file, axis): rms} of the delay/smoothing model (before), files, files '
    'whose z is not used, {label: (delay [s], rms static, rms straight)} of a pure delay of the truth instead '
    'of the fusion (the alternative structure: no single delay fits both).')

FUSION_GRID = ((0.05, 0.1, 0.2, 0.4, 0.8, 1.5), (0.05, 0.15, 0.25, 0.35))   # (k, D) starting points


def _fusion_series(logs, axes):
    series = []
    for log in logs:
        for axis in axes:
            if axis == 'z' and not log.name.startswith('static'):
                continue               # level straight flight: z says nothing about the fusion
            series.append((log.name, axis, log.t, log.columns[axis + '_sphinx'], log.columns['v%s_anafi' % axis],
                           log.columns[axis + '_anafi']))
    return series


def _fusion_cost(series, k, d, per_series=None):
    total = 0.0
    for name, axis, t, truth, velocity, est in series:
        r = fused_position_response(t, truth, velocity, d, k, est[0]) - est
        ms = float(np.mean(r[1:] ** 2))
        total += ms
        if per_series is not None:
            per_series[(name, axis)] = math.sqrt(ms)
    return total / max(len(series), 1)


def _fit_fusion(series, start=None):
    """(k, D_effective, rms) of ``series``: Nelder-Mead from the best ``FUSION_GRID`` point, or from ``start``."""
    def cost(p):
        if not (1e-4 <= p[0] <= 5.0 and 0.0 <= p[1] <= 1.0):
            return 1e12
        return _fusion_cost(series, p[0], p[1])

    if start is None:
        start = min((cost((k, d)), k, d) for k in FUSION_GRID[0] for d in FUSION_GRID[1])
    else:
        start = (cost(start),) + tuple(start)
    result = minimize(cost, [start[1], start[2]], method='Nelder-Mead',
                      options={'xatol': 1e-4, 'fatol': 1e-12, 'maxiter': 400})
    best = result.x if result.fun <= start[0] else np.array(start[1:])
    return float(best[0]), float(best[1]), math.sqrt(min(result.fun, start[0]))


def fit_position_fusion(logs, rate, baseline_delay, baseline_time_constant):
    """The position estimate as a fusion (``StateEstimate``'s ``estimate_position_fusion``); ``PositionFusionFit``.

    Every clean log, x and y (z only in the static-waypoint logs: the straight flights are level): the
    logged estimate velocity integrated and corrected toward the truth delayed by D with gain k, started at
    the logged estimate, against the logged position estimate; (k, D) common to all series (grid, then
    Nelder-Mead). The velocity the firmware integrates is its own estimate, so the fit uses the logged one
    (the simulator uses its modelled velocity estimate). ``baseline_*``: the delay/smoothing model
    (estimate_delay, estimate_time_constant at ``rate``) the position had without the fusion, for the
    per-series comparison.
    """
    clean = [log for log in logs if is_clean(log)]
    if not clean:
        raise ValueError('fit_position_fusion: no clean log')
    series = _fusion_series(clean, ('x', 'y', 'z'))
    k, d, rms = _fit_fusion(series)
    per_series = collections.OrderedDict()
    _fusion_cost(series, k, d, per_series)
    groups = collections.OrderedDict()
    static, straight = _static_and_straight(clean)
    subsets = (('horizontal', clean, ('x', 'y')), ('vertical', clean, ('z',)),
               ('static', static, ('x', 'y', 'z')), ('straight', straight, ('x', 'y')))
    for group, subset, axes in subsets:
        part = _fusion_series(subset, axes)
        if part:
            groups[group] = _fit_fusion(part, start=(k, d)) + (math.sqrt(_fusion_cost(part, k, d)),)
    baseline = collections.OrderedDict()
    for name, axis, t, truth, _, est in series:
        model = estimate_model_response(t, truth, baseline_delay, baseline_time_constant, rate, step=ESTIMATE_STEP)
        baseline[(name, axis)] = float(np.sqrt(np.mean((model - est)[1:] ** 2)))
    pure = collections.OrderedDict()
    for label, delay in (('velocity/attitude lag', baseline_delay + 0.5 / rate), ('steady position lag', d)):
        rms_kind = []
        for subset, axes in ((static, ('x', 'y', 'z')), (straight, ('x', 'y'))):
            part = _fusion_series(subset, axes)
            ms = [float(np.mean((np.interp(t - delay, t, truth) - est)[1:] ** 2)) for _, _, t, truth, _, est in part]
            rms_kind.append(math.sqrt(np.mean(ms)) if ms else float('nan'))
        pure[label] = (delay,) + tuple(rms_kind)
    return PositionFusionFit(max(0.0, d - 0.5 / rate), d, k, rms, groups, per_series, baseline,
                             tuple(log.name for log in clean),
                             tuple(log.name for log in clean if not log.name.startswith('static')), pure)


FusionProfileRow = collections.namedtuple('FusionProfileRow', ['fix_gain', 'effective_delay', 'fix_delay', 'rms',
                                                               'rms_static', 'rms_straight'])
FusionProfileRow.__doc__ = (
    'The position fusion fit at a given fix gain k [1/s]: the effective delay D [s] (the best for that k over '
    'all clean series, or the one ``fusion_profile`` was told to hold), the model fix delay [s] (D - 0.5/rate), '
    'and the rms [m] over all series, the static-waypoint ones and the straight-line ones (each series weighted '
    'equally, as ``fit_position_fusion``).')


def _static_and_straight(clean):
    """(static-waypoint logs, straight-line logs) of ``clean`` (by name): the transients and the steady flight."""
    return ([log for log in clean if log.name.startswith('static')],
            [log for log in clean if not log.name.startswith('static')])


def fusion_profile(logs, gains, rate, effective_delays=None):
    """How well the shared logs allow each fix gain k in ``gains`` [1/s]: the fusion fit with k held and the
    effective delay D refitted (bounded scalar search over 0..0.6 s), or held at ``effective_delays[i]`` [s]
    where that is given (not None: e.g. a model's own delay); [``FusionProfileRow``]. ``rate``: the estimate's
    rate [Hz] (the hold adds half a period to the model's delay)."""
    clean = [log for log in logs if is_clean(log)]
    if not clean:
        raise ValueError('fusion_profile: no clean log')
    static_logs, straight_logs = _static_and_straight(clean)
    every = _fusion_series(clean, ('x', 'y', 'z'))
    static = _fusion_series(static_logs, ('x', 'y', 'z'))
    straight = _fusion_series(straight_logs, ('x', 'y'))
    delays = list(effective_delays) if effective_delays is not None else [None] * len(gains)
    if len(delays) != len(gains):
        raise ValueError('fusion_profile: %d gains but %d delays' % (len(gains), len(delays)))
    rows = []
    for k, d in zip(gains, delays):
        k = float(k)
        if d is None:
            d = float(minimize_scalar(lambda x: _fusion_cost(every, k, x), bounds=(0.0, 0.6), method='bounded',
                                      options={'xatol': 1e-5}).x)
        d = float(d)
        rows.append(FusionProfileRow(k, d, max(0.0, d - 0.5 / rate), math.sqrt(_fusion_cost(every, k, d)),
                                     math.sqrt(_fusion_cost(static, k, d)) if static else float('nan'),
                                     math.sqrt(_fusion_cost(straight, k, d)) if straight else float('nan')))
    return rows


VelocityErrorFit = collections.namedtuple('VelocityErrorFit', ['time_constant', 'rms', 'rms_zero', 'per_series',
                                                               'files', 'window'])
VelocityErrorFit.__doc__ = (
    'Decay of the velocity estimate\'s own error: time constant [s] (0 = no straight-line log), rms [m/s] of '
    'the fit and of "no error" (b = 0), {(file, axis): (initial error b0 [m/s], rms with b = 0, rms of the '
    'decay)}, files, window [s] of the initial line fit.')


def _velocity_error_series(logs, window):
    series = []
    for log in logs:
        if log.name.startswith('static'):
            continue
        t = log.t - log.t[0]
        for axis in VELOCITY_ERROR_AXES:
            b0 = initial_velocity_error(log, axis, window)
            if not math.isfinite(b0):
                continue
            b, ok = velocity_error(log, axis)
            series.append((log.name, axis, t[ok], b[ok], b0))
    return series


def fit_velocity_error(logs, window=INITIAL_WINDOW):
    """``VelocityErrorFit``: the straight-line logs (clean ones) start with a velocity estimate that is off
    the truth by up to 0.1 m/s across the motion (x_straight_4_pid: vy_anafi - vy_sphinx = -0.10 m/s at the
    start, ~0 after 10 s), which decays. Model: b(t) = b0 exp(-t / T), b0 = the error at log time 0 (a line
    through the first ``window`` s), common T over every log and horizontal axis (bounded scalar search, each
    series weighted equally)."""
    series = _velocity_error_series([log for log in logs if is_clean(log)], float(window))
    if not series:
        return VelocityErrorFit(0.0, float('nan'), float('nan'), collections.OrderedDict(), (), float(window))

    def cost(tau):
        return float(np.mean([np.mean((b - b0 * np.exp(-t / tau)) ** 2) for _, _, t, b, b0 in series]))
    best = minimize_scalar(cost, bounds=(0.1, 100.0), method='bounded', options={'xatol': 1e-3})
    tau = float(best.x)
    per_series = collections.OrderedDict()
    for name, axis, t, b, b0 in series:
        per_series[(name, axis)] = (b0, math.sqrt(float(np.mean(b ** 2))),
                                    math.sqrt(float(np.mean((b - b0 * np.exp(-t / tau)) ** 2))))
    zero = math.sqrt(float(np.mean([np.mean(b ** 2) for _, _, t, b, b0 in series])))
    return VelocityErrorFit(tau, math.sqrt(cost(tau)), zero, per_series,
                            tuple(collections.OrderedDict.fromkeys(n for n, _, _, _, _ in series)), float(window))


# --------------------------------------------------------------------------- open-loop replay


def replay_estimate(log, params, lead=20.0, rate=200.0):
    """Open-loop check: the simulator's ``StateEstimate`` fed the logged truth; dict of arrays at ``log.t``.

    The truth is fed at ``rate`` Hz (linear between the log's samples, yaw on the circle), preceded by
    ``lead`` s of steady flight at the first sample's velocity (so a straight-line log starts in the
    estimate's steady state, as the logged estimate does). The estimate re-samples half a hold period
    before each log sample (the logs are stamped on the estimate's 20 Hz grid; the fitted delays assume
    a held value is on average half a period old when logged). Keys: x, y, z, vx, vy, vz, roll, pitch, yaw.
    """
    from anafi_sim.sim.state_estimate import StateEstimate
    est = StateEstimate(params)
    phase = 0.5 / est.rate - float(log.t[0])      # estimate time = log time + phase
    t = log.t
    grid = np.arange(t[0] - lead, t[-1] + 0.5 / rate, 1.0 / rate)
    truth = {}
    for name in STATE_NAMES:
        values = log.columns[name + '_sphinx']
        values = np.unwrap(values) if name == 'yaw' else values
        truth[name] = np.interp(grid, t, values)
    before = grid < t[0]
    for axis in ('x', 'y', 'z'):
        truth[axis][before] = log.columns[axis + '_sphinx'][0] + log.columns['v%s_sphinx' % axis][0] * (grid[before]
                                                                                                         - t[0])
    rows = np.column_stack([truth[name] for name in STATE_NAMES])
    rows[:, 8] = (rows[:, 8] + math.pi) % (2.0 * math.pi) - math.pi
    out = np.empty_like(rows)
    update = est.update
    for i, (time, row) in enumerate(zip(grid.tolist(), rows.tolist())):
        update(time + phase, *row)
        out[i] = est.values()
    index = np.clip(np.searchsorted(grid, t + 1e-9, side='right') - 1, 0, len(grid) - 1)
    return dict((name, out[index, j]) for j, name in enumerate(STATE_NAMES))


EstimateReplay = collections.namedtuple('EstimateReplay', ['rms', 'steady_lag', 'transient_lag', 'on_grid'])
EstimateReplay.__doc__ = (
    'Open-loop estimate replays of every log, effects off ("before") and on ("after"): {file: {channel: '
    '(rms before, rms after)}} (position per axis [m], velocity [m/s] and yaw [rad]; garbage columns '
    'left out), {file: (logged, before, after)} lag along the motion [s] of the straight-line logs and of '
    'the static-waypoint transients (|v| > 1 m/s), {column: fraction of the replayed estimate on its '
    'quantisation grid} after.')


def replay_estimates(logs, before, after, lead=20.0):
    """``EstimateReplay`` of ``logs`` with the model dicts ``before`` and ``after``."""
    rms = collections.OrderedDict()
    steady = collections.OrderedDict()
    transient = collections.OrderedDict()
    grid_hits = collections.defaultdict(list)
    quanta = {'x': after.get('estimate_quantum_x', 0.0), 'y': after.get('estimate_quantum_y', 0.0),
              'z': after.get('estimate_quantum_z', 0.0), 'vx': after.get('estimate_quantum_velocity', 0.0),
              'vy': after.get('estimate_quantum_velocity', 0.0), 'vz': after.get('estimate_quantum_velocity', 0.0)}
    for log in logs:
        garbage = detect_garbage(log)
        runs = (replay_estimate(log, before, lead), replay_estimate(log, after, lead))
        per = collections.OrderedDict()
        for name in ('x', 'y', 'z', 'vx', 'vy', 'vz', 'yaw'):
            column = name + '_anafi'
            ok = ~garbage.mask(column, name + '_sphinx')
            if not ok.any():
                continue
            logged = log.columns[column][ok]
            errors = []
            for run in runs:
                r = run[name][ok] - logged
                if name == 'yaw':
                    r = np.angle(np.exp(1j * r))
                errors.append(float(np.sqrt(np.mean(r ** 2))))
            per[name] = tuple(errors)
            q = quanta.get(name, 0.0)
            if q > 0.0:
                v = runs[1][name][ok] / q
                grid_hits[name].append(np.abs(v - np.round(v)) < 1e-6)
        rms[log.name] = per
        axes = [a for a in ('x', 'y', 'z') if not garbage.mask(a + '_anafi').any()]
        truth_p = np.column_stack([log.columns[a + '_sphinx'] for a in axes])
        velocity = np.column_stack([log.columns['v%s_sphinx' % a] for a in axes])
        lags = tuple(lag_along_motion(log.t, truth_p, est, velocity)
                     for est in [np.column_stack([log.columns[a + '_anafi'] for a in axes])]
                     + [np.column_stack([run[a] for a in axes]) for run in runs])
        (transient if log.name.startswith('static') else steady)[log.name] = lags
    on_grid = collections.OrderedDict((name, float(np.mean(np.concatenate(hits))))
                                      for name, hits in grid_hits.items())
    return EstimateReplay(rms, steady, transient, on_grid)


# --------------------------------------------------------------------------- quantisation, yaw bias


QuantumFit = collections.namedtuple('QuantumFit', ['steps', 'on_grid', 'truth_on_grid', 'samples', 'grids'])
QuantumFit.__doc__ = ('Quantisation of the estimate: {column: step} (0 where none is found), {column: fraction '
                      'of the estimate\'s values on that grid}, {column: the same fraction for the truth (what '
                      'chance gives)}, {column: values tested}; measured where the float16 storage of the logs is '
                      'at least 4x finer than the step. grids: {position column: (step [m], concentration of the '
                      'estimate, of the truth)} of the grids that are no power of two (``estimate_grid``).')

QUANTUM_CANDIDATES = tuple(2.0 ** -n for n in range(3, 10))     # 1/8 .. 1/512 (fixed-point steps)


def _informative(values, step):
    """The finite ``values`` whose float16 spacing is at most step/4 (|v| < 512 step): a grid shows there."""
    v = np.asarray(values, dtype=np.float64)
    return v[np.isfinite(v) & (np.abs(v) < 512.0 * step)]


def estimate_quantum(values, hit=0.98, min_samples=50):
    """Step of a quantised column (0.0 when it is not): the coarsest power-of-two step (``QUANTUM_CANDIDATES``)
    with >= ``hit`` of the informative values (``_informative``, float16 round trip, ``quantum_fraction``) on
    its grid; a random float16 column has 1/4 of them there at most."""
    for step in sorted(QUANTUM_CANDIDATES, reverse=True):
        v = _informative(values, step)
        if v.size >= min_samples and quantum_fraction(v, step) >= hit:
            return step
    return 0.0


GRID_RANGE = (0.004, 0.05)      # m, the steps ``estimate_grid`` searches (GPS-like position grids)


def grid_concentration(series, step):
    """Mean over the ``series`` (value arrays, one per log: each flight may have its own grid offset) of
    |mean(exp(2 pi i v / step))|: 1 when every value lies on one grid of ``step`` (any offset), ~0 for values
    spread over it. Only the values whose float16 storage is 8x finer than the step count, and only series
    whose values span 20 steps at least (a few neighbouring grid points fit a band of steps)."""
    out = []
    for values in series:
        v = np.asarray(values, dtype=np.float64)
        v = v[np.isfinite(v) & (np.abs(v) < 128.0 * step)]
        if v.size >= 20 and np.ptp(v) >= 20.0 * step:
            out.append(abs(np.mean(np.exp(2j * np.pi * v / step))))
    return float(np.mean(out)) if out else float('nan')


def estimate_grid(series, step_range=GRID_RANGE, resolution=1e-5, hit=0.9):
    """(step [m], concentration) of the coarsest grid, power of two or not, on which the values of ``series``
    (``grid_concentration``) lie with a concentration >= ``hit``; (0.0, best concentration) when none. The
    coarsest: the values of a grid of step q also lie on q / 2, q / 3, ... but not on 2 q."""
    steps = np.arange(step_range[1], step_range[0], -resolution)
    conc = np.array([grid_concentration(series, q) for q in steps])
    above = np.nonzero(np.nan_to_num(conc) >= hit)[0]
    if above.size == 0:
        return 0.0, float(np.nanmax(conc)) if np.isfinite(conc).any() else float('nan')
    first = above[0]                             # the coarsest step over the threshold: refine to its peak
    last = first
    while last + 1 < len(steps) and conc[last + 1] >= hit:
        last += 1
    best = first + int(np.argmax(conc[first:last + 1]))
    return round(float(steps[best]), 6), float(conc[best])


def fit_quantisation(logs, columns=('x', 'y', 'z', 'vx', 'vy', 'vz', 'roll', 'pitch', 'yaw')):
    """``QuantumFit`` of the estimate columns of the clean logs (the truth columns as the control)."""
    clean = [log for log in logs if is_clean(log)]
    steps = collections.OrderedDict()
    on_grid = collections.OrderedDict()
    truth = collections.OrderedDict()
    samples = collections.OrderedDict()
    for name in columns:
        est = np.concatenate([log.columns[name + '_anafi'] for log in clean])
        tru = np.concatenate([log.columns[name + '_sphinx'] for log in clean])
        step = estimate_quantum(est)
        steps[name] = step
        probe = step or PROBE_STEP          # where none is found: the fractions on the 1/256 grid
        on_grid[name] = quantum_fraction(_informative(est, probe), probe)
        truth[name] = quantum_fraction(_informative(tru, probe), probe)
        samples[name] = int(_informative(est, probe).size)
    grids = collections.OrderedDict()
    for name in ('x', 'y'):        # no power-of-two grid: search any step (per log, for its own grid offset)
        if name in steps and steps[name] == 0.0:
            step, conc = estimate_grid([log.columns[name + '_anafi'] for log in clean])
            if step > 0.0:
                steps[name] = step
                grids[name] = (step, conc, grid_concentration([log.columns[name + '_sphinx'] for log in clean],
                                                              step))
    return QuantumFit(steps, on_grid, truth, samples, grids)


YawBiasFit = collections.namedtuple('YawBiasFit', ['bias', 'per_file', 'spread', 'by_controller', 'turn'])
YawBiasFit.__doc__ = ('Yaw estimate bias [rad]: the median over the clean logs of their mean yaw_anafi - '
                      'yaw_sphinx, {file: mean}, (min, max), {controller: median}, {file: (before the turn, '
                      'end of the log)} of the logs with a 180 deg turn.')


def fit_yaw_bias(logs, estimate):
    """``YawBiasFit`` from ``estimate.yaw_bias`` (per-file means) and the static 180 deg turns."""
    per_file = collections.OrderedDict((name, value) for name, value in estimate.yaw_bias.items())
    values = list(per_file.values())
    by_controller = collections.OrderedDict()
    for controller in CONTROLLERS:
        own = [v for name, v in per_file.items() if name.endswith('_' + controller)]
        if own:
            by_controller[controller] = float(np.median(own))
    turn = collections.OrderedDict()
    for log in logs:
        if log.name.startswith('static_waypoint_yaw_180') and is_clean(log):
            e = np.angle(np.exp(1j * (log.yaw_anafi - log.yaw_sphinx)))
            wp = log.waypoint()[:, 6]
            first = int(np.argmax(wp != wp[0])) if np.any(wp != wp[0]) else len(e)
            turn[log.name] = (float(np.mean(e[:max(first, 1)])), float(np.mean(e[-20:])))
    return YawBiasFit(float(np.median(values)), per_file, (float(min(values)), float(max(values))), by_controller,
                      turn)
