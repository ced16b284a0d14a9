"""anafi_sim.mission.model_following: a target's pose -> waypoint with consistent velocity (pure core)."""
import math

import pytest

from anafi_sim.mission.model_following import ModelFollower, yaw_of_quaternion


def quat(yaw):
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def test_yaw_of_quaternion():
    for yaw in (0.0, 0.5, -2.0, 3.0):
        assert yaw_of_quaternion(*quat(yaw)) == pytest.approx(yaw)


def test_offset_in_the_heading_frame_and_yaw_modes():
    f = ModelFollower(offset=(-6.0, 0.0, -2.0))
    wp = f.update(0.0, (10.0, 5.0, 10.0), quat(math.pi / 2), (0.0, 0.0, 0.0), 0.0)
    # heading north (+y): 6 m behind = 6 m south, 2 m below
    assert (wp.x, wp.y, wp.z) == pytest.approx((10.0, -1.0, 8.0))
    assert wp.yaw == pytest.approx(90.0)
    f = ModelFollower(offset=(0.0, 3.0, 0.0), offset_frame='world', yaw_mode='face')
    wp = f.update(0.0, (1.0, 1.0, 5.0), quat(1.0), (0.0, 0.0, 0.0), 0.0)
    assert (wp.x, wp.y) == pytest.approx((1.0, 4.0))
    assert wp.yaw == pytest.approx(-90.0)              # looking from the waypoint south at the target
    f = ModelFollower(yaw_mode='fixed', yaw_offset=190.0)
    assert f.update(0.0, (0, 0, 5), quat(1.0)).yaw == pytest.approx(-170.0)


def circling_target(t, r=20.0, w=0.05):
    """Target on a circle, nose along the velocity: position, orientation, velocity, yaw rate."""
    a = w * t
    pos = (r * math.cos(a), r * math.sin(a), 10.0)
    vel = (-r * w * math.sin(a), r * w * math.cos(a), 0.0)
    return pos, quat(a + math.pi / 2), vel, w


def test_twist_velocity_is_the_derivative_of_the_waypoint_position():
    f = ModelFollower(offset=(-6.0, 2.0, -2.0), velocity_source='twist')
    t, h = 7.0, 1e-4
    wp = f.update(t, *circling_target(t))
    a = ModelFollower(offset=(-6.0, 2.0, -2.0)).update(t - h, *circling_target(t - h))
    b = ModelFollower(offset=(-6.0, 2.0, -2.0)).update(t + h, *circling_target(t + h))
    numeric = ((b.x - a.x) / (2 * h), (b.y - a.y) / (2 * h), (b.z - a.z) / (2 * h))
    assert (wp.vx, wp.vy, wp.vz) == pytest.approx(numeric, abs=1e-5)
    # without the rotation term the velocity would be the target's: clearly different here
    target_v = circling_target(t)[2]
    assert abs(wp.vx - target_v[0]) + abs(wp.vy - target_v[1]) > 0.05


def test_difference_velocity_converges_when_the_twist_is_missing_or_zero():
    for source, twist in (('difference', True), ('auto', False), ('auto', 'zero')):
        f = ModelFollower(offset=(-6.0, 0.0, -2.0), velocity_source=source, smoothing=0.2)
        wp = None
        for k in range(200):
            t = k * 0.05
            pos, q, vel, w = circling_target(t)
            if twist is False:
                wp = f.update(t, pos, q)
            elif twist == 'zero':
                wp = f.update(t, pos, q, (0.0, 0.0, 0.0), 0.0)
            else:
                wp = f.update(t, pos, q, vel, w)
        exact = ModelFollower(offset=(-6.0, 0.0, -2.0), velocity_source='twist').update(t, pos, q, vel, w)
        assert not f.used_twist
        # the filtered difference lags by about the smoothing time: speed matches, direction within ~a few deg
        assert math.hypot(wp.vx, wp.vy) == pytest.approx(math.hypot(exact.vx, exact.vy), rel=0.05)
        assert math.hypot(wp.vx - exact.vx, wp.vy - exact.vy) < 0.05 * math.hypot(exact.vx, exact.vy) + 0.02


def test_auto_uses_a_real_twist():
    f = ModelFollower()
    pos, q, vel, w = circling_target(1.0)
    f.update(0.0, *circling_target(0.0))
    f.update(1.0, pos, q, vel, w)
    assert f.used_twist


def test_garbage_is_refused_and_time_going_back_resets():
    f = ModelFollower()
    assert f.update(0.0, (float('nan'), 0, 0), quat(0.0)) is None
    assert f.update(0.0, (0, 0, 0), (0, 0, 0, 0)) is None          # zero quaternion
    assert f.update(0.0, (0, 0), quat(0.0)) is None
    assert f.update('x', (0, 0, 0), quat(0.0)) is None
    assert f.rejected == 4
    f.update(1.0, (0, 0, 10), quat(0.0))
    f.update(2.0, (1, 0, 10), quat(0.0))
    f.update(1.5, (1, 0, 10), quat(0.0))
    assert f.resets == 1
    with pytest.raises(ValueError):
        ModelFollower(offset=(1, 2))
    with pytest.raises(ValueError):
        ModelFollower(velocity_source='magic')
    with pytest.raises(ValueError):
        ModelFollower(offset_frame='body')
