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
frame), ~waypoint_topic (default position_control/waypoint; ~waypoint_type
anafi_sim = anafi_sim/Waypoint, the default, or anafi_control = the reference
implementation's anafi_control/Waypoint).

Safety (the controllers' input gate and failsafes, anafi_control.contract,
docs/reliability.md): the flight envelope (anafi_control.envelope, pid.yaml:
~geofence_radius around the first state, ~min_altitude..~max_altitude, reach
~max_waypoint_jump, reference speeds) limits the target the loops get (WARN
'limiting'); a non-finite or stale (> ~waypoint_timeout s; 0 = never)
waypoint -> HOLD: the
loops get the hold point (the drone's position and heading when the hold
began, zero velocity) instead of the waypoint, so the PID graph brakes and
holds there; no waypoint yet, no / non-finite / stale state (> ~state_timeout
s), clock jumped back -> SILENT: nothing is published to the loops and
<pid_namespace>/pid_enable (latched std_msgs/Bool) goes false (the loops stop,
the command node publishes nothing, the firmware's hover brake stops the
drone). A diagnostic on /diagnostics (1 Hz wall) says why, with counters. Bad
parameters: logfatal, exit code 1.
"""
import threading

import rospy
from std_msgs.msg import Bool, Float64

import anafi_sim  # noqa: F401 (before anafi_control: checks it is the control library, README)
from anafi_control.contract import MESSAGES, NO_STATE, NO_WAYPOINT, TRACKING, InputGate, health
from anafi_control.pid_framework import DEFAULTS, relative_state
from anafi_control.pid_wiring import input_topics, loop_inputs
from anafi_sim import names
from anafi_sim.ros.conversions import amend_health, subscribe_inputs, waypoint_admission, waypoint_limits
from anafi_sim.ros.waypoints import DEFAULT_WAYPOINT_TYPE, WAYPOINT_TYPES
from anafi_sim.ros.node import (Timer, diagnostics_publisher, health_status, namespace_id, private_params, run_node,
                                start_diagnostics_thread)


class RelativeStateNode(object):
    def __init__(self):
        p = private_params()
        self.rate = p.positive('rate', DEFAULTS['rate'])
        state_topic = p.ros_name('state_topic', names.ESTIMATE)
        waypoint_topic = p.ros_name('waypoint_topic', names.WAYPOINT)
        waypoint_type = p.choice('waypoint_type', DEFAULT_WAYPOINT_TYPE, WAYPOINT_TYPES)
        pid_ns = p.ros_name('pid_namespace', names.PID_NAMESPACE)
        self.gate = InputGate(p.positive('state_timeout', DEFAULTS['state_timeout']),
                              p.number('waypoint_timeout', DEFAULTS['waypoint_timeout'], minimum=0.0),  # 0: never
                              limits=waypoint_limits(p))
        self.lock = threading.Lock()
        self.enabled = None
        self.published_cycles = 0
        self.key, self.reason = NO_STATE, MESSAGES[NO_STATE]     # of the last cycle
        self.pubs = {}
        for topic in input_topics():
            self.pubs[topic] = rospy.Publisher('%s/%s' % (pid_ns, topic), Float64, queue_size=10)
        self.pub_enable = rospy.Publisher(names.pid_topic(names.PID_ENABLE, pid_ns), Bool, queue_size=1, latch=True)
        self.pub_diag = diagnostics_publisher()
        self._set_enabled(False)
        self.admission = waypoint_admission(p)
        self.state_topic, self.waypoint_topic = subscribe_inputs(self.gate, self.lock, state_topic, waypoint_topic,
                                                                  waypoint_type, self.admission)
        rospy.loginfo('%s: state %s, waypoint %s -> %s/<loop>/{setpoint,state} at %g Hz',
                      rospy.get_name(), self.state_topic, self.waypoint_topic,
                      rospy.resolve_name(pid_ns), self.rate)

    def _set_enabled(self, enabled):
        if enabled != self.enabled:
            self.enabled = enabled
            self.pub_enable.publish(Bool(enabled))

    def _on_timer(self, event):
        t = rospy.get_time()
        with self.lock:
            inputs, key, reason = self.gate.check(t)
            rel = None if inputs is None else relative_state(inputs.pos, inputs.vel, inputs.yaw, inputs.waypoint)
            self.gate.count_cycle(key)
            self.key, self.reason = key, reason
        if rel is None:     # SILENT (relative_state refuses nothing after the gate's checks)
            self._set_enabled(False)
            if key != NO_WAYPOINT:
                rospy.logwarn_throttle(5.0, '%s: %s: pid disabled, no command (firmware hover brake)'
                                       % (rospy.get_name(), reason))
            return
        if key not in TRACKING:       # HOLD: rel is relative to the hold point
            rospy.logwarn_throttle(5.0, '%s: %s: holding position' % (rospy.get_name(), reason))
        self._set_enabled(True)
        for topic, value in loop_inputs(rel):
            self.pubs[topic].publish(Float64(value))
        self.published_cycles += 1

    def _diagnostic_statuses(self):
        with self.lock:
            h = amend_health(health(self.key, self.reason, list(self.gate.counters.items())), self.admission)
            extra = [('published cycles', self.published_cycles),
                     ('state topic', self.state_topic), ('waypoint topic', self.waypoint_topic),
                     ('ROS time jumps back (timer kept running)', self.timer.jumps_back)]
        return [health_status('pid_relative_state: %s' % rospy.get_name(), h, namespace_id(), extra)]

    def run(self):
        self.timer = Timer(1.0 / self.rate, self._on_timer, 'relative state')     # survives /clock going back
        start_diagnostics_thread(1.0, self._diagnostic_statuses, self.pub_diag)
        rospy.spin()


def main():
    run_node('pid_relative_state', RelativeStateNode, respawned=True)
