#!/usr/bin/env python3
"""Foundation demo: step commands to the simulated Anafi, printing what the interface saw.

Stage: (demo) -> piloting command; reads the interface's ground truth and the
drone's estimate. Waits until the drone reports ``flying``, then streams the
``StepSchedule`` on drone/rpyt at ~rate Hz, prints ground truth and estimate
every ~print_period s, and a summary at the end, then shuts down.
Topics (relative to /<drone>/): drone/rpyt (out), ground_truth/odom,
drone/odom, drone/state (in).
"""
import math

import rospy
from nav_msgs.msg import Odometry
from std_msgs.msg import String

import anafi_sim  # noqa: F401 (before anafi_control: checks it is the control library, README)
from anafi_control.frames import quaternion_to_euler
from anafi_sim import names
from anafi_sim.ros.node import private_params, run_node
from anafi_sim.ros.wire_types import piloting_command_class
from anafi_sim.sim.step_schedule import StepSchedule


def _pose(msg):
    p = msg.pose.pose.position
    q = msg.pose.pose.orientation
    return (p.x, p.y, p.z), [math.degrees(a) for a in quaternion_to_euler(q.x, q.y, q.z, q.w)]


class StepDemo(object):
    def __init__(self):
        p = private_params()
        self.rate = p.positive('rate', 10.0)
        self.print_period = p.positive('print_period', 0.5)
        self.timeout = p.positive('start_timeout', 30.0)
        self.schedule = StepSchedule()
        self.cmd_cls = piloting_command_class()
        self.pub = rospy.Publisher(names.COMMAND, self.cmd_cls, queue_size=1)
        self.truth = self.estimate = None
        self.truth_count = self.estimate_count = 0
        self.state = ''
        self.max_error_estimate = 0.0
        rospy.Subscriber(names.GROUND_TRUTH, Odometry, self._on_truth, queue_size=10)
        rospy.Subscriber(names.ESTIMATE, Odometry, self._on_estimate, queue_size=10)
        rospy.Subscriber(names.DRONE_STATE, String, self._on_state, queue_size=1)

    def _on_truth(self, msg):
        self.truth = msg
        self.truth_count += 1

    def _on_estimate(self, msg):
        self.estimate = msg
        self.estimate_count += 1

    def _on_state(self, msg):
        if msg.data != self.state:
            rospy.loginfo('drone state: %s', msg.data)
        self.state = msg.data

    def run(self):
        ok = self.demo()
        rospy.signal_shutdown('demo finished')
        return ok

    def demo(self):
        t0 = rospy.get_time()
        rate = rospy.Rate(self.rate)
        while not rospy.is_shutdown() and not (self.state == 'flying' and self.truth is not None):
            if rospy.get_time() - t0 > self.timeout:
                rospy.logerr('no ground truth / drone not flying after %.0f s (state %r, %d truth msgs)',
                             self.timeout, self.state, self.truth_count)
                return False
            rate.sleep()
        start = rospy.get_time()
        counts0 = (self.truth_count, self.estimate_count)
        last_print = -1e9
        label = None
        print('\n  t[s]  command (roll pitch yawrate gaz)   ground truth x y z [m]   roll pitch yaw [deg]'
              '     estimate x y z [m]')
        while not rospy.is_shutdown():
            t = rospy.get_time() - start
            idx, seg = self.schedule.segment(t)
            if seg is None:
                break
            if seg.label != label:
                label = seg.label
                print('  --- %s' % label)
            cmd = self.cmd_cls()
            cmd.header.stamp = rospy.Time.now()
            cmd.roll, cmd.pitch, cmd.yaw, cmd.gaz = seg.roll, seg.pitch, seg.yaw_rate, seg.gaz
            self.pub.publish(cmd)
            if t - last_print >= self.print_period and self.truth is not None and self.estimate is not None:
                last_print = t
                (x, y, z), (r, p, yw) = _pose(self.truth)
                (ex, ey, ez), _ = _pose(self.estimate)
                self.max_error_estimate = max(self.max_error_estimate,
                                              math.sqrt((x - ex) ** 2 + (y - ey) ** 2 + (z - ez) ** 2))
                print('%6.1f  %5.1f %5.1f %5.1f %4.1f   %8.3f %8.3f %7.3f   %6.1f %6.1f %7.1f   %8.3f %8.3f %7.3f'
                      % (t, seg.roll, seg.pitch, seg.yaw_rate, seg.gaz, x, y, z, r, p, yw, ex, ey, ez))
            rate.sleep()
        elapsed = max(1e-6, rospy.get_time() - start)
        print('\nsummary: %.1f s, ground truth %.1f Hz (%d msgs), estimate %.1f Hz, '
              'max |truth - estimate| %.2f m (the estimate lags)' % (
                  elapsed, (self.truth_count - counts0[0]) / elapsed, self.truth_count - counts0[0],
                  (self.estimate_count - counts0[1]) / elapsed, self.max_error_estimate))
        return True


def main():
    run_node('step_demo', StepDemo)
