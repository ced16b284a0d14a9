"""anafi_control.pid: the pid package's controller computation, step by step, and the reconfigure gain split.

Expected numbers come from hand-worked sequences (written out as literal
arithmetic below) and from ``RefPid``, a literal transcription of the
shared doc's step list (shared/interfaces/pid_package.md) kept independent
of the code under test.
"""
import math
import random

import pytest

from anafi_control.pid import PidController, join_gain, split_gain

D = 1.0 + 1.0 + 1.414          # filter denominator for c = 1: 1 + c^2 + 1.414 c
B2 = 1.0 - 1.414 + 1.0         # coefficient of fe[2] for c = 1 (the fe[1] one, -2c^2 + 2, is 0)


class RefPid(object):
    """Doc steps 1-9 transcribed literally; the wrap reset is the pid package's (derivative history
    and integral, inside the wrap loops), see anafi_control/pid.py for why."""

    def __init__(self, Kp=1.0, Ki=0.0, Kd=0.0, upper_limit=1000.0, lower_limit=-1000.0,
                 windup_limit=1000.0, cutoff_frequency=-1.0, angle_error=False,
                 angle_wrap=2 * math.pi):
        self.Kp, self.Ki, self.Kd = Kp, Ki, Kd
        self.up, self.lo, self.windup = upper_limit, lower_limit, windup_limit
        self.cutoff, self.angle_error, self.wrap = cutoff_frequency, angle_error, angle_wrap
        self.e = [0.0] * 3
        self.fe = [0.0] * 3
        self.d = [0.0] * 3
        self.fd = [0.0] * 3
        self.integral = 0.0
        self.prev = None
        self.enabled = True

    def step(self, setpoint, state, now):
        e, fe, d, fd = self.e, self.fe, self.d, self.fd
        e[2] = e[1]
        e[1] = e[0]
        e[0] = setpoint - state
        if self.angle_error:
            while e[0] < -self.wrap / 2.0:
                e[0] += self.wrap
                d[0] = d[1] = d[2] = 0.0
                self.integral = 0.0
            while e[0] > self.wrap / 2.0:
                e[0] -= self.wrap
                d[0] = d[1] = d[2] = 0.0
                self.integral = 0.0
        if self.prev is None:
            self.prev = now
            return None
        dt = now - self.prev
        self.prev = now
        if dt == 0:
            return None
        self.integral += e[0] * dt
        if self.integral > abs(self.windup):
            self.integral = abs(self.windup)
        if self.integral < -abs(self.windup):
            self.integral = -abs(self.windup)
        c = 1.0
        if self.cutoff != -1:
            t = math.tan(self.cutoff * 2 * math.pi * dt / 2)
            if t <= 0 and t > -0.01:
                t = -0.01
            if t >= 0 and t < 0.01:
                t = 0.01
            c = 1 / t
        fe[2] = fe[1]
        fe[1] = fe[0]
        fe[0] = (e[2] + 2 * e[1] + e[0] - (c * c - 1.414 * c + 1) * fe[2]
                 - (-2 * c * c + 2) * fe[1]) / (1 + c * c + 1.414 * c)
        d[2] = d[1]
        d[1] = d[0]
        d[0] = (e[0] - e[1]) / dt
        fd[2] = fd[1]
        fd[1] = fd[0]
        fd[0] = (d[2] + 2 * d[1] + d[0] - (c * c - 1.414 * c + 1) * fd[2]
                 - (-2 * c * c + 2) * fd[1]) / (1 + c * c + 1.414 * c)
        u = self.Kp * fe[0] + self.Ki * self.integral + self.Kd * fd[0]
        u = min(self.up, max(self.lo, u))
        if not self.enabled:
            self.integral = 0.0
            return None
        return u


def run(pid, seq):
    """Feed [(setpoint, state, t), ...]; return the list of outputs."""
    return [pid.update(sp, st, t) for sp, st, t in seq]


# -- first cycle, default filter (c = 1) ----------------------------------------
def test_first_computation_only_stores_time():
    pid = PidController()
    assert pid.update(5.0, 0.0, 100.0) is None
    out = pid.update(5.0, 0.0, 100.1)
    # e = [5, 5, 0]: fe = (0 + 2*5 + 5) / 3.414, Kp = 1
    assert out == pytest.approx(15.0 / D, rel=1e-12)


