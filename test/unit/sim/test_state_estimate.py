"""anafi_sim.sim.state_estimate: delay, smoothing, sample-and-hold and float16 quantisation of the drone's estimate."""
import math

import numpy as np
import pytest

from anafi_sim.sim.state_estimate import StateEstimate

DT = 0.005


def make(delay=0.2, tau=0.0, rate=20.0, f16=False, **extra):
    params = {'estimate_delay': delay, 'estimate_time_constant': tau, 'estimate_rate': rate,
              'estimate_float16': f16}
    params.update(extra)
    return StateEstimate(params)


def feed(est, signal, t_end, t0=0.0):
    """Feed truth = signal(t) (9-tuple) at 200 Hz; returns the list of (t, values) after each update."""
    out = []
    n = int(round((t_end - t0) / DT))
    for k in range(n + 1):
        t = t0 + k * DT
        est.update(t, *signal(t))
        out.append((t, est.values()))
    return out


def ramp(t):
    return (t, 2.0 * t, 5.0, 1.0, 2.0, 0.0, 0.0, 0.0, 0.1 * t)


def test_bad_parameters():
    with pytest.raises(ValueError, match='estimate_rate'):
        make(rate=0.0)
    with pytest.raises(ValueError, match='estimate_delay'):
        make(delay=float('nan'))
    with pytest.raises(ValueError, match='estimate_float16'):
        make(f16='yes')
    with pytest.raises(ValueError, match='missing'):
        StateEstimate({'estimate_delay': 0.1})
    make(gravity=9.81)                               # the whole model dict is accepted


def test_not_ready_before_first_update():
    est = make()
    assert not est.ready and est.values() is None and est.position() is None


def test_pure_delay_without_smoothing():
    est = make(delay=0.2, tau=0.0, rate=1000.0)      # sampling faster than the feed: pure delay only
    feed(est, ramp, 3.0)
    x, y, z = est.position()
    assert x == pytest.approx(3.0 - 0.2, abs=1e-9)
    assert y == pytest.approx(2.0 * (3.0 - 0.2), abs=1e-9)
    assert est.attitude()[2] == pytest.approx(0.1 * 2.8, abs=1e-9)


def test_first_order_smoothing_of_a_step():
    tau = 0.1
    est = make(delay=0.0, tau=tau, rate=1000.0)
    step = lambda t: (0.0 if t < 1.0 else 1.0,) + (0.0,) * 8
    out = feed(est, step, 1.0 + tau)
    assert out[-1][1][0] == pytest.approx(1.0 - math.exp(-1.0), abs=0.03)
    out = feed(est, step, 2.0, t0=1.0 + tau + DT)
    assert out[-1][1][0] == pytest.approx(1.0, abs=1e-3)


def test_steady_ramp_lag_is_delay_plus_time_constant():
    est = make(delay=0.15, tau=0.05, rate=1000.0)
    feed(est, ramp, 5.0)
    # a first-order filter lags a ramp by tau (minus half a step of the discrete filter)
    assert est.position()[0] == pytest.approx(5.0 - 0.15 - 0.05, abs=0.004)


def test_sample_and_hold_at_estimate_rate():
    est = make(delay=0.0, tau=0.0, rate=20.0)
    out = feed(est, ramp, 2.0)
    changes = [t for (t, v), (_, prev) in zip(out[1:], out[:-1]) if v != prev]
    assert 38 <= len(changes) <= 40                   # 20 Hz over 2 s
    gaps = np.diff(changes)
    assert gaps == pytest.approx(0.05, abs=1e-6)
    assert est.samples == len(changes) + 1


def test_float16_quantisation():
    est = make(delay=0.0, tau=0.0, rate=1000.0, f16=True)
    signal = lambda t: (48.8, 0.0342, 7.027, 0.995, -0.008766, 0.0, 0.001, -0.02, -0.1138)
    feed(est, signal, 0.1)
    values = est.values()
    expected = [float(np.float16(v)) for v in signal(0.0)]
    assert list(values) == expected
    assert values[0] != 48.8 and abs(values[0] - 48.8) <= 0.016     # float16 spacing at 32..64 is 1/32


def test_yaw_is_smoothed_across_the_wrap():
    est = make(delay=0.0, tau=0.1, rate=1000.0)
    yaw = lambda t: (0.0,) * 8 + (3.1 if t < 0.5 else -3.1,)
    feed(est, yaw, 1.5)
    assert abs(est.attitude()[2]) == pytest.approx(3.1, abs=1e-3)      # took the short way
    out = feed(est, yaw, 1.6, t0=1.5 + DT)
    assert all(abs(v[8]) > 3.0 for _, v in out)


