"""The node glue of a hosted node instance (anafi_sim.ros.context.NodeContext on a host's bus): the commander
watch, ~params, hardware ids and tuning topic of the instance, not of the process (no ROS master needed)."""
import pytest

rospy = pytest.importorskip('rospy')
from std_msgs.msg import String  # noqa: E402

from anafi_control.commanders import CLEAR, DOWN, LISTEN  # noqa: E402
from anafi_sim.ros import node  # noqa: E402
from anafi_sim.ros.commander_watch import CommandTopicWatch  # noqa: E402
from anafi_sim.ros.context import NodeContext  # noqa: E402
from anafi_sim.ros.reconfigure import drone_topic  # noqa: E402


class FakeBus(object):
    """What NodeContext asks of a LocalBus here: the host's caller id and subscriptions (recorded)."""

    def __init__(self, caller_id='/host'):
        self.caller_id = caller_id
        self.subscriptions = []

    def subscriber(self, topic, data_class, callback, **kwargs):
        self.subscriptions.append((topic, callback))
        return object()


def hosted_watch(name='/anafi1/mpc_controller'):
    bus = FakeBus()
    watch = CommandTopicWatch('drone/rpyt', String, ctx=NodeContext(name, bus))
    return watch, bus


def from_process(caller, data='x'):
    msg = String(data=data)
    msg._connection_header = {'callerid': caller}
    return msg


def test_a_hosted_watch_subscribes_the_instances_command_topic():
    watch, bus = hosted_watch()
    assert (watch.topic, watch.me, watch.host) == ('/anafi1/drone/rpyt', '/anafi1/mpc_controller', '/host')
    assert [topic for topic, _ in bus.subscriptions] == ['/anafi1/drone/rpyt']


def test_a_hosted_watch_ignores_its_own_commands_and_hears_the_other_instances():
    watch, bus = hosted_watch()
    callback = bus.subscriptions[0][1]
    own = String(data='own')
    watch.sent(own)
    callback(own)                                   # the bus hands the instance's own command back
    assert watch.guard.foreign_commands == 0
    assert watch.check() != DOWN
    callback(String(data='own'))                    # equal, but another instance's message object
    assert watch.guard.foreign_commands == 1
    assert list(watch.guard.heard) == ['/host (an instance of this host)']
    assert watch.check() == DOWN
    assert 'an instance of this host' in watch.message()


def test_a_hosted_watch_hears_other_processes_by_caller_id():
    watch, bus = hosted_watch()
    bus.subscriptions[0][1](from_process('/teleop'))
    bus.subscriptions[0][1](from_process('/anafi1/mpc_controller'))     # its own name: not another commander
    assert list(watch.guard.heard) == ['/teleop']


def test_the_process_watch_is_unchanged(monkeypatch):
    subscribed = []
    monkeypatch.setattr(rospy, 'get_name', lambda: '/anafi/mpc_controller')
    monkeypatch.setattr(rospy, 'resolve_name', lambda name, caller_id=None: '/anafi/' + name)
    monkeypatch.setattr(rospy, 'Subscriber', lambda topic, cls, cb, **kw: subscribed.append((topic, cb)))
    watch = CommandTopicWatch('drone/rpyt', String)
    assert (watch.topic, watch.me, watch.host) == ('/anafi/drone/rpyt', '/anafi/mpc_controller', None)
    mine = String(data='own')
    watch.sent(mine)                                # nothing kept: the process's commands carry its caller id
    subscribed[0][1](from_process('/anafi/mpc_controller'))
    assert watch.guard.foreign_commands == 0 and watch.check() in (CLEAR, LISTEN)
    subscribed[0][1](from_process('/teleop'))
    assert watch.check() == DOWN


def test_params_hardware_id_and_tuning_topic_of_an_instance(monkeypatch):
    values = {'/anafi2/mpc_controller/rate': 20.0}
    monkeypatch.setattr(rospy, 'get_param', lambda name, default=None: values.get(name, default))
    ctx = NodeContext('/anafi2/mpc_controller', FakeBus())
    assert node.private_params(ctx).positive('rate', 10.0) == 20.0
    assert node.private_params(ctx).positive('state_timeout', 0.5) == 0.5
    assert node.namespace_id(ctx) == 'anafi2'
    assert node.namespace_id(NodeContext('/mpc_controller', FakeBus())) == 'anafi'
    assert drone_topic('tuning/changes', ctx) == '/anafi2/tuning/changes'
    assert drone_topic('tuning/changes', NodeContext('/anafi3/pid/x_loop', FakeBus())) == '/anafi3/tuning/changes'
