"""Log lines through a NodeContext (anafi_sim.ros.context): a hosted instance's lines name it and its throttled
lines are throttled per (instance, call site); the process's own node logs through rospy exactly as before (same
text, rospy's throttle per line of code). No ROS master: rospy's log functions are replaced by recorders, or its
own throttle runs on a fake ROS time."""
import logging
import threading

import pytest

rospy = pytest.importorskip('rospy')
from nav_msgs.msg import Odometry  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from anafi_control.commanders import DOWN  # noqa: E402
from anafi_sim.ros import context, conversions, node  # noqa: E402
from anafi_sim.ros.commander_watch import CommandTopicWatch  # noqa: E402
from anafi_sim.ros.context import NodeContext  # noqa: E402

LEVELS = ('logdebug', 'loginfo', 'logwarn', 'logerr', 'logfatal')


class FakeBus(object):
    """What NodeContext asks of a LocalBus here: the host's caller id and subscriptions (recorded)."""

    def __init__(self, caller_id='/fleet_ground_truth'):
        self.caller_id = caller_id
        self.subscriptions = []

    def subscriber(self, topic, data_class, callback, **kwargs):
        self.subscriptions.append((topic, callback))
        return object()


class Clock(object):
    """Stands for the time module in anafi_sim.ros.context: monotonic() returns ``now`` [s]."""

    def __init__(self, now=0.0):
        self.now = now

    def monotonic(self):
        return self.now


@pytest.fixture
def lines(monkeypatch):
    """rospy's log functions -> [(function, text as rospy would print it)]; rospy's throttled ones fail the test
    (a hosted line must not go through rospy's per-line throttle)."""
    out = []
    for level in LEVELS:
        monkeypatch.setattr(rospy, level, lambda text, *args, level=level: out.append(
            (level, text % args if args else text)))
    for level in ('loginfo_throttle', 'logwarn_throttle', 'logerr_throttle'):
        monkeypatch.setattr(rospy, level, lambda *a, level=level: pytest.fail('rospy.%s called' % level))
    return out


@pytest.fixture
def clock(monkeypatch):
    fake = Clock()
    monkeypatch.setattr(context, 'time', fake)
    return fake


def hosted(name):
    return NodeContext(name, FakeBus())


def warn_telemetry_exit(ctx, pid):
    """One call site, as a node's (the interface's restart warning)."""
    ctx.logwarn_throttle(10.0, 'interface: telemetry process %s exited with code %s', pid, 1)


def test_hosted_lines_carry_the_instance_name(lines):
    ctx = hosted('/anafi3/interface')
    for level in LEVELS:
        getattr(ctx, level)('interface: telemetry process %s exited (%s)', 1234, level)
    ctx.loginfo('interface: 100% of the samples')         # no arguments: the text as it is, as rospy prints it
    ctx.logerr_throttle(5.0, 'interface: publishing failed (%d times)', 3)
    assert lines == [(level, '[/anafi3/interface] interface: telemetry process 1234 exited (%s)' % level)
                     for level in LEVELS] + [
        ('loginfo', '[/anafi3/interface] interface: 100% of the samples'),
        ('logerr', '[/anafi3/interface] interface: publishing failed (3 times)')]


def test_two_instances_throttled_lines_from_one_call_site_both_pass(lines, clock):
    a, b = hosted('/anafi1/interface'), hosted('/anafi2/interface')
    clock.now = 50.0
    warn_telemetry_exit(a, 11)
    warn_telemetry_exit(b, 22)          # same line of code, same instant: another drone's, so it passes too
    assert lines == [('logwarn', '[/anafi1/interface] interface: telemetry process 11 exited with code 1'),
                     ('logwarn', '[/anafi2/interface] interface: telemetry process 22 exited with code 1')]


def test_one_instances_repeat_is_dropped_within_the_period_and_passes_after_it(lines, clock):
    ctx = hosted('/anafi1/interface')
    clock.now = 0.0                     # the first line passes whatever the clock reads
    warn_telemetry_exit(ctx, 1)
    clock.now = 9.9
    warn_telemetry_exit(ctx, 2)         # within 10 s of the first: dropped
    ctx.logwarn_throttle(10.0, 'interface: another call site')     # another line of the same instance: passes
    clock.now = 10.0
    warn_telemetry_exit(ctx, 3)         # the period is over
    clock.now = 15.0
    warn_telemetry_exit(ctx, 4)         # within 10 s of the third
    assert [text for _, text in lines] == [
        '[/anafi1/interface] interface: telemetry process 1 exited with code 1',
        '[/anafi1/interface] interface: another call site',
        '[/anafi1/interface] interface: telemetry process 3 exited with code 1']


class Records(logging.Handler):
    """The records rospy's logger ('rosout') emits: (level name, message)."""

    def __init__(self):
        logging.Handler.__init__(self, logging.DEBUG)
        self.got = []

    def emit(self, record):
        self.got.append((record.levelname, record.getMessage()))


