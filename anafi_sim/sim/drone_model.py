"""Dynamics of the simulated Anafi (stand-in for Sphinx + firmware), pure Python.

Stage: piloting command -> simulated drone. ``AnafiModel`` takes the PCMD
percents the anafi_ros bridge would send (``anafi_sim.sim.bridge.PilotingMapping``
turns them into firmware setpoints) and integrates:

- roll/pitch: first-order tracking (``attitude_time_constant``) of the
  setpoint after a pure delay (``attitude_delay``, applied to the whole PCMD),
  clamped to the max tilt; yaw rate: first order (``yaw_rate_time_constant``);
- vertical speed: first order (``vertical_speed_time_constant``), realised by
  choosing the specific thrust T along body z;
- translation: a = T z_body - g e_z - drag; horizontal drag on the airspeed
  v_air = v - wind: (drag_linear + drag_quadratic |v_air_h|) v_air_h; vertical
  drag ``drag_vertical`` v_air_z; wind = constant + Ornstein-Uhlenbeck gusts
  (seeded numpy Generator: deterministic for a seed and a step sequence);
- a flight state machine ``landed | taking_off | flying | landing`` and the
  firmware's hover brake when no command came for ``command_timeout`` s.

Firmware effects switched by keys that are OFF by default (``EFFECTS_OFF``;
fitted by ``anafi_lab/calibration/fit.py``, see docs/calibration.md):

- ``tilt_attenuation`` a: the firmware delivers (1 - a) of the roll/pitch a
  PCMD commands (before the max-tilt clamp); its own hover brake is not
  attenuated; with ``tilt_attenuation_speed`` v0 > 0 [m/s] it acts as a speed
  governor instead: only above that horizontal speed, by a x clip((|v| - v0) /
  (v1 - v0), 0, 1) with v1 = ``tilt_attenuation_speed_full`` [m/s] (> v0), |v|
  the true horizontal speed when the PCMD arrives, and only on the part of the
  tilt that drives the drone along its velocity (a braking or sideways tilt is
  delivered whole: the logs show steady fast flight only, see
  docs/calibration.md);
- ``max_descent_speed`` [m/s]: the firmware descends at most this fast,
  whatever the commanded vertical speed (0 = no limit beyond the PCMD's);
- ``tilt_rate_limit`` R [rad/s]: the roll/pitch loop moves the tilt (the vector
  (roll, pitch)) at most this fast: a large attitude step ramps at R, a small
  one follows the first order (0 = no limit); its fit refits
  ``attitude_time_constant`` with it (``EFFECT_GROUPS``);
- ``vertical_acceleration_limit`` A [m/s^2]: the vertical-speed loop accelerates
  at most this much (up and down): a large step ramps at A, a small one follows
  the first order (0 = no limit). Its fit refits ``vertical_speed_time_constant``
  with it (``EFFECT_GROUPS``);
- ``gyroscopic_coupling`` G [s]: while the drone yaws at r [rad/s] the roll/pitch
  loop's step is turned and slowed, d(tilt)/dt = (setpoint - tilt) / tau +
  G r J d(tilt)/dt in the (forward, left) tilt plane (J: a quarter turn
  counter-clockwise), i.e. each step is multiplied by (I - G r J)^-1: rotated by
  atan(G r) and shortened by 1 / sqrt(1 + (G r)^2) (``frames.gyroscopic_step``;
  the exact first-order step, then the turn: the meaning of G depends slightly on
  dt, ~1.4 % at 5 ms, the step of the fit). With G < 0 (the fit) the tilt swings
  round the long way in the sense of the yaw, as Sphinx's does in the 180 deg
  turns (docs/calibration.md); no effect without a yaw rate (0 = none, signed).
  The same effect has two more terms, fitted with G: ``yaw_tilt_authority`` c
  [1/rad]: the loop's rate 1 / tau is reduced by c |r| (none left beyond
  |r| = 1 / (c tau): the tilt is held, not driven to the setpoint), and
  ``yaw_tilt_precession`` w [-]: the tilt turns in the body frame at w r
  (after the step; not bound by ``tilt_rate_limit``, which caps the step).
  Through Sphinx's 180 deg turns (yaw rate 100-140 deg/s) the tilt keeps its
  magnitude (25-30 deg) and turns with the body at ~1.3x the yaw rate while the
  command swings through level (docs/calibration.md). The whole loop:
  ``frames.tilt_loop_step``.

The firmware's wind handling (identified from the real-flight logs, anafi_sim/data/reference_logs/real; settings,
not model keys, because Sphinx flew without wind and cannot show it; docs/calibration.md "Wind handling"):
``wind_compensation`` K [-] (0 = off) and ``wind_compensation_time_constant`` tau_w [s]. The firmware keeps
an estimate d of the horizontal acceleration the wind puts on the drone, the difference between the drag on
the airspeed and the drag on the ground speed, (k(|v|) v - k(|v_air|) v_air), followed by a first order of
time constant tau_w (0: at once), and adds the tilt that cancels K x d to the roll/pitch setpoint (world
acceleration -K d turned into the body axes, added to the setpoint's own thrust acceleration at a level
altitude) before the max-tilt clamp, in
every flight state. The real Anafi, piloted by near-zero attitude commands, holds ~0.2 rad of tilt into a
~6 m/s wind (drag-equivalent) and keeps its point. The estimate is the model's, not a sensor's: the effect
is inert without wind (no step runs it while the wind and the gusts are zero: bit for bit the model
without it).

The estimate's effects (position fusion, yaw bias, quantisation) are
``anafi_sim/sim/state_estimate.py``'s. With every effect off the model is bit
for bit the one without them.

Firmware behaviour without a command (shared/interfaces/anafi_ros.md): a
streamed PCMD of zeros holds level attitude and 0 m/s climb, so the drone
keeps drifting with its momentum and the wind; when the stream stops for
``command_timeout`` s the hover brake stops the drone and holds the point.

Frames and units (REP-103): world ENU [m, m/s]; Euler roll/pitch/yaw of the
FLU body [rad] (R = Rz(yaw) Ry(pitch) Rx(roll), positive pitch = nose down);
body quantities in FLU. The body linear acceleration is the *kinematic*
acceleration dv/dt rotated into the body frame (no gravity), as Sphinx
reports it. Integration: semi-implicit Euler at the caller's dt with exact
first-order discretisation of the loops.
"""
import collections
import math
import os

