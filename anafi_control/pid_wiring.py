"""Wiring and safety rules of the distributed PID framework (pure core, no ROS).

Stage: controllers (glue). The paper's PID framework is a set of nodes: a
relative-state node (~30 Hz), six pid-package controllers and a command
node (10 Hz). This module holds what those nodes decide, so they stay thin:

* ``LOOP_INPUTS`` / ``loop_inputs(rel)``: which relative-state value is
  published to which loop's ``setpoint`` / ``state`` topic; ``CASCADES``:
  the inner loops take their setpoint from the outer loop's
  ``control_effort`` (set as the inner node's ~setpoint_topic, as a pid
  package user wires a cascade); ``COMMAND_LOOPS``: which loop's effort is
  which PilotingCommand field. ``loop_topics(loop)`` gives the four topic
  names of a loop relative to the PID namespace (``<drone>/pid``).
* ``odometry_state``: nav_msgs/Odometry numbers (pose in the world frame,
  twist in the child = body frame) -> world position [m], world velocity
  [m/s], heading [rad].
* ``InputGate``: last state / waypoint with receive times; ``step(t)`` says
  whether a relative-state cycle may run or why the framework must hover
  (no input yet, stale, non-finite).
* ``CommandAssembler``: last effort of each command loop with its time;
  ``command(t)`` = PilotingCommand tuple (roll, pitch [deg], yaw rate
  [deg/s], gaz [m/s]) or hover (zeros) with the reason.

Times are seconds on the caller's clock (ROS time in the nodes). A clock
that goes backwards (simulation restarted) drops all held inputs.
"""
import collections
import math

from anafi_control.frames import is_finite, rotation_matrix, quaternion_to_euler
from anafi_control.pid_framework import HOVER, LOOP_NAMES

#: (loop, 'setpoint' | 'state', RelativeState field or None for the constant 0)
#: published by the relative-state node, outer loops first. Position loops get
#: the waypoint relative to the drone as setpoint and 0 as state (the drone is
#: the origin of its stability axes); inner loops get the drone velocity as
#: state (their setpoint is the outer effort, see CASCADES); yaw gets absolute
#: world angles in degrees (the pid wraps the error).
LOOP_INPUTS = (
    ('x_outer', 'setpoint', 'wp_x'),
    ('x_outer', 'state', None),
    ('y_outer', 'setpoint', 'wp_y'),
    ('y_outer', 'state', None),
    ('x_inner', 'state', 'vx'),
    ('y_inner', 'state', 'vy'),
    ('vertical', 'setpoint', 'wp_z'),
    ('vertical', 'state', None),
    ('yaw', 'setpoint', 'wp_yaw_deg'),
    ('yaw', 'state', 'yaw_deg'),
)

#: inner loop -> outer loop whose control_effort is the inner setpoint
CASCADES = collections.OrderedDict([('x_inner', 'x_outer'), ('y_inner', 'y_outer')])

#: PilotingCommand field -> loop whose effort it is (in message field order)
COMMAND_LOOPS = collections.OrderedDict([('roll', 'y_inner'), ('pitch', 'x_inner'),
                                         ('yaw', 'yaw'), ('gaz', 'vertical')])

#: the pid package's default topic names (relative to the controller's namespace)
PID_TOPIC_DEFAULTS = collections.OrderedDict([
    ('setpoint_topic', 'setpoint'), ('topic_from_plant', 'state'),
    ('topic_from_controller', 'control_effort'), ('pid_enable_topic', 'pid_enable')])


def loop_topics(loop):
    """The pid node params of ``loop`` (pid package names -> topic, relative to the PID namespace).

    Each controller node is named like its loop and lives in the PID
    namespace, so its topics are '<loop>/setpoint' etc.; the inner loops'
    setpoint is the outer loop's control effort; pid_enable is shared.
    """
    if loop not in LOOP_NAMES:
        raise ValueError('unknown PID loop %r' % (loop,))
    setpoint = loop + '/setpoint'
    if loop in CASCADES:
        setpoint = CASCADES[loop] + '/control_effort'
    return collections.OrderedDict([('setpoint_topic', setpoint), ('topic_from_plant', loop + '/state'),
                                    ('topic_from_controller', loop + '/control_effort'),
                                    ('pid_enable_topic', 'pid_enable')])


