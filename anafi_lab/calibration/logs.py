"""Helpers on reference logs shared by the calibration fits (pure numpy/scipy, no ROS): sample rate, garbage,
the thrust axis of an attitude and the truth's yaw rate."""
import numpy as np
from scipy.signal import savgol_filter

from anafi_sim.mission.reference_log import detect_garbage

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


def measured_yaw_rate(log, window=5):
    """Yaw rate [rad/s] of the truth (Savitzky-Golay derivative of the unwrapped yaw)."""
    rate = log_rate(log)
    tu = np.arange(log.t[0], log.t[-1] + 1e-9, 1.0 / rate)
    yaw = np.interp(tu, log.t, np.unwrap(log.yaw_sphinx))
    return np.interp(log.t, tu, savgol_filter(yaw, window, 2, deriv=1, delta=1.0 / rate, mode='interp'))
