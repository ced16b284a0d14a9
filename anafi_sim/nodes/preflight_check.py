#!/usr/bin/env python3
"""Pre-flight check node: starts the scenario on a real drone only when it is safe to, and aborts on request.

Stage: bridge state + scenario -> 'start' (real_anafi.launch). Thin node over
anafi_sim.mission.preflight.PreflightCheck. Topics relative to the node's namespace (/<drone>/):

- in ~state_topic (drone/odom, nav_msgs/Odometry: bridge_state.py's), drone/state (std_msgs/String);
- out ~start_topic (trajectory_generator/command, std_msgs/String, latched): 'start' once the state is
  fresh (within ~state_timeout s; ~state_from: where it comes from, named while it is missing), drone/state is flying and the scenario's first waypoint (~scenario or
  ~scenario_file, as the generator) is within ~max_reach m of the drone. Until then the generator publishes
  no waypoint, so the controller sends no command; every ~log_period s (wall, 2.0) one line says what it
  waits for.
- in ~abort_topic (abort, std_msgs/Empty): ends the roslaunch that started it as Ctrl-C does (this node is
  required): the controller stops, the PCMD stream ends and the firmware hovers.

Bad parameters (a scenario that does not load): logfatal, exit 1.
"""
import time

import rospy
from nav_msgs.msg import Odometry
from std_msgs.msg import Empty, String

from anafi_sim import names
from anafi_sim.mission.preflight import DEFAULTS, PreflightCheck
from anafi_sim.mission.trajectory import load_scenario
from anafi_sim.ros.node import end_parent_launch, private_params, run_node, wait_for_clock


class PreflightCheckNode(object):
    def __init__(self):
        p = private_params()
        scenario_file = p.string('scenario_file', '')
        scenario = load_scenario(scenario_file or p.string('scenario', 'circle_r2_v1', allow_empty=False))
        first = scenario.waypoint(0.0)[:3]
        self.core = PreflightCheck(first, max_reach=p.positive('max_reach', DEFAULTS['max_reach']),
                                   state_timeout=p.positive('state_timeout', DEFAULTS['state_timeout']),
                                   state_from=p.string('state_from', ''))
        self.log_period = p.positive('log_period', 2.0)
        self.started = False
        self.aborted = False
        self.pub_start = rospy.Publisher(p.ros_name('start_topic', names.TRAJECTORY_COMMAND), String, queue_size=1,
                                         latch=True)
        state_topic = p.ros_name('state_topic', names.ESTIMATE)
        rospy.Subscriber(state_topic, Odometry, self._on_state, queue_size=5)
        rospy.Subscriber(names.DRONE_STATE, String, lambda msg: self.core.on_drone_state(msg.data), queue_size=5)
        rospy.Subscriber(p.ros_name('abort_topic', 'abort'), Empty, self._on_abort, queue_size=1)
        rospy.loginfo('%s: scenario %s, first waypoint (%.2f, %.2f, %.2f); state from %s', rospy.get_name(),
                      scenario.name, first[0], first[1], first[2], rospy.resolve_name(state_topic))

    def _on_state(self, msg):
        q = msg.pose.pose.position
        self.core.on_state(rospy.get_time(), (q.x, q.y, q.z))

    def _on_abort(self, _msg):
        self.aborted = True

    def run(self):
        wait_for_clock()
        last_log = 0.0
        while not rospy.is_shutdown() and not self.aborted:
            if not self.started:
                ready, waiting = self.core.check(rospy.get_time())
                if ready:
                    self.pub_start.publish(String('start'))
                    self.started = True
                    rospy.loginfo('%s: pre-flight check passed: scenario started (abort: rostopic pub -1 %s '
                                  'std_msgs/Empty, or Ctrl-C)', rospy.get_name(), rospy.resolve_name('abort'))
                elif time.monotonic() - last_log >= self.log_period:
                    rospy.loginfo('%s: waiting for %s', rospy.get_name(), '; '.join(waiting))
                    last_log = time.monotonic()
            time.sleep(0.05)
        if self.aborted:
            rospy.logwarn('%s: abort: ending the launch (the PCMD stream stops, the firmware hovers)',
                          rospy.get_name())
            if not end_parent_launch():
                rospy.signal_shutdown('abort')


def main():
    run_node('preflight_check', PreflightCheckNode)