def test_proportional_term_acts_on_filtered_error_default_c():
    pid = PidController(Kp=2.0)
    out = run(pid, [(1.0, 0.0, 0.1 * k) for k in range(6)])
    f1 = 3.0 / D                       # e = [1, 1, 0]
    f2 = 4.0 / D                       # e = [1, 1, 1], fe[2] = 0
    f3 = (4.0 - B2 * f1) / D           # fe[2] = f1
    f4 = (4.0 - B2 * f2) / D
    f5 = (4.0 - B2 * f3) / D
    assert out[0] is None
    assert out[1:] == pytest.approx([2 * f1, 2 * f2, 2 * f3, 2 * f4, 2 * f5], rel=1e-12)
    # steady state of the filter has unit gain: (1+2+1) / (3.414 + 0.586) = 1
    for k in range(6, 200):
        last = pid.update(1.0, 0.0, 0.1 * k)
    assert last == pytest.approx(2.0, rel=1e-9)


def test_derivative_is_filtered_raw_difference_quotient():
    pid = PidController(Kp=0.0, Kd=1.0)
    out = run(pid, [(0.0, 0.0, 0.0), (1.0, 0.0, 0.1), (1.0, 0.0, 0.2), (1.0, 0.0, 0.3)])
    g1 = 10.0 / D                      # d = [10, 0, 0]
    g2 = 20.0 / D                      # d = [0, 10, 0]
    g3 = (10.0 - B2 * g1) / D          # d = [0, 0, 10], fd[2] = g1
    assert out == [None, pytest.approx(g1), pytest.approx(g2), pytest.approx(g3)]


# -- cut-off frequency ------------------------------------------------------------
def test_cutoff_frequency_filter_constant():
    pid = PidController(cutoff_frequency=1.0)
    dt = 0.1
    c = 1.0 / math.tan(1.0 * 2 * math.pi * dt / 2)      # = 3.0777 for 1 Hz at 10 Hz
    den = 1 + c * c + 1.414 * c
    out = run(pid, [(1.0, 0.0, 0.0), (1.0, 0.0, 0.1), (1.0, 0.0, 0.2), (1.0, 0.0, 0.3)])
    h1 = 3.0 / den
    h2 = (4.0 - (-2 * c * c + 2) * h1) / den
    h3 = (4.0 - (c * c - 1.414 * c + 1) * h1 - (-2 * c * c + 2) * h2) / den
    assert out[1:] == pytest.approx([h1, h2, h3], rel=1e-12)
    assert pid.c == pytest.approx(3.0776835, rel=1e-6)


@pytest.mark.parametrize('cutoff,expected_c', [
    (0.01, 100.0),      # tan(0.00314) < 0.01 -> forced to 0.01
    (-0.01, -100.0),    # keeps its sign
    (0.0, -100.0),      # tan == 0 falls into the first (<= 0) branch of the pid package
])
def test_tiny_tan_is_forced_to_one_hundredth(cutoff, expected_c):
    pid = PidController(cutoff_frequency=cutoff)
    run(pid, [(1.0, 0.0, 0.0), (1.0, 0.0, 0.1)])
    assert pid.c == pytest.approx(expected_c)


# -- windup, saturation -------------------------------------------------------------
@pytest.mark.parametrize('windup', [0.25, -0.25])
def test_integral_is_clamped_to_abs_windup_limit(windup):
    pid = PidController(Kp=0.0, Ki=2.0, windup_limit=windup)
    out = run(pid, [(1.0, 0.0, 0.1 * k) for k in range(5)])
    # integral 0.1, 0.2, 0.25 (clamped), 0.25; Ki x integral
    assert out[1:] == pytest.approx([0.2, 0.4, 0.5, 0.5])
    # the clamp is on the error integral: it comes down from 0.25 at once
    assert pid.update(-1.0, 0.0, 0.5) == pytest.approx(2.0 * 0.15)


def test_zero_windup_limit_makes_integral_dead():
    pid = PidController(Kp=0.0, Ki=5.0, windup_limit=0.0)
    assert run(pid, [(3.0, 0.0, 0.1 * k) for k in range(4)])[1:] == [0.0, 0.0, 0.0]


