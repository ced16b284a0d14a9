"""Gazebo mirror core: ground truth -> the model states sent to Gazebo (pure, no ROS).

Stage: telemetry -> interface -> **mirror** -> Gazebo (or the kinematic stand-in world).

Inputs are the interface's numbers: drone position [m] and orientation
quaternion (x, y, z, w) in the world ENU frame, body-frame (FLU) linear [m/s]
and angular [rad/s] velocity (nav_msgs/Odometry carries the twist in the
child frame), the gimbal roll/pitch motor angles [rad, relative to the body]
and the sample's stamp [s, ROS clock]. Outputs are ``ModelStateSpec`` s for
two models, the drone body and its camera, with the twist rotated into the
world frame (gazebo_msgs/ModelState's twist is in ``reference_frame``).
The camera pose is ``anafi_sim.interface.ground_truth.camera_pose`` (gimbal angles from the telemetry,
``camera_attitude_source='telemetry'``), or, with ``camera_attitude_source='bridge'``, the camera attitude
the anafi_ros bridge publishes on camera/attitude (``on_camera_attitude``): referenced to north-west-up
despite its frame_id "/body" (``anafi_sim.sim.bridge``, README "The camera attitude"), so the world
orientation is ``anafi_control.frames.enu_from_nwu`` of it, heading included; position as above.

``Mirror`` rejects non-finite, stale (older than ``stale_timeout``),
future-stamped and duplicate samples with counters, limits the output to
``rate``, keeps lag statistics (ground-truth stamp -> sent), and, once the
input goes stale, emits one "hold" state (zero twist) so that a world that
integrates the twist does not drift away. Its ``spawn`` attribute is the
``anafi_sim.gazebo.spawn.SpawnTracker`` of the two models (spawn bookkeeping).
Rotations: ``anafi_control.frames``.
"""
import collections
import math

import numpy as np

from anafi_control import frames
from anafi_sim.gazebo import urdf_model
from anafi_sim.gazebo.spawn import SpawnTracker
from anafi_sim.interface.ground_truth import (DEFAULT_CAMERA_OFFSET, ERROR, OK, WARN, Health, NewCounts, RateWindow,
                                             RateLimiter, camera_pose)

ModelStateSpec = collections.namedtuple('ModelStateSpec',
                                        'model_name position orientation linear angular reference_frame')
"""One gazebo_msgs/ModelState: position (x, y, z) [m] and orientation (x, y, z, w) in ``reference_frame``
('world'); linear [m/s] and angular [rad/s] velocity in the same frame."""

LagStats = collections.namedtuple('LagStats', 'count mean p50 p99 max')
"""Lag [s] statistics over the window (None values when empty)."""


def model_names(drone_name, drone_model_name='', camera_model_name=''):
    """Gazebo model names of a drone: ('<drone>', '<drone>_camera') unless given explicitly."""
    base = str(drone_name).strip('/').replace('/', '_') or 'anafi'
    return (drone_model_name or base), (camera_model_name or base + '_camera')


def _rotate(rot, v):
    """``rot`` (3x3, nested lists) times the 3-vector ``v``, as a tuple of floats. Plain Python: for one
    3-vector per sample it is several times cheaper than numpy's call overhead (np.cross alone was a third of
    the mirror's CPU; benchmarks/results/fleet.md)."""
    x, y, z = float(v[0]), float(v[1]), float(v[2])
    return tuple(r[0] * x + r[1] * y + r[2] * z for r in rot)


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def body_twist_to_world(orientation, linear_body, angular_body):
    """Rotate a body-frame twist into the world frame: (linear [m/s], angular [rad/s]) tuples."""
    rot = frames.quaternion_matrix(orientation).tolist()
    return _rotate(rot, linear_body), _rotate(rot, angular_body)


def drone_model_state(name, position, orientation, linear_body, angular_body, reference_frame='world'):
    """ModelStateSpec of the drone body from its world pose and body-frame twist."""
    q = frames.normalize_quaternion(orientation)
    lin, ang = body_twist_to_world(q, linear_body, angular_body)
    return ModelStateSpec(name, tuple(float(v) for v in position), q, lin, ang, reference_frame)


