"""The in-process delivery of a fleet host (anafi_sim.ros.context.LocalBus): local subscribers get a publication
in the publishing thread (deferred ones on the delivery thread), rospy only when another process listens, the
host's own copies coming back through rospy are dropped, a failing callback stops nobody (no ROS master: rospy's
publisher and subscriber are replaced by fakes)."""
import threading

import pytest

rospy = pytest.importorskip('rospy')
from std_msgs.msg import String  # noqa: E402

from anafi_sim.ros import context  # noqa: E402


class Conn(object):
    def __init__(self, endpoint_id):
        self.endpoint_id = endpoint_id


class FakePublisher(object):
    def __init__(self, topic, data_class, latch=False, **kwargs):
        self.impl = type('Impl', (), {'connections': []})()
        self.sent = []

    def publish(self, msg):
        self.sent.append(msg)

    def unregister(self):
        pass


class FakeSubscriber(object):
    made = []

    def __init__(self, topic, data_class, callback, **kwargs):
        self.topic, self.callback, self.kwargs = topic, callback, kwargs
        FakeSubscriber.made.append(self)

    def get_num_connections(self):
        return 0

    def unregister(self):
        pass


@pytest.fixture
def bus(monkeypatch):
    monkeypatch.setattr(rospy, 'Publisher', FakePublisher)
    monkeypatch.setattr(rospy, 'Subscriber', FakeSubscriber)
    FakeSubscriber.made = []
    return context.LocalBus('/host')


def test_local_subscribers_get_the_message_in_the_publishing_thread_with_its_publisher(bus):
    got = []
    bus.subscriber('/a/t', String, lambda m: got.append((m.data, m._connection_header['callerid'],
                                                          threading.current_thread())))
    pub = bus.publisher('/a/t', String, owner='/a/node')
    pub.publish(String(data='x'))
    assert got == [('x', '/a/node', threading.current_thread())]
    assert pub.pub.sent == []                       # nobody elsewhere listens: rospy not bothered
    assert pub.get_num_connections() == 1


def test_external_subscribers_are_recounted_whenever_rospy_changes_its_connection_list(bus):
    pub = bus.publisher('/a/t', String, owner='/a/node')
    listed = pub.pub.impl.connections = [Conn('/rosbag')]
    assert pub.external_connections() == 1
    pub.pub.impl.connections = [Conn('/rosbag'), Conn('/rviz'), Conn('/host')]    # a subscriber came (a new list)
    assert pub.external_connections() == 2
    pub.pub.impl.connections = listed                                              # went again
    assert pub.external_connections() == 1
    del listed[:]                                                                  # rospy closing: emptied in place
    assert pub.external_connections() == 0
    pub.publish(String(data='x'))
    assert pub.pub.sent == []


def test_rospy_gets_it_when_another_process_listens_and_the_hosts_copies_are_dropped(bus):
    got = []
    bus.subscriber('/a/t', String, lambda m: got.append(m.data))
    pub = bus.publisher('/a/t', String, owner='/a/node')
    pub.pub.impl.connections = [Conn('/host')]     # only the host's own rospy subscriber
    pub.publish(String(data='1'))
    assert pub.pub.sent == [] and got == ['1']
    pub.pub.impl.connections = [Conn('/host'), Conn('/rosbag')]
    pub.publish(String(data='2'))
    assert [m.data for m in pub.pub.sent] == ['2'] and pub.external_connections() == 1
    from_rospy = FakeSubscriber.made[0].callback
    own = String(data='2')
    own._connection_header = {'callerid': '/host'}  # the copy that went out and came back
    other = String(data='3')
    other._connection_header = {'callerid': '/teleop'}
    from_rospy(own)
    from_rospy(other)
    assert got == ['1', '2', '3']


def test_a_failing_callback_is_counted_and_the_others_still_get_the_message(bus):
    errors, got = [], []
    bus.on_error = lambda topic, error: errors.append((topic, str(error)))
    bus.subscriber('/a/t', String, lambda m: 1 / 0)
    bus.subscriber('/a/t', String, lambda m: got.append(m.data))
    bus.publisher('/a/t', String).publish(String(data='x'))
    assert got == ['x'] and bus.callback_errors == 1 and errors[0][0] == '/a/t'


def test_deferred_callbacks_run_on_the_delivery_thread_in_order(bus):
    done = threading.Event()
    got = []

    def slow(m):
        got.append((m.data, threading.current_thread().name))
        if len(got) == 3:
            done.set()
    bus.subscriber('/a/t', String, slow, deferred=True)
    inline = []
    bus.subscriber('/a/t', String, lambda m: inline.append(m.data))
    pub = bus.publisher('/a/t', String)
    for k in range(3):
        pub.publish(String(data=str(k)))
    assert inline == ['0', '1', '2']                # not held up by the deferred one
    assert done.wait(5.0)
    assert got == [('0', 'local_bus'), ('1', 'local_bus'), ('2', 'local_bus')]
    assert 'deferred' not in FakeSubscriber.made[0].kwargs   # rospy never sees the option


def test_a_late_subscriber_of_a_latched_topic_gets_the_last_message_and_unregister_stops_it(bus):
    pub = bus.publisher('/a/state', String, latch=True)
    pub.publish(String(data='flying'))
    assert [m.data for m in pub.pub.sent] == ['flying']     # latched: rospy keeps it for later subscribers
    got = []
    sub = bus.subscriber('/a/state', String, lambda m: got.append(m.data))
    assert got == ['flying']
    sub.unregister()
    pub.publish(String(data='landing'))
    assert got == ['flying']


def test_a_hosted_context_resolves_its_names_against_its_own():
    ctx = context.NodeContext('/anafi1/interface', bus=object())
    assert ctx.resolve('ground_truth/odom') == '/anafi1/ground_truth/odom'
    assert ctx.resolve('~rate') == '/anafi1/interface/rate'
    assert ctx.resolve('/gazebo/set_model_state') == '/gazebo/set_model_state'
    assert ctx.namespace_id == 'anafi1' and ctx.private('rate') == '/anafi1/interface/rate'
