"""Trajectory generator core: scenario time -> the paper's waypoint (pure Python, no ROS).

Stage: trajectory -> waypoint (-> PID / MPC controller). Units and frames:
positions [m] and velocities [m/s] in the ENU world frame, yaw [deg] (world,
counter-clockwise positive), time [s]. Every trajectory returns a
``WaypointSample`` (x, y, z, vx, vy, vz, yaw) at time t, and its velocity is
always the exact time derivative of its position (closed form, not a finite
difference).

Building blocks are 1-D *axis components* (``Constant``, ``Ramp``, ``Sine``),
each giving (position, velocity) at t; ``PerAxis`` combines one component per
axis (x, y, z, and yaw in degrees). The paper's shapes are ``PerAxis``
subclasses:

- ``StaticWaypoint(x, y, z, yaw)``;
- ``StraightLine(start, direction, speed, yaw)``: p = start + speed * d * t
  (d = direction normalised);
- ``Circle(centre, radius, speed, yaw)`` in the xy-plane at the centre's
  altitude: angular rate w = speed / radius, x = cx + r cos(w t + phase),
  y = cy + r sin(w t + phase) (counter-clockwise; ``clockwise=True`` flips);
- ``VerticalPeriodic(centre, radius, speed, yaw)``: z = z0 + r sin(v t / r),
  vz = v cos(v t / r) (the paper's rectilinear periodic trajectory).

``period()`` is the smallest common period of the axes (None when the
trajectory is static or not periodic).

Scenarios (``Scenario``, loaded from YAML by ``load_scenario``) put a
trajectory into phases. Schema (see anafi_sim/config/scenarios/README.md)::

    name: circle_r2_v1                  # optional, default: file name
    description: text                   # optional
    start: {x: 2, y: 0, z: 5, yaw: 0}   # hover point first [m, deg]; 'trajectory' (default):
                                        #   the trajectory's position and yaw at t = 0
    trajectory: {type: circle, centre: [0, 0, 5], radius: 2, speed: 1, yaw: 0}
    phases:                             # run in order
      - {name: approach, duration: 8, hold: start}  # waypoint = start, velocity 0
      - {name: settle, periods: 1}                  # follow the trajectory
      - {name: measure, periods: 1, measure: true}  # the measured window (exactly one)

Trajectory types: ``static`` (position [x, y, z], yaw), ``line`` (start,
direction, speed, yaw), ``circle`` (centre, radius, speed, yaw, phase [rad],
clockwise), ``vertical`` (centre [x, y, z0], radius, speed, yaw), ``airship`` (a
followed scripted target: path {airship.yaml keys}, offset, offset_frame, yaw_mode, yaw_offset), ``per_axis``
(x, y, z, yaw: each {type: constant, value} | {type: ramp, start, speed} |
{type: sine, offset, amplitude, omega [rad/s], phase [rad]}; missing axes are
constant 0). A phase has ``duration`` [s] or ``periods`` (whole trajectory
periods, needs a periodic trajectory), optional ``hold: start`` and
``measure: true``. Trajectory time starts at 0 with the first following phase
and runs on across following phases (hold phases pause it). After the last
phase the waypoint holds the final position with zero velocity.
Invalid input raises ValueError naming the file and the field.
"""
import collections
import math
import os

import yaml

from anafi_sim import paths
from anafi_sim.gazebo.airship_path import AirshipPath
from anafi_sim.mission.model_following import ModelFollower
from anafi_sim.mission.waypoint import WaypointSample

SCENARIO_DIR = paths.config_path('scenarios')
"""Directory of the shipped scenario files (anafi_sim/config/scenarios)."""


def _number(value, what, positive=False, non_negative=False):
    """``value`` as a finite float, else ValueError mentioning ``what``."""
    if isinstance(value, bool):
        raise ValueError('%s must be a number, got %r' % (what, value))
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ValueError('%s must be a number, got %r' % (what, value))
    if not math.isfinite(out):
        raise ValueError('%s must be finite, got %r' % (what, value))
    if positive and out <= 0.0:
        raise ValueError('%s must be > 0, got %r' % (what, value))
    if non_negative and out < 0.0:
        raise ValueError('%s must be >= 0, got %r' % (what, value))
    return out


