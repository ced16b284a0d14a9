"""The drone's state from what a real anafi_ros bridge publishes (pure core, no rospy).

Stage: bridge topics -> the controllers' state (the numbers of a nav_msgs/Odometry on drone/odom). No
anafi_ros bridge publishes drone/odom (``shared/interfaces/anafi_ros.md``); the state comes from one of

- ``state_enu``: the paper authors' bridge fork's position_control/state_enu (anafi_control/State): pose
  and world ENU velocity in one message, one stamp;
- ``pose_speed``: a pose (geometry_msgs/PoseStamped, world ENU: the fork's drone/pose_enu, or an external
  pose source such as motion capture for the upstream bridge, which has no local position) and the
  bridge's drone/speed (geometry_msgs/Vector3Stamped, north-west-up: (north, -east, -down) of the firmware's
  NED speed), paired by their header stamps.

Time alignment, by each message's own stamp: a message whose stamp does not advance on its topic's last
one is refused (``repeated``); one older than ``stale_after`` [s] on the caller's clock when it arrives is
refused (``stale``: a late or frozen stream); a pose is paired with the drone/speed sample nearest to it in
stamp, at most ``max_skew`` [s] away, else refused (``skew``: the speed stream dropped or froze). A pose
waits for the speed of its own moment until a speed stamped at or after it, or the next pose, arrives (at
most one sample of latency). A refused sample gives no state: when a part freezes, no state is produced,
the controllers' input gate goes SILENT after its state_timeout, the PCMD stream ends and the firmware
hovers. ``health(now)`` names the parts not heard for ``stale_after``.

The pose source's world frame: ``world_yaw`` [rad] is the heading of its x axis, counter-clockwise from
east (0: the pose is ENU, as drone/pose_enu and our simulator; a motion-capture room is rarely aligned with
north, so measure it, e.g. with the drone's own heading from drone/attitude). drone/speed is rotated into
the pose frame with it.
"""
import collections
import math

from anafi_control import frames

SOURCES = ('state_enu', 'pose_speed')

#: defaults of the assembler's settings (one source of truth; the node's ~params default to these)
DEFAULTS = collections.OrderedDict([
    ('source', 'state_enu'),   # 'state_enu' (the authors' fork) or 'pose_speed' (a pose topic + drone/speed)
    ('max_skew', 0.1),         # [s] largest |pose stamp - speed stamp| of a pair (3 bridge periods at 30 Hz)
    ('stale_after', 0.3),      # [s] oldest a message may be when it arrives; silence after which a part is stale
    ('world_yaw', 0.0),        # [rad] heading of the pose frame's x axis, counter-clockwise from east
])

COUNTERS = ('states', 'refused', 'bad', 'repeated', 'stale', 'skew')

SPEED_BUFFER = 8
"""drone/speed samples kept for pairing (at 30 Hz: about 0.27 s)."""

BridgeState = collections.namedtuple('BridgeState', 'stamp position orientation velocity body_velocity')
"""One state: stamp [s], position (x, y, z) [m] and orientation quaternion (x, y, z, w) in the pose's world
frame, velocity (vx, vy, vz) [m/s] in that world frame, body_velocity [m/s] in the body frame (FLU; an
Odometry's twist in its child frame)."""


def _finite(values):
    try:
        return all(math.isfinite(float(x)) for x in values)
    except (TypeError, ValueError):
        return False


