"""Stage: controllers -> piloting command. The one controller contract (pure core, no ROS).

Like mav_control_rw's position-controller interface, every tracking controller (the MPC of
``mpc_tracking.MpcTracking``, the single-process PID framework of ``pid_framework.PidTracking``, the ones to
come) is a ``Controller``:

* ``on_state(t, position, orientation, twist_linear)``: a nav_msgs/Odometry sample received at time ``t``
  [s, the caller's clock = ROS time in the node]: position [m] world ENU, orientation quaternion
  (x, y, z, w), linear twist [m/s] in the child (body, FLU) frame (``twist_frame='world'``: world ENU).
  Returns False when the sample is refused (non-finite, malformed, not a rotation).
* ``on_waypoint(t, waypoint)``: the paper's waypoint (x, y, z [m], v_x, v_y, v_z [m/s] ENU, yaw [deg]
  world). Returns False when refused.
* ``cycle(t) -> CycleOutput(command, ok, reason, key, result)``, called every 1/``RATE`` s: ``command`` =
  (roll [deg], pitch [deg], yaw rate [deg/s], gaz [m/s]) in the olympe_bridge/PilotingCommand convention
  (+roll = right, +pitch = nose down, +yaw rate = CCW, +gaz = up); ``ok`` False -> ``command`` is
  ``HOVER`` and ``key`` (one of ``HOVER_KEYS``) / ``reason`` (``MESSAGES[key]`` plus details) say why;
  ``result`` is the implementation's detail (MpcResult, RelativeState) or None. A cycle never raises.
  ``ok`` True may still carry HOVER while an implementation warms up (a PID loop's first computation).
  ``COMMAND_RATE`` (None = every cycle) is the rate at which the node sends ``last.command``.
* ``health()``: level (``LEVEL_*`` = diagnostic_msgs levels), message and values (counters) of the last cycle.

Input gate (``InputGate``, the one rule set, also used by the distributed PID relative-state node): the
latest state and waypoint with their receipt times; a cycle hovers with the first key that applies, in
this order: bad_state (the last state sample refused, or a non-finite cycle time), no_state (none yet),
stale_state (older than ``state_timeout`` [s]), bad_waypoint, no_waypoint, stale_waypoint (older than
``waypoint_timeout`` [s]; 0 = a waypoint never goes stale); clock_jump: a time (sample or cycle) more than
``state_timeout`` before the newest time seen (a simulation restart) drops both held inputs (counted), and
the cycles say clock_jump until each input has arrived again. A time slightly before the newest one (a
callback that won the lock after the cycle read the clock) is normal. Counters: ``COUNTER_NAMES``.

Hover cycles reset the implementation's internal state (``_hover``; nothing latches): the next good cycle
computes a command again.
"""
import collections
import math

from anafi_control.frames import TWIST_FRAMES, is_finite, odometry_to_world

#: the hover command (all zero, as the paper's code published)
HOVER = (0.0, 0.0, 0.0, 0.0)

OK = 'ok'
NO_STATE, NO_WAYPOINT = 'no_state', 'no_waypoint'
BAD_STATE, BAD_WAYPOINT = 'bad_state', 'bad_waypoint'
STALE_STATE, STALE_WAYPOINT = 'stale_state', 'stale_waypoint'
CLOCK_JUMP = 'clock_jump'
SOLVER_FAILED, BAD_OUTPUT = 'solver_failed', 'bad_output'

#: reason key -> message (the diagnostics' words; details may follow in parentheses or after a colon)
MESSAGES = collections.OrderedDict([
    (NO_STATE, 'no state received yet'),
    (NO_WAYPOINT, 'no waypoint received yet'),
    (BAD_STATE, 'non-finite state'),
    (BAD_WAYPOINT, 'non-finite waypoint'),
    (STALE_STATE, 'stale state'),
    (STALE_WAYPOINT, 'stale waypoint'),
    (CLOCK_JUMP, 'clock jumped back, inputs dropped'),
    (SOLVER_FAILED, 'solver'),
    (BAD_OUTPUT, 'non-finite output'),
])
HOVER_KEYS = tuple(MESSAGES)

#: keys of a controller that waits for its inputs (normal before the experiment starts)
WAITING = (NO_STATE, NO_WAYPOINT)

#: counters of the gate (samples) and of the cycles (totals and one per hover key)
COUNTER_NAMES = ('cycles', OK, 'hover') + HOVER_KEYS + (
    'states', 'waypoints', 'rejected_states', 'rejected_waypoints', 'clock_jumps')

CycleOutput = collections.namedtuple('CycleOutput', ['command', 'ok', 'reason', 'key', 'result'])
CycleOutput.__doc__ = ('One cycle: command (roll deg, pitch deg, yaw rate deg/s, gaz m/s); ok False -> command is '
                       'HOVER and reason/key say why; result = the implementation\'s detail or None.')

