#!/usr/bin/env python3
"""rostest (real_anafi.test, real_anafi_preview.test): our controller flies a circle through only the real bridge's
topics (real_anafi.launch on the simulated bridge; the simulator's drone/odom is hidden), its e_mu on
bridge_state.py's drone/odom within 10 % of e_mu against the simulator's own estimate; then the relayed bridge
topic (~relay: position_control/state_enu, or drone/speed) freezes and the PCMD stream ends within the
controller's state_timeout (+ two control periods)."""
import threading
import unittest

import rospy
import rostest
import rosgraph
import yaml
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from std_msgs.msg import Header, String

from anafi_sim.mission.evaluation import evaluate_messages
from anafi_sim.msg import Waypoint
from anafi_sim.ros.wire_types import paper_state_class, piloting_command_class

NS = '/anafi'
STATE_TIMEOUT = 0.5      # s, the controllers' default state_timeout (anafi_control.contract)
PERIOD = 0.1             # s, the MPC's command period


class Recorder(object):
    def __init__(self):
        self.lock = threading.Lock()
        self.frozen = False
        self.hidden = []         # (t, Odometry) of the simulator's own estimate
        self.waypoints = []      # (t, Waypoint)
        self.commands = []       # stamps [s] of drone/rpyt
        self.begin = self.end = None   # std_msgs/Header
        self.summary = None
        topic = rospy.get_param('~relay', 'position_control/state_enu')
        cls = paper_state_class() if topic.endswith('state_enu') else Vector3Stamped
        self.relay = rospy.Publisher('%s/%s' % (NS, topic), cls, queue_size=10)
        rospy.Subscriber('%s/bridge_raw/%s' % (NS, topic.split('/')[-1]), cls, self._on_raw, queue_size=10)
        rospy.Subscriber(NS + '/hidden/odom', Odometry, self._on_hidden, queue_size=50)
        rospy.Subscriber(NS + '/position_control/waypoint', Waypoint, self._on_waypoint, queue_size=50)
        rospy.Subscriber(NS + '/drone/rpyt', piloting_command_class(), self._on_command, queue_size=50)
        rospy.Subscriber(NS + '/trajectory/begin', Header, lambda m: setattr(self, 'begin', m))
        rospy.Subscriber(NS + '/trajectory/end', Header, lambda m: setattr(self, 'end', m))
        rospy.Subscriber(NS + '/evaluation/summary', String, self._on_summary)

    def _on_raw(self, msg):
        if not self.frozen:
            self.relay.publish(msg)

    def _on_hidden(self, msg):
        with self.lock:
            self.hidden.append((rospy.get_time(), msg))

    def _on_waypoint(self, msg):
        with self.lock:
            self.waypoints.append((rospy.get_time(), msg))

    def _on_command(self, msg):
        with self.lock:
            self.commands.append(rospy.get_time())

    def _on_summary(self, msg):
        s = yaml.safe_load(msg.data)
        if isinstance(s, dict) and s.get('state') == 'final':
            self.summary = s


def wait(cond, timeout_sim, what):
    end = rospy.get_time() + timeout_sim
    while not rospy.is_shutdown() and not cond():
        if rospy.get_time() > end:
            raise AssertionError('timed out (%.0f s of simulation time) waiting for %s' % (timeout_sim, what))
        rospy.sleep(0.1)


class TestRealAnafi(unittest.TestCase):
    def test_circle_through_the_bridge_topics_then_a_frozen_state(self):
        rospy.init_node('test_real_anafi')
        rec = Recorder()
        wait(lambda: rec.summary is not None, 120.0, 'the final evaluation summary')
        # only the real bridge's topics reach our nodes: drone/odom is bridge_state's alone, no ground truth
        master = rosgraph.Master('/test_real_anafi')
        pubs = dict((topic, nodes) for topic, nodes in master.getSystemState()[0])
        self.assertEqual(pubs.get(NS + '/drone/odom'), [NS + '/bridge_state'])
        self.assertNotIn(NS + '/ground_truth/odom', pubs)
        # the same evaluation (anafi_sim.mission.evaluation) on the simulator's own estimate
        with rec.lock:
            reference = evaluate_messages(list(rec.waypoints), list(rec.hidden), begins=[(0.0, rec.begin)],
                                          ends=[(0.0, rec.end)])
        e_mu_hidden = reference.estimate.e_mu
        e_mu = float(rec.summary['estimate']['e_mu'])
        rospy.loginfo('e_mu on the bridge path %.3f m, on the simulator estimate %.3f m', e_mu, e_mu_hidden)
        self.assertLess(abs(e_mu - e_mu_hidden), 0.1 * e_mu_hidden)
        # freeze the relayed topic: drone/odom stops, the controller goes silent, the PCMD stream ends
        t_freeze = rospy.get_time()
        with rec.lock:
            self.assertTrue(rec.commands and rec.commands[-1] > t_freeze - 1.0, 'no commands before the freeze')
        rec.frozen = True
        rospy.sleep(3.0)
        with rec.lock:
            last = rec.commands[-1]
        self.assertLessEqual(last - t_freeze, STATE_TIMEOUT + 2 * PERIOD)


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'test_real_anafi', TestRealAnafi)