def test_saturation_and_integral_keeps_running():
    pid = PidController(Kp=100.0, Ki=1.0, upper_limit=5.0, lower_limit=-3.0)
    out = run(pid, [(1.0, 0.0, 0.1 * k) for k in range(4)])
    assert out[1:] == [5.0, 5.0, 5.0]
    assert pid.error_integral == pytest.approx(0.3)      # no anti-windup beyond the clamp
    out = run(pid, [(-1.0, 0.0, 0.4 + 0.1 * k) for k in range(4)])
    assert out[-1] == -3.0


def test_equal_limits_are_allowed_and_pin_the_effort():
    pid = PidController(upper_limit=0.5, lower_limit=0.5)
    assert run(pid, [(9.0, 0.0, 0.0), (-9.0, 0.0, 0.1)])[1] == 0.5


# -- angle wrap -----------------------------------------------------------------------
def test_angle_wrap_resets_integral_keeps_error_history():
    pid = PidController(Kp=1.0, Ki=1.0, angle_error=True, angle_wrap=360.0)
    out = run(pid, [(10.0, 0.0, 0.0), (10.0, 0.0, 0.1), (179.0, -179.0, 0.2)])
    p1 = 30.0 / D                     # e = [10, 10, 0]
    assert out[1] == pytest.approx(p1 + 1.0)          # integral 10 * 0.1
    # 358 -> -2 deg; e = [-2, 10, 10]; integral 0 then += -2 * 0.1; fe[2] = 0
    assert out[2] == pytest.approx(28.0 / D - 0.2)
    assert pid.error[:] == [-2.0, 10.0, 10.0]


def test_angle_wrap_resets_raw_derivative_history():
    pid = PidController(Kp=0.0, Kd=1.0, angle_error=True, angle_wrap=360.0)
    out = run(pid, [(0.0, 0.0, 0.0), (10.0, 0.0, 0.1), (179.0, -179.0, 0.2)])
    assert out[1] == pytest.approx(100.0 / D)         # d = [100, 0, 0]
    # wrap: d = [0, 0, 0], then d = [(-2 - 10) / 0.1, 0, 0]; fd[1] (= 100/D) has factor 0 for c = 1
    # (without the reset it would be (-120 + 2 * 100) / D = 80 / D)
    assert out[2] == pytest.approx(-120.0 / D)


def test_error_wrapping_every_cycle_keeps_full_proportional_gain():
    # absolute angles across +-180 (the paper's yaw loop near 180 deg): steady wrapped error -2 deg
    pid = PidController(Kp=0.6, Ki=0.2, Kd=0.003, windup_limit=0.5, angle_error=True,
                        angle_wrap=360.0)
    out = run(pid, [(179.0, -179.0, k / 30.0) for k in range(60)])
    assert out[-1] == pytest.approx(0.6 * -2.0 + 0.2 * -2.0 / 30.0, rel=1e-6)


def test_no_reset_without_an_actual_wrap():
    pid = PidController(Kp=0.0, Ki=1.0, angle_error=True, angle_wrap=360.0)
    out = run(pid, [(100.0, 0.0, 0.0), (100.0, 0.0, 0.1), (180.0, 0.0, 0.2), (0.0, 180.0, 0.3)])
    # +-180 exactly are inside the inclusive bounds: integral 10, 28, 10
    assert out[1:] == pytest.approx([10.0, 28.0, 10.0])


@pytest.mark.parametrize('sp,st,expected', [
    (540.0, 0.0, 180.0), (0.0, 541.0, 179.0), (1000.0, -1000.0, -160.0), (-190.0, 0.0, 170.0),
])
def test_wrap_of_large_errors(sp, st, expected):
    pid = PidController(angle_error=True, angle_wrap=360.0)
    pid.update(sp, st, 0.0)
    assert pid.error[0] == pytest.approx(expected)


def test_default_wrap_is_two_pi_radians():
    pid = PidController(angle_error=True)
    pid.update(math.radians(170), math.radians(-170), 0.0)
    assert pid.error[0] == pytest.approx(math.radians(-20))


def test_angle_error_false_does_not_wrap():
    pid = PidController()
    pid.update(179.0, -179.0, 0.0)
    assert pid.error[0] == 358.0