def _vector3(value, what):
    if isinstance(value, dict):
        missing = [k for k in ('x', 'y', 'z') if k not in value]
        if missing:
            raise ValueError('%s lacks %s' % (what, ', '.join(missing)))
        value = [value['x'], value['y'], value['z']]
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise ValueError('%s must be [x, y, z], got %r' % (what, value))
    return tuple(_number(v, '%s[%d]' % (what, i)) for i, v in enumerate(value))


# ---------------------------------------------------------------- axis components

class Constant(object):
    """p(t) = value, v = 0."""

    def __init__(self, value=0.0):
        self.value = _number(value, 'constant value')

    def __call__(self, t):
        return self.value, 0.0

    def acceleration(self, t):
        """0."""
        return 0.0

    def period(self):
        """None: constant (compatible with any period)."""
        return None

    def __repr__(self):
        return 'Constant(%r)' % self.value


class Ramp(object):
    """p(t) = start + speed * t, v = speed."""

    def __init__(self, start=0.0, speed=0.0):
        self.start = _number(start, 'ramp start')
        self.speed = _number(speed, 'ramp speed')

    def __call__(self, t):
        return self.start + self.speed * t, self.speed

    def acceleration(self, t):
        """0."""
        return 0.0

    def period(self):
        """None when the speed is 0 (constant), else inf (never repeats)."""
        return None if self.speed == 0.0 else math.inf

    def __repr__(self):
        return 'Ramp(start=%r, speed=%r)' % (self.start, self.speed)


class Sine(object):
    """p(t) = offset + amplitude sin(omega t + phase), v = amplitude omega cos(omega t + phase)."""

    def __init__(self, offset=0.0, amplitude=0.0, omega=0.0, phase=0.0):
        self.offset = _number(offset, 'sine offset')
        self.amplitude = _number(amplitude, 'sine amplitude')
        self.omega = _number(omega, 'sine omega')
        self.phase = _number(phase, 'sine phase')

    def __call__(self, t):
        a = self.omega * t + self.phase
        return (self.offset + self.amplitude * math.sin(a),
                self.amplitude * self.omega * math.cos(a))

    def acceleration(self, t):
        """-amplitude omega^2 sin(omega t + phase)."""
        return -self.amplitude * self.omega * self.omega * math.sin(self.omega * t + self.phase)

    def period(self):
        """2 pi / |omega| [s]; None when constant (omega or amplitude 0)."""
        if self.omega == 0.0 or self.amplitude == 0.0:
            return None
        return 2.0 * math.pi / abs(self.omega)

    def __repr__(self):
        return 'Sine(offset=%r, amplitude=%r, omega=%r, phase=%r)' % (
            self.offset, self.amplitude, self.omega, self.phase)


COMPONENT_TYPES = {'constant': Constant, 'ramp': Ramp, 'sine': Sine}


def common_period(periods, max_multiple=64, rel_tol=1e-9):
    """Smallest common period of ``periods`` (None entries = constant, ignored).

    Returns None when every entry is None, or when some entry is inf or the
    periods are not commensurate (no common multiple within ``max_multiple``
    times the longest one).
    """
    finite = [p for p in periods if p is not None]
    if not finite:
        return None
    if any(math.isinf(p) for p in finite):
        return None
    longest = max(finite)
    for k in range(1, max_multiple + 1):
        candidate = k * longest
        if all(abs(candidate / p - round(candidate / p)) <= rel_tol * max(1.0, candidate / p) for p in finite):
            return candidate
    return None


def _acceleration(component, t):
    """A component's acceleration (0 for a custom component without ``acceleration``)."""
    accel = getattr(component, 'acceleration', None)
    return 0.0 if accel is None else float(accel(t))


# ---------------------------------------------------------------- trajectories

