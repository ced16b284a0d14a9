"""Model follower core (pure Python, no ROS): a tracked model's pose -> the paper's waypoint with velocity.

Stage: target (e.g. the airship in /gazebo/model_states) -> waypoint (-> PID / MPC controller).
Frames and units: ENU world frame, positions [m], velocities [m/s], yaw of the waypoint [deg]
(world, counter-clockwise positive), the target's orientation as a quaternion (x, y, z, w), its
angular velocity [rad/s] in the world frame (as gazebo_msgs/ModelStates twists), time [s].

The waypoint is the target's position plus an ``offset`` [m]: in the target's heading frame
(``offset_frame='heading'``: x forward along the target's yaw, y left, z up; e.g. (-6, 0, -2) =
6 m behind and 2 m below) or in the world frame (``'world'``). Its velocity is consistent with its
position:

- ``velocity_source='twist'``: v_target + yaw_rate x (R(yaw) offset) from the model's twist;
- ``'difference'``: the finite difference of successive waypoint positions, low-pass filtered with
  time constant ``smoothing`` [s];
- ``'auto'`` (default): the twist when it is given, finite and not all zero while the target
  visibly moves (a world that does not fill in twists), else the difference.

Waypoint yaw: ``yaw_mode='heading'`` = the target's yaw + ``yaw_offset`` [deg]; ``'face'`` = looking
from the waypoint at the target (+ offset; the heading itself when the offset is purely along it);
``'fixed'`` = ``yaw_offset``. Non-finite or malformed input is refused (counted in ``rejected``,
``update`` returns None) and does not disturb the filter; a time that does not increase resets the
difference estimate.
"""
import math

from anafi_control.frames import normalize_quaternion, yaw_from_quaternion
from anafi_sim.mission.waypoint import WaypointSample

VELOCITY_SOURCES = ('auto', 'twist', 'difference')
OFFSET_FRAMES = ('heading', 'world')
YAW_MODES = ('heading', 'face', 'fixed')
MOVING_SPEED = 0.05   # m/s: a target moving faster than this with an all-zero twist has no twist


#: yaw [rad] (rotation about world z) of a quaternion (x, y, z, w)
yaw_of_quaternion = yaw_from_quaternion


def _finite(values):
    try:
        return all(math.isfinite(float(v)) for v in values)
    except (TypeError, ValueError):
        return False


