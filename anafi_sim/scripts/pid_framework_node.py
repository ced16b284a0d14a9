#!/usr/bin/env python3
"""The paper's PID framework in ONE process (thin node over anafi_control.pid_framework.PidFramework).

Stage: controllers -> piloting command. Same inputs and output as the
distributed framework (pid_relative_state.py + six pid_controller.py +
pid_command.py) and the same numbers per cycle, without the inter-node
messages: every 1/~rate s of ROS time (~30 Hz) one relative-state cycle
steps the six loops (outer before inner); every 1/~command_rate s (10 Hz)
the assembled olympe_bridge/PilotingCommand goes to ~command_topic
(default drone/rpyt). Inputs relative to /<drone>/: ~state_topic
(nav_msgs/Odometry, default drone/odom = the estimate; ground_truth/odom
selectable), ~waypoint_topic (anafi_sim/Waypoint, default
position_control/waypoint).

Loop parameters: ~<loop>/<pid param> (x_outer, x_inner, y_outer, y_inner,
vertical, yaw; pid package names), defaults = DEFAULT_CONFIG = pid.yaml.
Safety: no waypoint yet, no / stale (~state_timeout, ~waypoint_timeout;
0 = never) / non-finite input -> loops reset, hover command (zeros) and a
diagnostic (/diagnostics, 1 Hz wall). Bad parameters: logfatal, exit 1.
No dynamic_reconfigure here (use the distributed mode for live tuning).
"""
import threading

import rospy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nav_msgs.msg import Odometry

from anafi_control.pid_framework import HOVER, LOOP_NAMES, PidFramework
from anafi_control.pid_wiring import NO_WAYPOINT, InputGate, gate_health
from anafi_sim.msg import Waypoint
from anafi_sim.ros.node import (diagnostic_status, namespace_id, private_params, run_node,
                                start_diagnostics_thread)
from anafi_sim.ros.wire_types import piloting_command_class


class PidFrameworkNode(object):
    def __init__(self):
        p = private_params()
        self.rate = p.positive('rate', 30.0)
        self.command_rate = p.positive('command_rate', 10.0)
        overrides = {}
        for loop in LOOP_NAMES:
            params = rospy.get_param('~' + loop, {})
            if not isinstance(params, dict):
                raise ValueError('~%s must be a mapping of pid parameters, got %r' % (loop, params))
            overrides[loop] = params
        self.framework = PidFramework(overrides)        # ValueError on bad values
        self.gate = InputGate(p.positive('state_timeout', 0.5),
                              p.number('waypoint_timeout', 1.0, minimum=0.0))     # 0 = never stale
        state_topic = p.ros_name('state_topic', 'drone/odom')
        waypoint_topic = p.ros_name('waypoint_topic', 'position_control/waypoint')
        command_topic = p.ros_name('command_topic', 'drone/rpyt')
        self.lock = threading.Lock()
        self.reason = NO_WAYPOINT
        self.hovers = self.commands = 0
        self.cls = piloting_command_class()
        self.pub = rospy.Publisher(command_topic, self.cls, queue_size=10)
        self.pub_diag = rospy.Publisher('/diagnostics', DiagnosticArray, queue_size=5)
        self.state_topic = rospy.resolve_name(state_topic)
        self.waypoint_topic = rospy.resolve_name(waypoint_topic)
        rospy.Subscriber(state_topic, Odometry, self._on_state, queue_size=5)
        rospy.Subscriber(waypoint_topic, Waypoint, self._on_waypoint, queue_size=5)
        rospy.loginfo('%s: state %s, waypoint %s -> %s; cycle %g Hz, command %g Hz', rospy.get_name(),
                      self.state_topic, self.waypoint_topic, rospy.resolve_name(command_topic),
                      self.rate, self.command_rate)

    def _on_state(self, msg):
        p, q, v = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear
        with self.lock:
            ok = self.gate.on_state(rospy.get_time(), (p.x, p.y, p.z), (q.x, q.y, q.z, q.w), (v.x, v.y, v.z))
        if not ok:
            rospy.logwarn_throttle(5.0, '%s: non-finite state refused (%d so far): hovering'
                                   % (rospy.get_name(), self.gate.bad_states))

    def _on_waypoint(self, msg):
        with self.lock:
            ok = self.gate.on_waypoint(rospy.get_time(), (msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz, msg.yaw))
        if not ok:
            rospy.logwarn_throttle(5.0, '%s: non-finite waypoint refused (%d so far): hovering'
                                   % (rospy.get_name(), self.gate.bad_waypoints))

    def _on_cycle(self, event):
        t = rospy.get_time()
        with self.lock:
            inputs, reason = self.gate.step(t)
            if inputs is None:
                if self.reason is None:
                    self.framework.hover()
            elif not self.framework.update(t, *inputs):
                reason = 'input refused by the framework'
            self.reason = reason
        if reason is not None and reason != NO_WAYPOINT:
            rospy.logwarn_throttle(5.0, '%s: %s: hovering' % (rospy.get_name(), reason))

    def _on_command(self, event):
        stamp = rospy.Time.now()
        with self.lock:
            cmd = HOVER if self.reason is not None else self.framework.command()
            self.commands += 1
            if cmd == HOVER:
                self.hovers += 1
        msg = self.cls()
        msg.header.stamp = stamp
        msg.roll, msg.pitch, msg.yaw, msg.gaz = cmd
        self.pub.publish(msg)

    def _diagnostic_statuses(self):
        with self.lock:
            g, fw = self.gate, self.framework
            reason = self.reason
            values = [('cycles', g.cycles), ('hover cycles', g.hover_cycles),
                      ('commands sent', self.commands), ('hover commands', self.hovers),
                      ('refused states (non-finite)', g.bad_states),
                      ('refused waypoints (non-finite)', g.bad_waypoints),
                      ('framework refused inputs', fw.rejected_inputs)]
            values += [('%s effort' % loop, '%g' % fw.efforts[loop]) for loop in LOOP_NAMES]
        warning, message = gate_health(reason)
        level = DiagnosticStatus.WARN if warning else DiagnosticStatus.OK
        return [diagnostic_status('pid_framework: %s' % rospy.get_name(), level, message, values, namespace_id())]

    def run(self):
        start_diagnostics_thread(1.0, self._diagnostic_statuses, self.pub_diag)
        rospy.Timer(rospy.Duration(1.0 / self.rate), self._on_cycle)
        rospy.Timer(rospy.Duration(1.0 / self.command_rate), self._on_command)
        rospy.spin()


if __name__ == '__main__':
    run_node('pid_framework', PidFrameworkNode)
