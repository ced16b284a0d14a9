"""anafi_control.frames: rotations, quaternions, stability axes (hand-checked values)."""
import math

import numpy as np
import pytest

from anafi_control import frames


@pytest.mark.parametrize('angle,expected', [(0.0, 0.0), (math.pi + 0.1, -math.pi + 0.1),
                                            (-math.pi - 0.1, math.pi - 0.1), (3 * math.pi, -math.pi),
                                            (2 * math.pi - 0.2, -0.2)])
def test_wrap_angle(angle, expected):
    assert frames.wrap_angle(angle) == pytest.approx(expected)


def test_wrap_angle_degrees():
    assert frames.wrap_angle(190.0, 360.0) == pytest.approx(-170.0)
    assert frames.wrap_angle(-358.0, 360.0) == pytest.approx(2.0)


def test_quaternion_of_pure_yaw_90():
    q = frames.euler_to_quaternion(0.0, 0.0, math.pi / 2)
    assert q == pytest.approx((0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)))


@pytest.mark.parametrize('rpy', [(0.1, -0.2, 0.3), (-0.5, 0.4, 3.0), (0.0, 0.0, -2.5), (0.3, 1.2, -1.0)])
def test_euler_quaternion_round_trip_and_matrix(rpy):
    q = frames.euler_to_quaternion(*rpy)
    assert frames.quaternion_to_euler(*q) == pytest.approx(rpy)
    assert frames.yaw_from_quaternion(*q) == pytest.approx(rpy[2])
    # The quaternion and the matrix describe the same rotation.
    x, y, z, w = q
    m = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    assert frames.rotation_matrix(*rpy) == pytest.approx(m)


def test_flu_sign_conventions_of_thrust_axis():
    # Positive pitch = nose down: body z tilts towards +x (forward acceleration).
    zb = frames.rotation_matrix(0.0, 0.2, 0.0)[:, 2]
    assert zb[0] > 0 and abs(zb[1]) < 1e-12
    # Positive roll = right wing down: body z tilts towards -y (to the right).
    zb = frames.rotation_matrix(0.2, 0.0, 0.0)[:, 2]
    assert zb[1] < 0 and abs(zb[0]) < 1e-12


def test_quaternion_multiply_composes_yaws():
    a = frames.euler_to_quaternion(0, 0, 0.4)
    b = frames.euler_to_quaternion(0, 0, 0.5)
    assert frames.yaw_from_quaternion(*frames.quaternion_multiply(a, b)) == pytest.approx(0.9)


@pytest.mark.parametrize('yaw_deg,world,stab', [
    (0.0, (1.0, 0.0), (1.0, 0.0)),
    (90.0, (0.0, 1.0), (1.0, 0.0)),      # heading north: north is ahead
    (90.0, (1.0, 0.0), (0.0, -1.0)),     # heading north: east is to the right
    (180.0, (1.0, 0.0), (-1.0, 0.0)),    # heading west: east is behind
    (-135.0, (-1.0, -1.0), (math.sqrt(2), 0.0)),
])
def test_world_to_stability_and_back(yaw_deg, world, stab):
    yaw = math.radians(yaw_deg)
    assert frames.world_to_stability(world[0], world[1], yaw) == pytest.approx(stab, abs=1e-12)
    assert frames.stability_to_world(stab[0], stab[1], yaw) == pytest.approx(world, abs=1e-12)


def test_is_finite():
    assert frames.is_finite(1.0, -2, 0.0)
    assert not frames.is_finite(1.0, float('nan'))
    assert not frames.is_finite(float('inf'))
    assert not frames.is_finite(None)


# -- the one Odometry -> numbers conversion --------------------------------------------------
NAN = float('nan')
LEVEL = (0.0, 0.0, 0.0, 1.0)


def test_normalize_quaternion():
    assert frames.normalize_quaternion((0, 0, 2.0, 0)) == (0.0, 0.0, 1.0, 0.0)
    for bad in [(0, 0, 0, 0), (0, 0, 0, NAN), (0, 0, 0, float('inf')), (0, 0, 1), None, 'abcd']:
        with pytest.raises(ValueError):
            frames.normalize_quaternion(bad)
    with pytest.raises(ValueError):
        frames.normalize_quaternion((0, 0, 0, 1e-7), min_norm=1e-6)