import numpy as np

from anafi_control import frames
from anafi_sim import paths
from anafi_sim.sim import state_estimate
from anafi_sim.sim.bridge import PilotingMapping
from anafi_sim.telemetry.protocol import TelemetrySample

LANDED = 'landed'
TAKING_OFF = 'taking_off'
FLYING = 'flying'
LANDING = 'landing'
FLIGHT_STATES = (LANDED, TAKING_OFF, FLYING, LANDING)

# Keys every model dict has (anafi_sim/config/anafi_model.yaml, fitted by scripts/calibrate_model.py).
REQUIRED_KEYS = (
    'gravity',                       # m/s^2
    'attitude_time_constant',        # s
    'attitude_delay',                # s
    'yaw_rate_time_constant',        # s
    'vertical_speed_time_constant',  # s
    'drag_linear',                   # 1/s
    'drag_quadratic',                # 1/m
    'drag_vertical',                 # 1/s
    'estimate_delay',                # s
    'estimate_time_constant',        # s
    'estimate_rate',                 # Hz
    'estimate_float16',              # bool
)
# Optional effect keys and the values that switch them off (missing = off); anafi_model.yaml ships them off,
# anafi_model_fitted.yaml has every one on (docs/calibration.md).
EFFECTS_OFF = collections.OrderedDict((
    ('tilt_attenuation', 0.0),       # fraction of the commanded roll/pitch not delivered, in [0, 1)
    ('tilt_attenuation_speed', 0.0),       # m/s, v0: no attenuation below this horizontal speed (0 = at any speed)
    ('tilt_attenuation_speed_full', 0.0),  # m/s, v1 > v0: the full fraction from this speed on (ramp v0..v1)
    ('max_descent_speed', 0.0),      # m/s, firmware descent limit (0 = none)
    ('vertical_acceleration_limit', 0.0),  # m/s^2, vertical-speed loop acceleration limit (0 = none)
    ('tilt_rate_limit', 0.0),        # rad/s, roll/pitch loop: largest rate of the tilt vector (0 = none)
    ('gyroscopic_coupling', 0.0),    # s, roll/pitch step turned by atan(G x yaw rate) and slowed (0 = none, signed)
    ('yaw_tilt_authority', 0.0),     # 1/rad, roll/pitch loop's rate 1/tau reduced by this x |yaw rate| (0 = none)
    ('yaw_tilt_precession', 0.0),    # -, the tilt turned in the body frame at this x yaw rate (0 = none, signed)
))
EFFECTS_OFF.update(state_estimate.EFFECTS_OFF)
# The effects by name and their keys (the estimate's delay/smoothing, refitted on velocity and attitude alone
# when the position has its own model, goes with the fusion).
EFFECT_GROUPS = collections.OrderedDict((
    ('position_fusion', ('estimate_position_fusion', 'estimate_position_fix_delay', 'estimate_position_fix_gain',
                         'estimate_delay', 'estimate_time_constant')),
    ('velocity_error', ('estimate_velocity_error_time_constant',)),
    ('tilt_attenuation', ('tilt_attenuation', 'tilt_attenuation_speed', 'tilt_attenuation_speed_full')),
    ('max_descent_speed', ('max_descent_speed',)),
    ('vertical_acceleration_limit', ('vertical_acceleration_limit', 'vertical_speed_time_constant')),
    ('tilt_rate_limit', ('tilt_rate_limit', 'attitude_time_constant')),
    ('gyroscopic_coupling', ('gyroscopic_coupling', 'yaw_tilt_authority', 'yaw_tilt_precession')),
    ('yaw_bias', ('estimate_yaw_bias',)),
    ('quantisation', ('estimate_quantum_x', 'estimate_quantum_y', 'estimate_quantum_z', 'estimate_quantum_velocity')),
))
# Every key of anafi_model.yaml, in file order.
MODEL_KEYS = REQUIRED_KEYS + tuple(EFFECTS_OFF)
_POSITIVE = ('gravity', 'estimate_rate')
_BOOLEAN = ('estimate_float16',)