# -- enable / disable --------------------------------------------------------------
def test_disable_publishes_nothing_and_resets_integral():
    pid = PidController(Kp=0.0, Ki=1.0)
    assert run(pid, [(1.0, 0.0, 0.0), (1.0, 0.0, 1.0), (1.0, 0.0, 2.0)])[1:] == [1.0, 2.0]
    pid.set_enabled(False)
    assert run(pid, [(1.0, 0.0, 3.0), (1.0, 0.0, 4.0)]) == [None, None]
    assert pid.error_integral == 0.0
    pid.set_enabled(True)
    # integral restarts from 0: 1 * 1 s
    assert pid.update(1.0, 0.0, 5.0) == pytest.approx(1.0)


def test_disabled_controller_keeps_its_filters_running():
    a, b = PidController(Kp=1.0), PidController(Kp=1.0)
    seq = [(float(k % 3), 0.0, 0.1 * k) for k in range(8)]
    b.set_enabled(False)
    run(a, seq[:5])
    run(b, seq[:5])
    b.set_enabled(True)
    assert run(a, seq[5:]) == run(b, seq[5:])


# -- dt == 0, non-finite input, clock going backwards ---------------------------
def test_dt_zero_is_skipped_and_counted():
    pid = PidController(Kp=0.0, Ki=1.0)
    out = run(pid, [(1.0, 0.0, 0.0), (1.0, 0.0, 1.0), (5.0, 0.0, 1.0), (1.0, 0.0, 2.0)])
    assert out[2] is None
    assert pid.skipped_dt_zero == 1
    assert out[3] == pytest.approx(2.0)      # dt measured from t = 1


