"""dynamic_reconfigure that leaves a trace: every live tuning change logged and published for the run's files.

``TracedServer`` is dynamic_reconfigure's ``Server`` (same type, callback, services and topics) that, for
each request (``rosrun dynamic_reconfigure dynparam set NODE PARAM VALUE``, a client, rqt where packaged),
compares the configuration before, the values asked for (before the server clamps them to the cfg's range)
and the configuration the node's callback applied (``anafi_control.tuning.changes``), and

- logs each change on /rosout: INFO ``tuning NODE: PARAM: OLD -> NEW``; WARN when a value was clamped to its
  range or not applied by the controller (with the value asked for);
- publishes the node's tuning history on ``/<drone>/tuning/changes`` (``TUNING_CHANGES`` under the first
  part of the node's namespace; std_msgs/String, latched, so a subscriber that connects later still gets
  every change: YAML ``{node: NAME, changes: [...]}``, each change ``stamp`` (ROS time [s]), ``wall`` (Unix
  time [s]), ``node``, ``parameter``, ``old``, ``new``, ``requested``, ``outcome`` applied | clamped |
  refused; a new message after each request). experiment_monitor.py keeps them in the run's RUN.run.yaml
  (``tuning``), experiment.launch's bag records the topic.
"""
import copy
import time

import rospy
import yaml
from dynamic_reconfigure.encoding import extract_params
from dynamic_reconfigure.server import Server
from std_msgs.msg import String

from anafi_control.tuning import changes, describe
from anafi_sim import names


def drone_topic(name, ctx=None):
    """``name`` under the drone's namespace: the first part of this node's namespace ('/anafi/pid/' -> /anafi;
    ``ctx``: a NodeContext's namespace)."""
    first = (rospy.get_namespace() if ctx is None else ctx.namespace).strip('/').split('/')[0]
    return '/%s/%s' % (first, name) if first else '/' + name


class TracedServer(Server):
    """dynamic_reconfigure ``Server`` whose requests are logged and published (module doc). ``ctx``: the
    NodeContext of the node instance (default the process's node); a hosted instance's server lives under
    its own name (``<ctx.name>/set_parameters``, ...), as the node's would."""

    def __init__(self, type, callback, namespace='', ctx=None):
        self.trace_topic = drone_topic(names.TUNING_CHANGES, ctx)
        if ctx is None:
            self.trace_pub = rospy.Publisher(self.trace_topic, String, queue_size=10, latch=True)
        else:
            self.trace_pub = ctx.publisher(self.trace_topic, String, queue_size=10, latch=True)
        self.history = []
        self.names = [p['name'] for p in extract_params(type.config_description)]
        self.minimum = dict((n, type.min[n]) for n in self.names if type.min.get(n, '') != '')
        self.maximum = dict((n, type.max[n]) for n in self.names if type.max.get(n, '') != '')
        self.node = rospy.get_name() if ctx is None else ctx.name
        self.log = rospy if ctx is None else ctx     # what logs the changes
        if ctx is not None and ctx.hosted:    # Server's '~' names are the process's node: the instance's instead
            namespace = ctx.resolve('~' + namespace.strip('~')) if namespace else ctx.name
        Server.__init__(self, type, callback, namespace)
        if ctx is not None:     # the Server's own topics and service, in the instance's wiring
            base = ctx.resolve(namespace or '~').rstrip('/')
            ctx.record('publishes', base + '/parameter_descriptions', base + '/parameter_updates')
            ctx.record('services', base + '/set_parameters')

    def update_configuration(self, changes_asked):
        with self.mutex:
            before = copy.deepcopy(self.config)
            requested = dict((k, v) for k, v in changes_asked.items() if k in self.names)
            new_config = copy.deepcopy(self.config)
            new_config.update(changes_asked)
            self._clamp(new_config)
            applied = self._change_config(new_config, self._calc_level(new_config, self.config))
        self.trace(before, requested, applied)
        return applied

    def trace(self, before, requested, applied):
        """Log and publish what one request changed; the records."""
        records = changes(before, requested, applied, self.names, self.minimum, self.maximum)
        stamp, wall = rospy.get_time(), time.time()
        for record in records:
            line = 'tuning %s: %s' % (self.node, describe(record, self.minimum, self.maximum))
            if record['outcome'] == 'applied':
                self.log.loginfo(line)
            else:
                self.log.logwarn(line)
            self.history.append(dict(stamp=round(stamp, 6), wall=round(wall, 3), node=self.node, **record))
        if records:
            self.trace_pub.publish(String(yaml.safe_dump({'node': self.node, 'changes': self.history},
                                                         default_flow_style=None, sort_keys=False)))
        return records