class PerAxis(object):
    """A trajectory built from one axis component per axis; yaw component in degrees.

    ``sample(t)`` -> ``WaypointSample``: positions and velocities from the x,
    y, z components (ENU), yaw [deg] from the yaw component's position.
    """

    kind = 'per_axis'

    def __init__(self, x=None, y=None, z=None, yaw=None):
        self.axes = collections.OrderedDict()
        for name, comp in (('x', x), ('y', y), ('z', z), ('yaw', yaw)):
            comp = Constant(0.0) if comp is None else comp
            if not callable(comp) or not hasattr(comp, 'period'):
                raise ValueError('axis %s must be an axis component (Constant, Ramp, Sine), got %r'
                                 % (name, comp))
            self.axes[name] = comp

    def sample(self, t):
        """Waypoint at trajectory time ``t`` [s]."""
        t = float(t)
        x, vx = self.axes['x'](t)
        y, vy = self.axes['y'](t)
        z, vz = self.axes['z'](t)
        yaw, _ = self.axes['yaw'](t)
        return WaypointSample(x, y, z, vx, vy, vz, yaw)

    __call__ = sample

    def acceleration(self, t):
        """(ax, ay, az) [m/s^2] at ``t`` (the exact second derivative of the position)."""
        t = float(t)
        return tuple(_acceleration(self.axes[a], t) for a in ('x', 'y', 'z'))

    def position(self, t):
        """(x, y, z) [m] at ``t``."""
        s = self.sample(t)
        return s.x, s.y, s.z

    def velocity(self, t):
        """(vx, vy, vz) [m/s] at ``t``."""
        s = self.sample(t)
        return s.vx, s.vy, s.vz

    def period(self):
        """Smallest common period [s] of all axes, None when static or not periodic."""
        return common_period([c.period() for c in self.axes.values()])

    def __repr__(self):
        return '%s(%s)' % (type(self).__name__, ', '.join('%s=%r' % kv for kv in self.axes.items()))


class StaticWaypoint(PerAxis):
    """A fixed waypoint (x, y, z [m], yaw [deg]) with zero velocity."""

    kind = 'static'

    def __init__(self, x, y, z, yaw=0.0):
        PerAxis.__init__(self, Constant(x), Constant(y), Constant(z), Constant(yaw))


class StraightLine(PerAxis):
    """p(t) = start + speed * d * t with d = direction / |direction| (ENU), constant yaw [deg]."""

    kind = 'line'

    def __init__(self, start, direction, speed, yaw=0.0):
        start = _vector3(start, 'line start')
        direction = _vector3(direction, 'line direction')
        speed = _number(speed, 'line speed', non_negative=True)
        norm = math.sqrt(sum(d * d for d in direction))
        if norm < 1e-9:
            raise ValueError('line direction must be a non-zero vector, got %r' % (direction,))
        self.start = start
        self.direction = tuple(d / norm for d in direction)
        self.speed = speed
        PerAxis.__init__(self, *[Ramp(s, speed * d) for s, d in zip(start, self.direction)],
                         yaw=Constant(yaw))


class Circle(PerAxis):
    """Circle in the xy-plane at the centre's altitude, constant yaw [deg].

    Angular rate w = speed / radius [rad/s] (counter-clockwise seen from
    above, or clockwise); starts at angle ``phase`` [rad] (0: at centre + (r, 0)).
    Period 2 pi r / v.
    """

    kind = 'circle'

    def __init__(self, centre, radius, speed, yaw=0.0, phase=0.0, clockwise=False):
        centre = _vector3(centre, 'circle centre')
        radius = _number(radius, 'circle radius', positive=True)
        speed = _number(speed, 'circle speed', positive=True)
        phase = _number(phase, 'circle phase')
        self.centre, self.radius, self.speed = centre, radius, speed
        self.clockwise = bool(clockwise)
        w = (-1.0 if self.clockwise else 1.0) * speed / radius
        self.omega = w
        # x = cx + r cos(w t + phase) = cx + r sin(w t + phase + pi/2)
        PerAxis.__init__(self,
                         Sine(centre[0], radius, w, phase + 0.5 * math.pi),
                         Sine(centre[1], radius, w, phase),
                         Constant(centre[2]),
                         Constant(yaw))


class VerticalPeriodic(PerAxis):
    """The paper's vertical rectilinear periodic motion: z = z0 + r sin(v t / r), vz = v cos(v t / r).

    ``centre`` = (x, y, z0) [m]; period 2 pi r / v; constant yaw [deg].
    """

    kind = 'vertical'

    def __init__(self, centre, radius, speed, yaw=0.0):
        centre = _vector3(centre, 'vertical centre')
        radius = _number(radius, 'vertical radius', positive=True)
        speed = _number(speed, 'vertical speed', positive=True)
        self.centre, self.radius, self.speed = centre, radius, speed
        PerAxis.__init__(self, Constant(centre[0]), Constant(centre[1]),
                         Sine(centre[2], radius, speed / radius, 0.0), Constant(yaw))


