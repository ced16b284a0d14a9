"""The flight envelope every controller shares: bounds on the target a controller tracks and on its command.

Stage: waypoint -> **controller input** (pure, no ROS). ``contract.InputGate`` applies it every cycle to the
held waypoint (and to the hold point), the preview MPC to its reference over the horizon, and
``contract.Controller.cycle`` to the command; so the nodes, the distributed PID's relative-state node and
the in-process engine fly the same envelope. Defaults (``ENVELOPE_DEFAULTS``) = the controllers' YAML files
(anafi_sim/config/{mpc,pid,preview_mpc}.yaml, section "flight envelope"):

- ``max_reference_speed`` [m/s], ``max_reference_vertical_speed`` [m/s]: the reference velocity (the waypoint's
  v_x, v_y scaled down to this horizontal speed, v_z clipped). 10 m/s and 2 m/s: the paper's Table 1
  (v_max of both controllers; the Anafi itself reaches ~15 m/s) and the firmware's max vertical speed the
  paper set (shared/interfaces/anafi_ros.md).
- ``max_reference_acceleration`` [m/s^2]: the reference acceleration of a preview (horizontal norm and |a_z|) and the
  braking deceleration of the fence below. 5 m/s^2: the paper's a_max (Table 1), the tilt asin(5/g).
  A waypoint carries no acceleration; its velocity steps are left to the controllers' own limits (the MPC's
  a_max, the PID's inner loops) and to ``max_command_tilt_deg``.
- ``max_command_tilt_deg`` [deg]: |roll| and |pitch| of the command (per axis, as the bridge maps them);
  30.65 deg: the firmware setting of the paper, 30.64 deg = asin(5 / 9.81) = 30.643 deg (the MPC's a_max),
  rounded up (the bridge maps both to 100 %; it clips gaz to the firmware's max vertical speed itself).
- The geofence: a vertical cylinder of ``geofence_radius`` [m] around the horizontal position of the first
  state the gate receives (the take-off point), cut by [``min_altitude``, ``max_altitude``] [m] (world z).
  The target's fence is that cylinder less ``geofence_margin`` [m] horizontally (``target_radius``; the
  margin is the drone's room to lag behind and overshoot its target). A target outside it is moved onto it
  (the nearest point), and the target's velocity pointing out of it is reduced to the speed from which
  braking at half ``max_reference_acceleration`` (``BRAKING``; the other half is the controller's margin to
  follow) stops on it (sqrt(2 a d), d = the distance left: from the target or from the drone, whichever is
  nearer the fence): zero there. So the target, moving at its reference velocity and braking within the
  envelope, stays inside, and the drone, lagging behind it, too; a target that trails the drone (a waypoint
  at where the drone was, late) brakes from the drone's distance, not its own.
- ``max_waypoint_jump`` [m] (the reach): a target farther than this from the drone is replaced by the point
  at this distance on the way to it, with zero velocity: the drone approaches a far waypoint at the speed
  the controllers allow and tracks it again once it is within reach (no lock-out).

Each ``limit_*`` returns the limited values and the notes of the limits that acted ([(name, text)], names
``LIMITS``); no limit acting leaves every number untouched (bit for bit), so the envelope is inert for
references inside it. Non-finite input is the gate's business (refused before); huge finite numbers are safe.
"""
import collections
import math

#: the envelope's defaults (= the controllers' YAML files; test/unit/control/test_envelope.py checks)
ENVELOPE_DEFAULTS = collections.OrderedDict([
    ('geofence_radius', 250.0),               # [m] horizontal radius of the fence around the take-off point
    ('min_altitude', 0.5),                    # [m] floor of the fence (world z)
    ('max_altitude', 50.0),                   # [m] ceiling of the fence
    ('geofence_margin', 3.0),                 # [m] the target stays this far inside (the drone's room)
    ('max_waypoint_jump', 50.0),              # [m] reach: farthest target from the drone (airship: <= 38 m)
    ('max_reference_speed', 10.0),            # [m/s] reference horizontal speed (Table 1 v_max)
    ('max_reference_vertical_speed', 2.0),    # [m/s] reference vertical speed (firmware setting)
    ('max_reference_acceleration', 5.0),      # [m/s^2] preview acceleration, fence braking (Table 1 a_max)
    ('max_command_tilt_deg', 30.65),          # [deg] command |roll|, |pitch| (asin(5 / 9.81) = 30.643, rounded up)
])

