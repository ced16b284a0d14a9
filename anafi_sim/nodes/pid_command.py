#!/usr/bin/env python3
"""Command node of the paper's distributed PID framework (thin node).

Stage: controllers -> piloting command. Collects the control efforts of the
four command loops (anafi_control.pid_wiring.COMMAND_LOOPS: roll <- y_inner
[deg], pitch <- x_inner [deg], yaw rate <- yaw [deg/s], gaz <- vertical
[m/s]; std_msgs/Float64 on <~pid_namespace>/<loop>/control_effort) and
publishes one olympe_bridge/PilotingCommand (wire-identical, see
anafi_sim.ros.wire_types) on ~command_topic (default drone/rpyt, relative to
/<drone>/) every 1/~rate s of ROS time (10 Hz).

Safety (anafi_control.pid_wiring.CommandAssembler, docs/reliability.md): pid
disabled (<pid_namespace>/pid_enable false), an effort missing, older than
~effort_timeout s or non-finite -> no command is published (the firmware's
hover brake stops and holds the drone; an all-zero command would only level
it and let it coast), counted and reported on /diagnostics (1 Hz wall). Commands of another node on
~command_topic (a second commander, anafi_control.commanders): ERROR naming it and no command until it
is gone. Bad parameters: logfatal, then the node stays up in ERROR (not respawned: docs/nodes.md).
"""
import threading

import rospy
from diagnostic_msgs.msg import DiagnosticStatus
from std_msgs.msg import Bool, Float64

import anafi_sim  # noqa: F401 (before anafi_control: checks it is the control library, README)
from anafi_control.pid_wiring import COMMAND_LOOPS, CommandAssembler
from anafi_sim import names
from anafi_control.commanders import DOWN, LISTEN
from anafi_sim.ros.commander_watch import CommandTopicWatch
from anafi_sim.ros.node import (Timer, diagnostic_status, diagnostics_publisher, namespace_id, private_params,
                                run_node, start_diagnostics_thread)
from anafi_sim.ros.wire_types import piloting_command_class


class PidCommandNode(object):
    def __init__(self):
        p = private_params()
        self.rate = p.positive('rate', 10.0)
        self.assembler = CommandAssembler(p.positive('effort_timeout', 0.5))
        pid_ns = p.ros_name('pid_namespace', names.PID_NAMESPACE)
        command_topic = p.ros_name('command_topic', names.COMMAND)
        self.frame_id = p.string('frame_id', '')
        self.lock = threading.Lock()
        self.last_hovers = 0       # hover commands at the previous diagnostic
        self.cls = piloting_command_class()
        self.pub = rospy.Publisher(command_topic, self.cls, queue_size=10)
        self.commanders = CommandTopicWatch(command_topic, self.cls)   # one drone, one commander
        self.pub_diag = diagnostics_publisher()
        for field, loop in COMMAND_LOOPS.items():
            rospy.Subscriber('%s/%s/control_effort' % (pid_ns, loop), Float64,
                             self._on_effort, callback_args=field, queue_size=10)
        rospy.Subscriber(names.pid_topic(names.PID_ENABLE, pid_ns), Bool, self._on_enable, queue_size=5)
        self.command_topic = rospy.resolve_name(command_topic)
        rospy.loginfo('%s: efforts from %s/<loop>/control_effort -> %s at %g Hz', rospy.get_name(),
                      rospy.resolve_name(pid_ns), self.command_topic, self.rate)

    def _on_effort(self, msg, field):
        with self.lock:
            ok = self.assembler.on_effort(field, rospy.get_time(), msg.data)
        if not ok:
            rospy.logwarn_throttle(5.0, '%s: non-finite %s effort refused (%d so far): hovering'
                                   % (rospy.get_name(), field, self.assembler.bad_efforts))

    def _on_enable(self, msg):
        with self.lock:
            self.assembler.on_enable(msg.data)

    def _on_timer(self, event):
        if self.commanders.check() in (DOWN, LISTEN):   # another node commands this drone, or listening first
            return
        stamp = rospy.Time.now()
        with self.lock:
            cmd, reason = self.assembler.command(stamp.to_sec())
        if reason is not None:
            if not reason.startswith('pid disabled'):
                rospy.logwarn_throttle(10.0, '%s: no command (firmware hover brake): %s' % (rospy.get_name(), reason))
            return
        msg = self.cls()
        msg.header.stamp = stamp
        msg.header.frame_id = self.frame_id
        msg.roll, msg.pitch, msg.yaw, msg.gaz = cmd
        self.pub.publish(msg)

    def _diagnostic_statuses(self):
        a = self.assembler
        with self.lock:
            reason, hovers, commands, bad = a.last_reason, a.hovers, a.commands, a.bad_efforts
            last = dict((f, a.values[f]) for f in COMMAND_LOOPS)
        if reason is None:
            level, message = DiagnosticStatus.OK, 'commanding'
        else:
            level = DiagnosticStatus.OK if reason.startswith('pid disabled') else DiagnosticStatus.WARN
            message = 'no command, firmware hover brake: %s' % reason
        values = [('command periods', commands), ('periods without a command', hovers),
                  ('periods without a command last second', hovers - self.last_hovers),
                  ('refused efforts (non-finite)', bad), ('command topic', self.command_topic),
                  ('ROS time jumps back (timer kept running)', self.timer.jumps_back)]
        values += [('%s effort' % f, 'none' if v is None else ('bad' if v is False else '%g' % v))
                   for f, v in last.items()]
        self.commanders.check_presence()
        values += self.commanders.values()
        second = self.commanders.message()
        if second is not None:
            level, message = DiagnosticStatus.ERROR, second
        self.last_hovers = hovers
        return [diagnostic_status('pid_command: %s' % rospy.get_name(), level, message, values, namespace_id())]

    def run(self):
        self.timer = Timer(1.0 / self.rate, self._on_timer, 'command')     # survives /clock going back
        start_diagnostics_thread(1.0, self._diagnostic_statuses, self.pub_diag)
        rospy.spin()


def main():
    run_node('pid_command', PidCommandNode, respawned=True)