Inputs = collections.namedtuple('Inputs', ['pos', 'vel', 'yaw', 'waypoint'])
Inputs.__doc__ = ('Drone position [m], world velocity [m/s] (ENU tuples), heading [rad], waypoint '
                  '(x, y, z, vx, vy, vz, yaw_deg).')


def hover_output(key, detail=None, result=None):
    """CycleOutput of a hover cycle for reason ``key`` (``detail`` appended to the message)."""
    reason = MESSAGES[key] if detail is None else '%s%s' % (MESSAGES[key], detail)
    return CycleOutput(HOVER, False, reason, key, result)


#: health levels (the values of diagnostic_msgs/DiagnosticStatus, as every core's Health uses them)
LEVEL_OK, LEVEL_WARN, LEVEL_ERROR = 0, 1, 2

Health = collections.namedtuple('Health', 'level message values')
Health.__doc__ = 'Health of a controller: level (LEVEL_*), message, values [(key, value)].'


def health(key, reason, values=()):
    """Health of a controller whose last cycle had ``key``/``reason``: OK tracking or waiting for the first
    waypoint, WARN hovering for missing or bad input, ERROR the controller itself failed."""
    if key == OK:
        return Health(LEVEL_OK, 'tracking', list(values))
    message = 'hovering: %s' % reason
    if key == NO_WAYPOINT:
        level = LEVEL_OK
    elif key in (SOLVER_FAILED, BAD_OUTPUT):
        level = LEVEL_ERROR
    else:
        level = LEVEL_WARN
    return Health(level, message, list(values))


