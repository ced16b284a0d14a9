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
