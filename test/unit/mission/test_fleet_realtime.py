"""Whether a running fleet keeps real time (anafi_sim/mission/fleet_realtime.py): the rates over a window and
the rule a fleet host reports on /diagnostics."""
import pytest

from anafi_sim.mission import fleet_realtime as fr


def feed(window, key, rate, start=0.0, seconds=6.0, period=1.0, value0=0.0):
    t = start
    while t <= start + seconds + 1e-9:
        window.add(key, t, value0 + rate * (t - start))
        t += period


def test_the_rate_is_over_the_last_window_once_it_spans_it_and_advanced_before():
    w = fr.RateWindow(window=5.0)
    w.add('sim', 0.0, 0.0)
    w.add('sim', 1.0, 1.0)
    assert w.rate('sim') is None                     # 1 s of the 5: not rated yet
    feed(w, 'sim', 0.9, start=1.0, seconds=8.0, value0=1.0)
    assert w.rate('sim') == pytest.approx(0.9)       # only the last 5 s count: the first second's 1.0 is gone
    assert w.rate('nothing') is None


def test_a_counter_that_never_advanced_before_the_window_is_not_rated():
    w = fr.RateWindow(window=5.0)
    for t in range(0, 6):
        w.add('truth', float(t), 0.0)                 # no telemetry yet
    feed(w, 'truth', 100.0, start=6.0, seconds=3.0)   # starts: the window still holds its silent start
    assert w.rate('truth') is None
    feed(w, 'truth', 100.0, start=9.0, seconds=6.0, value0=300.0)
    assert w.rate('truth') == pytest.approx(100.0)


def test_a_counter_going_back_starts_again_and_a_repeated_instant_is_ignored():
    w = fr.RateWindow(window=5.0)
    feed(w, 'sim', 1.0, seconds=8.0, value0=100.0)
    w.add('sim', 8.0, 200.0)                          # same instant: ignored
    assert w.rate('sim') == pytest.approx(1.0)
    w.add('sim', 9.0, 0.5)                            # respawned host, a new simulator
    assert w.rate('sim') is None
    w.forget('sim')
    assert w.rate('sim') is None
    with pytest.raises(ValueError):
        fr.RateWindow(window=0.0)


def test_behind_real_time_names_the_worst_drone_of_each_figure():
    rtf = {'anafi1': 1.0, 'anafi2': 0.93, 'anafi3': 0.97}
    truth = {'anafi1': 99.9, 'anafi2': 100.0, 'anafi3': 89.2}
    expected = dict((d, 100.0) for d in truth)
    status = fr.real_time_status(rtf, truth, expected)
    assert status.behind
    assert status.message == 'behind real time: RTF 0.93 (anafi2) / ground truth 89 Hz (anafi3); 2 of 3 drones'
    values = dict(status.values)
    assert values['drones behind'] == '2' and values['behind'] == 'anafi2, anafi3'
    assert values['RTF min'] == '0.930 (anafi2)' and values['ground truth min [Hz]'] == '89.2 (anafi3)'


def test_at_the_thresholds_a_fleet_keeps_real_time():
    status = fr.real_time_status({'a': fr.MIN_RTF}, {'a': 97.0}, {'a': 100.0})
    assert not status.behind and status.message == 'real time: RTF min 0.98, ground truth min 97 Hz (1 drones)'
    assert fr.real_time_status({'a': 0.9799}, {}, {}).message == 'behind real time: RTF 0.98 (a); 1 of 1 drones'
    status = fr.real_time_status({}, {"a": 48.6}, {"a": 50.0})    # the interface's own rate is the reference
    assert not status.behind
    assert fr.real_time_status({}, {'a': 46.0}, {'a': 50.0}).behind


def test_drones_not_rated_yet_are_not_behind():
    status = fr.real_time_status({'a': None}, {'a': None}, {'a': 100.0})
    assert not status.behind and status.message == 'real time: not rated yet'
    status = fr.real_time_status({'a': None, 'b': 1.0}, {'b': 80.0}, {})       # no expected rate: not judged
    assert not status.behind and dict(status.values)['drones rated'] == '1'