class FollowedTarget(object):
    """The waypoint ``model_follower.py`` makes of a scripted moving target: the airship of the multi-robot
    scene (``anafi_sim.gazebo.airship_path.AirshipPath``, parameters ``path``: its keys of
    anafi_sim/config/airship.yaml, which gives the defaults) followed at ``offset`` [m] in its heading frame
    (``ModelFollower``: offset_frame, yaw_mode, yaw_offset [deg]) with the velocity from its twist, as the
    follower computes it from /gazebo/model_states. A pure function of time, for the in-process engine
    (``airship_follow`` scenario). ``acceleration`` is a central difference of the velocity (h = 1 ms).
    """

    kind = 'airship'
    PATH_KEYS = ('shape', 'size', 'period', 'altitude', 'z_amplitude', 'z_period', 'center', 'phase')

    def __init__(self, path=None, offset=(-6.0, 0.0, -2.0), offset_frame='heading', yaw_mode='heading',
                 yaw_offset=0.0):
        params = airship_defaults()
        if path is not None:
            _check_keys(path, self.PATH_KEYS, 'airship path')
            params.update(path)
        self.path = AirshipPath(**params)
        self.follower = ModelFollower(list(offset), offset_frame, yaw_mode, yaw_offset, velocity_source='twist')

    def sample(self, t):
        """Waypoint at trajectory time ``t`` [s]."""
        t = float(t)
        st = self.path.state(t)
        half = 0.5 * st.yaw
        self.follower.reset()          # a pure function of t: no history (the velocity is the twist's)
        return self.follower.update(t, st.position, (0.0, 0.0, math.sin(half), math.cos(half)),
                                    linear=st.velocity, angular_z=st.yaw_rate)

    __call__ = sample

    def acceleration(self, t, h=1e-3):
        """(ax, ay, az) [m/s^2] at ``t`` (central difference of the waypoint velocity)."""
        a, b = self.sample(t - h), self.sample(t + h)
        return ((b.vx - a.vx) / (2 * h), (b.vy - a.vy) / (2 * h), (b.vz - a.vz) / (2 * h))

    def period(self):
        """Lap and bob periods' common period [s]."""
        return common_period([self.path.period, self.path.z_period])


def airship_defaults():
    """The airship path's parameters of anafi_sim/config/airship.yaml (the scene's single source)."""
    with open(paths.config_path('airship.yaml')) as stream:
        data = yaml.safe_load(stream)
    return dict((k, data[k]) for k in FollowedTarget.PATH_KEYS if k in data)


# ---------------------------------------------------------------- construction from dicts

def _check_keys(d, allowed, what):
    if not isinstance(d, dict):
        raise ValueError('%s must be a mapping, got %r' % (what, d))
    unknown = sorted(set(d) - set(allowed))
    if unknown:
        raise ValueError('%s: unknown field(s) %s (allowed: %s)' % (what, ', '.join(map(str, unknown)),
                                                                    ', '.join(sorted(allowed))))


def _require(d, key, what):
    if key not in d:
        raise ValueError('%s: missing field %r' % (what, key))
    return d[key]


def component_from_dict(d, what='axis'):
    """An axis component from {type: constant|ramp|sine, ...} (a bare number = constant)."""
    if isinstance(d, (int, float)) and not isinstance(d, bool):
        return Constant(d)
    if not isinstance(d, dict):
        raise ValueError('%s must be a number or a mapping with a type, got %r' % (what, d))
    kind = d.get('type')
    if kind not in COMPONENT_TYPES:
        raise ValueError('%s: type must be one of %s, got %r' % (what, ', '.join(sorted(COMPONENT_TYPES)), kind))
    fields = {'constant': ('value',), 'ramp': ('start', 'speed'),
              'sine': ('offset', 'amplitude', 'omega', 'phase')}[kind]
    _check_keys(d, ('type',) + fields, what)
    kwargs = dict((k, d[k]) for k in fields if k in d)
    try:
        return COMPONENT_TYPES[kind](**kwargs)
    except ValueError as e:
        raise ValueError('%s: %s' % (what, e))