@pytest.mark.parametrize('roll,pitch,yaw,body,world', [
    (0.0, 0.0, 0.0, (1.0, 2.0, 3.0), (1.0, 2.0, 3.0)),
    (0.0, 0.0, 90.0, (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),        # nose north: forward = +y
    (0.0, 0.0, 180.0, (1.0, 1.0, 0.0), (-1.0, -1.0, 0.0)),
    (0.0, 30.0, 0.0, (1.0, 0.0, 0.0), (math.cos(math.radians(30)), 0.0, -math.sin(math.radians(30)))),
    (20.0, 0.0, -90.0, (0.0, 1.0, 0.0), (math.cos(math.radians(20)), 0.0, math.sin(math.radians(20)))),
])
def test_odometry_child_twist_is_rotated_from_body_to_world(roll, pitch, yaw, body, world):
    rpy = (math.radians(roll), math.radians(pitch), math.radians(yaw))
    pos, vel, angles = frames.odometry_to_world((1.0, 2.0, 3.0), frames.euler_to_quaternion(*rpy), body)
    assert pos == (1.0, 2.0, 3.0)
    assert vel == pytest.approx(world, abs=1e-12)
    assert angles == pytest.approx(rpy, abs=1e-12)
    # a world twist is taken as is
    _, vel, _ = frames.odometry_to_world((1.0, 2.0, 3.0), frames.euler_to_quaternion(*rpy), body, 'world')
    assert vel == body


def test_odometry_normalises_the_quaternion():
    q = (0.0, 0.0, 2.0 * math.sin(0.25), 2.0 * math.cos(0.25))
    _, vel, (roll, pitch, yaw) = frames.odometry_to_world((0, 0, 0), q, (1, 0, 0))
    assert yaw == pytest.approx(0.5) and vel == pytest.approx((math.cos(0.5), math.sin(0.5), 0.0))


@pytest.mark.parametrize('args', [
    ((0, NAN, 0), LEVEL, (0, 0, 0)),
    ((0, 0, 0), (0, 0, 0, 0), (0, 0, 0)),               # zero quaternion: not a rotation
    ((0, 0, 0), (0, 0, 0, 1e-9), (0, 0, 0)),
    ((0, 0, 0), (0, 0, 0, float('inf')), (0, 0, 0)),
    ((0, 0, 0), LEVEL, (0, 0, NAN)),
    ((0, 0, 0), LEVEL, (float('inf'), 0, 0)),
    ((0, 0), LEVEL, (0, 0, 0)),
    (None, LEVEL, (0, 0, 0)),
    ((0, 0, 0), (0, 0, 1), (0, 0, 0)),
])
@pytest.mark.parametrize('twist_frame', frames.TWIST_FRAMES)
def test_odometry_refuses_unusable_input(args, twist_frame):
    assert frames.odometry_to_world(*args, twist_frame=twist_frame) is None


def test_odometry_partial_marks_what_cannot_be_computed():
    pos, vel, rpy = frames.odometry_to_world((1, NAN, 3), (0, 0, 0, 0), (1, 2, 3), partial=True)
    assert pos[0] == 1.0 and math.isnan(pos[1]) and all(math.isnan(v) for v in vel + rpy)
    pos, vel, rpy = frames.odometry_to_world((1, 2, 3), (0, 0, 0, 0), (1, 2, 3), 'world', partial=True)
    assert vel == (1.0, 2.0, 3.0) and all(math.isnan(a) for a in rpy)
    pos, vel, rpy = frames.odometry_to_world((1, 2, 3), LEVEL, (NAN, 0, 0), partial=True)
    assert rpy == (0.0, 0.0, 0.0) and math.isnan(vel[0])
    with pytest.raises(ValueError):
        frames.odometry_to_world((1, 2, 3), LEVEL, (0, 0, 0), 'body')


@pytest.mark.parametrize('turn', [0.0, 0.4, -1.7])
def test_gyroscopic_step_is_the_same_law_in_every_tilt_coordinate(turn):
    """(I - turn J)^-1: turned by atan(turn), shortened by 1/sqrt(1 + turn^2); the same formula whether the step
    is written in (roll, pitch), in (forward, left) = (pitch, -roll) or in world axes at any yaw."""
    d_roll, d_pitch = 0.03, -0.05
    r, p = frames.gyroscopic_step(d_roll, d_pitch, turn)
    assert math.hypot(r, p) == pytest.approx(math.hypot(d_roll, d_pitch) / math.sqrt(1 + turn * turn))
    angle = math.atan2(p, r) - math.atan2(d_pitch, d_roll)
    assert frames.wrap_angle(angle) == pytest.approx(math.atan(turn))
    f, l = frames.gyroscopic_step(d_pitch, -d_roll, turn)                  # (forward, left)
    assert (f, l) == pytest.approx((p, -r))
    for yaw in (0.7, -2.5):
        wx, wy = frames.stability_to_world(d_pitch, -d_roll, yaw)
        gx, gy = frames.gyroscopic_step(wx, wy, turn)
        assert (gx, gy) == pytest.approx(frames.stability_to_world(f, l, yaw))


def test_tilt_loop_step_terms():
    """The firmware's roll/pitch loop (frames.tilt_loop_step): without a yaw rate the plain first-order step
    whatever the yaw terms; the gyroscopic coupling is gyroscopic_step's; the loss of authority replaces the lag
    by the exact step of the reduced rate, and none beyond; the precession turns the tilt after the step; the
    rate limit caps the step; the law is the same in (roll, pitch) and (forward, left) = (pitch, -roll)."""
    tau, dt = 0.18, 0.005
    lag = 1.0 - math.exp(-dt / tau)
    x, y, xs, ys = 0.1, -0.2, 0.3, 0.25
    plain = (x + lag * (xs - x), y + lag * (ys - y))
    assert frames.tilt_loop_step(x, y, xs, ys, lag, dt, 0.0, tau, -1.0, 3.0, 1.2) == plain
    gx, gy = frames.gyroscopic_step(lag * (xs - x), lag * (ys - y), -1.0 * 1.5)
    assert frames.tilt_loop_step(x, y, xs, ys, lag, dt, 1.5, tau, coupling=-1.0) == pytest.approx((x + gx, y + gy))
    slow = 1.0 - math.exp(-(1.0 / tau - 2.0 * 1.5) * dt)
    assert frames.tilt_loop_step(x, y, xs, ys, lag, dt, -1.5, tau, authority=2.0) == pytest.approx(
        (x + slow * (xs - x), y + slow * (ys - y)))
    assert frames.tilt_loop_step(x, y, xs, ys, lag, dt, 4.0, tau, authority=2.0) == (x, y)     # held
    a = 1.2 * 1.5 * dt
    px, py = plain
    assert frames.tilt_loop_step(x, y, xs, ys, lag, dt, 1.5, tau, precession=1.2) == pytest.approx(
        (math.cos(a) * px - math.sin(a) * py, math.sin(a) * px + math.cos(a) * py))
    capped = frames.tilt_loop_step(x, y, xs, ys, lag, dt, rate_limit=0.1)
    assert math.hypot(capped[0] - x, capped[1] - y) == pytest.approx(0.1 * dt)
    every = dict(yaw_rate=1.5, time_constant=tau, coupling=-0.7, authority=2.0, precession=1.2, rate_limit=0.5)
    r, p = frames.tilt_loop_step(x, y, xs, ys, lag, dt, **every)
    # the order: the reduced rate's step, turned by G, capped, added, then the precession
    dx, dy = frames.gyroscopic_step(slow * (xs - x), slow * (ys - y), -0.7 * 1.5)
    k = min(1.0, 0.5 * dt / math.hypot(dx, dy))
    assert k < 1.0                                                          # the cap binds here
    px, py = x + k * dx, y + k * dy
    assert (r, p) == pytest.approx((math.cos(a) * px - math.sin(a) * py, math.sin(a) * px + math.cos(a) * py),
                                   abs=1e-15)
    f, l = frames.tilt_loop_step(y, -x, ys, -xs, lag, dt, **every)         # (forward, left)
    assert (f, l) == pytest.approx((p, -r))
