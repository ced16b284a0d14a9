"""Node boilerplate: ~params, the 1 Hz /diagnostics thread, start-up with fatal bad parameters.

Stage: ROS wiring only. Diagnostics run on WALL time, so a node still reports
when /clock stops.
"""
import sys
import threading
import time

import rospy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from anafi_sim.ros.params import ParamReader


def private_params():
    """A ParamReader over the node's private parameters (``~name``)."""
    return ParamReader(lambda name, default: rospy.get_param('~' + name, default))


def namespace_id():
    """The node's namespace without its slashes, 'anafi' at the root (hardware_id of the PID nodes)."""
    return rospy.get_namespace().strip('/') or 'anafi'


def diagnostic_status(name, level, message, values, hardware_id=''):
    """A DiagnosticStatus; ``values`` are (key, value) pairs, both stored as strings."""
    return DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id,
                            values=[KeyValue(str(k), str(v)) for k, v in values])


def publish_diagnostics(pub, statuses):
    """Publish ``statuses`` in one DiagnosticArray stamped now; False once ROS is shut down (pub closed)."""
    array = DiagnosticArray(status=list(statuses))
    try:
        array.header.stamp = rospy.Time.now()
        pub.publish(array)
    except rospy.ROSException:
        return False
    return True


def start_diagnostics_thread(period, make_statuses, pub):
    """Daemon thread publishing ``make_statuses()`` on ``pub`` every ``period`` s of wall time until shutdown."""
    def loop():
        while True:
            time.sleep(period)
            if rospy.is_shutdown() or not publish_diagnostics(pub, make_statuses()):
                return
    thread = threading.Thread(target=loop, name='diagnostics', daemon=True)
    thread.start()
    return thread


def run_node(name, factory, fatal_exit_code=1):
    """init_node(name), then ``factory().run()``; a ValueError from factory (bad parameters) is fatal."""
    rospy.init_node(name)
    try:
        node = factory()
    except ValueError as error:
        rospy.logfatal('%s: bad parameters: %s', rospy.get_name(), error)
        sys.exit(fatal_exit_code)
    node.run()