def test_time_going_back_resets():
    est = make(delay=0.2, tau=0.0, rate=1000.0)
    feed(est, ramp, 3.0)
    est.update(0.0, *ramp(0.0))                      # simulator restart
    assert est.position()[0] == pytest.approx(0.0)


# ------------------------------------------------------------------ fidelity effects
FUSION = {'estimate_position_fusion': True, 'estimate_position_fix_delay': 0.2, 'estimate_position_fix_gain': 0.3}


def cruise(speed, start=0.0):
    """Constant-velocity truth along x at ``speed`` [m/s] from x = 0 at t = ``start``."""
    return lambda t: (speed * max(0.0, t - start), 1.0, 5.0, speed if t >= start else 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def held_lag(est, speed, t):
    """Lag [s] of the held x estimate behind the truth at ``t`` (truth x = speed t)."""
    return (speed * t - est.position()[0]) / speed


@pytest.mark.parametrize('speed', [1.0, 5.0])
def test_fusion_steady_lag_is_fix_delay_times_speed(speed):
    rate = 1000.0                                    # hold negligible: the lag is the fusion's alone
    est = make(delay=0.0, tau=0.0, rate=rate, **FUSION)
    feed(est, cruise(speed), 40.0)                   # >> 1/k: steady state
    assert held_lag(est, speed, 40.0) == pytest.approx(0.2, abs=0.005)
    # velocity and attitude are not lagged by the fix delay
    assert est.velocity()[0] == pytest.approx(speed)


def test_fusion_lag_adds_the_hold():
    est = make(delay=0.0, tau=0.0, rate=20.0, **FUSION)
    out = feed(est, cruise(2.0), 40.0)
    # lag of the published value averaged over the last second: D + half a hold period
    lags = [(2.0 * t - v[0]) / 2.0 for t, v in out[-200:]]
    assert np.mean(lags) == pytest.approx(0.2 + 0.5 / 20.0, abs=0.005)


def test_fusion_transient_shows_no_steady_lag():
    """A short manoeuvre (0.5 s << 1/k) from hover: the position follows the velocity, not the delayed fix."""
    k = FUSION['estimate_position_fix_gain']
    est = make(delay=0.0, tau=0.0, rate=1000.0, **FUSION)
    feed(est, cruise(2.0, start=1.0), 1.5)           # 0.5 s of motion
    lag = held_lag(est, 2.0, 0.5)
    assert lag < 0.2 * (1.0 - math.exp(-k * 0.5)) + 0.005   # the lag only starts to build up ...
    assert lag < 0.05                                        # ... far from the steady 0.2 s
    # the delay-only estimate (no fusion) with the same delay lags by the full 0.2 s at once
    delayed = make(delay=0.2, tau=0.0, rate=1000.0)
    feed(delayed, cruise(2.0, start=1.0), 1.5)
    assert held_lag(delayed, 2.0, 0.5) == pytest.approx(0.2, abs=0.006)


def test_fusion_corrects_toward_the_fix():
    """A velocity estimate that is wrong (truth jumps without velocity): the position converges at rate k."""
    est = make(delay=0.0, tau=0.0, rate=1000.0, **FUSION)
    feed(est, lambda t: (0.0, 0.0, 5.0) + (0.0,) * 6, 1.0)
    jump = lambda t: (1.0, 0.0, 5.0) + (0.0,) * 6        # teleport: no velocity to integrate
    feed(est, jump, 1.0 + 0.2 + 1.0 / 0.3, t0=1.0 + DT)
    # after the fix delay, 1 - exp(-1) of the jump is corrected within 1/k
    assert est.position()[0] == pytest.approx(1.0 - math.exp(-1.0), abs=0.01)


def test_yaw_bias_is_added_and_wrapped():
    est = make(delay=0.0, tau=0.0, rate=1000.0, estimate_yaw_bias=0.3)
    feed(est, lambda t: (0.0,) * 8 + (3.0,), 0.1)
    assert est.attitude()[2] == pytest.approx(3.3 - 2.0 * math.pi)
    neg = make(delay=0.0, tau=0.0, rate=1000.0, estimate_yaw_bias=-0.1)
    feed(neg, lambda t: (0.0,) * 8 + (0.5,), 0.1)
    assert neg.attitude()[2] == pytest.approx(0.4)
    assert neg.attitude()[:2] == (0.0, 0.0) and neg.position() == (0.0, 0.0, 0.0)


def test_quantisation_puts_values_on_their_grid():
    q, qv = 1.0 / 256.0, 1.0 / 128.0
    est = make(delay=0.0, tau=0.0, rate=1000.0, estimate_quantum_z=q, estimate_quantum_velocity=qv,
               estimate_quantum_x=0.01)
    signal = lambda t: (0.1234567, 0.3333333, 5.0011, 0.123, -0.777, 0.0101, 0.01234, 0.0, 0.5)
    feed(est, signal, 0.05)
    x, y, z, vx, vy, vz, roll, pitch, yaw = est.values()
    for value, step in ((x, 0.01), (z, q), (vx, qv), (vy, qv), (vz, qv)):
        assert abs(value / step - round(value / step)) < 1e-9
    assert x == pytest.approx(0.12) and z == pytest.approx(1280.0 / 256.0) and vx == pytest.approx(16.0 / 128.0)
    assert vz == pytest.approx(1.0 / 128.0) and vy == pytest.approx(-99.0 / 128.0)
    assert (y, roll, yaw) == (0.3333333, 0.01234, 0.5)      # quantum 0: untouched


def test_every_effect_off_is_bit_for_bit_the_plain_estimate():
    from anafi_sim.sim.state_estimate import EFFECTS_OFF
    plain = make(delay=0.07, tau=0.03, rate=20.0, f16=True)
    off = make(delay=0.07, tau=0.03, rate=20.0, f16=True, **EFFECTS_OFF)
    wobble = lambda t: (math.sin(t), 2.0 * math.cos(0.7 * t), 5.0 + 0.3 * t, math.cos(t), -1.4 * math.sin(0.7 * t),
                        0.3, 0.1 * math.sin(3 * t), -0.05 * t, 3.0 * math.sin(0.4 * t))
    assert feed(plain, wobble, 5.0) == feed(off, wobble, 5.0)


@pytest.mark.parametrize('key, value', [
    ('estimate_position_fusion', 1), ('estimate_position_fix_delay', -0.1),
    ('estimate_position_fix_gain', float('nan')),
    ('estimate_yaw_bias', float('inf')), ('estimate_quantum_z', -1.0 / 256), ('estimate_quantum_velocity', 'x'),
    ('estimate_yaw_bias', True)])
def test_bad_effect_values_raise_value_error(key, value):
    with pytest.raises(ValueError, match=key):
        make(**{key: value})


# ------------------------------------------------------------------ translation and an estimate error (replays)
@pytest.mark.parametrize('extra', [{}, FUSION, dict(FUSION, estimate_quantum_x=0.02)])
def test_translating_the_world_moves_the_estimate_by_the_same_offset(extra):
    """Two estimators fed the same cruise, one with the world moved by d at 10 s: from then on its outputs
    are the other's + d (the errors it carries - lag, fusion state - are unchanged)."""
    d = (0.3, -0.2, 0.1)
    a = make(delay=0.05, tau=0.02, rate=20.0, **extra)
    b = make(delay=0.05, tau=0.02, rate=20.0, **extra)
    feed(a, cruise(2.0), 10.0)
    feed(b, cruise(2.0), 10.0)
    b.translate(*d)
    moved = lambda t: tuple(v + (d[i] if i < 3 else 0.0) for i, v in enumerate(cruise(2.0)(t)))
    out_a = feed(a, cruise(2.0), 12.0, t0=10.0 + DT)
    out_b = feed(b, moved, 12.0, t0=10.0 + DT)
    q = extra.get('estimate_quantum_x', 0.0)
    for (_, va), (_, vb) in zip(out_a, out_b):
        for i in range(3):
            assert vb[i] == pytest.approx(va[i] + d[i], abs=q + 1e-9)
        assert vb[3:] == pytest.approx(va[3:])


def test_a_position_error_added_to_the_fusion_decays_at_its_gain():
    k = FUSION['estimate_position_fix_gain']
    a = make(delay=0.0, tau=0.0, rate=1000.0, **FUSION)
    b = make(delay=0.0, tau=0.0, rate=1000.0, **FUSION)
    for est in (a, b):
        feed(est, cruise(3.0), 30.0)
    assert b.add_position_error(0.0, 0.1, 0.0) is True
    assert b.position()[1] - a.position()[1] == pytest.approx(0.1)          # visible at once
    assert b.position_state[1] - a.position_state[1] == pytest.approx(0.1)
    feed(a, cruise(3.0), 30.0 + 1.0 / k, t0=30.0 + DT)
    feed(b, cruise(3.0), 30.0 + 1.0 / k, t0=30.0 + DT)
    assert b.position()[1] - a.position()[1] == pytest.approx(0.1 * math.exp(-1.0), abs=0.002)


def test_without_the_fusion_an_estimate_error_cannot_be_held():
    est = make()
    assert est.add_position_error(0.1, 0.0) is False           # before the first update too
    feed(est, cruise(1.0), 1.0)
    before = est.values()
    assert est.position_state == pytest.approx(est.values()[0:3], abs=0.05)   # the smoothed delayed truth
    assert est.add_position_error(0.1, 0.0) is False
    assert est.values() == before
    with pytest.raises(ValueError):
        est.translate(float('nan'), 0.0)
    with pytest.raises(ValueError):
        make(**FUSION).add_position_error(float('inf'), 0.0)


def test_a_velocity_error_decays_and_the_fusion_integrates_it():
    """An error of the velocity estimate set at 30 s: published at once, decays as exp(-t/T); the fused
    position drifts by its integral (less what the fix corrects)."""
    T = 4.0
    a = make(delay=0.0, tau=0.0, rate=1000.0, **FUSION)
    b = make(delay=0.0, tau=0.0, rate=1000.0, estimate_velocity_error_time_constant=T, **FUSION)
    for est in (a, b):
        feed(est, cruise(3.0), 30.0)
    assert a.add_velocity_error(0.0, -0.1) is False              # no such state without the time constant
    assert b.add_velocity_error(0.0, -0.1) is True
    assert b.velocity()[1] == pytest.approx(-0.1) and b.velocity_error == pytest.approx((0.0, -0.1, 0.0))
    feed(a, cruise(3.0), 30.0 + T, t0=30.0 + DT)
    feed(b, cruise(3.0), 30.0 + T, t0=30.0 + DT)
    assert b.velocity()[1] == pytest.approx(-0.1 * math.exp(-1.0), abs=1e-3)
    assert b.velocity()[0] == pytest.approx(a.velocity()[0])
    drift = b.position()[1] - a.position()[1]
    integral = -0.1 * T * (1.0 - math.exp(-1.0))                 # what dead reckoning would accumulate
    assert integral < drift < 0.5 * integral                     # the fix takes part of it back (k = 0.3)
    assert a.position()[1] == pytest.approx(1.0)


def test_the_velocity_error_state_is_inert_without_an_error():
    """Shipped on, the velocity error changes nothing in a flight: T > 0 and no error added is T = 0 bit for
    bit (fusion, quantisation and yaw bias on)."""
    extra = dict(FUSION, estimate_quantum_x=0.0175, estimate_quantum_velocity=1.0 / 256.0, estimate_yaw_bias=0.02)
    a = make(delay=0.005, tau=0.015, **extra)
    b = make(delay=0.005, tau=0.015, estimate_velocity_error_time_constant=4.1, **extra)
    wobble = lambda t: (3.0 * t + math.sin(t), math.cos(2.0 * t), 5.0 + 0.1 * t, 3.0 + math.cos(t),
                        -2.0 * math.sin(2.0 * t), 0.1, 0.05 * math.sin(t), 0.1, 0.3 * t)
    assert [v for _, v in feed(a, wobble, 20.0)] == [v for _, v in feed(b, wobble, 20.0)]


def test_an_added_position_error_keeps_the_output_held():
    """Mid-hold, the published position moves by the error and stays held (not replaced by the running
    fused state)."""
    est = make(delay=0.0, tau=0.0, rate=20.0, **FUSION)
    feed(est, cruise(4.0), 30.0)
    feed(est, cruise(4.0), 30.02, t0=30.0 + DT)       # 20 ms into a 50 ms hold
    held = est.values()
    est.add_position_error(0.0, 0.1)
    assert est.values()[0] == held[0] and est.values()[1] == pytest.approx(held[1] + 0.1)


def test_a_stall_holds_the_output_then_jumps_to_the_current_estimate():
    est = make(delay=0.0, tau=0.0, rate=20.0, **FUSION)
    feed(est, cruise(2.0), 10.0)
    held = est.values()
    est.stall(10.2)
    out = feed(est, cruise(2.0), 10.3, t0=10.0 + DT)
    assert all(v == held for t, v in out if t < 10.2 - 1e-9)
    after = [v for t, v in out if t >= 10.2]
    assert after[0][0] == pytest.approx(held[0] + 2.0 * 0.2, abs=0.02)      # fresh: the filters kept running
    with pytest.raises(ValueError):
        est.stall(float('nan'))
