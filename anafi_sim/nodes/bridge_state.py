#!/usr/bin/env python3
"""Bridge state node: what a real anafi_ros bridge publishes -> drone/odom, the controllers' state input.

Stage: bridge topics -> state (-> MPC / PID controllers, evaluator). Thin node over
anafi_sim.interface.bridge_state.BridgeStateAssembler. No anafi_ros bridge publishes drone/odom; with this
node the controllers run unchanged on a real drone, and on our simulated bridge through the same topics.

- in, ~source state_enu (default; the paper authors' bridge fork): ~state_enu_topic
  (position_control/state_enu, anafi_control/State);
- in, ~source pose_speed: ~pose_topic (drone/pose_enu, geometry_msgs/PoseStamped; for the upstream bridge,
  which has no local position, an external pose source such as motion capture, e.g. /vrpn_client_node/anafi/pose,
  with ~world_yaw [rad] the heading of its x axis from east) and ~speed_topic (drone/speed,
  geometry_msgs/Vector3Stamped, north-west-up as the bridge publishes it), paired by header stamp within
  ~max_skew s;
- out ~odom_topic (drone/odom, nav_msgs/Odometry): header.stamp = the pose's stamp, frame_id ~frame_id
  (world), child_frame_id ~child_frame_id (<drone>/base_link), twist in the child frame (angular 0), as the
  simulator publishes its estimate; /diagnostics at 1 Hz (wall): states published, refused (bad, repeated,
  stale, skew), and WARN naming the parts not heard for ~stale_after s.

A message stamped more than ~stale_after s before it arrives, or not after its topic's last stamp, is
refused and counted: when a part freezes, drone/odom stops, the controller goes silent after its
state_timeout and the firmware hovers. Stamps and this node's clock must be the same clock (an external
pose source on another host: synchronise the clocks). Bad parameters: logfatal, exit 1.
"""
import threading

import rospy
from geometry_msgs.msg import PoseStamped, Vector3Stamped
from nav_msgs.msg import Odometry

from anafi_sim import names
from anafi_sim.interface.bridge_state import DEFAULTS, SOURCES, BridgeStateAssembler
from anafi_sim.ros import conversions
from anafi_sim.ros.node import (OK, WARN, diagnostic_status, diagnostics_publisher, namespace_id, private_params,
                                run_node, start_diagnostics_thread)
from anafi_sim.ros.wire_types import paper_state_class


class BridgeStateNode(object):
    def __init__(self):
        p = private_params()
        self.core = BridgeStateAssembler(source=p.choice('source', DEFAULTS['source'], SOURCES),
                                         max_skew=p.positive('max_skew', DEFAULTS['max_skew']),
                                         stale_after=p.positive('stale_after', DEFAULTS['stale_after']),
                                         world_yaw=p.number('world_yaw', DEFAULTS['world_yaw']))
        self.drone = namespace_id()
        self.frame_id = p.string('frame_id', 'world', allow_empty=False)
        self.child_frame_id = p.string('child_frame_id', '%s/base_link' % self.drone, allow_empty=False)
        self.lock = threading.Lock()
        self.refused = 0
        self.pub = rospy.Publisher(p.ros_name('odom_topic', names.ESTIMATE), Odometry, queue_size=10)
        self.pub_diag = diagnostics_publisher(queue_size=5)
        if self.core.source == 'state_enu':
            topics = [p.ros_name('state_enu_topic', names.STATE_ENU)]
            rospy.Subscriber(topics[0], paper_state_class(), self._on_state_enu, queue_size=10)
        else:
            topics = [p.ros_name('pose_topic', names.POSE_ENU), p.ros_name('speed_topic', names.SPEED)]
            rospy.Subscriber(topics[0], PoseStamped, self._on_pose, queue_size=10)
            rospy.Subscriber(topics[1], Vector3Stamped, self._on_speed, queue_size=10)
        self.topics = [rospy.resolve_name(t) for t in topics]
        rospy.loginfo('%s: state from %s (%s) -> %s', rospy.get_name(), ' + '.join(self.topics), self.core.source,
                      rospy.resolve_name(self.pub.name))

    # -- inputs ---------------------------------------------------------------------------------
    def _on_state_enu(self, msg):
        p, q, v = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear.vector
        with self.lock:
            states = self.core.on_state_enu(msg.header.stamp.to_sec(), (p.x, p.y, p.z), (q.x, q.y, q.z, q.w),
                                            (v.x, v.y, v.z), rospy.get_time())
        self._publish(states)

    def _on_pose(self, msg):
        p, q = msg.pose.position, msg.pose.orientation
        with self.lock:
            states = self.core.on_pose(msg.header.stamp.to_sec(), (p.x, p.y, p.z), (q.x, q.y, q.z, q.w),
                                       rospy.get_time())
        self._publish(states)

    def _on_speed(self, msg):
        v = msg.vector
        with self.lock:
            states = self.core.on_speed(msg.header.stamp.to_sec(), (v.x, v.y, v.z), rospy.get_time())
        self._publish(states)

    def _publish(self, states):
        refused = self.core.counters['refused']
        if refused != self.refused:
            self.refused = refused
            rospy.logwarn_throttle(5.0, '%s: refused %d messages so far (%s)' % (
                rospy.get_name(), refused, ', '.join('%s %d' % (k, v) for k, v in self.core.counters.items()
                                                     if k not in ('states', 'refused') and v)))
        for s in states:
            msg = Odometry()
            msg.header.stamp = rospy.Time.from_sec(s.stamp)
            msg.header.frame_id = self.frame_id
            msg.child_frame_id = self.child_frame_id
            msg.pose.pose = conversions.pose(s.position, s.orientation)
            msg.twist.twist = conversions.twist(s.body_velocity, (0.0, 0.0, 0.0))
            self.pub.publish(msg)

    # -- diagnostics ----------------------------------------------------------------------------
    def diagnostic_statuses(self):
        with self.lock:
            fresh, stale = self.core.health(rospy.get_time())
            counters = list(self.core.counters.items())
        return [diagnostic_status('%s: state from the bridge' % rospy.get_name(), OK if fresh else WARN,
                                  'fresh' if fresh else 'stale: ' + '; '.join(stale),
                                  [('source', self.core.source), ('topics', ' + '.join(self.topics))] + counters,
                                  hardware_id=self.drone)]

    def run(self):
        start_diagnostics_thread(1.0, self.diagnostic_statuses, self.pub_diag, first=0.0)
        rospy.spin()


def main():
    run_node('bridge_state', BridgeStateNode)