def check_timeout(name, value, allow_zero=False):
    """A timeout parameter [s]: finite and > 0 (or == 0 with allow_zero: 'never stale'); ValueError else."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or value < 0.0 or (value == 0.0 and not allow_zero):
        raise ValueError('%s must be a finite number %s 0 [s], got %r'
                         % (name, '>=' if allow_zero else '>', value))
    return float(value)


class _Held(object):
    """One gated input: the last good value and its receipt time, or why there is none."""
    __slots__ = ('value', 'time', 'missing')

    def __init__(self):
        self.value = self.time = None
        self.missing = None      # None (value usable), or the key to hover with: no_*, bad_*, clock_jump

    def set(self, t, value, bad_key):
        self.time = t
        self.value = value
        self.missing = bad_key if value is None else None
        return value is not None

    def drop(self):
        self.value = self.time = None
        self.missing = CLOCK_JUMP


class InputGate(object):
    """The latest state and waypoint; ``check(t)`` says whether a cycle may run (see the module doc).

    ``state_timeout`` [s] > 0 (also the clock-jump tolerance); ``waypoint_timeout`` [s] >= 0, 0 = a
    waypoint never goes stale; ``twist_frame`` of the odometry twist ('child' or 'world');
    ``extra_counters``: more counter names for the owner; ``on_clock_jump()`` is called after a jump.
    """

    def __init__(self, state_timeout=0.5, waypoint_timeout=1.0, twist_frame='child', extra_counters=(),
                 on_clock_jump=None):
        self.state_timeout = check_timeout('state_timeout', state_timeout)
        self.waypoint_timeout = check_timeout('waypoint_timeout', waypoint_timeout, allow_zero=True)
        if twist_frame not in TWIST_FRAMES:
            raise ValueError('twist_frame must be one of %s, got %r' % (', '.join(TWIST_FRAMES), twist_frame))
        self.twist_frame = twist_frame
        self.counters = collections.OrderedDict((name, 0) for name in COUNTER_NAMES + tuple(extra_counters))
        self.on_clock_jump = on_clock_jump
        self.state = _Held()         # value: (pos, vel, yaw) with pos, vel tuples [m], [m/s] and yaw [rad]
        self.state.missing = NO_STATE
        self.waypoint = _Held()      # value: 7-tuple of floats
        self.waypoint.missing = NO_WAYPOINT
        self.newest = None           # newest time seen [s]
        self.jump = 0.0              # [s] size of the last clock jump

    # -- inputs -----------------------------------------------------------------------------
    def on_state(self, t, position, orientation, twist_linear):
        """A state sample (Odometry numbers) received at ``t``; False if refused."""
        self.counters['states'] += 1
        odo = odometry_to_world(position, orientation, twist_linear, self.twist_frame)
        value = None
        if odo is not None and self._clock(t):
            pos, vel, rpy = odo
            value = (pos, vel, rpy[2])
        if value is None:
            self.counters['rejected_states'] += 1
        return self.state.set(t, value, BAD_STATE)

    def on_waypoint(self, t, waypoint):
        """A waypoint (x, y, z, vx, vy, vz, yaw_deg) received at ``t``; False if refused."""
        self.counters['waypoints'] += 1
        try:
            wp = tuple(float(v) for v in waypoint)
        except (TypeError, ValueError):
            wp = ()
        value = wp if len(wp) == 7 and is_finite(*wp) and self._clock(t) else None
        if value is None:
            self.counters['rejected_waypoints'] += 1
        return self.waypoint.set(t, value, BAD_WAYPOINT)

    def _clock(self, t):
        """False for a non-finite time; drops the held inputs when ``t`` jumped back (see the module doc)."""
        if not is_finite(t):
            return False
        if self.newest is not None and t < self.newest - self.state_timeout:
            self.jump = self.newest - t
            self.counters['clock_jumps'] += 1
            self.state.drop()
            self.waypoint.drop()
            self.newest = t
            if self.on_clock_jump is not None:
                self.on_clock_jump()
        elif self.newest is None or t > self.newest:
            self.newest = t
        return True

    # -- cycle ------------------------------------------------------------------------------
    def fresh_waypoint(self, t):
        """The held waypoint when usable and not stale at ``t``, else None."""
        w = self.waypoint
        if w.missing is not None or (self.waypoint_timeout > 0.0 and t - w.time > self.waypoint_timeout):
            return None
        return w.value

    def check(self, t):
        """(Inputs, 'ok', 'ok') when a cycle may run at time ``t``, else (None, key, reason) -> hover."""
        key, detail = self._reason(t)
        if key is not None:
            return None, key, hover_output(key, detail).reason
        (pos, vel, yaw), wp = self.state.value, self.waypoint.value
        return Inputs(pos, vel, yaw, wp), OK, OK

    def _reason(self, t):
        if not self._clock(t):
            return BAD_STATE, ' (non-finite time)'
        if self.state.missing is not None:
            return self.state.missing, self._jump_detail(self.state.missing)
        age = t - self.state.time
        if age > self.state_timeout:
            return STALE_STATE, ' (%.2f s old > %.2f s)' % (age, self.state_timeout)
        if self.waypoint.missing is not None:
            return self.waypoint.missing, self._jump_detail(self.waypoint.missing)
        age = t - self.waypoint.time
        if self.waypoint_timeout > 0.0 and age > self.waypoint_timeout:
            return STALE_WAYPOINT, ' (%.2f s old > %.2f s)' % (age, self.waypoint_timeout)
        return None, None

    def _jump_detail(self, key):
        return ' (by %.2f s; waiting for fresh inputs)' % self.jump if key == CLOCK_JUMP else None

    def count_cycle(self, key):
        """Count one cycle that ended with ``key`` ('ok' or a hover key)."""
        self.counters['cycles'] += 1
        if key == OK:
            self.counters[OK] += 1
        else:
            self.counters['hover'] += 1
            self.counters[key] += 1


class Controller(object):
    """Base of every tracking controller (see the module doc). Subclasses implement ``_compute(t, inputs)``
    -> CycleOutput (called only with gated, finite inputs) and may override the hooks ``_state_received(t)``,
    ``_hover(out)`` (reset internal state on a hover cycle) and ``_clock_jumped()``.

    Class attributes: ``NAME`` (registry key of the node's ~controller), ``RATE`` [Hz] of ``cycle``,
    ``COMMAND_RATE`` [Hz] of the command output (None: every cycle), ``COUNTERS`` extra counter names.
    """
    NAME = None
    RATE = 10.0
    COMMAND_RATE = None
    COUNTERS = ()

    def __init__(self, state_timeout=0.5, waypoint_timeout=1.0, twist_frame='child'):
        self.gate = InputGate(state_timeout, waypoint_timeout, twist_frame, self.COUNTERS, self._clock_jumped)
        self.counters = self.gate.counters
        self.last = hover_output(NO_STATE, ' (no cycle yet)')

    def on_state(self, t, position, orientation, twist_linear):
        """Store an odometry sample received at ``t`` [s]; False if refused."""
        if not self.gate.on_state(t, position, orientation, twist_linear):
            return False
        self._state_received(float(t))
        return True

    def on_waypoint(self, t, waypoint):
        """Store a waypoint (x, y, z, vx, vy, vz, yaw_deg) received at ``t`` [s]; False if refused."""
        return self.gate.on_waypoint(t, waypoint)

    def cycle(self, t):
        """One cycle at time ``t`` [s]: CycleOutput (never raises on bad input)."""
        inputs, key, reason = self.gate.check(t)
        if inputs is None:
            out = CycleOutput(HOVER, False, reason, key, None)
        else:
            out = self._compute(float(t), inputs)
            if out.ok and not is_finite(*out.command):
                out = hover_output(BAD_OUTPUT, result=out.result)
        self.gate.count_cycle(out.key)
        if not out.ok:
            self._hover(out)
        self.last = out
        return out

    def health(self):
        """Health of the last cycle, with the last reason and the counters as values."""
        return health(self.last.key, self.last.reason,
                      [('last_reason', self.last.reason)] + list(self.counters.items()))

    # -- hooks ------------------------------------------------------------------------------
    def _compute(self, t, inputs):
        raise NotImplementedError

    def _state_received(self, t):
        """A good state arrived at ``t`` (the gate holds it)."""

    def _hover(self, out):
        """A hover cycle: forget internal state so that nothing stale is carried over."""

    def _clock_jumped(self):
        """The clock jumped back (the gate dropped both inputs)."""