def trajectory_from_dict(d, what='trajectory'):
    """A trajectory from its YAML mapping (see the module doc for the types and fields)."""
    if not isinstance(d, dict):
        raise ValueError('%s must be a mapping with a type, got %r' % (what, d))
    kind = d.get('type')
    try:
        if kind == 'static':
            _check_keys(d, ('type', 'position', 'yaw'), what)
            p = _vector3(_require(d, 'position', what), 'position')
            return StaticWaypoint(p[0], p[1], p[2], _number(d.get('yaw', 0.0), 'yaw'))
        if kind == 'line':
            _check_keys(d, ('type', 'start', 'direction', 'speed', 'yaw'), what)
            return StraightLine(_require(d, 'start', what), _require(d, 'direction', what),
                                _require(d, 'speed', what), _number(d.get('yaw', 0.0), 'yaw'))
        if kind == 'circle':
            _check_keys(d, ('type', 'centre', 'radius', 'speed', 'yaw', 'phase', 'clockwise'), what)
            clockwise = d.get('clockwise', False)
            if not isinstance(clockwise, bool):
                raise ValueError('clockwise must be true or false, got %r' % (clockwise,))
            return Circle(_require(d, 'centre', what), _require(d, 'radius', what), _require(d, 'speed', what),
                          _number(d.get('yaw', 0.0), 'yaw'), d.get('phase', 0.0), clockwise)
        if kind == 'vertical':
            _check_keys(d, ('type', 'centre', 'radius', 'speed', 'yaw'), what)
            return VerticalPeriodic(_require(d, 'centre', what), _require(d, 'radius', what),
                                    _require(d, 'speed', what), _number(d.get('yaw', 0.0), 'yaw'))
        if kind == 'airship':
            _check_keys(d, ('type', 'path', 'offset', 'offset_frame', 'yaw_mode', 'yaw_offset'), what)
            return FollowedTarget(d.get('path'), d.get('offset', (-6.0, 0.0, -2.0)),
                                  d.get('offset_frame', 'heading'), d.get('yaw_mode', 'heading'),
                                  _number(d.get('yaw_offset', 0.0), 'yaw_offset'))
        if kind == 'per_axis':
            _check_keys(d, ('type', 'x', 'y', 'z', 'yaw'), what)
            return PerAxis(*[component_from_dict(d[a], '%s.%s' % (what, a)) if a in d else None
                             for a in ('x', 'y', 'z', 'yaw')])
    except ValueError as e:
        msg = str(e)
        raise ValueError(msg if msg.startswith(what) else '%s (%s): %s' % (what, kind, msg))
    raise ValueError('%s: type must be one of static, line, circle, vertical, airship, per_axis, got %r'
                     % (what, kind))


# ---------------------------------------------------------------- scenarios

Phase = collections.namedtuple('Phase', 'name duration hold measure')
Phase.__doc__ = ('One scenario phase: name, duration [s], hold (True: waypoint = start, trajectory '
                 'time paused), measure (True: the measured window).')

PhaseState = collections.namedtuple('PhaseState', 'index phase start end trajectory_time')
PhaseState.__doc__ = ('Where scenario time t falls: phase index (None after the end), Phase, phase '
                      'start/end [s scenario time], trajectory time [s] (None while holding).')


