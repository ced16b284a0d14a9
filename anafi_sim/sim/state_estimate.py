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

Units and frames: position [m] and velocity [m/s] in the world ENU frame,
attitude roll/pitch/yaw [rad] (FLU Euler, yaw wrapped to [-pi, pi)).
"""
import collections
import math

import numpy as np

ESTIMATE_KEYS = ('estimate_delay', 'estimate_time_constant', 'estimate_rate', 'estimate_float16')

_TWO_PI = 2.0 * math.pi


def _wrap(angle):
    return (angle + math.pi) % _TWO_PI - math.pi


class StateEstimate(object):
    """Delayed, smoothed, sampled and quantised copy of the truth (see module doc).

    ``params`` is the model dict (only ``ESTIMATE_KEYS`` are used; the other
    model keys may be present).
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
        self.stamp = None          # caller time at which the current output was sampled [s]
        self.samples = 0           # number of output changes (sample instants)

    @property
    def ready(self):
        """True once an estimate exists."""
        return self._values is not None

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
        self._t_last = t

        if self._next_sample is not None and t < self._next_sample:
            return False
        values = list(smooth)
        values[8] = _wrap(values[8])
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