# Simulator / firmware settings that are not fitted (anafi_sim/config/sim.yaml holds the same values).
DEFAULT_SETTINGS = {
    'command_timeout': 0.5,          # s without PCMD -> hover brake
    'takeoff_altitude': 1.0,         # m
    'takeoff_speed': 0.8,            # m/s climb during take-off
    'landing_speed': 0.6,            # m/s descent during landing
    'initial_x': 0.0,                # m, world ENU
    'initial_y': 0.0,                # m
    'initial_yaw': 0.0,              # rad
    'wind_x': 0.0,                   # m/s, constant wind, world ENU
    'wind_y': 0.0,
    'wind_z': 0.0,
    'gust_std_horizontal': 0.0,      # m/s, stationary std of the gusts (x and y)
    'gust_std_vertical': 0.0,        # m/s
    'gust_time_constant': 2.0,       # s, correlation time of the gusts
    'brake_velocity_gain': 2.0,      # 1/s, hover brake: a = -k_v v, then hold: + k_p e + k_i int(e)
    'brake_position_gain': 2.0,      # 1/s^2, e = p_hold - p (horizontal)
    'brake_integral_gain': 0.8,      # 1/s^3 (holds position against wind)
    'brake_altitude_gain': 1.0,      # 1/s, vz = k_z (z_hold - z)
    'brake_capture_speed': 0.1,      # m/s, below this the brake captures the hold point ...
    'brake_capture_time': 3.0,       # s, ... or after braking this long (e.g. drifting in wind)
    'max_specific_thrust': 25.0,     # m/s^2, thrust clamp
    'wind_compensation': 0.0,        # -, K: firmware cancels K x its wind-force estimate (0 = off)
    'wind_compensation_time_constant': 0.0,  # s, tau_w: first order of that estimate (0 = instantaneous)
}
_SETTINGS_POSITIVE = ('takeoff_altitude', 'takeoff_speed', 'landing_speed', 'gust_time_constant',
                      'brake_velocity_gain', 'brake_capture_speed', 'brake_capture_time',
                      'max_specific_thrust')
_SETTINGS_NONNEGATIVE = ('command_timeout', 'gust_std_horizontal', 'gust_std_vertical',
                         'brake_position_gain', 'brake_integral_gain', 'brake_altitude_gain',
                         'wind_compensation', 'wind_compensation_time_constant')

DEFAULT_MODEL_FILE = paths.config_path('anafi_model.yaml')


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def validate_model_params(params):
    """Check the model dict and return a clean copy; ValueError otherwise.

    ``REQUIRED_KEYS`` must all be present, the effect keys (``EFFECTS_OFF``) may be (missing = off; the
    copy has only the keys given), nothing else.
    """
    if not isinstance(params, dict):
        raise ValueError('model parameters must be a dict, got %r' % (type(params).__name__,))
    missing = [k for k in REQUIRED_KEYS if k not in params]
    unknown = sorted(str(k) for k in params if k not in MODEL_KEYS)
    if missing or unknown:
        raise ValueError('bad Anafi model parameters: missing %s, unknown %s (expected %s, optionally %s)'
                         % (missing, unknown, list(REQUIRED_KEYS), list(EFFECTS_OFF)))
    clean = {}
    for key in REQUIRED_KEYS:
        value = params[key]
        if key in _BOOLEAN:
            if not isinstance(value, bool):
                raise ValueError('model parameter %s must be true or false, got %r' % (key, value))
            clean[key] = value
            continue
        if not _is_number(value):
            raise ValueError('model parameter %s must be a finite number, got %r' % (key, value))
        if key in _POSITIVE and value <= 0.0:
            raise ValueError('model parameter %s must be > 0, got %r' % (key, value))
        if value < 0.0:
            raise ValueError('model parameter %s must be >= 0, got %r' % (key, value))
        clean[key] = float(value)
    given = [key for key in EFFECTS_OFF if key in params]
    if given:
        effects = state_estimate.validate_effects(params)
        for key in ('tilt_attenuation', 'tilt_attenuation_speed', 'tilt_attenuation_speed_full',
                    'max_descent_speed', 'vertical_acceleration_limit', 'tilt_rate_limit', 'yaw_tilt_authority'):
            value = params.get(key, EFFECTS_OFF[key])
            if not _is_number(value) or value < 0.0:
                raise ValueError('model parameter %s must be a finite number >= 0, got %r' % (key, value))
            effects[key] = float(value)
        for key in ('gyroscopic_coupling', 'yaw_tilt_precession'):     # signed
            value = params.get(key, EFFECTS_OFF[key])
            if not _is_number(value):
                raise ValueError('model parameter %s must be a finite number, got %r' % (key, value))
            effects[key] = float(value)
        if not effects['tilt_attenuation'] < 1.0:
            raise ValueError('model parameter tilt_attenuation must be < 1, got %r' % (effects['tilt_attenuation'],))
        if effects['tilt_attenuation_speed'] > 0.0 and \
                not effects['tilt_attenuation_speed_full'] > effects['tilt_attenuation_speed']:
            raise ValueError('model parameter tilt_attenuation_speed_full must be > tilt_attenuation_speed (%r), '
                             'got %r' % (effects['tilt_attenuation_speed'], effects['tilt_attenuation_speed_full']))
        for key in given:
            clean[key] = effects[key]
    return clean


