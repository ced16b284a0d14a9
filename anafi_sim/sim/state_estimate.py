"""The Anafi's own state estimate, as the anafi_ros bridge publishes it (pure Python).

Stage: simulated drone -> bridge output. The firmware's estimate lags the
ground truth; the reference logs show a delay, some smoothing and values that
change only at about 20 Hz (the logs store every column, ground truth too, as
half floats, so half-float quantisation is a property of the logging, not of
the estimate: ``estimate_float16`` is false in the fitted model). ``StateEstimate``
reproduces that from the truth history, in this order:

1. pure delay ``estimate_delay`` [s] (the newest truth sample not younger
   than t - delay; the caller feeds truth at the physics rate),
2. first-order smoothing with ``estimate_time_constant`` [s] (yaw smoothed
   on the circle),
3. sample-and-hold: the output changes only at multiples of
   1/``estimate_rate`` [Hz] of the caller's time,
4. optional quantisation to numpy.float16 (``estimate_float16``).

Effects switched by keys that are OFF by default (``EFFECTS_OFF``; fitted by
``anafi_sim/calibration/fit.py``, see docs/calibration.md):

- ``estimate_position_fusion`` (bool): the position is not the delayed truth
  but a fusion: the estimated velocity (steps 1-2) integrated, corrected
  toward a delayed position fix, p' = v_est + k (p_truth(t - D) - p), with
  D = ``estimate_position_fix_delay`` [s] and k = ``estimate_position_fix_gain``
  [1/s]. In steady flight at velocity v the position trails the truth by D v
  (plus the hold); in a transient shorter than 1/k the lag has no time to
  build up (it approaches D v as 1 - exp(-k t)).
- ``estimate_yaw_bias`` [rad]: added to the published yaw.
- quantisation of the published values to multiples of ``estimate_quantum_x``,
  ``estimate_quantum_y``, ``estimate_quantum_z`` [m] and
  ``estimate_quantum_velocity`` [m/s] (round to nearest; 0 = off).

With every effect off the output is bit for bit that of the chain 1-4.

Units and frames: position [m] and velocity [m/s] in the world ENU frame,
attitude roll/pitch/yaw [rad] (FLU Euler, yaw wrapped to [-pi, pi)).
"""
import collections
import math

import numpy as np

ESTIMATE_KEYS = ('estimate_delay', 'estimate_time_constant', 'estimate_rate', 'estimate_float16')

# Optional effect keys and the values that switch them off (the shipped anafi_model.yaml has these values).
EFFECTS_OFF = collections.OrderedDict((
    ('estimate_position_fusion', False),     # bool: velocity-integrated position corrected toward a delayed fix
    ('estimate_position_fix_delay', 0.0),    # s, D (only with the fusion)
    ('estimate_position_fix_gain', 0.0),     # 1/s, k (only with the fusion; 0 = dead reckoning)
    ('estimate_yaw_bias', 0.0),              # rad, added to the yaw
    ('estimate_quantum_x', 0.0),             # m, step of the published x (0 = off)
    ('estimate_quantum_y', 0.0),             # m
    ('estimate_quantum_z', 0.0),             # m
    ('estimate_quantum_velocity', 0.0),      # m/s, step of vx, vy, vz
))
_EFFECT_BOOLEAN = ('estimate_position_fusion',)
_EFFECT_ANY_SIGN = ('estimate_yaw_bias',)

_TWO_PI = 2.0 * math.pi


def _wrap(angle):
    return (angle + math.pi) % _TWO_PI - math.pi


def validate_effects(params):
    """The effect keys of ``params`` (missing ones OFF) checked; {key: value} in ``EFFECTS_OFF`` order.

    ValueError on a wrong type or range (booleans must be bool, the rest finite numbers, >= 0 except the
    yaw bias).
    """
    clean = collections.OrderedDict()
    for key, off in EFFECTS_OFF.items():
        value = params.get(key, off)
        if key in _EFFECT_BOOLEAN:
            if not isinstance(value, bool):
                raise ValueError('%s must be true or false, got %r' % (key, value))
        else:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError('%s must be a finite number, got %r' % (key, value))
            if key not in _EFFECT_ANY_SIGN and value < 0.0:
                raise ValueError('%s must be >= 0, got %r' % (key, value))
            value = float(value)
        clean[key] = value
    return clean


def _quantise(value, quantum):
    """``value`` rounded to the nearest multiple of ``quantum`` (> 0)."""
    return round(value / quantum) * quantum


