#!/usr/bin/env python3
"""rostest: the PID framework (pid.launch) flies the simulated Anafi (sim.launch) in closed loop.

Under simulated time (/clock from the simulator, rtf > 1 to keep it short);
every duration below is simulated seconds. Parameters (~private):

* ~wp_yaw [deg]: yaw of the static waypoint (3, 2, 5) (paper Fig. 6: 0 or 180).
* ~settle [s], ~hold [s]: after ~settle s of tracking (counted from the controller's first
  non-hover command), every sample of the next ~hold s must be within ~tolerance [m] (0.3) of
  the waypoint. The
  assertion uses BOTH the ground truth (/<drone>/ground_truth/odom from the
  interface) and the drone's estimate (/<drone>/drone/odom, what the
  controller uses); both are reported. Yaw must end within ~yaw_tolerance deg.
* ~test_reconfigure (bool): also change x_outer's Kp through
  dynamic_reconfigure and observe the effect on its control effort and on the
  drone (Kp 0: the x loop stops pushing towards a waypoint 2 m ahead; Kp back
  to 0.875: the effort jumps and the drone goes there), without restarting.
"""
import math
import threading
import time
import unittest

import rospy
import rostest
from dynamic_reconfigure.client import Client
from nav_msgs.msg import Odometry
from std_msgs.msg import Float64, String

from anafi_sim.msg import Waypoint
from anafi_sim.ros.wire_types import piloting_command_class

WALL_TIMEOUT = 90.0   # s of wall time for any single wait


def yaw_of(q):
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


class Recorder(object):
    """Samples (t_sim, x, y, z, yaw_deg) of an Odometry topic."""

    def __init__(self, topic):
        self.lock = threading.Lock()
        self.samples = []
        rospy.Subscriber(topic, Odometry, self._cb, queue_size=50)

    def _cb(self, msg):
        p = msg.pose.pose.position
        # the sample's own (simulated) time: a delivery delay on a loaded machine does not shift it
        t = msg.header.stamp.to_sec() or rospy.get_time()
        with self.lock:
            self.samples.append((t, p.x, p.y, p.z, math.degrees(yaw_of(msg.pose.pose.orientation))))

    def last(self):
        with self.lock:
            return self.samples[-1] if self.samples else None

    def between(self, t0, t1):
        with self.lock:
            return [s for s in self.samples if t0 <= s[0] <= t1]


