#!/usr/bin/env python3
"""Relative-state node of the paper's distributed PID framework (thin node).

Stage: controllers (input side). Every 1/~rate s of ROS time (~30 Hz) it
expresses the waypoint and the drone state in the drone's stability axes
(anafi_control.pid_framework.relative_state) and publishes the setpoint /
state of each pid loop (std_msgs/Float64, anafi_control.pid_wiring.LOOP_INPUTS)
under ~pid_namespace (default <drone>/pid): positions [m], velocities [m/s],
yaw [deg, world]. Inner-loop setpoints are the outer loops' control efforts
(wired in the launch file).

Inputs (relative to the node's namespace, i.e. /<drone>/):
~state_topic (nav_msgs/Odometry, default drone/odom = the drone's estimate;
ground_truth/odom selectable; pose in the world frame, twist in the child
frame), ~waypoint_topic (anafi_sim/Waypoint, default position_control/waypoint).

Safety (anafi_control.pid_wiring.InputGate): no waypoint yet, no state,
stale state (> ~state_timeout s), stale waypoint (> ~waypoint_timeout s;
0 = never), non-finite input -> nothing is published to the loops and
<pid_namespace>/pid_enable (latched std_msgs/Bool) goes false (the loops
stop, the command node hovers); a diagnostic on /diagnostics (1 Hz wall)
says why, with counters. Bad parameters: logfatal, exit code 1.
"""
import threading

import rospy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nav_msgs.msg import Odometry
from std_msgs.msg import Bool, Float64

from anafi_control.pid_framework import relative_state
from anafi_control.pid_wiring import NO_WAYPOINT, InputGate, gate_health, input_topics, loop_inputs
from anafi_sim.msg import Waypoint
from anafi_sim.ros.node import (diagnostic_status, namespace_id, private_params, run_node,
                                start_diagnostics_thread)


def odometry_numbers(msg):
    """(position, orientation (x, y, z, w), body linear velocity) of a nav_msgs/Odometry."""
    p, q, v = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear
    return (p.x, p.y, p.z), (q.x, q.y, q.z, q.w), (v.x, v.y, v.z)


class RelativeStateNode(object):
    def __init__(self):
        p = private_params()
        self.rate = p.positive('rate', 30.0)
        state_topic = p.ros_name('state_topic', 'drone/odom')
        waypoint_topic = p.ros_name('waypoint_topic', 'position_control/waypoint')
        pid_ns = p.ros_name('pid_namespace', 'pid')
        self.gate = InputGate(p.positive('state_timeout', 0.5),
                              p.number('waypoint_timeout', 1.0, minimum=0.0))     # 0 = never stale
        self.lock = threading.Lock()
        self.enabled = None
        self.published_cycles = 0
        self.pubs = {}
        for topic in input_topics():
            self.pubs[topic] = rospy.Publisher('%s/%s' % (pid_ns, topic), Float64, queue_size=10)
        self.pub_enable = rospy.Publisher(pid_ns + '/pid_enable', Bool, queue_size=1, latch=True)
        self.pub_diag = rospy.Publisher('/diagnostics', DiagnosticArray, queue_size=5)
        self._set_enabled(False)
        self.state_topic = rospy.resolve_name(state_topic)
        self.waypoint_topic = rospy.resolve_name(waypoint_topic)
        rospy.Subscriber(state_topic, Odometry, self._on_state, queue_size=5)
        rospy.Subscriber(waypoint_topic, Waypoint, self._on_waypoint, queue_size=5)
        rospy.loginfo('%s: state %s, waypoint %s -> %s/<loop>/{setpoint,state} at %g Hz',
                      rospy.get_name(), self.state_topic, self.waypoint_topic,
                      rospy.resolve_name(pid_ns), self.rate)

    def _on_state(self, msg):
        with self.lock:
            ok = self.gate.on_state(rospy.get_time(), *odometry_numbers(msg))
        if not ok:
            rospy.logwarn_throttle(5.0, '%s: non-finite state on %s refused (%d so far): hovering'
                                   % (rospy.get_name(), self.state_topic, self.gate.bad_states))

    def _on_waypoint(self, msg):
        with self.lock:
            ok = self.gate.on_waypoint(rospy.get_time(), (msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz, msg.yaw))
        if not ok:
            rospy.logwarn_throttle(5.0, '%s: non-finite waypoint on %s refused (%d so far): hovering'
                                   % (rospy.get_name(), self.waypoint_topic, self.gate.bad_waypoints))

    def _set_enabled(self, enabled):
        if enabled != self.enabled:
            self.enabled = enabled
            self.pub_enable.publish(Bool(enabled))

    def _on_timer(self, event):
        t = rospy.get_time()
        with self.lock:
            inputs, reason = self.gate.step(t)
        if inputs is None:
            self._set_enabled(False)
            if reason != NO_WAYPOINT:
                rospy.logwarn_throttle(5.0, '%s: %s: pid disabled, hovering' % (rospy.get_name(), reason))
            return
        rel = relative_state(*inputs)
        if rel is None:     # cannot happen after the gate's checks; never forward garbage
            self._set_enabled(False)
            return
        self._set_enabled(True)
        for topic, value in loop_inputs(rel):
            self.pubs[topic].publish(Float64(value))
        self.published_cycles += 1

    def _diagnostic_statuses(self):
        g = self.gate
        with self.lock:
            reason = g.last_reason
            values = [('cycles', g.cycles), ('hover cycles', g.hover_cycles),
                      ('published cycles', self.published_cycles),
                      ('refused states (non-finite)', g.bad_states),
                      ('refused waypoints (non-finite)', g.bad_waypoints),
                      ('clock jumps back', g.clock_jumps),
                      ('state topic', self.state_topic), ('waypoint topic', self.waypoint_topic)]
        warning, message = gate_health(reason)
        level = DiagnosticStatus.WARN if warning else DiagnosticStatus.OK
        return [diagnostic_status('pid_relative_state: %s' % rospy.get_name(), level, message, values, namespace_id())]

    def run(self):
        start_diagnostics_thread(1.0, self._diagnostic_statuses, self.pub_diag)
        rospy.Timer(rospy.Duration(1.0 / self.rate), self._on_timer)
        rospy.spin()


if __name__ == '__main__':
    run_node('pid_relative_state', RelativeStateNode)
