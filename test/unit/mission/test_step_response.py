"""anafi_sim.mission.step_response: overshoot and settling of a static-waypoint step, on hand-made logs."""
import math

import numpy as np
import pytest

from anafi_sim.mission import step_response as sr
from experiment_logs import make_log


def test_settling_time_is_the_last_exit_from_the_band():
    t = np.arange(10) * 0.5
    err = np.array([5.0, 3.0, 0.1, 0.3, 0.15, 0.1, 0.05, 0.0, 0.0, 0.1])
    # last sample outside the 0.2 band is index 3 (0.3): settled from index 4 = 2.0 s
    assert sr.settling_time(t, err, 0.2) == pytest.approx(2.0)
    assert sr.settling_time(t, err, 0.4) == pytest.approx(1.0)      # last outside: index 1 (3.0)
    assert sr.settling_time(t, err, 10.0) == 0.0
    err[-1] = 0.5
    assert sr.settling_time(t, err, 0.2) is None                    # not inside at the end
    err[-1] = float('nan')
    assert sr.settling_time(t, err, 0.2) is None                    # NaN counts as outside
    assert sr.settling_time([], [], 0.2) is None


def test_overshoot_per_axis_in_the_approach_direction():
    start, goal = (0.0, 0.0, 1.0), (3.0, 2.0, 5.0)
    track = np.array([[0.0, 0.0, 1.0], [2.0, 2.3, 3.0], [3.4, 1.9, 5.2], [3.0, 2.0, 4.9]])
    per_axis, norm = sr.overshoot(track, start, goal)
    assert per_axis == pytest.approx([0.4, 0.3, 0.2])
    assert norm == pytest.approx(math.sqrt(0.16 + 0.09 + 0.04))
    # approaching from above: only excursions below the goal count
    per_axis, _ = sr.overshoot([[0.0, 0.0, 4.5], [0.0, 0.0, 6.0]], (0.0, 0.0, 10.0), (0.0, 0.0, 5.0))
    assert per_axis == pytest.approx([0.0, 0.0, 0.5])
    # an axis that did not have to move has no overshoot, whatever it does
    per_axis, _ = sr.overshoot([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]], (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    assert per_axis == pytest.approx([0.0, 0.0, 0.0])


def test_step_metrics_of_a_first_order_response_with_one_bump():
    t = np.arange(0, 20, 0.05)
    goal = np.array([3.0, 2.0, 5.0])
    start = np.array([0.0, 0.0, 1.0])
    step_at = 5.0
    s = np.clip(t - step_at, 0, None)
    frac = 1.0 - np.exp(-s / 0.8)
    est = start + np.outer(frac, goal - start)
    est[:, 0] += 0.3 * np.exp(-((t - 12.0) / 0.5) ** 2)      # a 0.3 m bump beyond x = 3 around t = 12 s
    wp = np.where((t >= step_at)[:, None], goal, start)
    yaw = np.where(t >= 9.0, math.pi, 0.0)
    log = make_log(t, est, wp, yaw=yaw, wp_yaw=np.where(t >= step_at, 180.0, 0.0))
    window = (step_at, t[-1])
    m = sr.step_metrics(log, window, band=0.2, yaw_band=5.0)
    assert m.goal == pytest.approx(tuple(goal))
    assert m.start[2] == pytest.approx(1.0, abs=0.01)
    assert m.overshoot_axes[0] == pytest.approx(0.3, abs=0.02)
    assert m.overshoot_axes[1] == pytest.approx(0.0, abs=1e-9)
    assert m.overshoot_axes[2] == pytest.approx(0.0, abs=1e-9)
    # e = |goal - p|: exponential tail below 0.2 m after -0.8 ln(0.2 / 5.39) = 2.63 s, but the bump is
    # above 0.2 m while |t - 12| < 0.5 sqrt(ln 1.5) = 0.32 s -> settled 12.32 - 5 = 7.32 s after the step
    assert m.settling_time == pytest.approx(7.32, abs=0.06)
    assert m.yaw_settling_time == pytest.approx(9.0 - step_at, abs=0.06)
    assert m.final_error < 0.01
    d = sr.as_dict(m)
    assert d['overshoot_x'] == pytest.approx(0.3, abs=0.02) and d['settling_time'] is not None


def test_goal_is_the_waypoint_at_the_window_end():
    # the window's first sample still carries the hover waypoint (zero-order hold at the step)
    t = np.arange(0, 10, 0.1)
    wp = np.where((t > 2.05)[:, None], [3.0, 0.0, 1.0], [0.0, 0.0, 1.0])
    est = np.column_stack([np.clip((t - 2.0) * 1.5, 0.0, 3.3) - np.clip(t - 4.2, 0.0, 0.3), 0 * t, 1 + 0 * t])
    m = sr.step_metrics(make_log(t, est, wp), (2.0, 9.9))
    assert m.goal == pytest.approx((3.0, 0.0, 1.0))
    assert m.overshoot_axes[0] == pytest.approx(0.3, abs=1e-6)
    assert m.settling_time is not None and m.final_error == pytest.approx(0.0, abs=1e-9)


def test_step_metrics_rejects_an_empty_window():
    t = np.arange(5) * 0.1
    log = make_log(t, np.zeros((5, 3)), np.zeros((5, 3)))
    with pytest.raises(ValueError):
        sr.step_metrics(log, (10.0, 20.0))
