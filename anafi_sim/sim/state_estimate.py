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
``anafi_lab/calibration/fit.py``, see docs/calibration.md):

- ``estimate_position_fusion`` (bool): the position is not the delayed truth
  but a fusion: the estimated velocity (steps 1-2) integrated, corrected
  toward a delayed position fix, p' = v_est + k (p_truth(t - D) - p), with
  D = ``estimate_position_fix_delay`` [s] and k = ``estimate_position_fix_gain``
  [1/s]. In steady flight at velocity v the position trails the truth by D v
  (plus the hold); in a transient shorter than 1/k the lag has no time to
  build up (it approaches D v as 1 - exp(-k t)).
- ``estimate_velocity_error_time_constant`` [s]: the velocity estimate has an
  error of its own, added to the published velocity (and integrated by the
  fusion), that decays with this time constant (0 = no such state). Nothing
  in the model creates it: ``add_velocity_error`` sets it (a replay starting
  from a logged estimate; Sphinx's logs start with errors their approach left).
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
    ('estimate_velocity_error_time_constant', 0.0),  # s, decay of the velocity estimate's own error (0 = none)
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


def _finite(what, values):
    """``values`` as a tuple of floats; ValueError naming ``what`` unless all are finite."""
    values = tuple(float(v) for v in values)
    if not all(math.isfinite(v) for v in values):
        raise ValueError('%s needs finite values, got %r' % (what, values))
    return values


def _shifted(values, d, start=0):
    """``values`` (a sequence) with the 3-vector ``d`` added at indices start..start+2; a tuple."""
    out = list(values)
    for i in range(3):
        out[start + i] += d[i]
    return tuple(out)


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
        self.velocity_error_time_constant = e['estimate_velocity_error_time_constant']
        # (index in the values, quantum) of the quantised outputs
        self._quanta = tuple((i, q) for i, q in enumerate((
            e['estimate_quantum_x'], e['estimate_quantum_y'], e['estimate_quantum_z'],
            e['estimate_quantum_velocity'], e['estimate_quantum_velocity'], e['estimate_quantum_velocity']))
            if q > 0.0)
        self.reset()

    def _output(self, values):
        """The published form of (x, y, z, vx, vy, vz, roll, pitch, yaw) (yaw bias already added): quantised,
        float16 when so configured; a tuple."""
        values = list(values)
        for i, quantum in self._quanta:
            values[i] = _quantise(values[i], quantum)
        if self.float16:
            values = [float(v) for v in np.asarray(values, dtype=np.float16)]
        return tuple(values)

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
        self._velocity_error = [0.0, 0.0, 0.0]   # the velocity estimate's own error [m/s] (decays)
        self._error_dt = None
        self._error_coef = 1.0
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
        dt = 0.0 if self._t_last is None else t - self._t_last
        velocity = smooth[3:6]
        error = self._velocity_error
        if error[0] or error[1] or error[2]:
            if dt != self._error_dt:
                self._error_dt = dt
                self._error_coef = math.exp(-dt / self.velocity_error_time_constant)
            c = self._error_coef
            for i in range(3):
                error[i] *= c
            velocity = [velocity[i] + error[i] for i in range(3)]
        if self.fusion:
            self._fuse(t, dt, (x, y, z), velocity)
        self._t_last = t

        if self._next_sample is not None and t < self._next_sample:
            return False
        values = list(smooth)
        values[3:6] = velocity
        values[8] = _wrap(values[8])
        if self.yaw_bias:
            values[8] = _wrap(values[8] + self.yaw_bias)
        if self.fusion:
            values[0:3] = self._fused
        self._values = self._output(values)
        self.stamp = t
        self.samples += 1
        self._next_sample = (math.floor(t * self.rate + 1e-6) + 1.0) / self.rate
        return True

    def translate(self, dx, dy, dz=0.0):
        """The world moved by (dx, dy, dz) [m] (``AnafiModel.translate``): every stored position moves along
        (truth history, fixes, smoothed and fused position, the current output), so the estimate's errors
        stay what they were."""
        d = _finite('translate', (dx, dy, dz))
        self._history = collections.deque((t, _shifted(row, d)) for t, row in self._history)
        self._fixes = collections.deque((t, _shifted(p, d)) for t, p in self._fixes)
        if self._smooth is not None:
            self._smooth = list(_shifted(self._smooth, d))
        if self._fused is not None:
            self._fused = list(_shifted(self._fused, d))
        if self._values is not None:
            self._values = self._output(_shifted(self._values, d))

    def stall(self, until):
        """Hold the published output until time ``until`` [s] (caller time), as a stalled estimate stream
        does (Sphinx's MPC lines at 2, 3 and 5 m/s each show one: the same estimate for 0.2-0.25 s, then a
        jump to the current one); the filters keep running underneath, the next sample at or after ``until``
        is the current estimate. No effect before the first update."""
        until, = _finite('stall', (until,))
        if self._values is not None:
            self._next_sample = max(self._next_sample, until)

    @property
    def position_state(self):
        """(x, y, z) [m] of the position estimate before hold and quantisation: the fusion's state with the
        fusion, else the smoothed delayed truth; None before the first update."""
        if self.fusion:
            return tuple(self._fused) if self._fused is not None else None
        return tuple(self._smooth[0:3]) if self._smooth is not None else None

    def add_position_error(self, dx, dy, dz=0.0):
        """Add (dx, dy, dz) [m] to the fused position (the estimate's own state: it decays as the fusion
        corrects toward the fix, 1/``estimate_position_fix_gain``), e.g. to start a replay from a logged
        estimate error. Only with ``estimate_position_fusion`` (without it the position is the delayed truth
        and holds no error of its own): returns False and changes nothing then, or before the first update."""
        d = _finite('add_position_error', (dx, dy, dz))
        if not self.fusion or self._fused is None:
            return False
        self._fused = list(_shifted(self._fused, d))
        if self._values is not None:                 # the held output moves along (it stays held)
            self._values = self._output(_shifted(self._values, d))
        return True

    def add_velocity_error(self, dvx, dvy, dvz=0.0):
        """Add (dvx, dvy, dvz) [m/s] to the velocity estimate's own error (it decays with
        ``estimate_velocity_error_time_constant``; the fusion integrates it), e.g. to start a replay from a
        logged velocity estimate. Returns False and changes nothing when that time constant is 0 (off)."""
        d = _finite('add_velocity_error', (dvx, dvy, dvz))
        if self.velocity_error_time_constant <= 0.0:
            return False
        self._velocity_error = list(_shifted(self._velocity_error, d))
        if self._values is not None:
            self._values = self._output(_shifted(self._values, d, 3))
        return True

    @property
    def velocity_error(self):
        """(x, y, z) [m/s] of the velocity estimate's own error now."""
        return tuple(self._velocity_error)

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
