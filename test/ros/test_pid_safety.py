#!/usr/bin/env python3
"""rostest: the PID framework's ROS wiring, signs and safety behaviour, without the simulator.

The test plays the drone: it publishes a state (nav_msgs/Odometry on /<drone>/drone/odom, 30 Hz) and
waypoints (10 Hz) and reads the piloting commands (/<drone>/drone/rpyt) and /diagnostics. Run for
every namespace in ~drones (pid.launch once per mode: 'anafi' = distributed, 'single' = single
process), both drones at the same time. Wall clock. Checked per phase:

* no waypoint yet -> no command at all (the firmware's hover brake holds the drone), diagnostic says so;
* a target ahead, to the left, above and counter-clockwise -> pitch > 0, roll < 0, gaz > 0, yaw rate > 0;
* yaw target 179 deg with the drone at -179 deg -> a small negative yaw rate (the error wraps);
* a waypoint 1 km away -> the flight envelope moves the target into the geofence and within reach: commands
  keep flowing toward it, WARN 'limiting: ...geofence...';
* non-finite or stale waypoint -> the controller holds the position (commands keep
  flowing, finite) and a WARN diagnostic says 'holding position' and the cause; stale or non-finite
  state -> no command at all (the firmware brakes; an all-zero command would let the drone coast) and a
  WARN diagnostic naming the cause; good input again -> commands again (docs/reliability.md).
"""
import math
import threading
import time
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nav_msgs.msg import Odometry

from anafi_control.frames import euler_to_quaternion
from anafi_sim.msg import Waypoint
from anafi_sim.ros.wire_types import piloting_command_class

NAN = float('nan')


class FakeDrone(object):
    def __init__(self, drone):
        self.drone = drone
        ns = '/%s/' % drone
        self.lock = threading.Lock()
        self.state = (0.0, 0.0, 5.0, 0.0)        # x, y, z [m], yaw [deg]
        self.state_on = True
        self.waypoint = None
        self.commands = []                      # (wall time, roll, pitch, yaw, gaz)
        self.pub_state = rospy.Publisher(ns + 'drone/odom', Odometry, queue_size=5)
        self.pub_wp = rospy.Publisher(ns + 'position_control/waypoint', Waypoint, queue_size=5)
        rospy.Subscriber(ns + 'drone/rpyt', piloting_command_class(), self._on_cmd, queue_size=20)
        threading.Thread(target=self._loop, daemon=True).start()

    def _on_cmd(self, msg):
        with self.lock:
            self.commands.append((time.time(), msg.roll, msg.pitch, msg.yaw, msg.gaz))

    def _loop(self):
        k = 0
        while not rospy.is_shutdown():
            with self.lock:
                state, on, wp = self.state, self.state_on, self.waypoint
            if on:
                odom = Odometry()
                odom.header.stamp = rospy.Time.now()
                odom.header.frame_id = 'world'
                odom.child_frame_id = self.drone + '/base_link'
                p = odom.pose.pose.position
                p.x, p.y, p.z = state[:3]
                q = euler_to_quaternion(0.0, 0.0, math.radians(state[3]))
                o = odom.pose.pose.orientation
                o.x, o.y, o.z, o.w = q
                self.pub_state.publish(odom)
            if wp is not None and k % 3 == 0:
                msg = Waypoint()
                msg.header.stamp = rospy.Time.now()
                msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz, msg.yaw = wp
                self.pub_wp.publish(msg)
            k += 1
            time.sleep(1.0 / 30.0)

    def set(self, **kw):
        with self.lock:
            for key, value in kw.items():
                setattr(self, key, value)

    def commands_since(self, t0):
        with self.lock:
            return [c[1:] for c in self.commands if c[0] >= t0]


