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
* The relative-state node gates its inputs with the controller contract's
  ``anafi_control.contract.InputGate`` (the same rules as every controller).
* ``CommandAssembler``: last effort of each command loop with its time;
  ``command(t)`` = PilotingCommand tuple (roll, pitch [deg], yaw rate
  [deg/s], gaz [m/s]) or None (send nothing: the firmware's hover brake
  stops the drone; an all-zero command would let it coast) with the reason.

Times are seconds on the caller's clock (ROS time in the nodes).
"""
import collections

from anafi_control.contract import check_timeout
from anafi_control.frames import is_finite
from anafi_control.pid_framework import LOOP_NAMES

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


# -- command assembly ---------------------------------------------------------------------
NO_EFFORT = 'no effort yet from'
STALE_EFFORT = 'stale effort from'
BAD_EFFORT = 'non-finite effort from'
DISABLED = 'pid disabled'


class CommandAssembler(object):
    """Latest effort per command loop -> PilotingCommand tuple, or None (no command) with the reason.

    None when the framework is disabled (pid_enable false), or any of the
    four efforts is missing, older than ``effort_timeout`` [s] or non-finite.
    Counts those periods (``hovers``) and refused efforts (``bad_efforts``).
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
        """pid_enable: while False every command is None; disabling forgets the held efforts."""
        self.enabled = bool(enabled)
        if not self.enabled:
            for field in COMMAND_LOOPS:
                self.values[field] = None
                self.times[field] = None

    def command(self, t):
        """(cmd, None) or (None, reason) at time t; cmd = (roll, pitch, yaw_rate, gaz)."""
        self.commands += 1
        reason = self._reason(t)
        self.last_reason = reason
        if reason is not None:
            self.hovers += 1
            return None, reason
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
