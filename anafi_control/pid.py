"""One PID loop exactly as the ROS ``pid`` package's controller node computes it (pure core).

Stage: controllers. A ``PidController`` turns (setpoint, state, time) into a
control effort in the loop's own units (whatever the setpoint/state units
are times the gains); it knows nothing about frames. Time ``t`` is in
seconds on the caller's clock (ROS time in the node, simulated time in
tests). Behaviour follows ``shared/interfaces/pid_package.md`` step for step:

1. error history shifts: e[2] = e[1], e[1] = e[0], e[0] = setpoint - state.
2. ``angle_error``: e[0] is wrapped into [-angle_wrap/2, angle_wrap/2]; when a
   wrap actually happened, the history and the error integral are reset to 0
   (which history: see below).
3. dt = t - time of the previous computation. The very first computation
   (and the first after ``reset()``) only stores ``t`` and returns None.
   dt == 0 -> the computation is skipped (returns None, ``skipped_dt_zero``
   counts it; the error history of step 1 has already shifted, as in the pid
   package, where the shift happens before the dt check).
4. integral += e[0] * dt, clamped to +-|windup_limit| (the *error* integral).
5. filter constant c = 1 by default; with cutoff_frequency != -1,
   t_f = tan(cutoff_frequency * 2*pi * dt / 2), forced to |t_f| >= 0.01
   keeping its sign (t_f == 0 becomes -0.01, as the pid package's two
   if-statements do), c = 1 / t_f (recomputed every computation).
6. fe[0] = (e[2] + 2 e[1] + e[0] - (c^2 - 1.414 c + 1) fe[2] - (-2 c^2 + 2) fe[1])
          / (1 + c^2 + 1.414 c)        (fe shifts like e)
7. d[0] = (e[0] - e[1]) / dt (d shifts like e), filtered into fd[0] by the
   same formula.
8. effort = Kp fe[0] + Ki integral + Kd fd[0], clamped to [lower_limit, upper_limit].
9. enabled -> return the effort; disabled -> return None and zero the integral
   (the computation itself still runs, filters keep their state).

Ambiguities / deliberate choices (documented, not hidden):

* Step 2, which history is reset. The shared doc words it "reset e[1], e[2]
  and the error integral". The pid package (PidObject.cpp, from memory: the
  source is not available on this machine) resets, inside its two wrap
  ``while`` loops, the *raw-derivative* history d[0..2] and the integral
  ("the proportional error will flip sign, but the integral error won't and
  the derivative error will be poorly defined. So, reset them."), leaving
  e[1], e[2] alone. We follow the pid package: d[0..2] = 0 and integral = 0,
  only when a wrap was actually applied. The paper's reference log
  ``static_waypoint_yaw_180_pid.csv`` supports this: its yaw loop (fed
  absolute angles, so the error wraps on every cycle once the drone is past
  -180/180) converges with the full Kp = 0.6 and settles ~2 deg off (the
  PCMD 1 % dead band, 1.8 deg/s / 0.6); zeroing e[1], e[2] on every cycle
  would cut the filtered proportional term to a quarter (fixed point of the
  filter with e = [e0, 0, 0] is e0 / 4) and leave ~12 deg.
  The wrap is inclusive at both ends (an error of exactly +angle_wrap/2 is
  kept), like the upstream ``while (e > wrap/2)`` / ``while (e < -wrap/2)``.
* Step 5: the doc's 2*pi is used (upstream writes the literal 6.2832; the
  relative difference is 2e-6).
* Robustness beyond upstream (a node must never be poisoned): a non-finite
  setpoint, state or t is rejected before step 1 (returns None, history
  untouched, counted in ``rejected_nonfinite``); a time that goes backwards
  (e.g. simulated clock restarted) resets the controller and is treated as a
  first computation (counted in ``time_jumps_back``). The upstream node would
  propagate NaN into its integral forever / integrate a negative dt.
* The pid package triggers one computation per received state *or* setpoint
  message; here the caller decides (one ``update`` = one computation).
"""
import math

FILTER_SQRT2 = 1.414          # the pid package's literal, not math.sqrt(2)
DEFAULT_CUTOFF = -1.0         # "no cut-off": c = 1
GAIN_SCALES = (0.1, 1.0, 10.0, 100.0)   # dynamic_reconfigure Kp_scale/Ki_scale/Kd_scale enum


def _check_finite(name, value):
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError('%s must be a number, got %r' % (name, value))
    if not math.isfinite(value):
        raise ValueError('%s must be finite, got %r' % (name, value))
    return value


