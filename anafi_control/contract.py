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

  - ``HOLD`` (the waypoint is bad, missing after tracking, stale, outside the geofence or jumped too far;
    the state is good): the controller holds the position where the hold began with its own loop (the
    held waypoint is replaced by that point with zero velocity and the heading of that moment), i.e. it
    brakes actively and stays there;
  - ``SILENT`` (no / bad / stale state, a clock jump, no waypoint yet, the controller itself failed):
    ``command`` is None and the node publishes nothing, so the firmware's own hover brake stops the drone
    and holds it (the real firmware does so when no PCMD arrives; an all-zero PCMD would only level the
    drone and let it coast).

  ``result`` is the implementation's detail (MpcResult, RelativeState) or None. A cycle never raises.
  ``ok`` True may still carry None while an implementation warms up (a PID loop's first computation).
  ``COMMAND_RATE`` (None = every cycle) is the rate at which the node sends ``last.command`` (not None).
* ``on_reference(t, samples)`` (optional, ``PREVIEW`` True): the upcoming reference over the horizon
  (``ReferenceSample``s); the default ignores it, so controllers without a preview are unchanged.
* ``health()``: level (``LEVEL_*`` = diagnostic_msgs levels), message and values (counters) of the last cycle.

Input gate (``InputGate``, the one rule set, also used by the distributed PID relative-state node): the
latest state and waypoint with their receipt times; a cycle hovers with the first key that applies, in
this order: bad_state (the last state sample refused, or a non-finite cycle time), no_state (none yet),
stale_state (older than ``state_timeout`` [s]), bad_waypoint (non-finite or malformed), geofence (outside the
cylinder of ``WaypointLimits.geofence_radius`` around the first state received, or outside the altitude band),
waypoint_jump (farther than ``WaypointLimits.max_waypoint_jump`` from the drone), no_waypoint, stale_waypoint
(older than ``waypoint_timeout`` [s]; 0 = a waypoint never goes stale); clock_jump: a time (sample or cycle) more than
``state_timeout`` before the newest time seen (a simulation restart) drops both held inputs (counted), and
the cycles say clock_jump until each input has arrived again. A time slightly before the newest one (a
callback that won the lock after the cycle read the clock) is normal. Counters: ``COUNTER_NAMES``.

Every silent cycle and every change of mode from tracking or holding resets the implementation's internal
state (``_hover``; nothing latches): the next good cycle computes a command again. The name "hover" stays
in the counters (``hover`` = cycles that did not track) for compatibility.
"""
import collections
import math

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
GEOFENCE, WAYPOINT_JUMP = 'geofence', 'waypoint_jump'

#: reason key -> message (the diagnostics' words; details may follow in parentheses or after a colon)
MESSAGES = collections.OrderedDict([
    (NO_STATE, 'no state received yet'),
    (NO_WAYPOINT, 'no waypoint received yet'),
    (BAD_STATE, 'non-finite state'),
    (BAD_WAYPOINT, 'non-finite waypoint'),
    (GEOFENCE, 'waypoint outside the geofence'),
    (WAYPOINT_JUMP, 'waypoint too far from the drone'),
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
HOLD_KEYS = (BAD_WAYPOINT, GEOFENCE, WAYPOINT_JUMP, STALE_WAYPOINT)


def failsafe(key):
    """HOLD or SILENT for a hover key (None for 'ok')."""
    if key == OK:
        return None
    return HOLD if key in HOLD_KEYS else SILENT

#: counters of the gate (samples) and of the cycles (totals and one per hover key)
COUNTER_NAMES = ('cycles', OK, 'hover', HOLD, SILENT) + HOVER_KEYS + (
    'states', 'waypoints', 'rejected_states', 'rejected_waypoints', 'rejected_geofence', 'rejected_jumps',
    'clock_jumps', 'holds')

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
    waypoint, WARN holding / silent for missing or bad input, ERROR the controller itself failed. The message
    names the failsafe: 'holding position: <reason>' (HOLD) or 'no command, firmware hover brake: <reason>'
    (SILENT)."""
    if key == OK:
        return Health(LEVEL_OK, 'tracking', list(values))
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

#: defaults of the waypoint limits (= the controller YAMLs anafi_sim/config/mpc.yaml and pid.yaml)
LIMIT_DEFAULTS = collections.OrderedDict([
    ('geofence_radius', 250.0),     # [m] horizontal distance of a waypoint from the first state received
    ('min_altitude', 0.5),          # [m] lowest waypoint z (world ENU)
    ('max_altitude', 50.0),         # [m] highest waypoint z
    ('max_waypoint_jump', 50.0),    # [m] largest distance of a waypoint from the drone's current position (the
                                    # airship scene needs ~38 m when the drone engages from the origin)
])


class WaypointLimits(object):
    """The geofence and the maximum waypoint jump (``LIMIT_DEFAULTS``; ValueError on bad values).

    The geofence is a vertical cylinder of ``geofence_radius`` [m] around the horizontal position of the first
    state the gate receives (the start), cut by the altitude band [``min_altitude``, ``max_altitude``] [m];
    ``max_waypoint_jump`` [m] bounds the distance of a waypoint from the drone's latest position."""

    def __init__(self, geofence_radius=LIMIT_DEFAULTS['geofence_radius'], min_altitude=LIMIT_DEFAULTS['min_altitude'],
                 max_altitude=LIMIT_DEFAULTS['max_altitude'], max_waypoint_jump=LIMIT_DEFAULTS['max_waypoint_jump']):
        values = dict(geofence_radius=geofence_radius, min_altitude=min_altitude, max_altitude=max_altitude,
                      max_waypoint_jump=max_waypoint_jump)
        for name, value in values.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError('%s must be a finite number [m], got %r' % (name, value))
        for name in ('geofence_radius', 'max_waypoint_jump'):
            if values[name] <= 0.0:
                raise ValueError('%s must be > 0 [m], got %r' % (name, values[name]))
        if not min_altitude < max_altitude:
            raise ValueError('min_altitude (%r) must be below max_altitude (%r)' % (min_altitude, max_altitude))
        self.geofence_radius = float(geofence_radius)
        self.min_altitude = float(min_altitude)
        self.max_altitude = float(max_altitude)
        self.max_waypoint_jump = float(max_waypoint_jump)

    def as_dict(self):
        return collections.OrderedDict((k, getattr(self, k)) for k in LIMIT_DEFAULTS)

    def check(self, waypoint, centre, drone):
        """None when ``waypoint`` (x, y, z, ...) is within the limits, else (key, detail). ``centre``: (x, y) of
        the geofence or None (not known yet: only the altitude band applies); ``drone``: its (x, y, z) or None."""
        x, y, z = waypoint[:3]
        if not self.min_altitude <= z <= self.max_altitude:
            return GEOFENCE, ' (z %.1f m outside [%.1f, %.1f] m)' % (z, self.min_altitude, self.max_altitude)
        if centre is not None:
            r = math.hypot(x - centre[0], y - centre[1])
            if r > self.geofence_radius:
                return GEOFENCE, ' (%.1f m from the start > %.1f m)' % (r, self.geofence_radius)
        if drone is not None:
            d = math.hypot(x - drone[0], math.hypot(y - drone[1], z - drone[2]))   # no overflow for huge values
            if d > self.max_waypoint_jump:
                return WAYPOINT_JUMP, ' (%.1f m > %.1f m)' % (d, self.max_waypoint_jump)
        return None


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
    ``limits``: the ``WaypointLimits`` (None: the defaults).

    ``check(t)`` returns the inputs of a cycle: the held ones when tracking, the hold point (``hold``:
    position and heading of the drone at the first cycle of a hold, zero velocity) in place of the waypoint
    for a HOLD key, None for a SILENT key.
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
        self.limits = WaypointLimits() if limits is None else limits
        if not isinstance(self.limits, WaypointLimits):
            raise ValueError('limits must be a WaypointLimits, got %r' % (limits,))
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
        key, detail = BAD_WAYPOINT, None
        if value is not None:
            drone = self.state.value[0] if self.state.missing is None else None
            beyond = self.limits.check(value, self.centre, drone)
            if beyond is not None:
                key, detail = beyond
                value = None
                self.counters['rejected_geofence' if key == GEOFENCE else 'rejected_jumps'] += 1
        if value is None:
            self.counters['rejected_waypoints'] += 1
        return self.waypoint.set(t, value, key, detail)

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
        key, detail = self._reason(t)
        if key is None:
            self.hold = None
            (pos, vel, yaw), wp = self.state.value, self.waypoint.value
            return Inputs(pos, vel, yaw, wp), OK, OK
        reason = hover_output(key, detail).reason
        if failsafe(key) != HOLD:
            self.hold = None
            return None, key, reason
        pos, vel, yaw = self.state.value
        if self.hold is None:
            self.hold = (pos[0], pos[1], pos[2], 0.0, 0.0, 0.0, math.degrees(yaw))
            self.counters['holds'] += 1
        return Inputs(pos, vel, yaw, self.hold), key, reason

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
        if key == OK:
            self.counters[OK] += 1
        else:
            self.counters['hover'] += 1
            self.counters[key] += 1
            self.counters[failsafe(key)] += 1


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
    #: True: the controller tracks a reference preview (``on_reference``); the node / engine then subscribes
    #: to the trajectory generator's preview (trajectory_msgs/MultiDOFJointTrajectory, command/trajectory)
    PREVIEW = False

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
        mode = OK if key == OK else failsafe(key)
        if mode == SILENT or (mode != self.mode and self.mode != SILENT):
            self._hover(None)        # a new mode starts from a clean state (a silent cycle already reset it)
        self.mode = mode
        if inputs is None:
            out = CycleOutput(None, False, reason, key, None)
        else:
            out = self._compute(float(t), inputs)
            if out.ok and out.command is not None and not is_finite(*out.command):
                out = hover_output(BAD_OUTPUT, result=out.result)
            if out.ok and key != OK:     # holding: the command of the hold point, under the hold's key
                out = CycleOutput(out.command, False, reason, key, out.result)
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