class BridgeStateAssembler(object):
    """Bridge messages in (``on_state_enu`` or ``on_pose`` + ``on_speed``), ``BridgeState`` out.

    Every ``on_*`` takes the message's stamp [s] and ``now`` [s], the caller's clock when it arrived (the
    same clock as the stamps), and returns the list of states it completes (empty when it completes none or
    refuses the message; the refusals are counted in ``counters``)."""

    def __init__(self, source=DEFAULTS['source'], max_skew=DEFAULTS['max_skew'],
                 stale_after=DEFAULTS['stale_after'], world_yaw=DEFAULTS['world_yaw']):
        if source not in SOURCES:
            raise ValueError('source must be one of %s, got %r' % (', '.join(SOURCES), source))
        for name, value in (('max_skew', max_skew), ('stale_after', stale_after)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise ValueError('%s must be a finite number > 0 [s], got %r' % (name, value))
        if not (isinstance(world_yaw, (int, float)) and math.isfinite(world_yaw)):
            raise ValueError('world_yaw must be a finite number [rad], got %r' % (world_yaw,))
        self.source = source
        self.max_skew = float(max_skew)
        self.stale_after = float(stale_after)
        self.world_yaw = float(world_yaw)
        self.counters = collections.OrderedDict((name, 0) for name in COUNTERS)
        self.parts = ('state_enu',) if source == 'state_enu' else ('pose', 'speed')
        self.last_stamp = dict((part, None) for part in self.parts)   # newest accepted stamp per part
        self.heard = dict((part, None) for part in self.parts)        # `now` of the newest accepted message
        self.speeds = collections.deque(maxlen=SPEED_BUFFER)          # (stamp, ENU velocity in the pose frame)
        self.pending = None                                           # (stamp, position, orientation)

    # -- inputs ---------------------------------------------------------------------------------
    def on_state_enu(self, stamp, position, orientation, velocity, now):
        """position_control/state_enu: pose and world ENU velocity of one stamp."""
        self._expect('state_enu')
        if not self._admit('state_enu', stamp, now, (position, orientation, velocity)):
            return []
        return self._emit(stamp, position, orientation, tuple(float(v) for v in velocity))

    def on_pose(self, stamp, position, orientation, now):
        """A pose (drone/pose_enu or an external source)."""
        self._expect('pose')
        if not self._admit('pose', stamp, now, (position, orientation)):
            return []
        out = self._flush() if self.pending is not None else []
        self.pending = (float(stamp), tuple(float(v) for v in position), tuple(float(v) for v in orientation))
        if self.speeds and self.speeds[-1][0] >= self.pending[0]:
            out.extend(self._flush())
        return out

    def on_speed(self, stamp, vector_nwu, now):
        """drone/speed: (north, west, up) [m/s] as the bridge publishes it."""
        self._expect('speed')
        if not self._admit('speed', stamp, now, (vector_nwu,)):
            return []
        east, north, up = frames.enu_from_nwu_vector(vector_nwu)
        c, s = math.cos(self.world_yaw), math.sin(self.world_yaw)
        self.speeds.append((float(stamp), (c * east + s * north, -s * east + c * north, up)))
        if self.pending is not None and float(stamp) >= self.pending[0]:
            return self._flush()
        return []

    # -- state ----------------------------------------------------------------------------------
    def health(self, now):
        """(fresh, stale_parts): fresh when every part was heard within ``stale_after`` of ``now``;
        stale_parts names the others ('never heard' or the age)."""
        stale = []
        for part in self.parts:
            heard = self.heard[part]
            if heard is None:
                stale.append('%s never heard' % part)
            elif now - heard > self.stale_after:
                stale.append('%s silent for %.2f s' % (part, now - heard))
        return not stale, stale

    # -- internals ------------------------------------------------------------------------------
    def _expect(self, part):
        if part not in self.parts:
            raise ValueError('a %s message on a %s assembler' % (part, self.source))

    def _refuse(self, key):
        self.counters[key] += 1
        self.counters['refused'] += 1
        return False

    def _admit(self, part, stamp, now, values):
        if not (_finite((stamp, now)) and all(_finite(v) for v in values)) \
                or (len(values) > 1 and not _quaternion_ok(values[1])):
            return self._refuse('bad')
        stamp = float(stamp)
        last = self.last_stamp[part]
        if last is not None and stamp <= last:
            return self._refuse('repeated')
        if float(now) - stamp > self.stale_after:
            return self._refuse('stale')
        self.last_stamp[part] = stamp
        self.heard[part] = float(now)
        return True

    def _flush(self):
        stamp, position, orientation = self.pending
        self.pending = None
        if not self.speeds:
            self._refuse('skew')
            return []
        speed_stamp, velocity = min(self.speeds, key=lambda sample: abs(sample[0] - stamp))
        if abs(speed_stamp - stamp) > self.max_skew:
            self._refuse('skew')
            return []
        return self._emit(stamp, position, orientation, velocity)

    def _emit(self, stamp, position, orientation, velocity):
        q = frames.normalize_quaternion(orientation, 1e-6)
        roll, pitch, yaw = frames.quaternion_to_euler(*q)
        self.counters['states'] += 1
        return [BridgeState(float(stamp), tuple(float(v) for v in position), tuple(q), velocity,
                            frames.world_to_body(roll, pitch, yaw, velocity))]


def _quaternion_ok(q):
    try:
        frames.normalize_quaternion(q, 1e-6)
    except (ValueError, TypeError):
        return False
    return len(q) == 4