class Scenario(object):
    """A trajectory in phases: hover at ``start``, then follow the trajectory, one measured phase.

    Scenario time t [s] starts at 0 when the generator starts. ``waypoint(t)``
    is the waypoint to publish; ``measure_window`` is (t_begin, t_end).
    """

    def __init__(self, name, trajectory, phases, start=None, description=''):
        if not name or not isinstance(name, str):
            raise ValueError('scenario name must be a non-empty string, got %r' % (name,))
        self.name = name
        self.description = description or ''
        self.trajectory = trajectory
        if start is None:
            s = trajectory.sample(0.0)
            start = WaypointSample(s.x, s.y, s.z, 0.0, 0.0, 0.0, s.yaw)
        self.start = WaypointSample(float(start[0]), float(start[1]), float(start[2]), 0.0, 0.0, 0.0,
                                    float(start[6] if len(start) > 6 else start[3]))
        self.phases = tuple(phases)
        if not self.phases:
            raise ValueError('scenario %s: at least one phase needed' % name)
        names = [p.name for p in self.phases]
        if len(set(names)) != len(names):
            raise ValueError('scenario %s: phase names must be unique, got %s' % (name, names))
        for p in self.phases:
            if not (p.duration > 0.0 and math.isfinite(p.duration)):
                raise ValueError('scenario %s: phase %s needs a finite duration > 0, got %r'
                                 % (name, p.name, p.duration))
        measured = [i for i, p in enumerate(self.phases) if p.measure]
        if len(measured) != 1:
            raise ValueError('scenario %s: exactly one phase must have measure: true, found %d'
                             % (name, len(measured)))
        self.measure_index = measured[0]
        self._bounds = []
        t = 0.0
        traj_t = 0.0
        for p in self.phases:
            self._bounds.append((t, t + p.duration, None if p.hold else traj_t))
            t += p.duration
            if not p.hold:
                traj_t += p.duration
        self.duration = t
        self.trajectory_duration = traj_t
        b = self._bounds[self.measure_index]
        self.measure_window = (b[0], b[1])
        self.final = self._final_waypoint()

    @property
    def measured_phase(self):
        return self.phases[self.measure_index]

    def period(self):
        """The trajectory's period [s] (None when static or not periodic)."""
        return self.trajectory.period()

    def phase_at(self, t):
        """``PhaseState`` of scenario time ``t`` [s] (t < 0 counts as 0; index None after the end)."""
        t = max(0.0, float(t))
        for i, (p, (t0, t1, traj0)) in enumerate(zip(self.phases, self._bounds)):
            if t < t1:
                return PhaseState(i, p, t0, t1, None if traj0 is None else traj0 + (t - t0))
        return PhaseState(None, None, self.duration, self.duration, None)

    def trajectory_time(self, t):
        """Trajectory time [s] at scenario time ``t``, None while holding the start or after the end."""
        return self.phase_at(t).trajectory_time

    def waypoint(self, t):
        """``WaypointSample`` to publish at scenario time ``t`` [s]."""
        state = self.phase_at(t)
        if state.index is None:
            return self.final
        if state.phase.hold:
            return self.start
        return self.trajectory.sample(state.trajectory_time)

    def reference(self, t):
        """(``WaypointSample``, acceleration (ax, ay, az) [m/s^2]) at scenario time ``t`` [s]: the waypoint of
        ``waypoint(t)`` and its acceleration (0 while holding and after the end)."""
        state = self.phase_at(t)
        if state.index is None:
            return self.final, (0.0, 0.0, 0.0)
        if state.phase.hold:
            return self.start, (0.0, 0.0, 0.0)
        return (self.trajectory.sample(state.trajectory_time),
                self.trajectory.acceleration(state.trajectory_time))

    def _final_waypoint(self):
        last = self.phases[-1]
        if last.hold:
            return self.start
        s = self.trajectory.sample(self.trajectory_duration)
        return WaypointSample(s.x, s.y, s.z, 0.0, 0.0, 0.0, s.yaw)

    def describe(self):
        """One line per phase: name, scenario-time span, hold/measure flags."""
        lines = ['%s: %s' % (self.name, self.description) if self.description else self.name]
        for p, (t0, t1, _) in zip(self.phases, self._bounds):
            lines.append('  %-10s %7.2f .. %7.2f s%s%s' % (p.name, t0, t1, '  hold start' if p.hold else '',
                                                          '  MEASURED' if p.measure else ''))
        return lines


SCENARIO_KEYS = ('name', 'description', 'start', 'trajectory', 'phases')
PHASE_KEYS = ('name', 'duration', 'periods', 'hold', 'measure')


def _start_from(value, trajectory, what):
    if value is None or value == 'trajectory':
        return None
    if isinstance(value, dict):
        _check_keys(value, ('x', 'y', 'z', 'yaw'), what)
        p = _vector3(value, what)
        yaw = _number(value.get('yaw', 0.0), what + '.yaw')
    elif isinstance(value, (list, tuple)) and len(value) in (3, 4):
        p = _vector3(list(value[:3]), what)
        yaw = _number(value[3], what + '[3] (yaw)') if len(value) == 4 else 0.0
    else:
        raise ValueError("%s must be {x, y, z, yaw}, [x, y, z(, yaw)] or 'trajectory', got %r" % (what, value))
    return WaypointSample(p[0], p[1], p[2], 0.0, 0.0, 0.0, yaw)


