"""First-order loop responses and their least-squares fits (pure numpy/scipy, no ROS).

Stage: offline, the building blocks of every calibration fit: the response of a first order + delay to a held
or sampled input (``first_order_response``), its fit shared by several series (``fit_first_order_delay``), and
the limited loops ``AnafiModel`` steps (an acceleration-limited first order, the tilt loop with a rate limit and
its coupling to the yaw rate). Units: SI (s, m, m/s, rad, rad/s).
"""
import collections
import math

import numpy as np
from scipy.optimize import minimize
from scipy.signal import lfilter

from anafi_control import frames

SIM_STEP = 0.002                   # s, integration step of the first-order responses in the fits
ESTIMATE_STEP = 0.005              # s, the same for the (long, many-channel) estimate fits


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


# --------------------------------------------------------------------------- limited loops


def rate_limited_response(t_u, u, time_constant, limit, delay, t_out, step=ESTIMATE_STEP, initial=0.0):
    """Response v(t_out) of the vertical-speed loop with an acceleration limit: v' = clip((u(t - delay) - v) /
    tau, -limit, limit), discretised as ``AnafiModel`` does (exact first-order step, then the clip); u held
    after each sample (t_u, u) [s, m/s]; limit [m/s^2] (<= 0: none, the first order). Starts at ``initial``."""
    t_u = np.asarray(t_u, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    t_out = np.asarray(t_out, dtype=np.float64)
    grid = np.arange(min(t_u[0], t_out[0]), t_out[-1] + 2.0 * step, step)
    samples = _held_means(t_u, u, grid - 0.5 * step - delay, grid + 0.5 * step - delay)
    c = (1.0 - math.exp(-step / time_constant)) / step if time_constant > 1e-6 else 1.0 / step
    cap = float(limit) if limit > 0.0 else float('inf')
    v = float(initial)
    out = np.empty(len(grid))
    for k, target in enumerate(samples):       # a clipped loop has no closed form: step it (5 ms)
        out[k] = v
        a = (target - v) * c
        v += (cap if a > cap else (-cap if a < -cap else a)) * step
    return np.interp(t_out, grid, out)


def _held_tilt_setpoints(t_u, roll_u, pitch_u, delay, t_out, step):
    """(grid, (roll targets, pitch targets)) of the tilt responses: a ``step`` [s] grid from the first command
    (or output) time to past ``t_out``'s end, and per step the mean of the held setpoint (t_u, roll_u,
    pitch_u), ``delay``-ed, over that step."""
    t_u = np.asarray(t_u, dtype=np.float64)
    grid = np.arange(min(t_u[0], t_out[0]), t_out[-1] + 2.0 * step, step)
    a, b = grid - 0.5 * step - delay, grid + 0.5 * step - delay
    return grid, (_held_means(t_u, np.asarray(roll_u, dtype=np.float64), a, b),
                  _held_means(t_u, np.asarray(pitch_u, dtype=np.float64), a, b))


def rate_limited_tilt_response(t_u, roll_u, pitch_u, time_constant, rate, delay, t_out, step=ESTIMATE_STEP):
    """(roll, pitch)(t_out) [rad] of the roll/pitch loop with a tilt-rate limit, discretised as ``AnafiModel``
    does: each step moves the tilt vector by the exact first-order step toward the setpoint (held after each
    sample (t_u, roll_u, pitch_u), delayed by ``delay`` [s]), shortened to ``rate`` x step when longer
    (``rate`` [rad/s] <= 0: the first order). Starts level. ``gyroscopic_tilt_response`` without a yaw rate."""
    return gyroscopic_tilt_response(t_u, roll_u, pitch_u, [0.0], [0.0], time_constant, 0.0, delay, t_out, step,
                                    rate_limit=max(float(rate), 0.0))


def gyroscopic_tilt_response(t_u, roll_u, pitch_u, t_r, yaw_rate, time_constant, coupling, delay, t_out,
                             step=ESTIMATE_STEP, authority=0.0, precession=0.0, rate_limit=0.0):
    """(roll, pitch)(t_out) [rad] of the roll/pitch loop coupled to the yaw rate as ``AnafiModel`` steps it
    (``frames.tilt_loop_step``): the exact first-order step toward the held, ``delay``-ed setpoint (t_u, roll_u,
    pitch_u), with r the yaw rate [rad/s] at that instant (interpolated from t_r, yaw_rate): the loop's rate
    reduced by ``authority`` x |r|, the step multiplied by (I - G r J)^-1 (G = ``coupling`` [s]), the tilt then
    turned by ``precession`` x r x step; ``rate_limit`` [rad/s] caps the step (0 = none). Every term 0 = the
    plain first order. Starts level."""
    t_out = np.asarray(t_out, dtype=np.float64)
    grid, targets = _held_tilt_setpoints(t_u, roll_u, pitch_u, delay, t_out, step)
    rates = np.interp(grid, t_r, yaw_rate).tolist()
    lag = 1.0 - math.exp(-step / time_constant) if time_constant > 1e-6 else 1.0
    g, c, w, cap = float(coupling), float(authority), float(precession), float(rate_limit)
    roll = pitch = 0.0
    out = np.empty((len(grid), 2))
    for k, (rs, ps, r) in enumerate(zip(targets[0].tolist(), targets[1].tolist(), rates)):
        out[k] = roll, pitch
        roll, pitch = frames.tilt_loop_step(roll, pitch, rs, ps, lag, step, r, time_constant, g, c, w, cap)
    return np.interp(t_out, grid, out[:, 0]), np.interp(t_out, grid, out[:, 1])