def test_dt_zero_still_shifts_error_history_like_the_pid_package():
    pid = PidController(Kp=0.0, Kd=1.0)
    out = run(pid, [(0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (4.0, 0.0, 1.0), (0.0, 0.0, 2.0)])
    # history at t = 2: e = [0, 4, 0]; d[0] = (0 - 4) / 1 -> fd = -4 / D
    assert out[3] == pytest.approx(-4.0 / D)


@pytest.mark.parametrize('bad', [float('nan'), float('inf'), -float('inf'), None, 'x'])
def test_non_finite_input_is_rejected_without_touching_state(bad):
    pid, ref = PidController(Kp=1.0, Ki=0.5, Kd=0.1), RefPid(Kp=1.0, Ki=0.5, Kd=0.1)
    seq = [(1.0 + 0.1 * k, 0.0, 0.1 * k) for k in range(6)]
    run(pid, seq[:3])
    assert pid.update(bad, 0.0, 0.35) is None
    assert pid.update(1.0, bad, 0.35) is None
    assert pid.update(1.0, 0.0, bad) is None
    assert pid.rejected_nonfinite == 3
    expected = [ref.step(*s) for s in seq]
    assert run(pid, seq[3:]) == pytest.approx(expected[3:], rel=1e-12)


def test_time_going_backwards_restarts_the_controller():
    pid = PidController(Kp=0.0, Ki=1.0)
    run(pid, [(1.0, 0.0, 10.0), (1.0, 0.0, 11.0)])
    assert pid.update(1.0, 0.0, 0.0) is None
    assert pid.time_jumps_back == 1
    assert pid.update(1.0, 0.0, 0.5) == pytest.approx(0.5)


def test_reset_makes_next_update_a_first_computation():
    pid = PidController(Kp=0.0, Ki=1.0)
    run(pid, [(1.0, 0.0, 0.0), (1.0, 0.0, 1.0)])
    pid.reset()
    assert pid.update(1.0, 0.0, 2.0) is None
    assert pid.update(1.0, 0.0, 3.0) == pytest.approx(1.0)


# -- against the literal transcription on random sequences ------------------------
@pytest.mark.parametrize('seed', range(6))
def test_matches_literal_transcription_on_random_sequences(seed):
    rnd = random.Random(seed)
    params = dict(Kp=rnd.uniform(-3, 3), Ki=rnd.uniform(-2, 2), Kd=rnd.uniform(-0.5, 0.5),
                  upper_limit=rnd.uniform(0.5, 20), lower_limit=-rnd.uniform(0.5, 20),
                  windup_limit=rnd.uniform(0, 3),
                  cutoff_frequency=rnd.choice([-1.0, 0.5, 3.0, 20.0]),
                  angle_error=bool(seed % 2), angle_wrap=rnd.choice([360.0, 2 * math.pi]))
    pid, ref = PidController(**params), RefPid(**params)
    t = 0.0
    for k in range(300):
        t += rnd.choice([0.0, 0.01, 0.033, 0.1, rnd.uniform(0.001, 0.2)])
        if k == 150:
            pid.set_enabled(False)
            ref.enabled = False
        if k == 170:
            pid.set_enabled(True)
            ref.enabled = True
        sp, st = rnd.uniform(-400, 400), rnd.uniform(-400, 400)
        expected = ref.step(sp, st, t)
        got = pid.update(sp, st, t)
        if expected is None:
            assert got is None, k
        else:
            assert got == pytest.approx(expected, rel=1e-9, abs=1e-9), k


# -- parameters --------------------------------------------------------------------
def test_defaults_are_the_pid_package_defaults():
    pid = PidController()
    assert (pid.Kp, pid.Ki, pid.Kd) == (1.0, 0.0, 0.0)
    assert (pid.upper_limit, pid.lower_limit, pid.windup_limit) == (1000.0, -1000.0, 1000.0)
    assert pid.cutoff_frequency == -1.0 and pid.angle_error is False
    assert pid.angle_wrap == pytest.approx(2 * math.pi)


@pytest.mark.parametrize('kwargs', [
    dict(lower_limit=1.0, upper_limit=0.0),
    dict(Kp=float('nan')), dict(Ki=float('inf')), dict(Kd=-float('inf')),
    dict(windup_limit=float('nan')), dict(upper_limit=float('inf')),
    dict(cutoff_frequency=float('nan')), dict(angle_wrap=0.0), dict(angle_wrap=float('nan')),
    dict(angle_error='yes'), dict(Kp='abc'),
])
def test_bad_parameters_are_refused(kwargs):
    with pytest.raises(ValueError):
        PidController(**kwargs)


def test_set_gains_takes_effect_next_computation_and_refuses_nan():
    pid = PidController(Kp=0.0, Ki=1.0)
    run(pid, [(1.0, 0.0, 0.0), (1.0, 0.0, 1.0)])
    pid.set_gains(0.0, 3.0, 0.0)
    assert pid.update(1.0, 0.0, 2.0) == pytest.approx(6.0)    # integral 2, Ki 3
    with pytest.raises(ValueError):
        pid.set_gains(float('nan'), 1.0, 0.0)
    assert (pid.Kp, pid.Ki, pid.Kd) == (0.0, 3.0, 0.0)


def test_gains_same_sign_warning_helper():
    assert PidController(Kp=-10, Ki=-1, Kd=0).gains_same_sign()
    assert not PidController(Kp=1, Ki=-1).gains_same_sign()


# -- dynamic_reconfigure value / scale ----------------------------------------------
@pytest.mark.parametrize('gain,value,scale', [
    (0.875, 0.875, 1.0), (10.0, 1.0, 10.0), (-10.0, -1.0, 10.0), (0.0001, 0.001, 0.1),
    (0.001, 0.01, 0.1), (0.003, 0.03, 0.1), (1.0, 1.0, 1.0), (0.0, 0.0, 0.1),
    (0.6, 0.6, 1.0), (0.2, 0.2, 1.0), (-1.0, -1.0, 1.0), (0.1, 0.1, 1.0), (0.05, 0.5, 0.1),
    (1.5, 0.15, 10.0), (55.0, 0.55, 100.0), (100.0, 1.0, 100.0), (-0.0001, -0.001, 0.1),
])
def test_split_gain(gain, value, scale):
    v, s = split_gain(gain)
    assert v == pytest.approx(value, rel=1e-12, abs=1e-15)
    assert s == scale
    assert -1.0 <= v <= 1.0
    assert join_gain(v, s) == pytest.approx(gain, rel=1e-12, abs=1e-15)


def test_split_gain_above_100_is_clamped():
    assert split_gain(500.0) == (1.0, 100.0)
    assert split_gain(-250.0) == (-1.0, 100.0)


def test_table2_gains_round_trip():
    for gain in (0.875, 0.0001, 0, 10, 1, 0.001, -10, -1, 0.001, 0.6, 0.2, 0.003):
        assert join_gain(*split_gain(gain)) == pytest.approx(gain, rel=1e-12, abs=1e-15)


def test_split_gain_refuses_non_finite():
    with pytest.raises(ValueError):
        split_gain(float('nan'))