def phase_from_dict(d, period, what='phase'):
    """A ``Phase`` from {name, duration | periods, hold, measure}; ``period`` of the trajectory or None."""
    _check_keys(d, PHASE_KEYS, what)
    name = _require(d, 'name', what)
    if not isinstance(name, str) or not name:
        raise ValueError('%s: name must be a non-empty string, got %r' % (what, name))
    what = '%s %s' % (what, name)
    if ('duration' in d) == ('periods' in d):
        raise ValueError('%s: give exactly one of duration [s] or periods' % what)
    hold = d.get('hold', None)
    if hold not in (None, 'start'):
        raise ValueError("%s: hold must be 'start' (or absent), got %r" % (what, hold))
    measure = d.get('measure', False)
    if not isinstance(measure, bool):
        raise ValueError('%s: measure must be true or false, got %r' % (what, measure))
    if 'duration' in d:
        duration = _number(d['duration'], what + ': duration', positive=True)
    else:
        if hold:
            raise ValueError('%s: a hold phase needs a duration, not periods' % what)
        periods = _number(d['periods'], what + ': periods', positive=True)
        if period is None:
            raise ValueError('%s: periods given but the trajectory is not periodic' % what)
        duration = periods * period
    return Phase(name, duration, hold == 'start', measure)


def scenario_from_dict(d, name=None, what=None):
    """A ``Scenario`` from its YAML mapping (``name`` is used when the mapping has none)."""
    what = what or 'scenario %s' % (d.get('name', name) if isinstance(d, dict) else name)
    if not isinstance(d, dict):
        raise ValueError('%s: must be a mapping, got %r' % (what, type(d).__name__))
    try:
        _check_keys(d, SCENARIO_KEYS, 'scenario')
        trajectory = trajectory_from_dict(_require(d, 'trajectory', 'scenario'))
        start = _start_from(d.get('start'), trajectory, 'start')
        phases = _require(d, 'phases', 'scenario')
        if not isinstance(phases, list) or not phases:
            raise ValueError('phases must be a non-empty list')
        period = trajectory.period()
        phases = [phase_from_dict(p, period, 'phase %d' % (i + 1)) for i, p in enumerate(phases)]
        scenario_name = d.get('name', name)
        description = d.get('description', '')
        if not isinstance(description, str):
            raise ValueError('description must be a string')
        scenario = Scenario(scenario_name, trajectory, phases, start=start, description=description)
        check_limits(scenario)
        return scenario
    except ValueError as e:
        raise ValueError('%s: %s' % (what, e))


#: bounds of a scenario a drone can fly (``check_limits``): total duration [s], measured phase [s], every
#: waypoint's |x|, |y| [m] and z [m] (world ENU), speed [m/s] (the Anafi flies up to 16 m/s) and acceleration
#: [m/s^2] (a circle's v^2 / r: radius and speed together)
SCENARIO_LIMITS = {'max_duration': 3600.0, 'min_measured': 0.5, 'max_xy': 1000.0, 'min_z': 0.0, 'max_z': 100.0,
                   'max_speed': 20.0, 'max_acceleration': 50.0}
_LIMIT_SAMPLES = 1000