def butterworth(x0, x1, x2, y1, y2, c):
    """The pid package's 2nd-order low-pass: new filtered value from inputs x[0..2] and outputs y[1..2]."""
    return ((x2 + 2.0 * x1 + x0
             - (c * c - FILTER_SQRT2 * c + 1.0) * y2
             - (-2.0 * c * c + 2.0) * y1)
            / (1.0 + c * c + FILTER_SQRT2 * c))


def filter_constant(cutoff_frequency, dt):
    """c of the filter for ``cutoff_frequency`` [Hz] and step ``dt`` [s]; 1.0 when cutoff is -1."""
    if cutoff_frequency == -1:
        return 1.0
    t = math.tan(cutoff_frequency * 2.0 * math.pi * dt / 2.0)
    if -0.01 < t <= 0.0:
        t = -0.01
    if 0.0 <= t < 0.01:
        t = 0.01
    return 1.0 / t


def wrap_error(error, wrap):
    """(wrapped error, wrapped?) with the pid package's inclusive [-wrap/2, wrap/2] semantics."""
    half = 0.5 * wrap
    wrapped = False
    if error > half:
        error -= math.ceil((error - half) / wrap) * wrap
        wrapped = True
    elif error < -half:
        error += math.ceil((-half - error) / wrap) * wrap
        wrapped = True
    # guard against floating-point round-off of the bulk step (bounded loops)
    for _ in range(4):
        if error > half:
            error -= wrap
        elif error < -half:
            error += wrap
        else:
            break
    return error, wrapped


class PidController(object):
    """One pid-package controller: ``update(setpoint, state, t)`` -> effort or None.

    Parameters have the pid package names, meanings and defaults (see module
    docstring). Raises ValueError for non-finite parameters, lower_limit >
    upper_limit, or angle_wrap <= 0.
    """

    def __init__(self, Kp=1.0, Ki=0.0, Kd=0.0, upper_limit=1000.0, lower_limit=-1000.0,
                 windup_limit=1000.0, cutoff_frequency=DEFAULT_CUTOFF, angle_error=False,
                 angle_wrap=2.0 * math.pi):
        self.Kp, self.Ki, self.Kd = 0.0, 0.0, 0.0
        self.set_gains(Kp, Ki, Kd)
        self.upper_limit = _check_finite('upper_limit', upper_limit)
        self.lower_limit = _check_finite('lower_limit', lower_limit)
        if self.lower_limit > self.upper_limit:
            raise ValueError('lower_limit (%g) must not be greater than upper_limit (%g)'
                             % (self.lower_limit, self.upper_limit))
        self.windup_limit = _check_finite('windup_limit', windup_limit)
        self.cutoff_frequency = _check_finite('cutoff_frequency', cutoff_frequency)
        if not isinstance(angle_error, bool):
            raise ValueError('angle_error must be a bool, got %r' % (angle_error,))
        self.angle_error = angle_error
        self.angle_wrap = _check_finite('angle_wrap', angle_wrap)
        if self.angle_wrap <= 0.0:
            raise ValueError('angle_wrap must be > 0, got %g' % self.angle_wrap)
        self.enabled = True
        self.skipped_dt_zero = 0
        self.rejected_nonfinite = 0
        self.time_jumps_back = 0
        self.reset()

    # -- configuration -------------------------------------------------
    def set_gains(self, Kp, Ki, Kd):
        """Set the gains (the dynamic_reconfigure callback); filter/integral state is kept."""
        Kp = _check_finite('Kp', Kp)
        Ki = _check_finite('Ki', Ki)
        Kd = _check_finite('Kd', Kd)
        self.Kp, self.Ki, self.Kd = Kp, Ki, Kd

    def gains_same_sign(self):
        """False when the gains mix signs (the pid package warns: 'should have the same sign')."""
        g = (self.Kp, self.Ki, self.Kd)
        return all(k <= 0.0 for k in g) or all(k >= 0.0 for k in g)

    def set_enabled(self, enabled):
        """pid_enable: a disabled controller computes but returns None and zeroes its integral."""
        self.enabled = bool(enabled)

    def reset(self):
        """Forget history, filters, integral and time: the next update is a first computation."""
        self.error = [0.0, 0.0, 0.0]
        self.filtered_error = [0.0, 0.0, 0.0]
        self.error_deriv = [0.0, 0.0, 0.0]
        self.filtered_error_deriv = [0.0, 0.0, 0.0]
        self.error_integral = 0.0
        self.prev_time = None
        self.c = 1.0
        self.proportional = 0.0
        self.integral = 0.0
        self.derivative = 0.0
        self.control_effort = 0.0

    # -- computation ----------------------------------------------------
    def update(self, setpoint, state, t):
        """One computation; returns the (clamped) effort, or None (first call, dt == 0, disabled, bad input)."""
        if not (_is_finite(setpoint) and _is_finite(state) and _is_finite(t)):
            self.rejected_nonfinite += 1
            return None
        setpoint, state, t = float(setpoint), float(state), float(t)

        # 1. error history
        e = self.error
        e[2] = e[1]
        e[1] = e[0]
        e[0] = setpoint - state

        # 2. angle wrap (resets on an actual wrap)
        if self.angle_error:
            e[0], wrapped = wrap_error(e[0], self.angle_wrap)
            if wrapped:
                self.error_deriv[0] = 0.0
                self.error_deriv[1] = 0.0
                self.error_deriv[2] = 0.0
                self.error_integral = 0.0

        # 3. dt; first computation / dt == 0 / time going backwards
        if self.prev_time is None:
            self.prev_time = t
            return None
        dt = t - self.prev_time
        if dt < 0.0:
            self.time_jumps_back += 1
            self.reset()
            self.error[0] = e[0]
            self.prev_time = t
            return None
        self.prev_time = t
        if dt == 0.0:
            self.skipped_dt_zero += 1
            return None

        # 4. integral with windup clamp
        limit = abs(self.windup_limit)
        self.error_integral += e[0] * dt
        self.error_integral = max(-limit, min(limit, self.error_integral))

        # 5. filter constant
        c = filter_constant(self.cutoff_frequency, dt)
        self.c = c

        # 6. filtered error
        fe = self.filtered_error
        fe[2] = fe[1]
        fe[1] = fe[0]
        fe[0] = butterworth(e[0], e[1], e[2], fe[1], fe[2], c)

        # 7. derivative, raw then filtered
        d = self.error_deriv
        d[2] = d[1]
        d[1] = d[0]
        d[0] = (e[0] - e[1]) / dt
        fd = self.filtered_error_deriv
        fd[2] = fd[1]
        fd[1] = fd[0]
        fd[0] = butterworth(d[0], d[1], d[2], fd[1], fd[2], c)

        # 8. effort with saturation
        self.proportional = self.Kp * fe[0]
        self.integral = self.Ki * self.error_integral
        self.derivative = self.Kd * fd[0]
        effort = self.proportional + self.integral + self.derivative
        if effort > self.upper_limit:
            effort = self.upper_limit
        elif effort < self.lower_limit:
            effort = self.lower_limit
        self.control_effort = effort

        # 9. enable / disable
        if not self.enabled:
            self.error_integral = 0.0
            return None
        return effort