class StateEstimate(object):
    """Delayed, smoothed, sampled and quantised copy of the truth (see module doc).

    ``params`` is the model dict (``ESTIMATE_KEYS`` are required, the keys of
    ``EFFECTS_OFF`` optional (missing = off); the other model keys may be present).
    """

    def __init__(self, params):
        missing = [k for k in ESTIMATE_KEYS if k not in params]
        if missing:
            raise ValueError('state estimate parameters missing: %s' % missing)
        self.delay = params['estimate_delay']
        self.time_constant = params['estimate_time_constant']
        self.rate = params['estimate_rate']
        self.float16 = params['estimate_float16']
        for name, value in (('estimate_delay', self.delay), ('estimate_time_constant', self.time_constant),
                            ('estimate_rate', self.rate)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError('%s must be a finite number, got %r' % (name, value))
        if self.delay < 0.0 or self.time_constant < 0.0 or self.rate <= 0.0:
            raise ValueError('need estimate_delay >= 0, estimate_time_constant >= 0, estimate_rate > 0; got %r, %r, %r'
                             % (self.delay, self.time_constant, self.rate))
        if not isinstance(self.float16, bool):
            raise ValueError('estimate_float16 must be true or false, got %r' % (self.float16,))
        self.effects = validate_effects(params)
        e = self.effects
        self.fusion = e['estimate_position_fusion']
        self.fix_delay = e['estimate_position_fix_delay']
        self.fix_gain = e['estimate_position_fix_gain']
        self.yaw_bias = e['estimate_yaw_bias']
        # (index in the values, quantum) of the quantised outputs
        self._quanta = tuple((i, q) for i, q in enumerate((
            e['estimate_quantum_x'], e['estimate_quantum_y'], e['estimate_quantum_z'],
            e['estimate_quantum_velocity'], e['estimate_quantum_velocity'], e['estimate_quantum_velocity']))
            if q > 0.0)
        self.reset()

    def reset(self):
        """Forget the history (e.g. after a simulator restart)."""
        self._history = collections.deque()
        self._smooth = None
        self._t_last = None
        self._dt = None
        self._coef = 1.0
        self._next_sample = None
        self._values = None
        self._fixes = collections.deque()   # (t, (x, y, z)) truth positions for the delayed fix
        self._fused = None                  # fused position [x, y, z]
        self._fix_dt = None
        self._fix_coef = 0.0
        self.stamp = None          # caller time at which the current output was sampled [s]
        self.samples = 0           # number of output changes (sample instants)

    @property
    def ready(self):
        """True once an estimate exists."""
        return self._values is not None

    def _fix(self, t):
        """Truth position at t - fix_delay, linear between the fed samples (oldest one before the history)."""
        fixes = self._fixes
        horizon = t - self.fix_delay
        while len(fixes) > 2 and fixes[1][0] <= horizon:
            fixes.popleft()
        t0, p0 = fixes[0]
        if len(fixes) == 1 or horizon <= t0:
            return p0
        t1, p1 = fixes[1]
        if horizon >= t1:                   # only two samples left and both old enough: the newer one
            return p1
        w = (horizon - t0) / (t1 - t0)
        return (p0[0] + w * (p1[0] - p0[0]), p0[1] + w * (p1[1] - p0[1]), p0[2] + w * (p1[2] - p0[2]))

    def _fuse(self, t, dt, position, velocity):
        """One step of the position fusion: integrate the estimated velocity, correct toward the fix."""
        self._fixes.append((t, position))
        fix = self._fix(t)
        fused = self._fused
        if fused is None:
            self._fused = list(fix)
            return
        if dt != self._fix_dt:
            self._fix_dt = dt
            self._fix_coef = 1.0 - math.exp(-self.fix_gain * dt) if dt > 0.0 else 0.0
        c = self._fix_coef
        for i in range(3):
            value = fused[i] + velocity[i] * dt
            fused[i] = value + c * (fix[i] - value)

    def update(self, t, x, y, z, vx, vy, vz, roll, pitch, yaw):
        """Feed the truth at time ``t`` [s]; True when the output was re-sampled at this call."""
        if self._t_last is not None and t < self._t_last:
            self.reset()                                   # time went backwards: start over
        history = self._history
        history.append((t, (x, y, z, vx, vy, vz, roll, pitch, yaw)))
        horizon = t - self.delay + 1e-9
        while len(history) > 1 and history[1][0] <= horizon:
            history.popleft()
        delayed = history[0][1]

        smooth = self._smooth
        if smooth is None:
            smooth = self._smooth = list(delayed)
        else:
            dt = t - self._t_last
            if dt != self._dt:
                self._dt = dt
                self._coef = 1.0 if self.time_constant <= 0.0 else 1.0 - math.exp(-dt / self.time_constant)
            c = self._coef
            for i in range(8):
                smooth[i] += c * (delayed[i] - smooth[i])
            smooth[8] = _wrap(smooth[8] + c * _wrap(delayed[8] - smooth[8]))
        if self.fusion:
            self._fuse(t, 0.0 if self._t_last is None else t - self._t_last, (x, y, z), smooth[3:6])
        self._t_last = t

        if self._next_sample is not None and t < self._next_sample:
            return False
        values = list(smooth)
        values[8] = _wrap(values[8])
        if self.fusion:
            values[0:3] = self._fused
        if self.yaw_bias:
            values[8] = _wrap(values[8] + self.yaw_bias)
        for i, quantum in self._quanta:
            values[i] = _quantise(values[i], quantum)
        if self.float16:
            values = [float(v) for v in np.asarray(values, dtype=np.float16)]
        self._values = tuple(values)
        self.stamp = t
        self.samples += 1
        self._next_sample = (math.floor(t * self.rate + 1e-6) + 1.0) / self.rate
        return True

    def values(self):
        """(x, y, z, vx, vy, vz, roll, pitch, yaw) of the current estimate, or None before the first update."""
        return self._values

    def position(self):
        """(x, y, z) [m], world ENU."""
        return self._values[0:3] if self._values is not None else None

    def velocity(self):
        """(vx, vy, vz) [m/s], world ENU."""
        return self._values[3:6] if self._values is not None else None

    def attitude(self):
        """(roll, pitch, yaw) [rad]."""
        return self._values[6:9] if self._values is not None else None
