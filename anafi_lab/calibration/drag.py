"""Calibration section (a): attitude -> acceleration, the drag of the translational model (pure numpy/scipy).

Stage: offline, the clean reference logs -> ``DragFit`` (drag_linear, drag_quadratic, drag_vertical and the
trim of the thrust axis), by linear least squares on Savitzky-Golay smoothed truth.
"""
import collections
import math

import numpy as np
from scipy.signal import savgol_filter

from anafi_lab.calibration.logs import is_clean, log_rate, thrust_axis

GRAVITY = 9.81


DRAG_WINDOW = 7                    # samples of the Savitzky-Golay window (0.35 s at 20 Hz)


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