def input_topics():
    """Topics (relative to the PID namespace) the relative-state node publishes, in LOOP_INPUTS order."""
    return ['%s/%s' % (loop, kind) for loop, kind, _ in LOOP_INPUTS]


def loop_inputs(rel):
    """[(topic relative to the PID namespace, value)] the relative-state node publishes for ``rel``."""
    out = []
    for loop, kind, field in LOOP_INPUTS:
        value = 0.0 if field is None else float(getattr(rel, field))
        out.append(('%s/%s' % (loop, kind), value))
    return out


def odometry_state(position, orientation, body_velocity):
    """(pos, vel_world, yaw) from Odometry numbers, or None if non-finite / not a rotation.

    position (x, y, z) [m] world; orientation quaternion (x, y, z, w) of the
    body in the world (normalised here; norm 0 refused); body_velocity
    (vx, vy, vz) [m/s] in the child (body) frame, rotated to the world here.
    """
    try:
        px, py, pz = (float(v) for v in position)
        qx, qy, qz, qw = (float(v) for v in orientation)
        bx, by, bz = (float(v) for v in body_velocity)
    except (TypeError, ValueError):
        return None
    if not is_finite(px, py, pz, qx, qy, qz, qw, bx, by, bz):
        return None
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if norm < 1e-6:
        return None
    roll, pitch, yaw = quaternion_to_euler(qx / norm, qy / norm, qz / norm, qw / norm)
    r = rotation_matrix(roll, pitch, yaw)
    vel = tuple(float(r[i, 0] * bx + r[i, 1] * by + r[i, 2] * bz) for i in range(3))
    return (px, py, pz), vel, yaw


# -- relative-state input gate ------------------------------------------------------------
#: reasons for hovering (also the diagnostic messages)
NO_STATE = 'no state received yet'
NO_WAYPOINT = 'no waypoint received yet'
STALE_STATE = 'stale state'
STALE_WAYPOINT = 'stale waypoint'
BAD_STATE = 'non-finite state'
BAD_WAYPOINT = 'non-finite waypoint'


def gate_health(reason):
    """(is_warning, message) of an input gate's last hover reason (None = tracking).

    Waiting for the first waypoint is normal (not a warning); any other hover reason is.
    """
    if reason is None:
        return False, 'tracking'
    return reason != NO_WAYPOINT, 'hovering: %s' % reason


Inputs = collections.namedtuple('Inputs', ['pos', 'vel', 'yaw', 'waypoint'])
Inputs.__doc__ = 'Drone position [m], world velocity [m/s], heading [rad], waypoint (x,y,z,vx,vy,vz,yaw_deg).'


