"""Hand-made reference logs for the experiment tests (test_plots, test_step_response): pure numpy.

``make_log(t, est, wp, truth=None, yaw=None, wp_yaw=None)``: a ReferenceLog with the drone estimate
positions ``est`` (n, 3) [m], the waypoint positions ``wp`` (n, 3) [m] and optionally ground truth,
yaw [rad] and waypoint yaw [deg]; everything else zero (velocities, roll, pitch).
"""
import collections

import numpy as np

from anafi_sim.mission.reference_log import COLUMNS, ReferenceLog


def make_log(t, est, wp, truth=None, yaw=None, wp_yaw=None):
    t = np.asarray(t, dtype=np.float64)
    n = len(t)
    est = np.asarray(est, dtype=np.float64).reshape(n, 3)
    wp = np.asarray(wp, dtype=np.float64).reshape(n, 3)
    cols = collections.OrderedDict((c, np.zeros(n)) for c in COLUMNS[1:])
    for i, a in enumerate('xyz'):
        cols[a + '_anafi'] = est[:, i].copy()
        cols['wp_' + a] = wp[:, i].copy()
        cols[a + '_sphinx'] = (np.asarray(truth, dtype=np.float64).reshape(n, 3)[:, i].copy()
                               if truth is not None else np.full(n, np.nan))
    if yaw is not None:
        cols['yaw_anafi'] = np.asarray(yaw, dtype=np.float64).copy()
    if wp_yaw is not None:
        cols['wp_yaw'] = np.asarray(wp_yaw, dtype=np.float64).copy()
    time_ns = (1700000000 * 10 ** 9 + np.round(t * 1e9)).astype(np.int64)
    return ReferenceLog(cols, time_ns)