#: the limits, in the order they are applied and reported
LIMITS = ('geofence', 'reach', 'speed', 'vertical_speed', 'fence_braking', 'acceleration', 'tilt')

#: fraction of max_reference_acceleration at which the target brakes before the fence (the rest: the
#: controller's margin to follow it)
BRAKING = 0.5

#: coordinates beyond this [m] are first clipped to it (keeps every difference finite; far outside any fence)
_FAR = 1.0e9


def _finite_number(name, value):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError('%s must be a finite number, got %r' % (name, value))
    return float(value)


def _clip(v, lo, hi):
    return lo if v < lo else hi if v > hi else v


def _norm2(x, y):
    """|(x, y)| without overflow for huge finite components."""
    return math.hypot(x, y) if abs(x) < 1e150 and abs(y) < 1e150 else \
        max(abs(x), abs(y)) * math.hypot(x / max(abs(x), abs(y)), y / max(abs(x), abs(y)))


class Envelope(object):
    """The flight envelope (see the module doc); keyword arguments = ``ENVELOPE_DEFAULTS`` (ValueError on bad
    values: not finite numbers, radius / reach / speeds / acceleration / tilt <= 0, tilt >= 90 deg,
    min_altitude >= max_altitude)."""

    def __init__(self, **values):
        unknown = sorted(set(values) - set(ENVELOPE_DEFAULTS))
        if unknown:
            raise ValueError('unknown envelope parameter(s) %s (known: %s)'
                             % (', '.join(unknown), ', '.join(ENVELOPE_DEFAULTS)))
        for name, default in ENVELOPE_DEFAULTS.items():
            value = _finite_number(name, values.get(name, default))
            if name not in ('min_altitude', 'max_altitude', 'geofence_margin') and value <= 0.0:
                raise ValueError('%s must be > 0, got %r' % (name, value))
            setattr(self, name, value)
        if not 0.0 <= self.geofence_margin < self.geofence_radius:
            raise ValueError('geofence_margin must be >= 0 and below geofence_radius, got %r'
                             % (self.geofence_margin,))
        #: [m] horizontal radius of the target's fence: the geofence less the drone's margin
        self.target_radius = self.geofence_radius - self.geofence_margin
        if self.max_command_tilt_deg >= 90.0:
            raise ValueError('max_command_tilt_deg must be < 90 deg, got %r' % (self.max_command_tilt_deg,))
        if not self.min_altitude < self.max_altitude:
            raise ValueError('min_altitude (%r) must be below max_altitude (%r)' % (self.min_altitude,
                                                                                  self.max_altitude))

    def as_dict(self):
        return collections.OrderedDict((k, getattr(self, k)) for k in ENVELOPE_DEFAULTS)

    # -- the fence -------------------------------------------------------------------------------
    def inside(self, position, centre, tolerance=1e-6, margin=0.0):
        """True when ``position`` (x, y, z) lies in the fence around ``centre`` (x, y) (None: only the altitude
        band) shrunk horizontally by ``margin`` [m] (``geofence_margin``: the target's fence), up to
        ``tolerance`` [m]."""
        x, y, z = position[:3]
        if not self.min_altitude - tolerance <= z <= self.max_altitude + tolerance:
            return False
        return centre is None or \
            _norm2(x - centre[0], y - centre[1]) <= self.geofence_radius - margin + tolerance

    def _fence(self, x, y, z, centre, notes):
        """(x, y, z) moved onto the fence when outside (a 'geofence' note)."""
        xc, yc, zc = _clip(x, -_FAR, _FAR), _clip(y, -_FAR, _FAR), _clip(z, self.min_altitude, self.max_altitude)
        moved = xc != x or yc != y or zc != z
        x, y = xc, yc
        if centre is not None:
            dx, dy = x - centre[0], y - centre[1]
            r = math.hypot(dx, dy)
            if r > self.target_radius:
                k = self.target_radius / r
                x, y = centre[0] + dx * k, centre[1] + dy * k
                moved = True
        if moved:
            notes.append(('geofence', 'target moved into the geofence (%.0f m around the take-off point less '
                                      '%.1f m, altitude %.1f-%.1f m)' % (self.geofence_radius, self.geofence_margin,
                                                                        self.min_altitude, self.max_altitude)))
        return x, y, zc

    def _brake(self, x, y, z, vx, vy, vz, centre, notes, drone=None):
        """The velocity with its outward part cut to sqrt(2 a d) (a 'fence_braking' note); d from the target
        (x, y, z) or the ``drone`` (x, y, z; None: the target alone), whichever is nearer the fence."""
        a = BRAKING * self.max_reference_acceleration
        cut = False
        if centre is not None:
            dx, dy = x - centre[0], y - centre[1]
            r = math.hypot(dx, dy)
            if r > 0.0:
                out = (vx * dx + vy * dy) / r
                rd = r if drone is None else max(r, math.hypot(_clip(drone[0], -_FAR, _FAR) - centre[0],
                                                               _clip(drone[1], -_FAR, _FAR) - centre[1]))
                allowed = math.sqrt(2.0 * a * max(0.0, self.target_radius - rd))
                if out > allowed:
                    vx -= (out - allowed) * dx / r
                    vy -= (out - allowed) * dy / r
                    cut = True
        top, bottom = (z, z) if drone is None else (max(z, drone[2]), min(z, drone[2]))
        up = math.sqrt(2.0 * a * max(0.0, self.max_altitude - top))
        down = math.sqrt(2.0 * a * max(0.0, bottom - self.min_altitude))
        if vz > up or vz < -down:
            vz = _clip(vz, -down, up)
            cut = True
        if cut:
            notes.append(('fence_braking', 'velocity toward the geofence cut to stop on it at %.1f m/s^2' % a))
        return vx, vy, vz

    # -- the target --------------------------------------------------------------------------------
    def limit_target(self, position, velocity, centre, drone):
        """(position, velocity, notes) of a target: ``position`` (x, y, z) [m], ``velocity`` (vx, vy, vz) [m/s]
        world ENU; ``centre`` (x, y) of the fence or None (only the altitude band); ``drone`` (x, y, z) or
        None (no reach limit). Unchanged tuples when no limit acts."""
        notes = []
        x, y, z = position
        vx, vy, vz = velocity
        x, y, z = self._fence(x, y, z, centre, notes)
        if drone is not None:
            dx, dy, dz = x - drone[0], y - drone[1], z - drone[2]
            d = math.hypot(_norm2(dx, dy), dz)
            if d > self.max_waypoint_jump:
                k = self.max_waypoint_jump / d
                x, y, z = drone[0] + dx * k, drone[1] + dy * k, drone[2] + dz * k
                vx = vy = vz = 0.0
                notes.append(('reach', 'waypoint too far from the drone (%.1f m > %.1f m): approaching it'
                              % (d, self.max_waypoint_jump)))
                x, y, z = self._fence(x, y, z, centre, [])       # a drone outside the fence: back onto it
        h = _norm2(vx, vy)
        if h > self.max_reference_speed:
            notes.append(('speed', 'reference speed %.3g m/s > %.1f m/s' % (h, self.max_reference_speed)))
            m = max(abs(vx), abs(vy))
            ux, uy = vx / m, vy / m
            k = self.max_reference_speed / math.hypot(ux, uy)
            vx, vy = ux * k, uy * k
        if abs(vz) > self.max_reference_vertical_speed:
            notes.append(('vertical_speed', 'reference vertical speed %.3g m/s > %.1f m/s'
                          % (abs(vz), self.max_reference_vertical_speed)))
            vz = math.copysign(self.max_reference_vertical_speed, vz)
        vx, vy, vz = self._brake(x, y, z, vx, vy, vz, centre, notes, drone)
        if not notes:
            return tuple(position), tuple(velocity), notes
        return (x, y, z), (vx, vy, vz), notes

    def limit_waypoint(self, waypoint, centre, drone):
        """(waypoint, notes): the waypoint (x, y, z, vx, vy, vz, yaw_deg) as a target (``limit_target``)."""
        position, velocity, notes = self.limit_target(waypoint[0:3], waypoint[3:6], centre, drone)
        if not notes:
            return waypoint, notes
        return tuple(position) + tuple(velocity) + tuple(waypoint[6:]), notes

    def limit_acceleration(self, acceleration):
        """(acceleration, notes): a reference acceleration (ax, ay, az) [m/s^2] bounded by
        max_reference_acceleration (horizontal norm and |a_z|)."""
        ax, ay, az = acceleration
        h = _norm2(ax, ay)
        if h <= self.max_reference_acceleration and abs(az) <= self.max_reference_acceleration:
            return acceleration, []
        if h > self.max_reference_acceleration:
            m = max(abs(ax), abs(ay))
            k = self.max_reference_acceleration / math.hypot(ax / m, ay / m)
            ax, ay = ax / m * k, ay / m * k
        az = _clip(az, -self.max_reference_acceleration, self.max_reference_acceleration)
        return (ax, ay, az), [('acceleration',
                               'reference acceleration > %.1f m/s^2' % self.max_reference_acceleration)]

    def inert(self, positions, velocities, accelerations, centre, drone, margin=1e-6):
        """True when neither ``limit_target`` nor ``limit_acceleration`` can act on any sample of the arrays
        (n, 3) (positions, velocities, accelerations world ENU; ``centre``, ``drone`` as ``limit_target``): every
        sample inside every limit by more than ``margin`` (far above the rounding of these few operations), so
        a whole reference is checked at once; False when one may act (then limit each sample) or on NaN."""
        import numpy as np
        P = np.asarray(positions, dtype=float)
        V = np.asarray(velocities, dtype=float)
        A = np.asarray(accelerations, dtype=float)
        x, y, z = P[:, 0], P[:, 1], P[:, 2]
        vx, vy, vz = V[:, 0], V[:, 1], V[:, 2]
        with np.errstate(all='ignore'):
            room_up, room_down = self.max_altitude - z, z - self.min_altitude
            ok = (room_up > margin) & (room_down > margin) & (np.abs(x) < 1e8) & (np.abs(y) < 1e8)
            a = BRAKING * self.max_reference_acceleration
            if centre is not None:
                dx, dy = x - centre[0], y - centre[1]
                r = np.sqrt(dx * dx + dy * dy)
                room = self.target_radius - r
                ok &= room > margin
                out = vx * dx + vy * dy
                ok &= (out <= 0.0) | (out / np.where(r > 0.0, r, 1.0) < np.sqrt(2.0 * a * np.maximum(room, 0.0)) - margin)
            if drone is not None:
                ddx, ddy, ddz = x - drone[0], y - drone[1], z - drone[2]
                ok &= np.sqrt(ddx * ddx + ddy * ddy + ddz * ddz) < self.max_waypoint_jump - margin
            ok &= np.sqrt(vx * vx + vy * vy) < self.max_reference_speed - margin
            ok &= np.abs(vz) < self.max_reference_vertical_speed - margin
            ok &= vz < np.sqrt(2.0 * a * np.maximum(room_up, 0.0)) - margin
            ok &= -vz < np.sqrt(2.0 * a * np.maximum(room_down, 0.0)) - margin
            ok &= np.sqrt(A[:, 0] * A[:, 0] + A[:, 1] * A[:, 1]) < self.max_reference_acceleration - margin
            ok &= np.abs(A[:, 2]) < self.max_reference_acceleration - margin
        return bool(np.all(ok))

    # -- the command -------------------------------------------------------------------------------
    def limit_command(self, command):
        """(command, notes): (roll deg, pitch deg, yaw rate deg/s, gaz m/s) with |roll|, |pitch| <=
        max_command_tilt_deg (gaz: the bridge clips it to the firmware's max vertical speed); None stays None."""
        if command is None:
            return command, []
        roll, pitch, yaw_rate, gaz = command
        notes = []
        t = self.max_command_tilt_deg
        if abs(roll) > t or abs(pitch) > t:
            notes.append(('tilt', 'commanded tilt (%.1f, %.1f) deg clipped to %.2f deg' % (roll, pitch, t)))
            roll, pitch = _clip(roll, -t, t), _clip(pitch, -t, t)
        if not notes:
            return command, notes
        return (roll, pitch, yaw_rate, gaz), notes


def reason(notes):
    """The text of the notes of one cycle: their texts joined by '; ' (each limit once)."""
    seen, texts = set(), []
    for name, text in notes:
        if name not in seen:
            seen.add(name)
            texts.append(text)
    return '; '.join(texts)