def check_limits(scenario, limits=None):
    """ValueError naming the value when ``scenario`` leaves ``SCENARIO_LIMITS``: its duration, its measured
    phase, or its waypoints (start, and the trajectory sampled at least 16 times per period) in position,
    speed or acceleration (e.g. a centre at 1e300 m, a radius of 1e-300 m, 1e6 m/s, a 1e6 s duration)."""
    lim = dict(SCENARIO_LIMITS, **(limits or {}))
    if scenario.duration > lim['max_duration']:
        raise ValueError('duration %.6g s > %g s' % (scenario.duration, lim['max_duration']))
    measured = scenario.measured_phase.duration
    if measured < lim['min_measured']:
        raise ValueError('measured phase %s lasts %.3g s < %g s' % (scenario.measured_phase.name, measured,
                                                                    lim['min_measured']))

    def check(what, sample, acc):
        x, y, z = sample[0], sample[1], sample[2]
        speed = math.sqrt(sample[3] ** 2 + sample[4] ** 2 + sample[5] ** 2)
        accel = math.sqrt(sum(a * a for a in acc))
        for name, value, ok in (
                ('x', x, abs(x) <= lim['max_xy']), ('y', y, abs(y) <= lim['max_xy']),
                ('z', z, lim['min_z'] <= z <= lim['max_z']), ('speed', speed, speed <= lim['max_speed']),
                ('acceleration', accel, accel <= lim['max_acceleration'])):
            if not ok:      # also NaN / inf
                bound = {'x': '|x| <= %g m' % lim['max_xy'], 'y': '|y| <= %g m' % lim['max_xy'],
                         'z': '%g <= z <= %g m' % (lim['min_z'], lim['max_z']),
                         'speed': '<= %g m/s' % lim['max_speed'],
                         'acceleration': '<= %g m/s^2 (v^2 / r of a circle)' % lim['max_acceleration']}[name]
                raise ValueError('%s: %s %.6g outside the limits (%s)' % (what, name, value, bound))

    check('start', scenario.start, (0.0, 0.0, 0.0))
    span = scenario.trajectory_duration
    if span <= 0.0:
        return
    period = scenario.period()
    step = span / _LIMIT_SAMPLES
    if period:
        step = min(step, period / 16.0)
    n = min(int(math.ceil(span / step)), 50 * _LIMIT_SAMPLES) if step > 0.0 else 1
    traj = scenario.trajectory
    for i in range(n + 1):
        t = span * i / n
        check('waypoint at trajectory time %.6g s' % t, traj.sample(t), traj.acceleration(t))


def scenario_path(name_or_path, directory=None):
    """Path of a scenario given a file path or a name in ``directory`` (default ``SCENARIO_DIR``)."""
    if os.sep in name_or_path or name_or_path.endswith(('.yaml', '.yml')):
        return name_or_path
    return os.path.join(directory or SCENARIO_DIR, name_or_path + '.yaml')


def load_scenario(name_or_path, directory=None):
    """Load a ``Scenario`` from a YAML file path or a scenario name (see ``scenario_path``)."""
    path = scenario_path(name_or_path, directory)
    if not os.path.isfile(path):
        known = list_scenarios(directory) if os.sep not in name_or_path else []
        raise ValueError('no scenario file %s%s' % (path, (' (known: %s)' % ', '.join(known)) if known else ''))
    from anafi_sim.safe_yaml import load_yaml
    data = load_yaml(path)
    base = os.path.splitext(os.path.basename(path))[0]
    return scenario_from_dict(data, name=base, what=path)


def list_scenarios(directory=None):
    """Sorted names of the scenario files (*.yaml) in ``directory`` (default ``SCENARIO_DIR``)."""
    directory = directory or SCENARIO_DIR
    if not os.path.isdir(directory):
        return []
    return sorted(os.path.splitext(f)[0] for f in os.listdir(directory) if f.endswith('.yaml'))


def scenario_in_folders(name_or_path, folders):
    """The path of scenario ``name_or_path`` (a name or a YAML path, as ``scenario_path`` with the first
    folder), only if the file lies inside one of ``folders`` (real paths compared: no ``..`` or link leads
    out); else ValueError that names the folders and shows nothing of the file."""
    real = [os.path.realpath(f) for f in folders if f]
    folders = [f for i, f in enumerate(real) if f not in real[:i]]
    path = os.path.realpath(scenario_path(name_or_path, folders[0] if folders else None))
    if os.path.splitext(path)[1] not in ('.yaml', '.yml') or not any(
            os.path.dirname(path) == f or path.startswith(f + os.sep) for f in folders):
        raise ValueError('refused: %r is not a scenario file in the scenario folders (%s)'
                         % (name_or_path[:200], ', '.join(folders)))
    return path


def scenario_folders(settings_dir=None):
    """The folders a scenario parameter (``~scenario_file``, ``~scenario_dir``, a 'switch' command) may name:
    the package's config folder (its scenarios), the package's test data, ``$ROS_HOME`` and the system's temp
    folder (where the fleet launcher and the tests write generated scenarios), and the folders of the
    root-owned settings file /etc/anafi_sim/data_folders."""
    import tempfile
    from anafi_sim import trusted
    return trusted.allowed_folders([SCENARIO_DIR, paths.config_path(), paths.data_path('..', 'test')],
                                   [trusted.ros_home(), tempfile.gettempdir()], directory=settings_dir)


# ---------------------------------------------------------------- generator state machine
