#!/usr/bin/env python3
"""rostest (real_anafi.test, real_anafi_preview.test): our controller flies a circle through only the real bridge's
topics, as well as it flies the same circle on drone/odom, and a frozen bridge topic ends the PCMD stream.

The launch file runs real_anafi.launch on the simulated bridge in lockstep (the simulator's ~sync: each control
period's /clock waits for the controller's command, so the machine's load does not change the flight); the
simulator's drone/odom and sim/truth are hidden under hidden/ (a real bridge has neither) and the relayed bridge
topic (~relay: position_control/state_enu, or drone/speed) goes through this node. Checks, in order:

1. only the real bridge's topics reach our nodes (drone/odom is bridge_state.py's, no ground_truth/odom);
2. after the final evaluation, ~relay freezes: the PCMD stream (drone/rpyt) ends. Asserted: no command
   stamped later than the freeze + GENEROUS x the nominal failsafe time (the controller's state_timeout +
   bridge_state's max_skew + a command period), over a quiet window as long again; the measured delay is logged;
3. the reference run: the same scenario, controller, rtf and lockstep on drone/odom (experiment.launch sync:=true
   on a private master, anafi_lab.engine.lockstep.run_sync). The evaluator's e_mu (against the estimate, the
   paper's metric) within 10 % of the reference's; e_mu against ground truth (the evaluator's core,
   anafi_sim.mission.evaluation, on hidden/truth; the reference's evaluator summary) within ~truth_tolerance
   (default 10 %) of the reference's; e_mu on bridge_state's drone/odom within 10 % of e_mu on the simulator's
   own estimate (hidden/odom) of the same flight. The lockstep holds the command, not the state's way to the
   controller: which estimate sample a cycle sees varies from run to run, and with the preview MPC's few
   centimetres of error against truth that moves its e_mu vs truth by tens of per cent between two runs on
   drone/odom alike (real_anafi_preview.test sets ~truth_tolerance).
"""
import os
import shutil
import sys
import tempfile
import threading
import unittest

import rospkg
import rospy
import rostest
import rosgraph
import yaml
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from std_msgs.msg import Header, String

from anafi_control.contract import TIMEOUT_DEFAULTS
from anafi_lab.engine import lockstep as lockstep_runs
from anafi_sim import paths
from anafi_sim.interface.bridge_state import DEFAULTS as BRIDGE_DEFAULTS
from anafi_sim.mission.evaluation import evaluate_messages
from anafi_sim.msg import Waypoint
from anafi_sim.ros.wire_types import paper_state_class, piloting_command_class

NS = '/anafi'
PERIOD = 0.1             # s, the MPC's command period
FAILSAFE = TIMEOUT_DEFAULTS['state_timeout'] + BRIDGE_DEFAULTS['max_skew'] + PERIOD
"""s of simulation time from the last bridge sample to the controller's last command, transport aside."""
GENEROUS = 4.0           # the bound asserted on the end of the PCMD stream: GENEROUS x FAILSAFE after the freeze
TOLERANCE = 0.10


class Recorder(object):
    def __init__(self):
        self.lock = threading.Lock()
        self.frozen = False
        self.last_relayed = None   # stamp [s] of the last relayed bridge message
        self.odom = []             # (t, Odometry): bridge_state.py's drone/odom
        self.hidden = []           # (t, Odometry): the simulator's own estimate
        self.truth = []            # (t, Odometry): ground truth
        self.waypoints = []        # (t, Waypoint)
        self.commands = []         # header stamps [s] of drone/rpyt
        self.begin = self.end = None   # std_msgs/Header
        self.summary = None
        topic = rospy.get_param('~relay', 'position_control/state_enu')
        cls = paper_state_class() if topic.endswith('state_enu') else Vector3Stamped
        self.relay = rospy.Publisher('%s/%s' % (NS, topic), cls, queue_size=10)
        rospy.Subscriber('%s/bridge_raw/%s' % (NS, topic.split('/')[-1]), cls, self._on_raw, queue_size=10)
        self._record(NS + '/drone/odom', Odometry, self.odom)
        self._record(NS + '/hidden/odom', Odometry, self.hidden)
        self._record(NS + '/hidden/truth', Odometry, self.truth)
        self._record(NS + '/position_control/waypoint', Waypoint, self.waypoints)
        rospy.Subscriber(NS + '/drone/rpyt', piloting_command_class(), self._on_command, queue_size=100)
        rospy.Subscriber(NS + '/trajectory/begin', Header, lambda m: setattr(self, 'begin', m))
        rospy.Subscriber(NS + '/trajectory/end', Header, lambda m: setattr(self, 'end', m))
        rospy.Subscriber(NS + '/evaluation/summary', String, self._on_summary)

    def _record(self, topic, cls, into):
        def store(msg):
            with self.lock:
                into.append((rospy.get_time(), msg))
        rospy.Subscriber(topic, cls, store, queue_size=500)

    def _on_raw(self, msg):
        with self.lock:
            if self.frozen:
                return
            self.last_relayed = msg.header.stamp.to_sec()
            self.relay.publish(msg)

    def freeze(self):
        with self.lock:
            self.frozen = True
            return self.last_relayed

    def _on_command(self, msg):
        with self.lock:
            self.commands.append(msg.header.stamp.to_sec())

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