def camera_model_state(name, position, orientation, linear_body, angular_body, gimbal_roll, gimbal_pitch,
                       offset=DEFAULT_CAMERA_OFFSET, reference_frame='world'):
    """ModelStateSpec of the camera: pose from ``camera_pose`` (drone pose + gimbal angles [rad] + body-frame
    ``offset`` [m]); twist of the rigidly attached point: v + w x (R offset), angular w (world frame;
    gimbal motor rates are not in the telemetry and are ignored)."""
    q = frames.normalize_quaternion(orientation)
    roll, pitch, yaw = frames.quaternion_to_euler(*q)
    cam_position, cam_q = camera_pose(position, roll, pitch, yaw, gimbal_roll, gimbal_pitch, offset)
    rot = frames.quaternion_matrix(q).tolist()
    lin, ang = _rotate(rot, linear_body), _rotate(rot, angular_body)
    lever = _rotate(rot, offset)
    lin = tuple(a + b for a, b in zip(lin, _cross(ang, lever)))
    return ModelStateSpec(name, cam_position, tuple(float(v) for v in cam_q), lin, ang, reference_frame)


def camera_model_state_from_attitude(name, position, orientation, linear_body, angular_body, camera_orientation,
                                     offset=DEFAULT_CAMERA_OFFSET, reference_frame='world'):
    """ModelStateSpec of the camera at its world orientation ``camera_orientation`` (x, y, z, w; ENU, FLU
    camera axes): position and twist of the body point ``offset`` as in ``camera_model_state``."""
    q = frames.normalize_quaternion(orientation)
    rot = frames.quaternion_matrix(q).tolist()
    lin, ang = _rotate(rot, linear_body), _rotate(rot, angular_body)
    lever = _rotate(rot, offset)
    lin = tuple(a + b for a, b in zip(lin, _cross(ang, lever)))
    cam_position = tuple(float(p) + d for p, d in zip(position, lever))
    cam_q = frames.normalize_quaternion(camera_orientation)
    return ModelStateSpec(name, cam_position, tuple(float(v) for v in cam_q), lin, ang, reference_frame)


def camera_world_orientation(bridge_quaternion):
    """World (ENU) orientation of the camera from the anafi_ros bridge's camera/attitude quaternion."""
    return frames.enu_from_nwu(frames.normalize_quaternion(bridge_quaternion))


CAMERA_ATTITUDE_SOURCES = ('telemetry', 'bridge')
"""Where the camera model's attitude comes from: the telemetry's gimbal angles, or the bridge's camera/attitude."""


def hold_state(state):
    """The same pose with zero twist (sent when the input goes stale)."""
    return state._replace(linear=(0.0, 0.0, 0.0), angular=(0.0, 0.0, 0.0))


def _finite(values):
    for v in values:
        if not isinstance(v, (int, float)) or v - v != 0.0:
            return False
    return True


BURST = 3
"""Samples the rate limit lets through at once (anafi_sim.interface.ground_truth.RateLimiter): the ground truth's
stamps are the interface's receipt times, which a busy process makes late, early or pairs; at most ~rate
samples per second pass on average."""