class ModelFollower(object):
    """See the module doc. ``update(t, position, orientation, linear=None, angular_z=None)`` ->
    ``WaypointSample`` or None."""

    def __init__(self, offset=(-6.0, 0.0, -2.0), offset_frame='heading', yaw_mode='heading', yaw_offset=0.0,
                 velocity_source='auto', smoothing=0.3):
        if offset_frame not in OFFSET_FRAMES:
            raise ValueError('offset_frame must be one of %s, got %r' % (', '.join(OFFSET_FRAMES), offset_frame))
        if yaw_mode not in YAW_MODES:
            raise ValueError('yaw_mode must be one of %s, got %r' % (', '.join(YAW_MODES), yaw_mode))
        if velocity_source not in VELOCITY_SOURCES:
            raise ValueError('velocity_source must be one of %s, got %r' % (', '.join(VELOCITY_SOURCES),
                                                                          velocity_source))
        if not isinstance(offset, (list, tuple)) or len(offset) != 3 or not _finite(offset):
            raise ValueError('offset must be 3 finite numbers [m], got %r' % (offset,))
        if not _finite([yaw_offset]):
            raise ValueError('yaw_offset must be a finite number [deg], got %r' % (yaw_offset,))
        if not _finite([smoothing]) or smoothing < 0:
            raise ValueError('smoothing must be a finite number >= 0 [s], got %r' % (smoothing,))
        self.offset = tuple(float(v) for v in offset)
        self.offset_frame = offset_frame
        self.yaw_mode = yaw_mode
        self.yaw_offset = float(yaw_offset)
        self.velocity_source = velocity_source
        self.smoothing = float(smoothing)
        self.rejected = 0
        self.resets = 0
        self.updates = 0
        self.used_twist = False
        self._last = None           # (t, waypoint position)
        self._diff_velocity = None  # filtered finite-difference velocity
        self._last_target = None    # (t, target position) for the 'moving' test

    def reset(self):
        """Forget the history (finite-difference velocity restarts)."""
        self._last = None
        self._diff_velocity = None
        self._last_target = None

    def world_offset(self, yaw):
        """The offset in the world frame [m] for a target yaw [rad]."""
        ox, oy, oz = self.offset
        if self.offset_frame == 'world':
            return ox, oy, oz
        c, s = math.cos(yaw), math.sin(yaw)
        return c * ox - s * oy, s * ox + c * oy, oz

    def update(self, t, position, orientation, linear=None, angular_z=None):
        """The waypoint for the target's state at time ``t`` [s] (see the module doc); None when refused."""
        try:
            t = float(t)
            position = tuple(float(v) for v in position)
            orientation = tuple(float(v) for v in orientation)
        except (TypeError, ValueError):
            self.rejected += 1
            return None
        if len(position) != 3 or len(orientation) != 4 or not _finite((t,) + position + orientation):
            self.rejected += 1
            return None
        try:
            yaw = yaw_from_quaternion(*normalize_quaternion(orientation))
        except ValueError:
            self.rejected += 1
            return None
        dx, dy, dz = self.world_offset(yaw)
        wp = (position[0] + dx, position[1] + dy, position[2] + dz)

        twist = None
        if linear is not None:
            try:
                lin = tuple(float(v) for v in linear)
                wz = 0.0 if angular_z is None else float(angular_z)
            except (TypeError, ValueError):
                lin, wz = None, None
            if lin is not None and len(lin) == 3 and _finite(lin + (wz,)):
                rot = (-wz * dy, wz * dx, 0.0) if self.offset_frame == 'heading' else (0.0, 0.0, 0.0)
                twist = tuple(a + b for a, b in zip(lin, rot))
                twist_zero = not any(abs(v) > 0.0 for v in lin) and wz == 0.0
            else:
                twist_zero = True
        else:
            twist_zero = True

        moving = False
        if self._last_target is not None and t > self._last_target[0]:
            dt = t - self._last_target[0]
            speed = math.sqrt(sum((a - b) ** 2 for a, b in zip(position, self._last_target[1]))) / dt
            moving = speed > MOVING_SPEED
        diff = self._difference(t, wp)
        self._last_target = (t, position)

        if self.velocity_source == 'twist' or (self.velocity_source == 'auto' and twist is not None
                                               and not (twist_zero and moving)):
            velocity = twist if twist is not None else (0.0, 0.0, 0.0)
            self.used_twist = twist is not None
        else:
            velocity = diff if diff is not None else (0.0, 0.0, 0.0)
            self.used_twist = False

        if self.yaw_mode == 'heading':
            yaw_deg = math.degrees(yaw) + self.yaw_offset
        elif self.yaw_mode == 'face':
            ex, ey = position[0] - wp[0], position[1] - wp[1]
            base = math.atan2(ey, ex) if math.hypot(ex, ey) > 1e-6 else yaw
            yaw_deg = math.degrees(base) + self.yaw_offset
        else:
            yaw_deg = self.yaw_offset
        yaw_deg = (yaw_deg + 180.0) % 360.0 - 180.0
        self.updates += 1
        return WaypointSample(wp[0], wp[1], wp[2], velocity[0], velocity[1], velocity[2], yaw_deg)

    def _difference(self, t, wp):
        """Filtered finite-difference velocity of the waypoint position (None before two samples)."""
        if self._last is None or t <= self._last[0]:
            if self._last is not None:
                self.resets += 1
            self._last = (t, wp)
            self._diff_velocity = None
            return None
        dt = t - self._last[0]
        raw = tuple((a - b) / dt for a, b in zip(wp, self._last[1]))
        self._last = (t, wp)
        if self._diff_velocity is None or self.smoothing == 0.0:
            self._diff_velocity = raw
        else:
            alpha = dt / (self.smoothing + dt)
            self._diff_velocity = tuple(v + alpha * (r - v) for v, r in zip(self._diff_velocity, raw))
        return self._diff_velocity