class Diagnostics(object):
    def __init__(self):
        self.lock = threading.Lock()
        self.items = []                      # (wall time, name, level, message)
        rospy.Subscriber('/diagnostics', DiagnosticArray, self._cb, queue_size=50)

    def _cb(self, msg):
        with self.lock:
            for s in msg.status:
                self.items.append((time.time(), s.name, s.level, s.message))

    def since(self, t0):
        with self.lock:
            return [i for i in self.items if i[0] >= t0]


class PidSafety(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.drones = rospy.get_param('~drones', ['anafi'])
        cls.diag = Diagnostics()
        cls.fake = dict((d, FakeDrone(d)) for d in cls.drones)

    def wait_commands(self, fake, seconds):
        t0 = time.time()
        time.sleep(seconds)
        return fake.commands_since(t0)

    def assert_diag(self, fake, cause, t0, diag_words, warn=True):
        msgs = [m for m in self.diag.since(t0 - 1.0) if diag_words in m[3] and
                (('/%s/' % fake.drone) in m[1])]
        self.assertTrue(msgs, '%s: %s: no diagnostic saying %r' % (fake.drone, cause, diag_words))
        if warn:
            self.assertTrue(any(m[2] == DiagnosticStatus.WARN for m in msgs), '%s: %s: not WARN' % (fake.drone, cause))

    def assert_silent(self, fake, cause, diag_words):
        """After a short transition no command at all (the firmware brakes); a diagnostic names the cause."""
        time.sleep(1.5)                           # timeouts (0.5 s state, 1.0 s waypoint) + 10 Hz period
        t0 = time.time()
        cmds = self.wait_commands(fake, 2.0)
        self.assertEqual(cmds, [], '%s: %s: commands while silent: %r' % (fake.drone, cause, cmds[:3]))
        self.assert_diag(fake, cause, t0, diag_words, warn=(diag_words != 'no waypoint'))

    def assert_hold(self, fake, cause, diag_words):
        """After a short transition commands keep flowing (the controller holds the position with its own
        loops), finite and within the limits; a WARN diagnostic says 'holding position' and the cause."""
        time.sleep(1.5)
        t0 = time.time()
        cmds = self.wait_commands(fake, 2.0)
        self.assertGreaterEqual(len(cmds), 12, '%s: %s: too few commands (%d)' % (fake.drone, cause, len(cmds)))
        for c in cmds:
            self.assertTrue(all(math.isfinite(v) for v in c) and abs(c[0]) <= 30.7 and abs(c[1]) <= 30.7, c)
        self.assert_diag(fake, cause, t0, 'holding position')
        self.assert_diag(fake, cause, t0, diag_words)

    def assert_flying(self, fake, cause, check=None, ready_timeout=0.0):
        """Non-zero commands during 1.5 s (after the first one shows up within ready_timeout s, if > 0)."""
        end = time.time() + ready_timeout
        t0 = time.time()
        while time.time() < end and not [c for c in fake.commands_since(t0) if c != (0.0, 0.0, 0.0, 0.0)]:
            time.sleep(0.1)
        cmds = self.wait_commands(fake, 1.5)
        moving = [c for c in cmds if c != (0.0, 0.0, 0.0, 0.0)]
        self.assertGreaterEqual(len(moving), 5, '%s: %s: no commands (%r)' % (fake.drone, cause, cmds[-3:]))
        if check is not None:
            check(moving[-1])
        return moving[-1]

    def run_drone(self, fake):
        # no waypoint yet (wait for the nodes: their diagnostics show up; a loaded machine starts them slowly)
        end = time.time() + 40.0
        while time.time() < end and not [m for m in self.diag.since(0.0) if ('/%s/' % fake.drone) in m[1]
                                         and 'no waypoint' in m[3]]:
            time.sleep(0.2)
        self.assert_silent(fake, 'no waypoint', 'no waypoint')

        # ahead (+x), left (+y), above, counter-clockwise (+30 deg): heading 0
        fake.set(waypoint=(4.0, 3.0, 6.0, 0.0, 0.0, 0.0, 30.0))
        # (the first time: the loop nodes may still be starting on a loaded machine)
        roll, pitch, yaw, gaz = self.assert_flying(fake, 'target ahead/left/above/ccw', ready_timeout=40.0)
        self.assertGreater(pitch, 0.0)
        self.assertLess(roll, 0.0)
        self.assertGreater(yaw, 0.0)
        self.assertGreater(gaz, 0.0)

        # heading 90 deg (facing +y): a target at world +y is ahead, one at world +x is to the right
        fake.set(state=(0.0, 0.0, 5.0, 90.0), waypoint=(3.0, 0.0, 5.0, 0.0, 0.0, 0.0, 90.0))
        time.sleep(0.5)
        roll, pitch, yaw, gaz = self.assert_flying(fake, 'target to the right at heading 90')
        self.assertGreater(roll, 0.0)
        self.assertAlmostEqual(pitch, 0.0, delta=1e-3)

        # yaw wrap: drone at -179 deg, target 179 deg -> turn clockwise by 2 deg, not 358 ccw
        fake.set(state=(0.0, 0.0, 5.0, -179.0), waypoint=(0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 179.0))
        time.sleep(0.5)
        _, _, yaw, _ = self.assert_flying(fake, 'yaw wrap')
        self.assertLess(yaw, 0.0)
        self.assertGreater(yaw, -10.0)

        good_wp = (4.0, 3.0, 6.0, 0.0, 0.0, 0.0, 30.0)
        fake.set(state=(0.0, 0.0, 5.0, 0.0), waypoint=good_wp)
        self.assert_flying(fake, 'back to a good waypoint')

        fake.set(waypoint=(4.0, 3.0, 6.0, 0.0, 0.0, 0.0, NAN))
        self.assert_hold(fake, 'non-finite waypoint', 'non-finite waypoint')
        fake.set(waypoint=good_wp)
        self.assert_flying(fake, 'recovered from a non-finite waypoint')

        fake.set(waypoint=None)                   # stop publishing: stale after 1 s
        self.assert_hold(fake, 'stale waypoint', 'stale waypoint')
        fake.set(waypoint=good_wp)
        self.assert_flying(fake, 'recovered from a stale waypoint')

        fake.set(waypoint=(1000.0, 0.0, 5.0, 0.0, 0.0, 0.0, 0.0))     # far outside the geofence (250 m)
        t0 = time.time()
        self.assert_flying(fake, 'waypoint 1 km away: the target limited by the flight envelope',
                           lambda c: self.assertGreater(c[1], 0.0))     # toward +x, within the fence
        self.assert_diag(fake, 'waypoint 1 km away', t0, 'limiting: ')
        self.assert_diag(fake, 'waypoint 1 km away', t0, 'geofence')
        fake.set(waypoint=good_wp)
        self.assert_flying(fake, 'recovered from a waypoint outside the geofence')

        fake.set(state_on=False)
        self.assert_silent(fake, 'stale state', 'stale state')
        fake.set(state_on=True)
        self.assert_flying(fake, 'recovered from a stale state')

        fake.set(state=(0.0, NAN, 5.0, 0.0))
        self.assert_silent(fake, 'non-finite state', 'non-finite state')
        fake.set(state=(0.0, 0.0, 5.0, 0.0))
        self.assert_flying(fake, 'recovered from a non-finite state')

    def test_wiring_signs_and_safety(self):
        errors = {}

        def run(drone):
            try:
                self.run_drone(self.fake[drone])
            except Exception as error:       # re-raised in the test's thread below
                errors[drone] = error

        threads = [threading.Thread(target=run, args=(d,)) for d in self.drones]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        for drone in self.drones:
            if drone in errors:
                raise errors[drone]


if __name__ == '__main__':
    rospy.init_node('test_pid_safety')
    rostest.rosrun('anafi_sim', 'test_pid_safety', PidSafety)
