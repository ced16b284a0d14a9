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
  (+roll = right, +pitch = nose down, +yaw rate = CCW, +gaz = up), or None = send nothing. ``ok`` False ->
  ``key`` (one of ``HOVER_KEYS``) / ``reason`` (``MESSAGES[key]`` plus details) say why, and the command is
  the failsafe of that key (``failsafe(key)``, docs/reliability.md):

  - ``HOLD`` (the waypoint is bad, missing after tracking or stale; the state is good): the controller
    holds the position where the hold began with its own loop (the held waypoint is replaced by that point
    with zero velocity and the heading of that moment, moved into the geofence), i.e. it brakes actively
    and stays there;
  - ``SILENT`` (no / bad / stale state, a clock jump, no waypoint yet, the controller itself failed):
    ``command`` is None and the node publishes nothing, so the firmware's own hover brake stops the drone
    and holds it (the real firmware does so when no PCMD arrives; an all-zero PCMD would only level the
    drone and let it coast).

  ``ok`` True with ``key`` 'limiting' (``LIMITING``): the cycle tracked, but a limit of the flight envelope
  acted (``reason`` says which); the health is WARN 'limiting: <reason>', never 'tracking'.
  ``result`` is the implementation's detail (MpcResult, RelativeState) or None. A cycle never raises.
  ``ok`` True may still carry None while an implementation warms up (a PID loop's first computation).
  ``COMMAND_RATE`` (None = every cycle) is the rate at which the node sends ``last.command`` (not None).
* ``on_reference(t, samples)`` (optional, ``PREVIEW`` True): the upcoming reference over the horizon
  (``ReferenceSample``s); the default ignores it, so controllers without a preview are unchanged.
* ``health()``: level (``LEVEL_*`` = diagnostic_msgs levels), message and values (counters) of the last cycle.

Input gate (``InputGate``, the one rule set, also used by the distributed PID relative-state node): the
latest state and waypoint with their receipt times; a cycle hovers with the first key that applies, in
this order: bad_state (the last state sample refused, or a non-finite cycle time), no_state (none yet),
stale_state (older than ``state_timeout`` [s]), bad_waypoint (non-finite or malformed), no_waypoint, stale_waypoint
(older than ``waypoint_timeout`` [s]; 0 = a waypoint never goes stale); clock_jump: a time (sample or cycle) more than
``state_timeout`` before the newest time seen (a simulation restart) drops both held inputs (counted), and
the cycles say clock_jump until each input has arrived again. A time slightly before the newest one (a
callback that won the lock after the cycle read the clock) is normal. Counters: ``COUNTER_NAMES``.

Flight envelope (``anafi_control.envelope``, the gate's ``envelope``, built from the ``LIMIT_DEFAULTS`` keys):
every cycle the gate limits the held waypoint as the target (into the geofence around the first state
received, within reach of the drone, the reference speeds, outward velocity braked before the fence); the
hold point is moved into the fence; ``Controller.cycle`` clips the command's tilt and gaz; the preview MPC
limits its preview. Any limit acting makes the cycle 'limiting'.

Every silent cycle and every change of mode from tracking or holding resets the implementation's internal
state (``_hover``; nothing latches): the next good cycle computes a command again. The name "hover" stays
in the counters (``hover`` = cycles that did not track) for compatibility.
"""
import collections
import math

from anafi_control.envelope import ENVELOPE_DEFAULTS, LIMITS, Envelope, reason as envelope_reason
from anafi_control.frames import TWIST_FRAMES, is_finite, odometry_to_world

#: the all-zero command the paper's code published as "hover" (NOT a stop: the drone levels and coasts).
#: No cycle sends it any more; kept for the PID framework's warm-up value and for comparisons.
HOVER = (0.0, 0.0, 0.0, 0.0)

OK = 'ok'
NO_STATE, NO_WAYPOINT = 'no_state', 'no_waypoint'
BAD_STATE, BAD_WAYPOINT = 'bad_state', 'bad_waypoint'
STALE_STATE, STALE_WAYPOINT = 'stale_state', 'stale_waypoint'
CLOCK_JUMP = 'clock_jump'
SOLVER_FAILED, BAD_OUTPUT = 'solver_failed', 'bad_output'
#: a tracking cycle in which a limit of the flight envelope acted (anafi_control.envelope): the command is
#: computed for the limited target and sent (ok True); health WARN 'limiting: <what acted>'
LIMITING = 'limiting'
#: the keys of a tracking cycle
TRACKING = (OK, LIMITING)

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

#: failsafes: HOLD = hold the position with the controller's own loop; SILENT = send no command (the
#: firmware's hover brake stops and holds the drone)
HOLD, SILENT = 'hold', 'silent'
#: keys whose failsafe is HOLD (the state is good, the waypoint is not usable); every other key is SILENT
HOLD_KEYS = (BAD_WAYPOINT, STALE_WAYPOINT)


def failsafe(key):
    """HOLD or SILENT for a hover key (None for a tracking key: 'ok', 'limiting')."""
    if key in TRACKING:
        return None
    return HOLD if key in HOLD_KEYS else SILENT

#: counters of the gate (samples) and of the cycles (totals and one per hover key)
#: (``ok`` counts every tracking cycle, ``limiting`` those in which a limit acted, ``limited_<limit>`` the
#: cycles in which that limit of ``envelope.LIMITS`` acted)
COUNTER_NAMES = ('cycles', OK, LIMITING, 'hover', HOLD, SILENT) + HOVER_KEYS + (
    'states', 'waypoints', 'rejected_states', 'rejected_waypoints', 'clock_jumps', 'holds') + tuple(
    'limited_%s' % name for name in LIMITS)

CycleOutput = collections.namedtuple('CycleOutput', ['command', 'ok', 'reason', 'key', 'result'])
CycleOutput.__doc__ = ('One cycle: command (roll deg, pitch deg, yaw rate deg/s, gaz m/s) or None (send nothing); '
                       'ok False -> key/reason say why and command is the failsafe (hold command or None); '
                       'result = the implementation\'s detail or None.')

ReferenceSample = collections.namedtuple('ReferenceSample', ['t', 'position', 'velocity', 'acceleration', 'yaw'])
ReferenceSample.__doc__ = ('One sample of a reference preview: time t [s], position [m], velocity [m/s], '
                           'acceleration [m/s^2] (world ENU 3-tuples), yaw [deg] world.')

Inputs = collections.namedtuple('Inputs', ['pos', 'vel', 'yaw', 'waypoint'])
Inputs.__doc__ = ('Drone position [m], world velocity [m/s] (ENU tuples), heading [rad], waypoint '
                  '(x, y, z, vx, vy, vz, yaw_deg).')


def hover_output(key, detail=None, result=None, command=None):
    """CycleOutput of a cycle that does not track, for reason ``key`` (``detail`` appended to the message);
    ``command`` None = send nothing (SILENT), else the hold command."""
    reason = MESSAGES[key] if detail is None else '%s%s' % (MESSAGES[key], detail)
    return CycleOutput(command, False, reason, key, result)


#: health levels (the values of diagnostic_msgs/DiagnosticStatus, as every core's Health uses them)
LEVEL_OK, LEVEL_WARN, LEVEL_ERROR = 0, 1, 2

Health = collections.namedtuple('Health', 'level message values')
Health.__doc__ = 'Health of a controller: level (LEVEL_*), message, values [(key, value)].'


def health(key, reason, values=()):
    """Health of a controller whose last cycle had ``key``/``reason``: OK tracking or waiting for the first
    waypoint, WARN limiting (a limit of the flight envelope acted), holding or silent for missing or bad
    input, ERROR the controller itself failed. The message names the failsafe: 'holding position: <reason>'
    (HOLD) or 'no command, firmware hover brake: <reason>' (SILENT); 'limiting: <reason>' while limited."""
    if key == OK:
        return Health(LEVEL_OK, 'tracking', list(values))
    if key == LIMITING:
        return Health(LEVEL_WARN, 'limiting: %s' % reason, list(values))
    if failsafe(key) == HOLD:
        message = 'holding position: %s' % reason
    else:
        message = 'no command, firmware hover brake: %s' % reason
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


#: defaults of the input gate's timeouts [s], every controller's (its YAML can set others): state older than
#: state_timeout -> SILENT (> 0), waypoint older than waypoint_timeout -> HOLD (>= 0; 0 = never stale)
TIMEOUT_DEFAULTS = collections.OrderedDict([('state_timeout', 0.5), ('waypoint_timeout', 1.0)])

#: defaults of the flight envelope (= the controller YAMLs' section "flight envelope"; anafi_control.envelope)
LIMIT_DEFAULTS = ENVELOPE_DEFAULTS



#: keys of a controller's YAML that are the node's wiring, not its core's parameters (``from_config`` leaves them)
NODE_KEYS = ('rate', 'command_rate', 'state_topic', 'waypoint_topic', 'waypoint_type', 'command_topic', 'frame_id',
             'reference_topic', 'model_file', 'timer_phase', 'stall_timeout', 'controller')


def envelope_from_config(config):
    """The flight envelope (``Envelope``) of a controller's flat parameters (the ``LIMIT_DEFAULTS`` keys)."""
    return Envelope(**dict((k, config.get(k, v)) for k, v in LIMIT_DEFAULTS.items()))


STALL_TIMEOUT = 3.0
"""Default [s of wall time] after which a node whose cycles stopped (e.g. /clock stopped) reports ``stalled``."""


def stalled(health_, idle, timeout=STALL_TIMEOUT):
    """``health_`` of a controller whose last cycle ran ``idle`` s of wall time ago: WARN 'stalled: no cycle for
    <idle> s (ROS time stopped?); last: <message>' beyond ``timeout`` [s], else unchanged."""
    if idle is None or not idle > timeout:
        return health_
    return health_._replace(level=max(health_.level, LEVEL_WARN),
                            message='stalled: no controller cycle for %.1f s of wall time (ROS time stopped?); '
                                    'last: %s' % (idle, health_.message))


class _Held(object):
    """One gated input: the last good value and its receipt time, or why there is none."""
    __slots__ = ('value', 'time', 'missing', 'detail')

    def __init__(self):
        self.value = self.time = self.detail = None
        self.missing = None      # None (value usable), or the key to hover with: no_*, bad_*, clock_jump

    def set(self, t, value, bad_key, detail=None):
        self.time = t
        self.value = value
        self.missing = bad_key if value is None else None
        self.detail = detail if value is None else None
        return value is not None

    def drop(self):
        self.value = self.time = self.detail = None
        self.missing = CLOCK_JUMP


class InputGate(object):
    """The latest state and waypoint; ``check(t)`` says whether a cycle may run (see the module doc).

    ``state_timeout`` [s] > 0 (also the clock-jump tolerance); ``waypoint_timeout`` [s] >= 0, 0 = a
    waypoint never goes stale; ``twist_frame`` of the odometry twist ('child' or 'world');
    ``extra_counters``: more counter names for the owner; ``on_clock_jump()`` is called after a jump;
    ``limits``: the flight envelope (``envelope.Envelope``; None: the defaults), kept as ``envelope``.

    ``check(t)`` returns the inputs of a cycle: the held ones when tracking, with the waypoint limited by the
    envelope (key 'limiting' when a limit acted: ``acting`` holds the notes of the cycle), the hold point
    (``hold``: position and heading of the drone at the first cycle of a hold, zero velocity, moved into the
    fence) in place of the waypoint for a HOLD key, None for a SILENT key.
    """

    def __init__(self, state_timeout=TIMEOUT_DEFAULTS['state_timeout'],
                 waypoint_timeout=TIMEOUT_DEFAULTS['waypoint_timeout'], twist_frame='child', extra_counters=(),
                 on_clock_jump=None, limits=None):
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
        self.envelope = Envelope() if limits is None else limits
        if not isinstance(self.envelope, Envelope):
            raise ValueError('limits must be an envelope.Envelope, got %r' % (limits,))
        self.acting = []             # notes [(limit, text)] of the limits that acted in this cycle
        self.centre = None           # (x, y) [m] of the geofence: the first good state's position
        self.hold = None             # hold waypoint (x, y, z, 0, 0, 0, yaw_deg) while holding, else None

    # -- inputs -----------------------------------------------------------------------------
    def on_state(self, t, position, orientation, twist_linear):
        """A state sample (Odometry numbers) received at ``t``; False if refused."""
        self.counters['states'] += 1
        odo = odometry_to_world(position, orientation, twist_linear, self.twist_frame)
        value = None
        if odo is not None and self._clock(t):
            pos, vel, rpy = odo
            value = (pos, vel, rpy[2])
            if self.centre is None:
                self.centre = (pos[0], pos[1])
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
        """(Inputs, 'ok', 'ok') when a cycle may track at time ``t``; (Inputs with the hold point as waypoint,
        key, reason) for a HOLD key; (None, key, reason) for a SILENT key (see the class doc)."""
        self.acting = []
        key, detail = self._reason(t)
        if key is None:
            self.hold = None
            (pos, vel, yaw), wp = self.state.value, self.waypoint.value
            target, notes = self.envelope.limit_waypoint(wp, self.centre, pos)
            self.note(notes)
            if notes:
                return Inputs(pos, vel, yaw, target), LIMITING, envelope_reason(notes)
            return Inputs(pos, vel, yaw, wp), OK, OK
        reason = hover_output(key, detail).reason
        if failsafe(key) != HOLD:
            self.hold = None
            return None, key, reason
        pos, vel, yaw = self.state.value
        if self.hold is None:
            here = (pos[0], pos[1], pos[2], 0.0, 0.0, 0.0, math.degrees(yaw))
            self.hold, notes = self.envelope.limit_waypoint(here, self.centre, None)
            self.note(notes)
            self.counters['holds'] += 1
        return Inputs(pos, vel, yaw, self.hold), key, reason

    def note(self, notes):
        """Record the notes [(limit, text)] of envelope limits that acted in this cycle (counted)."""
        for name, _ in notes:
            if not any(name == n for n, _ in self.acting):
                self.counters['limited_%s' % name] += 1
        self.acting.extend(notes)

    def _reason(self, t):
        if not self._clock(t):
            return BAD_STATE, ' (non-finite time)'
        if self.state.missing is not None:
            return self.state.missing, self._jump_detail(self.state.missing)
        age = t - self.state.time
        if age > self.state_timeout:
            return STALE_STATE, ' (%.2f s old > %.2f s)' % (age, self.state_timeout)
        if self.waypoint.missing is not None:
            return self.waypoint.missing, self._jump_detail(self.waypoint.missing) or self.waypoint.detail
        age = t - self.waypoint.time
        if self.waypoint_timeout > 0.0 and age > self.waypoint_timeout:
            return STALE_WAYPOINT, ' (%.2f s old > %.2f s)' % (age, self.waypoint_timeout)
        return None, None

    def _jump_detail(self, key):
        return ' (by %.2f s; waiting for fresh inputs)' % self.jump if key == CLOCK_JUMP else None

    def count_cycle(self, key):
        """Count one cycle that ended with ``key`` ('ok' or a hover key; 'hover' and its failsafe too)."""
        self.counters['cycles'] += 1
        if key in TRACKING:
            self.counters[OK] += 1
            self.counters[LIMITING] += key == LIMITING
        else:
            self.counters['hover'] += 1
            self.counters[key] += 1
            self.counters[failsafe(key)] += 1


class Controller(object):
    """Base of every tracking controller (see the module doc). Subclasses implement ``_compute(t, inputs)``
    -> CycleOutput (called only with gated, finite inputs) and may override the hooks ``_state_received(t)``,
    ``_hover(out)`` (reset internal state on a hover cycle) and ``_clock_jumped()``.

    Class attributes: ``NAME`` (its usual name in ``anafi_control.registry``), ``RATE`` [Hz] of ``cycle``,
    ``COMMAND_RATE`` [Hz] of the command output (None: every cycle), ``COUNTERS`` extra counter names.
    """
    NAME = None
    RATE = 10.0
    COMMAND_RATE = None
    COUNTERS = ()
    #: True: the controller tracks a reference preview (``on_reference``); the node / engine then subscribes
    #: to the trajectory generator's preview (trajectory_msgs/MultiDOFJointTrajectory, command/trajectory)
    PREVIEW = False

    #: the keys of its YAML (anafi_sim/config/, anafi_control.registry) that ``from_config`` reads
    CONFIG_KEYS = tuple(TIMEOUT_DEFAULTS) + tuple(LIMIT_DEFAULTS)

    @classmethod
    def from_config(cls, config, limits=None):
        """The controller from its parameters: a flat mapping of its YAML's keys, as the node's ~params have
        them or as the in-process engine reads the file (the one reader for both; other keys, e.g. topics,
        are left to the node). ``limits``: the flight envelope (default: from the ``LIMIT_DEFAULTS`` keys).
        A controller with more parameters overrides it (and ``CONFIG_KEYS``)."""
        return cls(state_timeout=config.get('state_timeout', TIMEOUT_DEFAULTS['state_timeout']),
                   waypoint_timeout=config.get('waypoint_timeout', TIMEOUT_DEFAULTS['waypoint_timeout']),
                   limits=envelope_from_config(config) if limits is None else limits)

    def __init__(self, state_timeout=TIMEOUT_DEFAULTS['state_timeout'],
                 waypoint_timeout=TIMEOUT_DEFAULTS['waypoint_timeout'], twist_frame='child', limits=None):
        self.gate = InputGate(state_timeout, waypoint_timeout, twist_frame, self.COUNTERS, self._clock_jumped,
                              limits)
        self.counters = self.gate.counters
        self.last = hover_output(NO_STATE, ' (no cycle yet)')
        self.mode = SILENT          # OK (tracking), HOLD or SILENT: the last cycle's

    def on_state(self, t, position, orientation, twist_linear):
        """Store an odometry sample received at ``t`` [s]; False if refused."""
        if not self.gate.on_state(t, position, orientation, twist_linear):
            return False
        self._state_received(float(t))
        return True

    def on_waypoint(self, t, waypoint):
        """Store a waypoint (x, y, z, vx, vy, vz, yaw_deg) received at ``t`` [s]; False if refused."""
        return self.gate.on_waypoint(t, waypoint)

    def on_reference(self, t, samples):
        """Optional hook: the upcoming reference received at ``t`` [s], a sequence of ``ReferenceSample``
        (time [s], position [m], velocity [m/s], acceleration [m/s^2] world ENU, yaw [deg]). The default
        ignores it and returns False (controllers without a preview: PREVIEW False); True when taken."""
        return False

    def cycle(self, t):
        """One cycle at time ``t`` [s]: CycleOutput (never raises on bad input); see the module doc."""
        inputs, key, reason = self.gate.check(t)
        mode = OK if key in TRACKING else failsafe(key)
        if mode == SILENT or (mode != self.mode and self.mode != SILENT):
            self._hover(None)        # a new mode starts from a clean state (a silent cycle already reset it)
        self.mode = mode
        if inputs is None:
            out = CycleOutput(None, False, reason, key, None)
        else:
            out = self._compute(float(t), inputs)
            if out.ok and out.command is not None and not is_finite(*out.command):
                out = hover_output(BAD_OUTPUT, result=out.result)
            if out.ok:
                command, notes = self.gate.envelope.limit_command(out.command)
                self.gate.note(notes)
                if mode == OK:       # tracking: 'limiting' when a limit acted (target, preview or command)
                    acting = self.gate.acting
                    key, reason = (LIMITING, envelope_reason(acting)) if acting else (OK, OK)
                    out = CycleOutput(command, True, reason, key, out.result)
                else:                # holding: the command of the hold point, under the hold's key
                    out = CycleOutput(command, False, reason, key, out.result)
        if out.key != key:               # the controller failed (tracking or holding): silent
            self.mode = SILENT
            self._hover(out)
        self.gate.count_cycle(out.key)
        self.last = out
        return out

    def reset(self):
        """Forget internal state as a silent cycle does (the node stood down, e.g. for a second commander);
        the next cycle starts clean."""
        self.mode = SILENT
        self._hover(None)

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
        """A new mode or a silent cycle: forget internal state so that nothing stale is carried over
        (``out`` is the failed CycleOutput when the controller itself failed, else None)."""

    def _clock_jumped(self):
        """The clock jumped back (the gate dropped both inputs)."""
