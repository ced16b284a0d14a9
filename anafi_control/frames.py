"""Frames and rotations shared by every stage (pure math, no ROS).

Conventions (REP-103): world frame ENU; body frame FLU (x forward, y left,
z up); Euler angles are roll (about x), pitch (about y), yaw (about z),
applied as R = Rz(yaw) Ry(pitch) Rx(roll), in radians. With FLU a positive
pitch is nose down (the drone accelerates forward) and a positive roll is
right wing down (the drone accelerates to the right, i.e. towards -y).

The *stability axes* of the paper: origin at the drone, x along the heading
in the horizontal plane, y to the left, z up, i.e. the world frame rotated by
the yaw angle only.

Quaternions are (x, y, z, w), as in geometry_msgs.
"""
import math

import numpy as np


def wrap_angle(angle, period=2.0 * math.pi):
    """Wrap ``angle`` into [-period/2, period/2)."""
    half = 0.5 * period
    return (angle + half) % period - half


def euler_to_quaternion(roll, pitch, yaw):
    """Quaternion (x, y, z, w) of R = Rz(yaw) Ry(pitch) Rx(roll) [rad]."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    return (sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy)


def quaternion_to_euler(x, y, z, w):
    """(roll, pitch, yaw) [rad] of a unit quaternion (x, y, z, w). The pitch is the atan2 of sin(pitch) and
    cos(pitch) (the norm of the rotation matrix's first column in the x-y plane), accurate near +-90 deg too,
    where an asin of sin(pitch) turns rounding of order eps into an error of order sqrt(eps)."""
    sinp = 2.0 * (w * y - z * x)
    cosp = math.hypot(w * w + x * x - y * y - z * z, 2.0 * (x * y + w * z))
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.atan2(sinp, cosp)
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def quaternion_multiply(a, b):
    """Hamilton product a*b of quaternions (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


#: (x, y, z, w) of the rotation from a north-west-up (NWU) world frame to ENU: +90 deg about z (north = ENU +y)
NWU_TO_ENU = (0.0, 0.0, math.sin(math.pi / 4.0), math.cos(math.pi / 4.0))


def enu_from_nwu(q):
    """An attitude (x, y, z, w) referenced to north-west-up, referenced to ENU instead (same body axes)."""
    return quaternion_multiply(NWU_TO_ENU, q)


def nwu_from_enu(q):
    """An attitude (x, y, z, w) referenced to ENU, referenced to north-west-up instead (same body axes)."""
    x, y, z, w = NWU_TO_ENU
    return quaternion_multiply((-x, -y, -z, w), q)


def enu_from_nwu_vector(v):
    """A vector (x, y, z) in a north-west-up world frame (the bridge's drone/speed) in ENU instead."""
    return (-float(v[1]), float(v[0]), float(v[2]))


def nwu_from_enu_vector(v):
    """A vector (x, y, z) in the ENU world frame in north-west-up instead (what the bridge publishes on
    drone/speed: (north, -east, -down) of the firmware's NED speed)."""
    return (float(v[1]), -float(v[0]), float(v[2]))


def yaw_from_quaternion(x, y, z, w):
    """Heading [rad] of a quaternion (x, y, z, w)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def rotation_matrix(roll, pitch, yaw):
    """3x3 matrix R = Rz(yaw) Ry(pitch) Rx(roll): body vector -> world vector."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def world_to_stability(x, y, yaw):
    """Rotate a horizontal world (ENU) vector (x, y) into stability axes of heading ``yaw`` [rad]."""
    c, s = math.cos(yaw), math.sin(yaw)
    return c * x + s * y, -s * x + c * y


def stability_to_world(x, y, yaw):
    """Rotate a horizontal stability-axes vector (x, y) into the world (ENU) frame."""
    c, s = math.cos(yaw), math.sin(yaw)
    return c * x - s * y, s * x + c * y


def gyroscopic_step(dx, dy, turn):
    """A tilt step (dx, dy) turned and shortened by the firmware's gyroscopic coupling (anafi_sim.sim.
    drone_model, ``gyroscopic_coupling``): (I - turn J)^-1 (dx, dy), turn = G x yaw rate [-], J the quarter turn
    counter-clockwise about z; i.e. rotated by atan(turn), shortened by 1 / sqrt(1 + turn^2). The same formula
    in (roll, pitch), (forward, left) or world (x, y) coordinates: the maps between them are proper rotations,
    which commute with J."""
    k = 1.0 / (1.0 + turn * turn)
    return k * (dx - turn * dy), k * (dy + turn * dx)


def tilt_loop_step(x, y, x_sp, y_sp, lag, dt, yaw_rate=0.0, time_constant=0.0, coupling=0.0, authority=0.0,
                   precession=0.0, rate_limit=0.0):
    """(x, y) [rad] after one step ``dt`` [s] of the firmware's roll/pitch loop (anafi_sim.sim.drone_model; the
    calibration's fits and the preview MPC's prediction use this law), the tilt (x, y) and its setpoint in
    (roll, pitch), (forward, left) or world coordinates (proper rotations of each other):

    - the first-order step ``lag`` (setpoint - tilt), ``lag`` = 1 - exp(-dt / ``time_constant``);
    - while the drone yaws at ``yaw_rate`` r [rad/s]: the loop's rate 1 / ``time_constant`` reduced by
      ``authority`` x |r| (none left beyond: the tilt is held), the step turned and shortened by the
      gyroscopic coupling (``gyroscopic_step``, G = ``coupling`` [s]);
    - the step capped at ``rate_limit`` x dt [rad] (0 = no cap);
    - the tilt then turned by ``precession`` x r x dt [rad] (counter-clockwise for positive values).

    Every yaw term is off at 0; without a yaw rate the step is the plain (capped) first order."""
    if yaw_rate and authority and time_constant > 0.0:
        rate = 1.0 / time_constant - authority * abs(yaw_rate)
        lag = 1.0 - math.exp(-rate * dt) if rate > 0.0 else 0.0
    dx = lag * (x_sp - x)
    dy = lag * (y_sp - y)
    if yaw_rate and coupling:
        dx, dy = gyroscopic_step(dx, dy, coupling * yaw_rate)
    if rate_limit > 0.0:
        cap = rate_limit * dt
        norm = math.sqrt(dx * dx + dy * dy)
        if norm > cap:
            dx *= cap / norm
            dy *= cap / norm
    x += dx
    y += dy
    if yaw_rate and precession:
        a = precession * yaw_rate * dt
        c, s = math.cos(a), math.sin(a)
        x, y = c * x - s * y, s * x + c * y
    return x, y


def is_finite(*values):
    """True when every value is a finite number."""
    try:
        return all(math.isfinite(v) for v in values)
    except TypeError:
        return False


def normalize_quaternion(q, min_norm=1e-9):
    """``q`` = (x, y, z, w) scaled to unit length, as a tuple of floats.

    ValueError when ``q`` is not 4 numbers, is non-finite or its norm is not above ``min_norm`` (not a
    rotation).
    """
    try:
        x, y, z, w = q
        x, y, z, w = float(x), float(y), float(z), float(w)
    except (TypeError, ValueError):
        raise ValueError('a quaternion must be 4 numbers (x, y, z, w), got %r' % (q,))
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not (math.isfinite(norm) and norm > min_norm):
        raise ValueError('quaternion of norm %r is not a rotation' % (norm,))
    return x / norm, y / norm, z / norm, w / norm


#: twist frames of ``odometry_to_world``: 'child' = nav_msgs/Odometry's child_frame_id (the body, FLU),
#: 'world' = already in the world (ENU) frame
TWIST_FRAMES = ('child', 'world')


def odometry_to_world(position, orientation, twist_linear, twist_frame='child', partial=False):
    """The one Odometry -> numbers conversion: (position, world velocity, (roll, pitch, yaw)), or None.

    ``position`` (x, y, z) [m] world ENU; ``orientation`` quaternion (x, y, z, w) of the body in the world,
    normalised here (norm below 1e-6 or non-finite: not a rotation); ``twist_linear`` (vx, vy, vz) [m/s] in
    ``twist_frame`` ('child': the body frame, rotated into the world with R(roll, pitch, yaw); 'world':
    taken as is). Returns three tuples of floats: position, velocity [m/s] world ENU, Euler angles [rad].

    Unusable input (malformed, non-finite, zero quaternion) gives None; with ``partial`` it gives the
    three tuples with NaN where a value cannot be computed instead (angles NaN without a rotation, a
    child-frame velocity NaN then too), for evaluation code that reports bad samples per column.
    """
    if twist_frame not in TWIST_FRAMES:
        raise ValueError('twist_frame must be one of %s, got %r' % (', '.join(TWIST_FRAMES), twist_frame))
    try:
        px, py, pz = (float(v) for v in position)
        bx, by, bz = (float(v) for v in twist_linear)
    except (TypeError, ValueError):
        return None
    if not partial and not is_finite(px, py, pz, bx, by, bz):
        return None
    nan = float('nan')
    try:
        rpy = quaternion_to_euler(*normalize_quaternion(orientation, 1e-6))
    except ValueError:
        if not partial:
            return None
        rpy = (nan, nan, nan)
    if twist_frame == 'world':
        vel = (bx, by, bz)
    elif is_finite(*rpy):
        r = rotation_matrix(*rpy).tolist()
        vel = tuple(r[i][0] * bx + r[i][1] * by + r[i][2] * bz for i in range(3))
    else:
        vel = (nan, nan, nan)
    return (px, py, pz), vel, rpy


def quaternion_matrix(q):
    """3x3 rotation matrix of a quaternion (x, y, z, w) (body vector -> world vector); ``q`` need not be
    unit length (it is normalised on the way). ValueError for a zero quaternion."""
    x, y, z, w = q
    n = x * x + y * y + z * z + w * w
    if not n > 0.0:
        raise ValueError('zero quaternion')
    s = 2.0 / n
    return np.array([
        [1.0 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)],
        [s * (x * y + z * w), 1.0 - s * (x * x + z * z), s * (y * z - x * w)],
        [s * (x * z - y * w), s * (y * z + x * w), 1.0 - s * (x * x + y * y)],
    ])


def world_to_body(roll, pitch, yaw, vector):
    """World (ENU) vector -> body (FLU) vector: R(roll, pitch, yaw)^T v, as a tuple of floats."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    x, y, z = vector
    return (cy * cp * x + sy * cp * y - sp * z,
            (cy * sp * sr - sy * cr) * x + (sy * sp * sr + cy * cr) * y + cp * sr * z,
            (cy * sp * cr + sy * sr) * x + (sy * sp * cr - cy * sr) * y + cp * cr * z)


def odometry_twist_frame(frame_id, child_frame_id):
    """Twist frame of a nav_msgs/Odometry by its frame names: 'child' (REP: the body frame) unless
    ``child_frame_id`` is empty or equals ``frame_id`` (the header's), then 'world'."""
    return 'child' if child_frame_id and child_frame_id != frame_id else 'world'