def check_timeout(name, value, allow_zero=False):
    """A timeout parameter [s]: finite and > 0 (or == 0 with allow_zero: 'never stale'); ValueError else."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or value < 0.0 or (value == 0.0 and not allow_zero):
        raise ValueError('%s must be a finite number %s 0 [s], got %r'
                         % (name, '>=' if allow_zero else '>', value))
    return float(value)


class InputGate(object):
    """Holds the latest state and waypoint; decides per cycle: run (Inputs) or hover (reason).

    ``state_timeout`` [s] > 0; ``waypoint_timeout`` [s] >= 0, 0 = a waypoint
    never goes stale (a single static waypoint is held). A non-finite sample
    replaces the held one as 'bad' (hover until a good one arrives; garbage
    is never forwarded) and is counted.
    """

    def __init__(self, state_timeout=0.5, waypoint_timeout=1.0):
        self.state_timeout = check_timeout('state_timeout', state_timeout)
        self.waypoint_timeout = check_timeout('waypoint_timeout', waypoint_timeout, allow_zero=True)
        self.state = None          # (pos, vel, yaw) or False for a bad sample
        self.state_time = None
        self.waypoint = None       # 7-tuple or False
        self.waypoint_time = None
        self.bad_states = 0
        self.bad_waypoints = 0
        self.clock_jumps = 0
        self.cycles = 0
        self.hover_cycles = 0
        self.last_reason = NO_WAYPOINT

    def on_state(self, t, position, orientation, body_velocity):
        """A state sample (Odometry numbers) received at t; False if refused (non-finite)."""
        self._check_clock(t)
        state = odometry_state(position, orientation, body_velocity)
        self.state_time = t
        if state is None:
            self.bad_states += 1
            self.state = False
            return False
        self.state = state
        return True

    def on_waypoint(self, t, waypoint):
        """A waypoint (x, y, z, vx, vy, vz, yaw_deg) received at t; False if refused."""
        self._check_clock(t)
        self.waypoint_time = t
        try:
            wp = tuple(float(v) for v in waypoint)
        except (TypeError, ValueError):
            wp = ()
        if len(wp) != 7 or not is_finite(*wp):
            self.bad_waypoints += 1
            self.waypoint = False
            return False
        self.waypoint = wp
        return True

    def _check_clock(self, t):
        for held in (self.state_time, self.waypoint_time):
            if held is not None and t < held:
                self.clock_jumps += 1
                self.state = self.waypoint = None
                self.state_time = self.waypoint_time = None
                return

    def step(self, t):
        """(Inputs, None) when a cycle may run at time t, else (None, reason) -> hover."""
        self._check_clock(t)
        self.cycles += 1
        reason = self._reason(t)
        self.last_reason = reason
        if reason is not None:
            self.hover_cycles += 1
            return None, reason
        pos, vel, yaw = self.state
        return Inputs(pos, vel, yaw, self.waypoint), None

    def _reason(self, t):
        if self.state is None:
            return NO_STATE
        if self.state is False:
            return BAD_STATE
        if t - self.state_time > self.state_timeout:
            return STALE_STATE
        if self.waypoint is None:
            return NO_WAYPOINT
        if self.waypoint is False:
            return BAD_WAYPOINT
        if self.waypoint_timeout > 0.0 and t - self.waypoint_time > self.waypoint_timeout:
            return STALE_WAYPOINT
        return None


# -- command assembly ---------------------------------------------------------------------
NO_EFFORT = 'no effort yet from'
STALE_EFFORT = 'stale effort from'
BAD_EFFORT = 'non-finite effort from'
DISABLED = 'pid disabled'


class CommandAssembler(object):
    """Latest effort per command loop -> PilotingCommand tuple, or HOVER with the reason.

    Hover when the framework is disabled (pid_enable false), or any of the
    four efforts is missing, older than ``effort_timeout`` [s] or non-finite.
    Counts hover commands (``hovers``) and refused efforts (``bad_efforts``).
    """

    def __init__(self, effort_timeout=0.5):
        self.effort_timeout = check_timeout('effort_timeout', effort_timeout)
        self.values = dict((field, None) for field in COMMAND_LOOPS)
        self.times = dict((field, None) for field in COMMAND_LOOPS)
        self.enabled = True
        self.bad_efforts = 0
        self.hovers = 0
        self.commands = 0
        self.last_reason = None

    def on_effort(self, field, t, value):
        """Effort for PilotingCommand ``field`` ('roll', 'pitch', 'yaw', 'gaz') received at t."""
        if field not in COMMAND_LOOPS:
            raise ValueError('unknown command field %r' % (field,))
        self.times[field] = t
        if not is_finite(value):
            self.bad_efforts += 1
            self.values[field] = False
            return False
        self.values[field] = float(value)
        return True

    def on_enable(self, enabled):
        """pid_enable: while False every command is HOVER; disabling forgets the held efforts."""
        self.enabled = bool(enabled)
        if not self.enabled:
            for field in COMMAND_LOOPS:
                self.values[field] = None
                self.times[field] = None

    def command(self, t):
        """(cmd, None) or (HOVER, reason) at time t; cmd = (roll, pitch, yaw_rate, gaz)."""
        self.commands += 1
        reason = self._reason(t)
        self.last_reason = reason
        if reason is not None:
            self.hovers += 1
            return HOVER, reason
        return tuple(self.values[f] for f in COMMAND_LOOPS), None

    def _reason(self, t):
        if not self.enabled:
            return DISABLED
        for field, loop in COMMAND_LOOPS.items():
            value, stamp = self.values[field], self.times[field]
            if value is None:
                return '%s %s' % (NO_EFFORT, loop)
            if value is False:
                return '%s %s' % (BAD_EFFORT, loop)
            age = t - stamp
            if age > self.effort_timeout or age < 0.0:
                return '%s %s' % (STALE_EFFORT, loop)
        return None