def _is_finite(value):
    try:
        return math.isfinite(value)
    except TypeError:
        return False


# -- dynamic_reconfigure helpers --------------------------------------------
def split_gain(gain):
    """Gain -> (value in [-1, 1], scale in {0.1, 1, 10, 100}) as the pid node seeds rqt_reconfigure.

    The pid package moves the decimal point one digit at a time while
    |value| > 1 or |value| < 0.1, at most twice up (scale 10, 100) and at most
    once down (scale 0.1), then clamps value into [-1, 1]. Hence:

    * 0.1 <= |gain| <= 1 -> (gain, 1); 1 < |gain| <= 10 -> (gain/10, 10);
      10 < |gain| <= 100 -> (gain/100, 100).
    * |gain| < 0.1 (including 0) -> (gain*10, 0.1): value is then below 0.01
      in magnitude but value*scale is still the gain, e.g. 0.0001 ->
      (0.001, 0.1), 0.003 -> (0.03, 0.1), 0 -> (0, 0.1).
    * |gain| > 100 cannot be represented: value is clamped to +-1 and the
      reconfigure GUI shows +-100 (the node itself keeps its ~param gain until
      the first user change).
    """
    value = _check_finite('gain', gain)
    digits = 0
    while (abs(value) > 1.0 or abs(value) < 0.1) and (-1 < digits < 2):
        if abs(value) > 1.0:
            value /= 10.0
            digits += 1
        else:
            value *= 10.0
            digits -= 1
    value = max(-1.0, min(1.0, value))
    return value, GAIN_SCALES[digits + 1]


def join_gain(value, scale):
    """(value, scale) from dynamic_reconfigure -> gain = value * scale (the pid node's callback)."""
    return _check_finite('value', value) * _check_finite('scale', scale)
