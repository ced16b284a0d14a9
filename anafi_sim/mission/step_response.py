"""Step response figures of a static-waypoint run (pure Python, no ROS): overshoot and settling time.

Stage: evaluation (the paper's static waypoints WP0 / WP1, Sec. V.B.1, Fig. 6). Input: a
``reference_log.ReferenceLog`` (e.g. the evaluator's CSV export) and the measured window (t0, t1)
[s since the log's first sample] that starts at the step. Positions [m] in the ENU world frame,
yaw of the drone [rad] and of the waypoint [deg]; results in m, s and deg.

- start = the drone's position at the window start, goal = the waypoint at the window's end (the
  first samples of the window may still carry the previous waypoint);
- overshoot per axis = the largest excursion beyond the goal coordinate in the direction that axis
  was approached from (0 for an axis that did not have to move more than ``min_move`` m); the
  figure reported is the norm over x, y, z;
- settling time = time after t0 from which e = |goal - position| stays within ``band`` m until
  the window's end (None when it is not within the band at the end); the yaw settling time the
  same with the yaw error and ``yaw_band`` deg;
- final error = e at the window's last sample.
"""
import collections
import math

import numpy as np

StepMetrics = collections.namedtuple('StepMetrics', 'start goal overshoot_axes overshoot settling_time '
                                                    'yaw_settling_time final_error band yaw_band')
StepMetrics.__doc__ = ('start, goal (x, y, z) [m]; overshoot_axes (x, y, z) [m] and their norm overshoot [m]; '
                       'settling_time, yaw_settling_time [s after the step] or None; final_error [m]; '
                       'band [m], yaw_band [deg].')


def settling_time(t, err, band):
    """Time (same unit as t, from t[0]) after which ``err`` stays <= ``band`` to the end; None if it is
    above the band at the end (or no finite sample). Non-finite samples count as outside the band."""
    t = np.asarray(t, dtype=np.float64)
    err = np.asarray(err, dtype=np.float64)
    if len(t) == 0:
        return None
    inside = np.isfinite(err) & (err <= band)
    if not inside[-1]:
        return None
    outside = np.nonzero(~inside)[0]
    if len(outside) == 0:
        return 0.0
    return float(t[outside[-1] + 1] - t[0])


def overshoot(positions, start, goal, min_move=0.05):
    """(per-axis overshoot (3,) [m], norm [m]) of ``positions`` (n, 3) stepping from ``start`` to ``goal``."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    start = np.asarray(start, dtype=np.float64)
    goal = np.asarray(goal, dtype=np.float64)
    per_axis = np.zeros(3)
    for i in range(3):
        delta = goal[i] - start[i]
        if abs(delta) <= min_move:
            continue
        col = positions[:, i]
        col = col[np.isfinite(col)]
        if len(col):
            per_axis[i] = max(0.0, float(np.max(np.sign(delta) * (col - goal[i]))))
    return per_axis, float(np.linalg.norm(per_axis))


BAND = 0.2          # m, the settling band of the position error
YAW_BAND = 5.0      # deg, the settling band of the yaw error


def step_metrics(log, window, source='anafi', band=BAND, yaw_band=YAW_BAND, min_move=0.05):
    """``StepMetrics`` of ``log`` over ``window`` (t0, t1) s since its first sample; ``source`` 'anafi'
    (the drone's estimate) or 'sphinx' (ground truth). ValueError when the window holds < 2 samples."""
    t = log.t
    m = (t >= window[0]) & (t <= window[1])
    if m.sum() < 2:
        raise ValueError('step window %r holds %d samples' % (tuple(window), int(m.sum())))
    tw = t[m]
    pos = np.column_stack([log.columns['%s_%s' % (a, source)][m] for a in ('x', 'y', 'z')])
    wp = np.column_stack([log.columns['wp_' + a][m] for a in ('x', 'y', 'z')])
    goal = wp[-1]
    start = pos[0]
    per_axis, norm = overshoot(pos, start, goal, min_move)
    err = np.linalg.norm(pos - goal, axis=1)
    yaw = log.columns['yaw_' + source][m]
    yaw_err = np.abs((np.degrees(yaw) - log.columns['wp_yaw'][m] + 180.0) % 360.0 - 180.0)
    return StepMetrics(tuple(float(v) for v in start), tuple(float(v) for v in goal),
                       tuple(float(v) for v in per_axis), norm, settling_time(tw, err, band),
                       settling_time(tw, yaw_err, yaw_band), float(err[-1]), float(band), float(yaw_band))


def as_dict(metrics):
    """Plain dict of ``StepMetrics`` rounded for reports (None stays None)."""
    def r(v):
        return None if v is None or not math.isfinite(v) else round(float(v), 3)
    return {
        'start': [r(v) for v in metrics.start], 'goal': [r(v) for v in metrics.goal],
        'overshoot_x': r(metrics.overshoot_axes[0]), 'overshoot_y': r(metrics.overshoot_axes[1]),
        'overshoot_z': r(metrics.overshoot_axes[2]), 'overshoot': r(metrics.overshoot),
        'settling_time': r(metrics.settling_time), 'yaw_settling_time': r(metrics.yaw_settling_time),
        'final_error': r(metrics.final_error), 'band': metrics.band, 'yaw_band': metrics.yaw_band,
    }
