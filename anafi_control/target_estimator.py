"""Stage: controllers. Predicts a moving target's reference from its waypoint history (pure core, no ROS).

Used by ``anafi_control.preview_mpc`` when no reference preview arrives (only the paper's 10 Hz waypoint
stream, e.g. a target seen by a camera or the airship). ``TargetEstimator.add(t, position, velocity)``
takes the waypoints (world ENU [m], [m/s], receipt time ``t`` [s]); ``predict(times)`` -> positions,
velocities, accelerations at the given times [s], shape (n, 3) each.

Motion model (one angular rate for all axes, per-axis amplitudes): over the last ``window`` seconds the
waypoint velocities are fitted by least squares with v(s) = A cos(w s) + B sin(w s) per axis (s = time
since the newest waypoint), for every w of a grid 0 < w <= ``max_rate`` [rad/s] refined around the best
one, and with v(s) = A + B s (constant acceleration, w = 0); the fit with the least residual wins. That
model is exact for the paper's shapes: a line (constant velocity), a circle (a constant turn rate: both
horizontal velocity components are sinusoids of w = v / r) and the vertical periodic motion (v_z a
sinusoid), and it is a constant-acceleration filter for anything else over a short window. The position is
the newest waypoint's, integrated with the fitted velocity in closed form. With fewer than three
waypoints it predicts a constant velocity. A gap longer than ``max_gap`` [s] or a waypoint farther than
``jump`` [m] from the prediction restarts the history (a new target or a new scenario phase).
"""
import collections
import math

import numpy as np

#: defaults (= anafi_sim/config/preview_mpc.yaml: estimator_window, estimator_max_rate, ...)
DEFAULTS = collections.OrderedDict([
    ('window', 1.0),      # [s] waypoint history fitted
    ('max_rate', 3.0),    # [rad/s] largest angular rate considered
    ('max_gap', 0.5),     # [s] a longer gap between waypoints restarts the history
    ('jump', 1.0),        # [m] a waypoint this far from the prediction restarts the history
])

_GRID_STEP = 0.05         # [rad/s] coarse grid of the angular rate, refined by a parabola