def effect_params(params):
    """The effect values of a (validated) model dict, the missing ones off: {key: value} in file order."""
    return collections.OrderedDict((key, params.get(key, off)) for key, off in EFFECTS_OFF.items())


def validate_settings(settings=None):
    """Defaults overridden by ``settings`` (only keys of ``DEFAULT_SETTINGS``); ValueError otherwise."""
    clean = dict(DEFAULT_SETTINGS)
    if settings is None:
        return clean
    unknown = sorted(str(k) for k in settings if k not in DEFAULT_SETTINGS)
    if unknown:
        raise ValueError('unknown simulator settings %s (known: %s)' % (unknown, sorted(DEFAULT_SETTINGS)))
    for key, value in settings.items():
        if not _is_number(value):
            raise ValueError('simulator setting %s must be a finite number, got %r' % (key, value))
        if key in _SETTINGS_POSITIVE and value <= 0.0:
            raise ValueError('simulator setting %s must be > 0, got %r' % (key, value))
        if key in _SETTINGS_NONNEGATIVE and value < 0.0:
            raise ValueError('simulator setting %s must be >= 0, got %r' % (key, value))
        clean[key] = float(value)
    return clean


def model_file_path(value, settings_dir=None):
    """The model file a parameter names (``~model_file``: a name in anafi_sim/config or a path): only YAML files
    in the package's config folder or a folder of the root-owned /etc/anafi_sim/data_folders (ValueError)."""
    from anafi_sim import trusted
    folders = trusted.allowed_folders([os.path.dirname(DEFAULT_MODEL_FILE)], directory=settings_dir)
    return trusted.file_parameter(value, folders, 'model_file')


def load_model_params(path=DEFAULT_MODEL_FILE):
    """Read and validate a model YAML file (default: anafi_sim/config/anafi_model.yaml); ValueError when it
    cannot be read or is not a valid model."""
    from anafi_sim.safe_yaml import load_yaml
    params = load_yaml(path, what='the model file %s' % path)
    try:
        return validate_model_params(params)
    except ValueError as error:
        raise ValueError('%s: %s' % (path, error))


def _lag_coefficient(dt, tau):
    """Exact discrete first-order step: x += c (target - x) with c = 1 - exp(-dt/tau)."""
    return 1.0 if tau <= 0.0 else 1.0 - math.exp(-dt / tau)


