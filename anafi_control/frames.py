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
    """(roll, pitch, yaw) [rad] of a unit quaternion (x, y, z, w)."""
    sinp = 2.0 * (w * y - z * x)
    sinp = max(-1.0, min(1.0, sinp))
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(sinp)
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


def is_finite(*values):
    """True when every value is a finite number."""
    try:
        return all(math.isfinite(v) for v in values)
    except TypeError:
        return False