class Mirror(object):
    """Turns ground-truth samples into model states for the drone and its camera.

    drone_name: names the models (``model_names``); rate [Hz]: at most this many states per model per
    second of stamp time (``rate_tolerance`` = fraction of a period a sample may come early);
    stale_timeout [s]: samples older than this (now - stamp) are rejected and the mirror holds;
    camera_offset: camera position in the body frame [m]; spawn_camera: mirror the camera model too;
    lag_window: number of lag samples kept; retry_period / missing_grace: see ``SpawnTracker``;
    camera_attitude_source: 'telemetry' (gimbal angles, ``on_gimbal``) or 'bridge' (``on_camera_attitude``).
    """

    def __init__(self, drone_name='anafi', rate=100.0, stale_timeout=0.2, camera_offset=DEFAULT_CAMERA_OFFSET,
                 drone_model_name='', camera_model_name='', spawn_camera=True, rate_tolerance=0.3,
                 lag_window=2000, rate_window=1.0, retry_period=1.0, missing_grace=1.0,
                 reference_frame='world', low_rate_fraction=0.9, camera_attitude_source='telemetry'):
        for name, value in (('rate', rate), ('stale_timeout', stale_timeout), ('rate_window', rate_window),
                            ('retry_period', retry_period)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError('%s must be a finite number > 0, got %r' % (name, value))
        if not 0.0 <= rate_tolerance < 1.0:
            raise ValueError('rate_tolerance must be in [0, 1), got %r' % (rate_tolerance,))
        offset = tuple(float(v) for v in camera_offset)
        if len(offset) != 3 or not _finite(offset):
            raise ValueError('camera_offset must be 3 finite numbers [m], got %r' % (camera_offset,))
        if camera_attitude_source not in CAMERA_ATTITUDE_SOURCES:
            raise ValueError('camera_attitude_source must be one of %s, got %r'
                             % (', '.join(CAMERA_ATTITUDE_SOURCES), camera_attitude_source))
        self.camera_attitude_source = camera_attitude_source
        self.camera_attitude = None    # world orientation of the camera from the bridge (x, y, z, w)
        if int(lag_window) < 1:
            raise ValueError('lag_window must be >= 1')
        self.drone_model, self.camera_model = model_names(drone_name, drone_model_name, camera_model_name)
        if self.drone_model == self.camera_model:
            raise ValueError('drone and camera model names must differ, both are %r' % self.drone_model)
        self.rate = float(rate)
        self.period = 1.0 / self.rate
        self.stale_timeout = float(stale_timeout)
        self.camera_offset = offset
        self.spawn_camera = bool(spawn_camera)
        self.reference_frame = reference_frame
        self.rate_window = float(rate_window)
        self.low_rate_fraction = low_rate_fraction
        self._early = rate_tolerance * self.period
        names = (self.drone_model, self.camera_model) if self.spawn_camera else (self.drone_model,)
        self.spawn = SpawnTracker(names, retry_period, missing_grace)
        # counters
        self.received = 0
        self.accepted = 0
        self.sent = 0                  # cycles that produced states to send
        self.decimated = 0
        self.rejected_nonfinite = 0
        self.rejected_stale = 0
        self.rejected_future = 0       # stamp ahead of the clock by more than stale_timeout
        self.duplicates = 0
        self.stamp_resets = 0          # stamp jumped back (simulator / interface restart)
        self.not_spawned = 0           # accepted samples with no model in the world to move
        self.holds = 0
        self.gimbal_received = 0
        self.gimbal_rejected = 0
        # state
        self.gimbal = None             # (roll, pitch) [rad]
        self.gimbal_stamp = None
        self.last_stamp = None
        self.last_receipt = None       # 'now' of the last accepted sample
        self.last_states = []
        self._held = False
        self._decimator = RateLimiter(self.period, burst=BURST)   # receipt-time stamps: jitter, pairs
        self._lags = collections.deque(maxlen=int(lag_window))
        self._sent = RateWindow(self.rate_window)
        self._new = NewCounts()

    # --- inputs -------------------------------------------------------------------------------

    def on_gimbal(self, gimbal_roll, gimbal_pitch, stamp, now):
        """Gimbal motor angles [rad, relative to the body]; returns True when accepted."""
        self.gimbal_received += 1
        if not _finite((gimbal_roll, gimbal_pitch, stamp, now)):
            self.gimbal_rejected += 1
            return False
        self.gimbal = (float(gimbal_roll), float(gimbal_pitch))
        self.gimbal_stamp = float(stamp)
        return True

    def on_camera_attitude(self, quaternion, stamp, now):
        """The bridge's camera/attitude quaternion (x, y, z, w; see the module doc); True when accepted
        (counted with the gimbal inputs)."""
        self.gimbal_received += 1
        try:
            if not _finite(tuple(quaternion) + (stamp, now)):
                raise ValueError('non-finite')
            self.camera_attitude = camera_world_orientation(quaternion)
        except (ValueError, TypeError):
            self.gimbal_rejected += 1
            return False
        self.gimbal_stamp = float(stamp)
        return True

    def on_ground_truth(self, position, orientation, linear_body, angular_body, stamp, now):
        """A ground-truth sample (see module doc; ``stamp`` and ``now`` on the ROS clock [s]).

        Returns the ModelStateSpec list to send now (drone, then camera; only models that are spawned),
        possibly empty.
        """
        self.received += 1
        numbers = tuple(position) + tuple(orientation) + tuple(linear_body) + tuple(angular_body)
        if len(numbers) != 13 or not _finite(numbers + (stamp, now)):
            self.rejected_nonfinite += 1
            return []
        try:
            q = frames.normalize_quaternion(orientation)
        except ValueError:
            self.rejected_nonfinite += 1
            return []
        age = now - stamp
        if age > self.stale_timeout:
            self.rejected_stale += 1
            return []
        if age < -self.stale_timeout:
            self.rejected_future += 1
            return []
        last = self.last_stamp
        if last is not None:
            if stamp == last:
                self.duplicates += 1
                return []
            if stamp < last:
                self.stamp_resets += 1
                self._decimator.reset()
        self.last_stamp = stamp
        self.last_receipt = now
        self.accepted += 1
        if not self._decimator.accept(stamp, self._early):
            self.decimated += 1
            return []

        states = [drone_model_state(self.drone_model, position, q, linear_body, angular_body,
                                    self.reference_frame)]
        if self.spawn_camera and self.camera_attitude_source == 'bridge':
            camera_q = self.camera_attitude
            if camera_q is None:         # none yet: level, along the drone's heading
                camera_q = frames.euler_to_quaternion(0.0, 0.0, frames.yaw_from_quaternion(*q))
            states.append(camera_model_state_from_attitude(self.camera_model, position, q, linear_body,
                                                           angular_body, camera_q, self.camera_offset,
                                                           self.reference_frame))
        elif self.spawn_camera:
            g_roll, g_pitch = self.gimbal if self.gimbal is not None else (0.0, 0.0)
            states.append(camera_model_state(self.camera_model, position, q, linear_body, angular_body,
                                             g_roll, g_pitch, self.camera_offset, self.reference_frame))
        self.last_states = states
        self._held = False
        states = [s for s in states if self.spawn.is_spawned(s.model_name)]
        if not states:
            self.not_spawned += 1
        return states

    def check_stale(self, now):
        """Called periodically: once the input is stale, returns the last states with zero twist (once)."""
        if self._held or not self.last_states or self.last_receipt is None:
            return []
        if now - self.last_receipt <= self.stale_timeout:
            return []
        self._held = True
        self.holds += 1
        return [hold_state(s) for s in self.last_states if self.spawn.is_spawned(s.model_name)]

    def spawn_pose(self, name):
        """(position, orientation) to spawn model ``name`` at: its latest state, else the world origin."""
        for state in self.last_states:
            if state.model_name == name:
                return state.position, state.orientation
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)

    def record_sent(self, stamp, sent_time):
        """The states of the sample stamped ``stamp`` went out at ``sent_time`` (ROS clock [s])."""
        self.sent += 1
        self._lags.append(sent_time - stamp)
        self._sent.add(sent_time)

    # --- statistics and health ----------------------------------------------------------------

    def sent_rate(self, now):
        """Send cycles per second over the last ``rate_window`` seconds."""
        return self._sent.rate(now)

    def lag_stats(self):
        """LagStats [s] of ground-truth stamp -> sent over the last ``lag_window`` cycles."""
        if not self._lags:
            return LagStats(0, None, None, None, None)
        lags = np.asarray(self._lags, dtype=float)
        return LagStats(len(lags), float(lags.mean()), float(np.percentile(lags, 50)),
                        float(np.percentile(lags, 99)), float(lags.max()))

    def input_age(self, now):
        """Seconds since the last accepted sample, or None."""
        return None if self.last_receipt is None else now - self.last_receipt

    def health(self, now):
        """Diagnostics summary (``ground_truth.Health``) at ``now``."""
        sp = self.spawn
        rate = self.sent_rate(now)
        lag = self.lag_stats()
        age = self.input_age(now)

        def ms(v):
            return 'n/a' if v is None else '%.1f' % (1000.0 * v)

        values = [
            ('mirror rate [Hz]', '%.1f' % rate),
            ('target rate [Hz]', '%.1f' % self.rate),
            ('lag p50 [ms]', ms(lag.p50)),
            ('lag p99 [ms]', ms(lag.p99)),
            ('lag max [ms]', ms(lag.max)),
            ('input age [s]', 'none yet' if age is None else '%.3f' % age),
            ('samples received', str(self.received)),
            ('samples sent', str(self.sent)),
            ('samples decimated', str(self.decimated)),
            ('rejected non-finite', str(self.rejected_nonfinite)),
            ('rejected stale', str(self.rejected_stale)),
            ('rejected future stamp', str(self.rejected_future)),
            ('duplicates', str(self.duplicates)),
            ('stamp resets', str(self.stamp_resets)),
            ('holds (zero twist on stale input)', str(self.holds)),
            ('gimbal received', str(self.gimbal_received)),
            ('gimbal rejected', str(self.gimbal_rejected)),
            ('world available', str(sp.world_available)),
            ('models', ', '.join('%s=%s' % (n, sp.state[n]) for n in sp.names)),
            ('spawns', str(sp.spawns)),
            ('respawns', str(sp.respawns)),
            ('spawn failures', str(sp.spawn_failures)),
            ('world restarts', str(sp.world_restarts)),
            ('world losses', str(sp.world_losses)),
            ('models missing', str(sp.models_missing)),
            ('last error', sp.last_error or 'none'),
        ]
        current = {'non-finite samples': self.rejected_nonfinite, 'stale samples': self.rejected_stale,
                   'future-stamped samples': self.rejected_future, 'gimbal rejects': self.gimbal_rejected,
                   'spawn failures': sp.spawn_failures, 'world restarts': sp.world_restarts + sp.world_losses,
                   'missing models': sp.models_missing}
        news = self._new.news(current)

        if not sp.world_available:
            level = ERROR
            message = ('Gazebo not available (waiting for spawn service, retrying)' if not sp.world_seen
                       else 'Gazebo went away; waiting to respawn')
        elif not sp.all_spawned:
            level, message = WARN, 'spawning models (%s)' % (sp.last_error or 'in progress')
        elif age is None:
            level = ERROR
            message = 'no ground truth accepted yet'
            if self.rejected_stale or self.rejected_future:
                message += ' (%d stale / %d future-stamped: clock mismatch?)' % (self.rejected_stale,
                                                                                 self.rejected_future)
        elif age > self.stale_timeout:
            level, message = ERROR, 'ground truth stale for %.1f s: holding models' % age
        elif rate < self.low_rate_fraction * self.rate:
            level, message = WARN, 'mirroring %.1f Hz < %.1f Hz' % (rate, self.rate)
        elif self.spawn_camera and self.camera_attitude_source == 'bridge' and self.camera_attitude is None:
            level, message = WARN, 'mirroring %.1f Hz, no camera attitude from the bridge yet (camera level)' % rate
        elif self.spawn_camera and self.camera_attitude_source == 'telemetry' and self.gimbal is None:
            level, message = WARN, 'mirroring %.1f Hz, no gimbal angles yet (camera at 0, 0)' % rate
        elif news:
            level, message = WARN, 'mirroring %.1f Hz but ' % rate + ', '.join(news)
        else:
            level, message = OK, 'mirroring %.1f Hz' % rate
        if news and level == ERROR:
            message += ' (' + ', '.join(news) + ')'
        return Health(level, message, values)


def model_warnings(xml):
    """What is wrong with a URDF to mirror (ValueError when it is unreadable): links with gravity ON sag
    between updates, collision geometry cannot act on Sphinx (the paper switches both off)."""
    try:
        model = urdf_model.parse_urdf(xml)
    except urdf_model.UrdfError as error:
        raise ValueError(str(error))
    warnings = []
    if model.has_gravity:
        warnings.append('gravity ON for links %s: it will sag between updates (the paper switches gravity off)'
                        % ', '.join(model.gravity_links))
    if model.has_collisions:
        warnings.append('collision geometry on links %s: contacts in Gazebo cannot act on Sphinx (the paper '
                        'switches collisions off)' % ', '.join(model.collision_links))
    return warnings


def namespaced_model_xml(xml, drone_name, default_name='anafi'):
    """Model XML with the ``<frameName>default_name/...`` of sensor plugins renamed to ``drone_name/...``."""
    base = str(drone_name).strip('/')
    if not base or base == default_name:
        return xml
    return xml.replace('<frameName>%s/' % default_name, '<frameName>%s/' % base)