class AnafiModel(object):
    """The simulated Anafi: PCMD percents in, ground-truth state out (see module doc)."""

    def __init__(self, params, mapping=None, seed=0, settings=None):
        self.params = validate_model_params(params)
        self.settings = validate_settings(settings)
        self.mapping = mapping if mapping is not None else PilotingMapping()
        self.seed = seed
        p = self.params
        s = self.settings
        self._g = p['gravity']
        self._tau_att = p['attitude_time_constant']
        self._delay = p['attitude_delay']
        self._tau_yaw = p['yaw_rate_time_constant']
        self._tau_vz = p['vertical_speed_time_constant']
        self._drag_lin = p['drag_linear']
        self._drag_quad = p['drag_quadratic']
        self._drag_vert = p['drag_vertical']
        effects = effect_params(p)
        self._tilt_attenuation = effects['tilt_attenuation']
        self._tilt_speed = effects['tilt_attenuation_speed']
        self._tilt_speed_full = effects['tilt_attenuation_speed_full']
        self._max_descent = effects['max_descent_speed']
        self._vz_accel_limit = effects['vertical_acceleration_limit']
        self._tilt_rate_limit = effects['tilt_rate_limit']
        self._gyro = effects['gyroscopic_coupling']
        self._yaw_authority = effects['yaw_tilt_authority']
        self._yaw_precession = effects['yaw_tilt_precession']
        self._max_tilt = math.radians(self.mapping.max_tilt_deg)
        self._max_vs = self.mapping.max_vertical_speed
        self._max_yaw_rate = math.radians(self.mapping.max_yaw_rate_deg)
        self._timeout = s['command_timeout']
        self._wind_mean = (s['wind_x'], s['wind_y'], s['wind_z'])
        self._gust_std = (s['gust_std_horizontal'], s['gust_std_horizontal'], s['gust_std_vertical'])
        self._gusty = any(v > 0.0 for v in self._gust_std)
        # the firmware's wind handling runs only where there is wind (inert, bit for bit, without)
        self._wind_comp = s['wind_compensation'] if (self._gusty or any(self._wind_mean)) else 0.0
        self._tau_wind = s['wind_compensation_time_constant']
        self._dt = None
        self.reset(s['initial_x'], s['initial_y'], 0.0, s['initial_yaw'], flying=False)

    # ------------------------------------------------------------------ state
    def reset(self, x=0.0, y=0.0, z=0.0, yaw=0.0, flying=False, t=0.0):
        """Put the drone at rest at (x, y, z) [m] with heading ``yaw`` [rad]; landed or already flying (hovering)."""
        self._rng = np.random.default_rng(self.seed)
        self.time = float(t)
        self.x, self.y, self.z = float(x), float(y), max(0.0, float(z))
        self.vx = self.vy = self.vz = 0.0
        self.roll = self.pitch = 0.0
        self.yaw = float(yaw)
        self.yaw_rate = 0.0                     # Euler yaw rate [rad/s] (+ = counter-clockwise)
        self.wx = self.wy = self.wz = 0.0       # body angular velocity (FLU) [rad/s]
        self.alpha = (0.0, 0.0, 0.0)            # body angular acceleration [rad/s^2]
        self.accel = (0.0, 0.0, 0.0)            # world kinematic acceleration [m/s^2]
        self.thrust = 0.0                       # specific thrust along body z [m/s^2]
        self.gust = [0.0, 0.0, 0.0]
        self.wind_estimate = [0.0, 0.0]         # firmware's estimate of the wind's horizontal acceleration [m/s^2]
        self.gimbal_pitch_command = 0.0         # rad, camera pitch in the world (+ = down in FLU)
        self._queue = collections.deque()       # (t_command, roll_sp, pitch_sp, yaw_rate_sp, vz_sp)
        self._active = None                     # delayed setpoints now applied
        self._last_command_time = None
        self.last_pcmd = (0, 0, 0, 0)
        self.commanding = False                 # True while PCMD setpoints drive the drone
        self._hold = None                       # hover-brake hold point (x, y, z) or None while braking
        self._brake_time = 0.0                  # s spent braking (before the hold point is captured)
        self._hold_integral = [0.0, 0.0]        # integral of the horizontal hold error [m s]
        if flying:
            self.state = FLYING
            self._set_hold((self.x, self.y, self.z))
        else:
            self.state = LANDED
            self.z = 0.0

    def translate(self, dx, dy, dz=0.0):
        """Move the drone by (dx, dy, dz) [m], everything else as it is (velocities, attitude, commands in
        flight, the hover-brake hold point moves along): a translation of the world, e.g. to start a replay
        from a logged position. z stays >= 0."""
        dx, dy, dz = float(dx), float(dy), float(dz)
        if not all(math.isfinite(v) for v in (dx, dy, dz)):
            raise ValueError('translate needs finite offsets, got %r' % ((dx, dy, dz),))
        self.x += dx
        self.y += dy
        z = max(0.0, self.z + dz)
        if self._hold is not None:
            self._hold = (self._hold[0] + dx, self._hold[1] + dy, max(0.0, self._hold[2] + z - self.z))
        self.z = z

    def set_command(self, roll_pct, pitch_pct, yaw_pct, gaz_pct, t):
        """One PCMD (integer percents, bridge signs) received at sim time ``t`` [s]."""
        pcmd = (int(roll_pct), int(pitch_pct), int(yaw_pct), int(gaz_pct))
        for value in pcmd:
            if value < -100 or value > 100:
                raise ValueError('PCMD percents must be in [-100, 100], got %r' % (pcmd,))
        self.last_pcmd = pcmd
        self._last_command_time = t
        if self.state == FLYING:
            setpoints = self.mapping.pcmd_to_setpoints(*pcmd)
            if self._tilt_attenuation > 0.0:     # firmware delivers less tilt than commanded
                roll, pitch = self.delivered_tilt(setpoints[0], setpoints[1])
                setpoints = (roll, pitch, setpoints[2], setpoints[3])
            self._queue.append((t,) + setpoints)

    def tilt_gain(self):
        """Fraction of a commanded tilt the firmware delivers at the current speed (1 = none taken): for the
        speed governor (tilt_attenuation_speed > 0) the fraction of the tilt's driving part."""
        a = self._tilt_attenuation
        if a == 0.0:
            return 1.0
        v0 = self._tilt_speed
        if v0 > 0.0:
            ramp = (math.hypot(self.vx, self.vy) - v0) / (self._tilt_speed_full - v0)
            a *= min(1.0, max(0.0, ramp))
        return 1.0 - a

    def delivered_tilt(self, roll, pitch):
        """(roll, pitch) [rad, FLU: + = right wing down, nose down] the firmware delivers for a commanded one."""
        gain = self.tilt_gain()
        if gain == 1.0:
            return roll, pitch
        if self._tilt_speed <= 0.0:                       # constant attenuation: the whole tilt
            return roll * gain, pitch * gain
        # speed governor: remove (1 - gain) of the tilt's component along the velocity when it drives it
        # (body axes: pitch accelerates forward, roll to the right = -left)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        speed = math.hypot(self.vx, self.vy)
        forward, left = (c * self.vx + s * self.vy) / speed, (-s * self.vx + c * self.vy) / speed
        drive = pitch * forward - roll * left
        if drive <= 0.0:
            return roll, pitch
        cut = (1.0 - gain) * drive
        return roll + cut * left, pitch - cut * forward

    def command_age(self, t):
        """Seconds since the last PCMD (inf if none)."""
        return math.inf if self._last_command_time is None else t - self._last_command_time

    def takeoff(self, t):
        """Start a take-off (only from ``landed``); True if accepted."""
        if self.state != LANDED:
            return False
        self.state = TAKING_OFF
        self._set_hold((self.x, self.y, self.settings['takeoff_altitude']))
        self._queue.clear()
        self._active = None
        self.commanding = False
        return True

    def land(self, t):
        """Start landing (from ``taking_off`` or ``flying``); True if accepted."""
        if self.state not in (TAKING_OFF, FLYING):
            return False
        self.state = LANDING
        self._set_hold(None)
        self._queue.clear()
        self._active = None
        self.commanding = False
        return True

    def set_gimbal_pitch(self, pitch):
        """Commanded camera pitch in the world [rad, FLU sign: + = looking down]."""
        self.gimbal_pitch_command = float(pitch)

    # --------------------------------------------------------------- dynamics
    def _set_dt(self, dt):
        self._dt = dt
        self._c_att = _lag_coefficient(dt, self._tau_att)
        self._c_yaw = _lag_coefficient(dt, self._tau_yaw)
        self._c_vz = _lag_coefficient(dt, self._tau_vz) / dt
        tau_g = self.settings['gust_time_constant']
        self._gust_decay = math.exp(-dt / tau_g)
        scale = math.sqrt(1.0 - self._gust_decay * self._gust_decay)
        self._gust_scale = tuple(scale * s for s in self._gust_std)
        self._c_wind = _lag_coefficient(dt, self._tau_wind)

    def _set_hold(self, hold):
        self._hold = hold
        self._brake_time = 0.0
        self._hold_integral = [0.0, 0.0]

    def _brake(self, dt):
        """Firmware hover brake: (roll_sp, pitch_sp, vz_sp) that stop the drone, then hold the captured point."""
        s = self.settings
        kv = s['brake_velocity_gain']
        hold = self._hold
        if hold is None:
            cap = s['brake_capture_speed']
            self._brake_time += dt
            if ((self.vx * self.vx + self.vy * self.vy < cap * cap
                 and (abs(self.vz) < cap or self.state == LANDING))
                    or self._brake_time >= s['brake_capture_time']):
                self._set_hold((self.x, self.y, self.z))
                hold = self._hold
                ki = s['brake_integral_gain']
                if ki > 0.0:      # bumpless: the integral takes over what the brake was pushing against
                    self._hold_integral = [-kv * self.vx / ki, -kv * self.vy / ki]
        if hold is None:
            ax = -kv * self.vx
            ay = -kv * self.vy
            vz_sp = 0.0
        else:
            ex = hold[0] - self.x
            ey = hold[1] - self.y
            ki = s['brake_integral_gain']
            integral = self._hold_integral
            if ki > 0.0:
                limit = self._g * math.tan(self._max_tilt) / ki
                integral[0] = max(-limit, min(limit, integral[0] + ex * dt))
                integral[1] = max(-limit, min(limit, integral[1] + ey * dt))
            kp = s['brake_position_gain']
            ax = kp * ex + ki * integral[0] - kv * self.vx
            ay = kp * ey + ki * integral[1] - kv * self.vy
            vz_sp = s['brake_altitude_gain'] * (hold[2] - self.z)
        c, sn = math.cos(self.yaw), math.sin(self.yaw)
        forward = c * ax + sn * ay
        left = -sn * ax + c * ay
        g = self._g
        return -math.atan(left / g), math.atan(forward / g), vz_sp

    def wind_force(self, gust=None):
        """Horizontal acceleration [m/s^2, world] the wind puts on the drone now: the drag on the ground
        speed minus the drag on the airspeed."""
        gust = self.gust if gust is None else gust
        wind = self._wind_mean
        ax, ay = self.vx - wind[0] - gust[0], self.vy - wind[1] - gust[1]
        k_air = self._drag_lin + self._drag_quad * math.sqrt(ax * ax + ay * ay)
        k_ground = self._drag_lin + self._drag_quad * math.sqrt(self.vx * self.vx + self.vy * self.vy)
        return k_ground * self.vx - k_air * ax, k_ground * self.vy - k_air * ay

    def _compensate_wind(self, roll_sp, pitch_sp, gust):
        """(roll, pitch) setpoints with the tilt that cancels K x the (lagged) wind-force estimate."""
        fx, fy = self.wind_force(gust)
        est = self.wind_estimate
        c = self._c_wind
        est[0] += c * (fx - est[0])
        est[1] += c * (fy - est[1])
        k = self._wind_comp
        cy, sy = math.cos(self.yaw), math.sin(self.yaw)
        forward = -k * (cy * est[0] + sy * est[1])
        left = -k * (-sy * est[0] + cy * est[1])
        # the setpoint's thrust at a level altitude pushes forward g tan(pitch) and left -g tan(roll) / cos(pitch)
        g = self._g
        pitch = math.atan(math.tan(pitch_sp) + forward / g)
        left += -g * math.tan(roll_sp) / math.cos(pitch_sp)
        return math.atan(-left * math.cos(pitch) / g), pitch

    def step(self, dt, t):
        """Advance the state from sim time ``t`` to ``t + dt`` [s]."""
        if not dt > 0.0:
            raise ValueError('step dt must be > 0, got %r' % (dt,))
        if dt != self._dt:
            self._set_dt(dt)
        self.time = t + dt
        state = self.state
        if state == LANDED:
            self.vx = self.vy = self.vz = 0.0
            self.roll = self.pitch = self.yaw_rate = 0.0
            self.wx = self.wy = self.wz = 0.0
            self.alpha = self.accel = (0.0, 0.0, 0.0)
            self.thrust = 0.0
            self._queue.clear()
            return
        gust = self._step_gusts()
        roll_sp, pitch_sp, yaw_rate_sp, vz_sp = self._setpoints(dt, t, state, gust)
        trig = self._step_attitude(dt, roll_sp, pitch_sp, yaw_rate_sp)
        self._step_translation(dt, state, vz_sp, gust, trig)

    def _step_gusts(self):
        """The wind gusts one step on (Ornstein-Uhlenbeck, exact discretisation); the gust vector [m/s]."""
        gust = self.gust
        if self._gusty:
            noise = self._rng.standard_normal(3)
            d = self._gust_decay
            sc = self._gust_scale
            gust[0] = d * gust[0] + sc[0] * noise[0]
            gust[1] = d * gust[1] + sc[1] * noise[1]
            gust[2] = d * gust[2] + sc[2] * noise[2]
        return gust

    def _setpoints(self, dt, t, state, gust):
        """(roll [rad], pitch [rad], yaw rate [rad/s], vz [m/s]) setpoints of this step: the delayed PCMD while
        flying and commanded, else the firmware's own loops; the wind handling added, then the firmware's
        limits."""
        yaw_rate_sp = 0.0
        if state == FLYING:
            queue = self._queue
            horizon = t - self._delay + 1e-9
            while queue and queue[0][0] <= horizon:
                self._active = queue.popleft()
            if self._active is not None and t - self._last_command_time <= self._timeout:
                self.commanding = True
                _, roll_sp, pitch_sp, yaw_rate_sp, vz_sp = self._active
            else:
                if self.commanding:          # command stream lost: brake, then hold
                    self.commanding = False
                    self._set_hold(None)
                    self._active = None
                roll_sp, pitch_sp, vz_sp = self._brake(dt)
        else:
            roll_sp, pitch_sp, vz_sp = self._brake(dt)
            if state == TAKING_OFF:
                vz_sp = self.settings['takeoff_speed']
            else:
                vz_sp = -self.settings['landing_speed']
        if self._wind_comp > 0.0:                   # the firmware's wind handling (module doc)
            roll_sp, pitch_sp = self._compensate_wind(roll_sp, pitch_sp, gust)
        tilt = self._max_tilt
        roll_sp = -tilt if roll_sp < -tilt else (tilt if roll_sp > tilt else roll_sp)
        pitch_sp = -tilt if pitch_sp < -tilt else (tilt if pitch_sp > tilt else pitch_sp)
        vmax = self._max_vs
        vz_sp = -vmax if vz_sp < -vmax else (vmax if vz_sp > vmax else vz_sp)
        if self._max_descent > 0.0 and vz_sp < -self._max_descent:
            vz_sp = -self._max_descent              # the firmware descends slower than commanded
        return roll_sp, pitch_sp, yaw_rate_sp, vz_sp

    def _step_attitude(self, dt, roll_sp, pitch_sp, yaw_rate_sp):
        """Attitude one step on: first order towards the setpoints; Euler rates -> body rates. Returns the new
        attitude's (cos roll, sin roll, cos pitch, sin pitch, cos yaw, sin yaw)."""
        roll0, pitch0, yaw0 = self.roll, self.pitch, self.yaw
        # the firmware's roll/pitch loop (frames.tilt_loop_step: with the yaw terms and the rate limit off, the
        # plain first order)
        roll, pitch = frames.tilt_loop_step(roll0, pitch0, roll_sp, pitch_sp, self._c_att, dt, self.yaw_rate,
                                            self._tau_att, self._gyro, self._yaw_authority,
                                            self._yaw_precession, self._tilt_rate_limit)
        self.yaw_rate += self._c_yaw * (yaw_rate_sp - self.yaw_rate)
        yaw = yaw0 + self.yaw_rate * dt
        if yaw >= math.pi or yaw < -math.pi:
            yaw = (yaw + math.pi) % (2.0 * math.pi) - math.pi
        roll_dot = (roll - roll0) / dt
        pitch_dot = (pitch - pitch0) / dt
        yaw_dot = self.yaw_rate
        cr, sr = math.cos(roll), math.sin(roll)
        cp, sp = math.cos(pitch), math.sin(pitch)
        cy, sy = math.cos(yaw), math.sin(yaw)
        wx = roll_dot - sp * yaw_dot
        wy = cr * pitch_dot + sr * cp * yaw_dot
        wz = -sr * pitch_dot + cr * cp * yaw_dot
        self.alpha = ((wx - self.wx) / dt, (wy - self.wy) / dt, (wz - self.wz) / dt)
        self.wx, self.wy, self.wz = wx, wy, wz
        self.roll, self.pitch, self.yaw = roll, pitch, yaw
        return cr, sr, cp, sp, cy, sy

    def _step_translation(self, dt, state, vz_sp, gust, trig):
        """Translation one step on: thrust along body z chosen so that vz follows its first-order loop; drag
        against the air (wind and gusts); then ground contact and the flight state machine."""
        cr, sr, cp, sp, cy, sy = trig
        vx0, vy0, vz0 = self.vx, self.vy, self.vz
        wind = self._wind_mean
        avx = vx0 - wind[0] - gust[0]
        avy = vy0 - wind[1] - gust[1]
        avz = vz0 - wind[2] - gust[2]
        g = self._g
        zbx = cy * sp * cr + sy * sr
        zby = sy * sp * cr - cy * sr
        zbz = cp * cr
        vert_drag = self._drag_vert * avz
        az_des = (vz_sp - vz0) * self._c_vz
        limit = self._vz_accel_limit
        if limit > 0.0:                              # the firmware ramps a large vertical-speed step
            az_des = -limit if az_des < -limit else (limit if az_des > limit else az_des)
        thrust = (az_des + g + vert_drag) / zbz
        tmax = self.settings['max_specific_thrust']
        thrust = 0.0 if thrust < 0.0 else (tmax if thrust > tmax else thrust)
        self.thrust = thrust
        k = self._drag_lin + self._drag_quad * math.sqrt(avx * avx + avy * avy)
        vx = vx0 + (thrust * zbx - k * avx) * dt
        vy = vy0 + (thrust * zby - k * avy) * dt
        vz = vz0 + (thrust * zbz - g - vert_drag) * dt
        x = self.x + vx * dt
        y = self.y + vy * dt
        z = self.z + vz * dt
        if z <= 0.0:
            z = 0.0
            if vz < 0.0:
                vz = 0.0
            if state == LANDING:
                vx = vy = vz = 0.0
                self.state = LANDED
        if state == TAKING_OFF and z >= self._hold[2] - self.settings['takeoff_speed'] * self._tau_vz:
            self.state = FLYING              # the vertical lag carries it to takeoff_altitude
        self.accel = ((vx - vx0) / dt, (vy - vy0) / dt, (vz - vz0) / dt)
        self.vx, self.vy, self.vz = vx, vy, vz
        self.x, self.y, self.z = x, y, z
        if self.state == LANDED:
            self.roll = self.pitch = self.yaw_rate = 0.0
            self.wx = self.wy = self.wz = 0.0
            self._set_hold(None)

    # -------------------------------------------------------------- accessors
    def position(self):
        """(x, y, z) [m], world ENU."""
        return (self.x, self.y, self.z)

    def velocity(self):
        """(vx, vy, vz) [m/s], world ENU."""
        return (self.vx, self.vy, self.vz)

    def attitude(self):
        """(roll, pitch, yaw) [rad], FLU Euler."""
        return (self.roll, self.pitch, self.yaw)

    def wind(self):
        """Current wind (constant + gust) [m/s], world ENU."""
        return tuple(m + g for m, g in zip(self._wind_mean, self.gust))

    def _to_body(self, v):
        """World vector -> body (FLU) vector: R^T v."""
        return frames.world_to_body(self.roll, self.pitch, self.yaw, v)

    def body_velocity(self):
        """Velocity in the body frame (FLU) [m/s]."""
        return self._to_body((self.vx, self.vy, self.vz))

    def body_angular_velocity(self):
        """Angular velocity in the body frame (FLU) [rad/s]."""
        return (self.wx, self.wy, self.wz)

    def body_linear_acceleration(self):
        """Kinematic acceleration dv/dt (gravity not included) in the body frame (FLU) [m/s^2]."""
        return self._to_body(self.accel)

    def body_angular_acceleration(self):
        """Angular acceleration in the body frame (FLU) [rad/s^2]."""
        return self.alpha

    def gimbal_angles(self):
        """Stabilised gimbal motor angles relative to the body (roll, pitch) [rad]."""
        return (0.0 - self.roll, self.gimbal_pitch_command - self.pitch)   # 0.0 - x: no -0.0 printed

    def truth_sample(self, t=None):
        """The ground truth as a ``TelemetrySample`` stamped with sim time ``t`` (default: model time)."""
        # velocity and acceleration into the body frame: frames.world_to_body's arithmetic, its trigonometry once
        cr, sr = math.cos(self.roll), math.sin(self.roll)
        cp, sp = math.cos(self.pitch), math.sin(self.pitch)
        cy, sy = math.cos(self.yaw), math.sin(self.yaw)
        r00, r01, r02 = cy * cp, sy * cp, -sp
        r10, r11, r12 = cy * sp * sr - sy * cr, sy * sp * sr + cy * cr, cp * sr
        r20, r21, r22 = cy * sp * cr + sy * sr, sy * sp * cr - cy * sr, cp * cr
        x, y, z = self.vx, self.vy, self.vz
        bv = (r00 * x + r01 * y + r02 * z, r10 * x + r11 * y + r12 * z, r20 * x + r21 * y + r22 * z)
        x, y, z = self.accel
        ba = (r00 * x + r01 * y + r02 * z, r10 * x + r11 * y + r12 * z, r20 * x + r21 * y + r22 * z)
        al = self.alpha
        g_roll, g_pitch = self.gimbal_angles()
        return TelemetrySample(
            self.x, self.y, self.z, self.vx, self.vy, self.vz, self.roll, self.pitch, self.yaw,
            bv[0], bv[1], bv[2], self.wx, self.wy, self.wz, ba[0], ba[1], ba[2],
            al[0], al[1], al[2], self.time if t is None else t, g_roll, g_pitch)
