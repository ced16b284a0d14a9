"""The in-process engine's clockwork (anafi_lab.engine.event_loop) on its own: event order, node clocks on
/clock ticks, ROS timers, topics with transport delays."""
import pytest

from anafi_lab.engine.event_loop import (DELIVERY, PHYSICS, TIMER, EventLoop, NodeClock, Timer, Topic, to_ns,
                                            to_s)

MS = 1000000
TICK = 5 * MS          # the physics period at 200 Hz


def test_events_run_in_time_then_order_then_fifo():
    loop = EventLoop()
    seen = []
    loop.at(10, seen.append, 'timer', order=TIMER)
    loop.at(10, seen.append, 'delivery 1', order=DELIVERY)
    loop.at(10, seen.append, 'physics', order=PHYSICS)
    loop.at(10, seen.append, 'delivery 2', order=DELIVERY)
    loop.at(5, seen.append, 'early')
    assert loop.run() is False
    assert seen == ['early', 'physics', 'delivery 1', 'delivery 2', 'timer']
    assert loop.now == 10 and loop.events == 5


def test_run_until_and_stop():
    loop = EventLoop()
    seen = []
    for t in (1, 2, 3, 4):
        loop.at(t, seen.append, t)
    loop.run(until=2)
    assert seen == [1, 2] and loop.now == 2
    loop.at(3, loop.stop)
    assert loop.run() is True                  # stopped after the event at 3 that called stop()
    assert seen == [1, 2, 3] and loop.now == 3
    loop.run()
    assert seen == [1, 2, 3, 4]
    with pytest.raises(ValueError):
        loop.at(1, seen.append, 'in the past')


def test_times_are_integer_nanoseconds():
    assert to_ns(0.1) == 100000000 and to_ns(1.0 / 30.0) == 33333333
    assert to_s(100000000) == 0.1 and to_s(3 * 1000000000 + 5) == 3.000000005


def test_node_clock_reads_the_newest_tick_that_arrived():
    loop = EventLoop()
    clock = NodeClock(loop, TICK)
    late = NodeClock(loop, TICK, latency=2 * MS)
    for t, expected, expected_late in ((0, 0, 0), (4 * MS, 0, 0), (5 * MS, 5 * MS, 0), (7 * MS, 5 * MS, 5 * MS),
                                       (12 * MS, 10 * MS, 10 * MS), (11 * MS, 10 * MS, 5 * MS)):
        loop.now = t
        assert clock.now() == expected and late.now() == expected_late, t
    assert clock.reaches(100 * MS) == 100 * MS and clock.reaches(101 * MS) == 105 * MS
    assert late.reaches(100 * MS) == 102 * MS


def test_timer_fires_on_the_first_tick_at_or_after_each_due_time():
    """rospy.Timer at 30 Hz on a 200 Hz /clock: due every 33.333333 ms, runs on the 5 ms ticks."""
    loop = EventLoop()
    clock = NodeClock(loop, TICK)
    fired = []
    Timer(loop, clock, to_ns(1.0 / 30.0), lambda now: fired.append((loop.now, now)))
    loop.run(until=200 * MS)
    assert [now for _, now in fired] == [35 * MS, 70 * MS, 100 * MS, 135 * MS, 170 * MS, 200 * MS]
    assert all(t == now for t, now in fired)   # no /clock latency: it runs at the tick it reads


def test_rate_loop_starts_at_once_and_keeps_its_phase():
    """A ``while: work(); rate.sleep()`` loop (first = 0), started at 15 ms: 15, 115, 215 ms ..."""
    loop = EventLoop()
    clock = NodeClock(loop, TICK, latency=1 * MS)
    fired = []
    timer = Timer(loop, clock, 100 * MS, lambda now: fired.append((loop.now, now)), start=15 * MS, first=0)
    loop.run(until=330 * MS)
    assert fired == [(16 * MS, 15 * MS), (116 * MS, 115 * MS), (216 * MS, 215 * MS), (316 * MS, 315 * MS)]
    timer.cancel()
    loop.run(until=600 * MS)
    assert len(fired) == 4


def test_topic_delivers_after_each_subscribers_delay():
    loop = EventLoop()
    topic = Topic(loop, 'x')
    got = []
    topic.subscribe(lambda m: got.append(('slow', loop.now, m)), delay=3 * MS)
    topic.subscribe(lambda m: got.append(('fast', loop.now, m)), delay=1 * MS)
    topic.subscribe(lambda m: got.append(('recorder', loop.now, m)))          # synchronous
    loop.at(10 * MS, topic.publish, 'a')
    loop.at(10 * MS, topic.publish, 'b', 2 * MS)   # leaves its publisher 2 ms later
    loop.run()
    assert got == [('recorder', 10 * MS, 'a'), ('recorder', 10 * MS, 'b'), ('fast', 11 * MS, 'a'),
                   ('slow', 13 * MS, 'a'), ('fast', 13 * MS, 'b'), ('slow', 15 * MS, 'b')]
    assert topic.published == 2


def test_each_consumer_sees_the_message_of_its_period_after_the_delay():
    """A 30 Hz publisher (ticks 35, 70, 100, 135, ... ms) stamping with its clock; a 10 Hz consumer using the
    newest message it received: the message of its own tick is still on its way (1 ms), so it sees the one
    of the tick before; with 31 ms the one before that."""
    for delay, expected in ((1 * MS, {100: 70, 200: 170, 300: 270}),
                            (31 * MS, {100: 35, 200: 135, 300: 235})):
        loop = EventLoop()
        clock = NodeClock(loop, TICK)
        topic = Topic(loop)
        latest = {}
        seen = {}
        topic.subscribe(lambda stamp: latest.update(stamp=stamp), delay=delay)
        Timer(loop, clock, to_ns(1.0 / 30.0), topic.publish)
        Timer(loop, clock, 100 * MS, lambda now: seen.update({now // MS: latest.get('stamp', -MS) // MS}))
        loop.run(until=300 * MS)
        assert seen == expected, delay