class PidClosedLoop(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.drone = rospy.get_param('~drone_name', 'anafi')
        cls.wp_yaw = float(rospy.get_param('~wp_yaw', 0.0))
        cls.settle = float(rospy.get_param('~settle', 25.0))
        cls.hold = float(rospy.get_param('~hold', 10.0))
        cls.tol = float(rospy.get_param('~tolerance', 0.3))
        cls.yaw_tol = float(rospy.get_param('~yaw_tolerance', 5.0))
        ns = '/%s/' % cls.drone
        cls.truth = Recorder(ns + 'ground_truth/odom')
        cls.estimate = Recorder(ns + 'drone/odom')
        cls.flight_state = None
        rospy.Subscriber(ns + 'drone/state', String, cls._on_state)
        cls.pub = rospy.Publisher(ns + 'position_control/waypoint', Waypoint, queue_size=5)
        cls.active_since = []           # simulated times of non-hover piloting commands
        rospy.Subscriber(ns + 'drone/rpyt', piloting_command_class(), cls._on_command, queue_size=20)
        cls.waypoint = None
        cls.wp_lock = threading.Lock()
        cls.stop = False
        threading.Thread(target=cls._publish_loop, daemon=True).start()

    @classmethod
    def tearDownClass(cls):
        cls.stop = True

    @classmethod
    def _on_command(cls, msg):
        if (msg.roll, msg.pitch, msg.yaw, msg.gaz) != (0.0, 0.0, 0.0, 0.0) and not cls.active_since:
            cls.active_since.append(rospy.get_time())

    @classmethod
    def _on_state(cls, msg):
        cls.flight_state = msg.data

    @classmethod
    def _publish_loop(cls):
        """The paper's waypoint stream: 10 Hz of simulated time."""
        next_t = 0.0
        while not cls.stop and not rospy.is_shutdown():
            t = rospy.get_time()
            with cls.wp_lock:
                wp = cls.waypoint
            if wp is not None and t >= next_t:
                msg = Waypoint()
                msg.header.stamp = rospy.Time.now()
                msg.header.frame_id = 'world'
                msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz, msg.yaw = wp
                cls.pub.publish(msg)
                next_t = t + 0.1
            time.sleep(0.005)

    def set_waypoint(self, wp):
        with self.wp_lock:
            type(self).waypoint = tuple(float(v) for v in wp)

    def wait_until(self, predicate, what, timeout=WALL_TIMEOUT):
        end = time.time() + timeout
        while time.time() < end and not rospy.is_shutdown():
            if predicate():
                return
            time.sleep(0.05)
        self.fail('timed out (%.0f s wall) waiting for %s' % (timeout, what))

    def wait_sim(self, seconds):
        t_end = rospy.get_time() + seconds
        self.wait_until(lambda: rospy.get_time() >= t_end, '%.1f s of simulated time' % seconds,
                        timeout=WALL_TIMEOUT + seconds)
        return t_end

    def wait_hover(self):
        self.wait_until(lambda: rospy.get_time() > 0.0, '/clock')
        self.wait_until(lambda: self.truth.last() is not None and self.estimate.last() is not None,
                        'ground truth and estimate')
        self.wait_until(lambda: self.flight_state == 'flying' and self.truth.last()[3] > 0.8,
                        'the drone to hover after take-off (state %r)' % self.flight_state)

    def test_static_waypoint(self):
        self.wait_hover()
        target = (3.0, 2.0, 5.0)
        self.set_waypoint(target + (0.0, 0.0, 0.0, self.wp_yaw))
        # the clock starts with the controller's first command (its nodes may start late on a busy machine)
        self.wait_until(lambda: self.active_since, 'a first non-hover piloting command')
        t0 = self.active_since[0]
        t_end = self.wait_sim(self.settle + self.hold - (rospy.get_time() - t0))
        report = []
        for name, rec in (('ground truth', self.truth), ('estimate', self.estimate)):
            self.wait_until(lambda: rec.last() is not None and rec.last()[0] >= t_end,
                            '%s samples up to %.1f s' % (name, t_end))
            window = rec.between(t0 + self.settle, t_end)
            self.assertGreater(len(window), 10 * self.hold, '%s: too few samples (%d)' % (name, len(window)))
            dist = [math.sqrt((s[1] - target[0]) ** 2 + (s[2] - target[1]) ** 2 + (s[3] - target[2]) ** 2)
                    for s in window]
            yaw_err = [abs((s[4] - self.wp_yaw + 180.0) % 360.0 - 180.0) for s in window]
            report.append('%s: max distance %.3f m, mean %.3f m, max yaw error %.2f deg over [%.0f, %.0f] s'
                          % (name, max(dist), sum(dist) / len(dist), max(yaw_err), self.settle,
                             self.settle + self.hold))
            self.assertLess(max(dist), self.tol, '%s left the %.2f m ball: %s' % (name, self.tol, report[-1]))
            self.assertLess(max(yaw_err), self.yaw_tol, '%s yaw: %s' % (name, report[-1]))
        rospy.loginfo('static waypoint yaw %g: %s', self.wp_yaw, '; '.join(report))
        print('static waypoint yaw %g deg: %s' % (self.wp_yaw, '; '.join(report)))


class PidClosedLoopAndReconfigure(PidClosedLoop):
    """The static waypoint first (test names sort), then the live Kp change."""

    def test_z_reconfigure_kp_takes_effect(self):
        self.wait_hover()
        loop = '/%s/pid/x_outer' % self.drone
        client = Client(loop, timeout=30.0)
        config = client.get_configuration(timeout=30.0)
        # seeded from ~Kp = 0.875 by the pid package's value/scale split
        self.assertAlmostEqual(config['Kp'] * config['Kp_scale'], 0.875, places=9)
        self.assertEqual(config['Kp_scale'], 1.0)
        efforts = []
        rospy.Subscriber(loop + '/control_effort', Float64,
                         lambda m: efforts.append((rospy.get_time(), m.data)), queue_size=50)

        # hold the current spot, heading 0 (stability x = world x)
        here = self.truth.last()
        self.set_waypoint((here[1], here[2], max(here[3], 3.0), 0.0, 0.0, 0.0, 0.0))
        self.wait_sim(8.0)
        start = self.truth.last()

        # Kp -> 0 (scale unchanged): a waypoint 2 m ahead produces (almost) no effort, the drone stays
        client.update_configuration({'Kp': 0.0})
        self.wait_sim(0.5)
        ahead = (start[1] + 2.0, start[2], start[3], 0.0, 0.0, 0.0, 0.0)
        self.set_waypoint(ahead)
        t1 = rospy.get_time()
        t2 = self.wait_sim(4.0)
        quiet = [e for t, e in efforts if t1 + 0.2 <= t <= t2]
        moved = [abs(s[1] - start[1]) for s in self.truth.between(t1, t2)]
        self.assertGreater(len(quiet), 20)
        self.assertLess(max(abs(e) for e in quiet), 0.05, 'x_outer effort with Kp = 0 (error 2 m)')
        self.assertLess(max(moved), 0.3, 'the drone moved in x although Kp = 0')

        # Kp back to 0.875: effort ~ 0.875 x 2 m at once, the drone reaches the waypoint
        client.update_configuration({'Kp': 0.875})
        t3 = rospy.get_time()
        t4 = self.wait_sim(1.0)
        strong = [e for t, e in efforts if t3 + 0.2 <= t <= t4]
        self.assertGreater(len(strong), 5)
        self.assertGreater(max(strong), 1.0, 'x_outer effort after Kp restored')
        self.wait_sim(12.0)
        last = self.truth.last()
        self.assertLess(abs(last[1] - ahead[0]), self.tol, 'drone x %.2f, waypoint x %.2f' % (last[1], ahead[0]))
        print('reconfigure: effort with Kp 0: max |%.4f|, drone moved %.3f m; with Kp 0.875: max %.2f; '
              'final x error %.3f m' % (max(abs(e) for e in quiet), max(moved), max(strong),
                                        abs(last[1] - ahead[0])))


if __name__ == '__main__':
    rospy.init_node('test_pid_closed_loop')
    case = PidClosedLoopAndReconfigure if rospy.get_param('~test_reconfigure', False) else PidClosedLoop
    rostest.rosrun('anafi_sim', 'test_pid_closed_loop', case)