class TargetEstimator(object):
    """Waypoint history -> predicted reference (see the module doc). ValueError on bad parameters."""

    def __init__(self, window=DEFAULTS['window'], max_rate=DEFAULTS['max_rate'], max_gap=DEFAULTS['max_gap'],
                 jump=DEFAULTS['jump']):
        for name, value in (('window', window), ('max_rate', max_rate), ('max_gap', max_gap), ('jump', jump)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                    math.isfinite(value) and value > 0.0):
                raise ValueError('target estimator %s must be a finite number > 0, got %r' % (name, value))
        self.window, self.max_rate, self.max_gap, self.jump = float(window), float(max_rate), float(max_gap), \
            float(jump)
        self.grid = np.arange(_GRID_STEP, self.max_rate + 1e-9, _GRID_STEP)
        self.restarts = 0
        self.reset()

    def reset(self):
        """Forget the history."""
        self.samples = collections.deque()     # (t, p (3,), v (3,))
        self._fit_cache = None                  # (w, A (3,), B (3,)) of the newest history, None: not fitted

    def add(self, t, position, velocity):
        """A waypoint received at ``t`` [s]; False (ignored) when not finite or older than the newest."""
        p = np.asarray(position, dtype=float).reshape(3)
        v = np.asarray(velocity, dtype=float).reshape(3)
        t = float(t)
        if not (math.isfinite(t) and np.all(np.isfinite(p)) and np.all(np.isfinite(v))):
            return False
        if self.samples:
            t_last = self.samples[-1][0]
            if t < t_last:
                return False
            if t == t_last:
                self.samples.pop()
            elif t - t_last > self.max_gap or np.linalg.norm(
                    self.samples[-1][1] + self.samples[-1][2] * (t - t_last) - p) > self.jump:
                self.restarts += 1
                self.samples.clear()
        self.samples.append((t, p, v))
        while self.samples and t - self.samples[0][0] > self.window + 1e-9:
            self.samples.popleft()
        self._fit_cache = None
        return True

    @property
    def fit(self):
        """(w [rad/s], A (3,), B (3,)) of the history (fitted on first use), None when empty."""
        if self._fit_cache is None and self.samples:
            self._fit_cache = self._fit()
        return self._fit_cache

    def _fit(self):
        n = len(self.samples)
        t_new, _, v_new = self.samples[-1]
        if n < 3:
            return 0.0, v_new.copy(), np.zeros(3)
        s = np.array([smp[0] - t_new for smp in self.samples])
        V = np.array([smp[2] for smp in self.samples])          # (n, 3)
        best = self._fit_linear(s, V)
        # residual of every grid rate (2x2 normal equations, all rates at once), then a parabola through the
        # best one and its neighbours
        res = self._residuals(s, V, self.grid)
        i = int(np.argmin(res))
        w = self.grid[i]
        if 0 < i < len(self.grid) - 1:
            r0, r1, r2 = res[i - 1], res[i], res[i + 1]
            denom = r0 - 2.0 * r1 + r2
            if denom > 0.0:
                w = w + 0.5 * _GRID_STEP * (r0 - r2) / denom
        harmonic = self._fit_harmonic(s, V, w)
        if harmonic[0] < best[0]:
            best = harmonic
        return best[1:]

    @staticmethod
    def _residuals(s, V, rates):
        """Least-squares residual of v = A cos(w s) + B sin(w s) for every w of ``rates``."""
        C = np.cos(np.outer(rates, s))
        S = np.sin(np.outer(rates, s))
        g11, g12, g22 = (C * C).sum(1), (C * S).sum(1), (S * S).sum(1)
        b1, b2 = C.dot(V), S.dot(V)
        det = g11 * g22 - g12 * g12
        ok = det > 1e-12 * np.maximum(g11 * g22, 1e-300)
        det = np.where(ok, det, 1.0)
        A = (g22[:, None] * b1 - g12[:, None] * b2) / det[:, None]
        B = (g11[:, None] * b2 - g12[:, None] * b1) / det[:, None]
        res = float(np.sum(V * V)) - (A * b1 + B * b2).sum(1)
        return np.where(ok, res, np.inf)

    @staticmethod
    def _fit_linear(s, V):
        M = np.column_stack([np.ones_like(s), s])
        coef, _, _, _ = np.linalg.lstsq(M, V, rcond=None)
        residual = float(np.sum((M.dot(coef) - V) ** 2))
        return residual, 0.0, coef[0], coef[1]

    @staticmethod
    def _fit_harmonic(s, V, w):
        M = np.column_stack([np.cos(w * s), np.sin(w * s)])
        coef, _, _, _ = np.linalg.lstsq(M, V, rcond=None)
        residual = float(np.sum((M.dot(coef) - V) ** 2))
        return residual, float(w), coef[0], coef[1]

    @property
    def rate(self):
        """Angular rate of the current fit [rad/s] (0: constant acceleration / velocity), None when empty."""
        return None if self.fit is None else self.fit[0]

    def predict(self, times):
        """(positions, velocities, accelerations), arrays (n, 3) [m, m/s, m/s^2] at ``times`` [s]; None when
        no waypoint was added yet."""
        if not self.samples:
            return None
        t_new, p0, _ = self.samples[-1]
        w, A, B = self.fit
        s = (np.asarray(times, dtype=float) - t_new)[:, None]
        if w == 0.0:        # v = A + B s
            vel = A + B * s
            pos = p0 + A * s + 0.5 * B * s * s
            acc = np.repeat(B[None, :], len(s), axis=0)
        else:               # v = A cos(w s) + B sin(w s)
            c, sn = np.cos(w * s), np.sin(w * s)
            vel = A * c + B * sn
            pos = p0 + (A * sn + B * (1.0 - c)) / w
            acc = w * (-A * sn + B * c)
        return pos, vel, acc
