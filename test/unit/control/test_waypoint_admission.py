"""anafi_control.waypoint_admission: stale, future, out-of-order and foreign-frame waypoints are dropped and
counted; unstamped / frameless waypoints (the paper's nodes) pass; a clock jumping back starts a new line."""
import pytest

from anafi_control.contract import LEVEL_OK, LEVEL_WARN, Health
from anafi_control.waypoint_admission import WaypointAdmission, SOURCE_SILENCE


def test_a_fresh_waypoint_in_the_world_frame_passes():
    a = WaypointAdmission(max_age=1.0)
    assert a.admit(10.0, 9.95, 'world') == (True, '')
    assert a.admit(10.1, 10.05, '/world') == (True, '')
    assert a.dropped == 0


def test_unstamped_and_frameless_waypoints_pass():
    a = WaypointAdmission()
    assert a.admit(10.0, 0.0, '')[0] and a.admit(10.1, 0.0, '')[0]
    assert a.dropped == 0


def test_a_second_stream_stamped_5_s_older_is_dropped_as_stale():
    a = WaypointAdmission(max_age=1.0)
    assert a.admit(20.0, 19.98, 'world')[0]
    ok, why = a.admit(20.05, 15.05, 'world')
    assert not ok and 'stale stamp' in why and '5.00 s' in why
    assert a.counters['stale'] == 1


def test_out_of_order_and_future_stamps_are_dropped():
    a = WaypointAdmission(max_age=1.0)
    assert a.admit(20.0, 19.9, 'world')[0]
    ok, why = a.admit(20.01, 19.5, 'world')
    assert not ok and 'out of order' in why
    ok, why = a.admit(20.02, 25.0, 'world')
    assert not ok and 'future' in why
    assert (a.counters['out_of_order'], a.counters['future']) == (1, 1)
    assert a.admit(20.1, 20.0, 'world')[0]


def test_a_waypoint_in_another_frame_is_refused():
    a = WaypointAdmission()
    ok, why = a.admit(1.0, 1.0, 'anafi/base_link')
    assert not ok and "'anafi/base_link'" in why and "'world'" in why
    assert a.counters['foreign_frame'] == 1


def test_the_receipt_clock_jumping_back_starts_a_new_time_line():
    a = WaypointAdmission(max_age=1.0)
    assert a.admit(100.0, 100.0, 'world')[0]
    assert a.admit(0.5, 0.4, 'world')[0]          # a simulator restart: not "out of order"


def test_news_and_values_for_the_diagnostics():
    a = WaypointAdmission(max_age=1.0)
    a.admit(10.0, 1.0, 'world')
    a.admit(10.0, 10.0, 'map')
    news = a.news()
    assert '1 stale stamp' in news and '1 foreign frame' in news and 'last: foreign frame' in news
    assert a.news() == ''
    assert dict(a.values())['dropped waypoints: stale stamp'] == 1


@pytest.mark.parametrize('kwargs', [{'max_age': 0}, {'max_age': float('nan')}, {'max_age': True}, {'frame': '/'}])
def test_bad_settings_are_refused(kwargs):
    with pytest.raises(ValueError):
        WaypointAdmission(**kwargs)


def test_amend_health_warns_with_the_drops():
    conversions = pytest.importorskip('anafi_sim.ros.conversions')
    a = WaypointAdmission()
    h = Health(LEVEL_OK, 'tracking', [('x', 1)])
    assert conversions.amend_health(h, a).level == LEVEL_OK
    a.admit(10.0, 1.0, 'world')
    amended = conversions.amend_health(h, a)
    assert amended.level == LEVEL_WARN and 'tracking; dropped waypoints: 1 stale stamp' in amended.message
    assert ('x', 1) in amended.values


A, B = 'http://127.0.0.1:40001/', 'http://127.0.0.1:40002/'


def test_one_waypoint_source_the_first_publisher_heard():
    a = WaypointAdmission()
    assert a.admit(10.0, 9.95, 'world', A) == (True, '')
    ok, why = a.admit(10.05, 0.0, '', B)              # a second stream stamped 0, frame ''
    assert not ok and 'another publisher' in why
    ok, why = a.admit(10.1, 11.0, 'world', B)         # stamped 0.9 s ahead: cannot displace the source
    assert not ok and 'another publisher' in why
    assert a.admit(10.15, 10.1, 'world', A) == (True, '')   # the legitimate stream is never out of order
    ok, why = a.admit(10.2, 0.0, 'world', A)          # stamp 0 from a stamped stream
    assert not ok and 'unstamped' in why
    assert a.counters['other_source'] == 2 and a.counters['unstamped'] == 1
    a.release_source()                                # the source left the topic: hand-over
    assert a.admit(10.3, 0.0, 'world', B) == (True, '') and a.source == B
    assert a.admit(10.4, 0.0, 'world', B) == (True, '')     # unstamped from its start: accepted
    assert dict(a.values())['waypoint sources taken'] == 2


def test_a_source_that_falls_silent_hands_over_to_the_next_publisher():
    a = WaypointAdmission()
    for k in range(10):                                   # the monitor's hold of the start at 10 Hz
        assert a.admit(10.0 + 0.1 * k, 10.0 + 0.1 * k, 'world', A) == (True, '')
    last = 10.9
    ok, why = a.admit(last + 0.1, last + 0.1, 'world', B)     # while the source is live: refused
    assert not ok and 'another publisher' in why
    t = last + SOURCE_SILENCE + 0.05                        # the source silent for longer: hand-over
    assert a.admit(t, t, 'world', B) == (True, '') and a.source == B
    ok, why = a.admit(t + 0.05, t + 0.05, 'world', A)       # the old source is now the other publisher
    assert not ok and 'another publisher' in why
    assert dict(a.values())['waypoint sources taken'] == 2