def tests_dir():
    """A new folder for this test's reference run, under ROS's home folder."""
    parent = os.path.join(rospkg.get_ros_home(), 'anafi_sim_tests')
    os.makedirs(parent, exist_ok=True)
    return tempfile.mkdtemp(prefix='real_anafi_reference_', dir=parent)


class TestRealAnafi(unittest.TestCase):
    def test_circle_through_the_bridge_topics_then_a_frozen_state(self):
        rospy.init_node('test_real_anafi')
        rec = Recorder()
        wait(lambda: rec.summary is not None, 300.0, 'the final evaluation summary')
        # 1. only the real bridge's topics reach our nodes: drone/odom is bridge_state's alone, no ground truth
        master = rosgraph.Master('/test_real_anafi')
        pubs = dict((topic, nodes) for topic, nodes in master.getSystemState()[0])
        self.assertEqual(pubs.get(NS + '/drone/odom'), [NS + '/bridge_state'])
        self.assertNotIn(NS + '/ground_truth/odom', pubs)
        self.check_frozen_topic_ends_the_stream(rec)
        self.check_against_the_odom_run(rec)

    def check_frozen_topic_ends_the_stream(self, rec):
        with rec.lock:
            self.assertTrue(rec.commands, 'no command before the freeze')
            self.assertGreater(rec.commands[-1], rospy.get_time() - 1.0, 'no command in the last second')
        t_freeze = rec.freeze()
        bound = t_freeze + GENEROUS * FAILSAFE
        wait(lambda: rospy.get_time() > bound + GENEROUS * FAILSAFE, 600.0, 'a quiet window after the freeze')
        with rec.lock:
            last = max(rec.commands)
        rospy.loginfo('%s frozen at %.2f s: last command %.2f s later (nominal failsafe %.2f s)',
                      rospy.get_param('~relay', 'position_control/state_enu'), t_freeze, last - t_freeze, FAILSAFE)
        self.assertLessEqual(last, bound, 'the PCMD stream went on %.2f s after the freeze' % (last - t_freeze))

    def check_against_the_odom_run(self, rec):
        with rec.lock:
            waypoints, odom, hidden, truth = list(rec.waypoints), list(rec.odom), list(rec.hidden), list(rec.truth)
        marks = dict(begins=[(0.0, rec.begin)], ends=[(0.0, rec.end)])
        flight = evaluate_messages(waypoints, odom, truth, **marks)
        own_estimate = evaluate_messages(waypoints, hidden, **marks)
        e_mu = float(rec.summary['estimate']['e_mu'])
        self.assertAlmostEqual(flight.estimate.e_mu, e_mu, delta=0.01 * e_mu)   # the evaluator node's figure
        self.assertIsNotNone(flight.truth, 'no ground truth recorded')
        controller = rospy.get_param('~controller')
        out = tests_dir()
        run = lockstep_runs.run_sync(controller, out, paths.config_path('scenarios', 'circle_r2_v1.yaml'),
                                     rtf=rospy.get_param(NS + '/anafi_sim/rtf'), timeout=300.0,
                                     extra=['sync_timeout:=%g' % rospy.get_param(NS + '/anafi_sim/sync_timeout')])
        truth_tolerance = rospy.get_param('~truth_tolerance', TOLERANCE)
        try:
            reference = lockstep_runs.e_mu(run['summary'], 'estimate')
            reference_truth = lockstep_runs.e_mu(run['summary'], 'truth')
            self.assertIsNotNone(reference, 'no reference summary (%s)' % run['log'])
            self.assertIsNotNone(reference_truth, 'no ground truth in the reference summary (%s)' % run['log'])
            rospy.loginfo('%s e_mu through the bridge topics / on drone/odom: vs estimate %.4f / %.4f m (ratio %.3f), '
                          'vs truth %.4f / %.4f m (ratio %.3f); this flight on the simulator estimate %.4f m',
                          controller, e_mu, reference, e_mu / reference, flight.truth.e_mu, reference_truth,
                          flight.truth.e_mu / reference_truth, own_estimate.estimate.e_mu)
            self.assertLess(abs(e_mu / reference - 1.0), TOLERANCE,
                            'e_mu %.4f m through the bridge topics, %.4f m on drone/odom' % (e_mu, reference))
            self.assertLess(abs(flight.truth.e_mu / reference_truth - 1.0), truth_tolerance,
                            'e_mu vs truth %.4f m through the bridge topics, %.4f m on drone/odom'
                            % (flight.truth.e_mu, reference_truth))
            self.assertLess(abs(e_mu / own_estimate.estimate.e_mu - 1.0), TOLERANCE)
        except AssertionError:
            raise AssertionError('%s\n(reference run files in %s)' % (sys.exc_info()[1], out))
        shutil.rmtree(out, ignore_errors=True)


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'test_real_anafi', TestRealAnafi)