@pytest.fixture
def rosout():
    logger = logging.getLogger('rosout')
    handler, level = Records(), logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.DEBUG)
    yield handler.got
    logger.removeHandler(handler)
    logger.setLevel(level)


def test_the_process_node_logs_through_rospy_unchanged(monkeypatch, rosout):
    recorded = []
    for level in LEVELS:
        monkeypatch.setattr(rospy, level, lambda *a, level=level: recorded.append((level,) + a))
    monkeypatch.setattr(rospy, 'get_name', lambda: '/anafi/interface')
    ctx = NodeContext.process()
    for level in LEVELS:
        getattr(ctx, level)('interface: telemetry process %s exited', 1234)
    assert recorded == [(level, 'interface: telemetry process %s exited', 1234) for level in LEVELS]
    # throttled: rospy's own throttle (ROS time), keyed by the line that called the context, not the context's
    now = [rospy.Time(100)]
    monkeypatch.setattr(rospy.Time, 'now', staticmethod(lambda: now[0]))
    monkeypatch.setattr(rospy.core._logging_throttle, 'last_logging_time_table', {})

    def other_call_site():
        ctx.logwarn_throttle(10.0, 'interface: telemetry process %s printed no sample', 2)
    warn_telemetry_exit(ctx, 1)
    now[0] = rospy.Time(105)
    warn_telemetry_exit(ctx, 2)         # the same line within 10 s of ROS time: rospy drops it
    other_call_site()                   # another line: passes
    ctx.logerr_throttle(10.0, 'interface: publishing failed (%d times)', 7)
    ctx.loginfo_throttle(10.0, 'interface: %s', 'waiting')
    now[0] = rospy.Time(110, 1)
    warn_telemetry_exit(ctx, 3)         # more than 10 s after the first
    other_call_site()                   # within 10 s of its first
    assert rosout == [('WARNING', 'interface: telemetry process 1 exited with code 1'),
                      ('WARNING', 'interface: telemetry process 2 printed no sample'),
                      ('ERROR', 'interface: publishing failed (7 times)'),
                      ('INFO', 'interface: waiting'),
                      ('WARNING', 'interface: telemetry process 3 exited with code 1')]


class ClosedPublisher(object):
    def publish(self, msg):
        raise rospy.ROSException('publish() to a closed topic')     # ends the diagnostics thread


def failing_once():
    """make_statuses for start_diagnostics_thread: raises, then no status."""
    calls = []

    def make_statuses():
        calls.append(1)
        if len(calls) == 1:
            raise KeyError('boom')
        return []
    return make_statuses


def test_the_helpers_log_for_their_instance(lines, clock, monkeypatch):
    """node.log_lines, node.start_diagnostics_thread, node.Timer, conversions.subscribe_inputs and
    CommandTopicWatch log through the instance's context: two instances' lines from one helper line both pass,
    each naming its instance."""
    monkeypatch.setattr(rospy, 'Timer', lambda period, cb, reset=False: cb)
    monkeypatch.setattr(rospy, 'get_time', lambda: 1.0)
    a, b = hosted('/anafi1/mpc_controller'), hosted('/anafi2/mpc_controller')
    for ctx in (a, b):
        node.log_lines([('warn', 'mirror: %s spawned' % ctx.namespace_id)], ctx)
    for ctx in (a, b):
        node.start_diagnostics_thread(0.0, failing_once(), ClosedPublisher(), stamp=lambda: rospy.Time(1),
                                      ctx=ctx).join(5.0)
    for ctx in (a, b):
        on_event = node.Timer(0.1, lambda event: 1 / 0, 'control', ctx=ctx)._timer
        on_event(rospy.timer.TimerEvent(None, None, None, rospy.Time(5), None))

    class Refusing(object):
        counters = {'rejected_states': 1, 'rejected_waypoints': 0}

        def on_state(self, *args):
            return False
    for ctx in (a, b):
        conversions.subscribe_inputs(Refusing(), threading.Lock(), 'drone/odom', 'waypoint', ctx=ctx)
        ctx.bus.subscriptions[0][1](Odometry())
    for ctx in (a, b):
        watch = CommandTopicWatch('drone/rpyt', String, ctx=ctx)
        ctx.bus.subscriptions[-1][1](String(data='x'))       # another instance of the host commands the drone
        assert watch.check() == DOWN
    assert [text.split(':')[0] for _, text in lines] == [
        '[/anafi1/mpc_controller] mirror', '[/anafi2/mpc_controller] mirror'] + [
        '[/anafi%d/mpc_controller] /anafi%d/mpc_controller' % (i, i) for i in (1, 2, 1, 2, 1, 2, 1, 2)]
    assert [text.split(': ', 1)[1][:24] for _, text in lines[2:]] == [
        "diagnostics failed: KeyE"] * 2 + ['control timer callback f'] * 2 + ['unusable state on /anafi'] * 2 + [
        'second commander on /ana'] * 2
