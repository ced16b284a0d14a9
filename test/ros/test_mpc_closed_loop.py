#!/usr/bin/env python3
"""rostest: the MPC (mpc.launch) flies the simulated Anafi to the paper's static waypoints (3, 2, 5) with yaw 0
and 180 deg (Fig. 6), with less overshoot than the PID framework (pid.launch) flown in the same run from the
same hover start, and with overshoots like Sphinx's in the shared logs (yaw 0: within +-35 %; yaw 180: less than
twice); a dynamic_reconfigure change of an MPC weight changes the flight live; ``rosrun anafi_sim echo.py``
decodes the MPC's drone/rpyt without olympe_bridge.

The simulator (sim.launch, sim time) is started by mpc_closed_loop.test; this script starts and stops the
controller launch files itself (one at a time, as its own subprocesses) and publishes the waypoint at 10 Hz.
Overshoot is measured on ground truth (ground_truth/odom): per axis, the largest excursion beyond the
waypoint coordinate in the direction that axis was approached from; the compared figure is the norm of the
three. (The projection of the excursion on the 3-D approach direction is printed too, but not compared: a
lateral overshoot that happens while the drone is still below the waypoint projects to a negative number.)
"""
import math
import os
import subprocess
import sys
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
from dynamic_reconfigure.client import Client
from nav_msgs.msg import Odometry

from anafi_control.frames import wrap_angle, yaw_from_quaternion
from anafi_sim import paths, processes
from anafi_sim.mission.reference_log import read_log
from anafi_sim.msg import MpcStats, Waypoint
from anafi_sim.ros.wire_types import piloting_command_class

NS = '/anafi'
START = (0.0, 0.0, 1.0)
GOAL = (3.0, 2.0, 5.0)
RUN_TIME = 15.0          # s (sim) per static-waypoint run
REACH_TOL = 0.3          # m, final distance to the waypoint
YAW_TOL = 5.0            # deg, final yaw error (the PCMD 1 % dead band alone leaves ~1.8 deg / Kp)


def overshoot(track, start, goal):
    """(per-axis overshoot [m] (3,), norm, projection on the approach direction) of positions (n, 3)."""
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    sign = np.sign(goal - start)
    per_axis = np.array([max(0.0, float(np.max(sign[i] * (track[:, i] - goal[i])))) if sign[i] else 0.0
                         for i in range(3)])
    d = (goal - start) / np.linalg.norm(goal - start)
    projection = max(0.0, float(np.max((track - goal).dot(d))))
    return per_axis, float(np.linalg.norm(per_axis)), projection


def sphinx_overshoot(path):
    """``overshoot`` norm of Sphinx's ground truth in a shared static-waypoint log, from the sample where the
    waypoint steps (> 0.5 m) to the end of the log."""
    log = read_log(path)
    wp = log.waypoint()
    step = int(np.argmax(np.linalg.norm(wp[:, :3] - wp[0, :3], axis=1) > 0.5))
    truth = log.position('sphinx')
    return overshoot(truth[step:], truth[step], wp[step, :3])[1]


class Controller(object):
    """One controller launch file run as a subprocess of this test (own process group, stopped by id)."""

    def __init__(self, launch, args=()):
        cmd = ['roslaunch', 'anafi_sim', launch, 'drone_name:=anafi', 'output:=log'] + list(args)
        self.proc = processes.start(cmd)

    def stop(self):
        processes.stop(self.proc, grace=15.0)


class TestMpcClosedLoop(unittest.TestCase):
    results = {}

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_mpc_closed_loop')
        cls.lock = threading.Lock()
        cls.track = []          # (t, x, y, z, yaw_deg, speed)
        cls.commands = []       # (t, roll, pitch, yaw, gaz)
        cls.stats = []
        cls.wp = (START[0], START[1], START[2], 0.0, 0.0, 0.0, 0.0)
        rospy.Subscriber(NS + '/ground_truth/odom', Odometry, cls._on_odom, queue_size=200)
        rospy.Subscriber(NS + '/drone/rpyt', piloting_command_class(), cls._on_cmd, queue_size=50)
        rospy.Subscriber(NS + '/mpc/stats', MpcStats, cls._on_stats, queue_size=50)
        cls.pub = rospy.Publisher(NS + '/position_control/waypoint', Waypoint, queue_size=5)
        cls.stop_pub = threading.Event()
        cls.wp_thread = threading.Thread(target=cls._publish_waypoints)
        cls.wp_thread.daemon = True
        cls.wp_thread.start()
        deadline = time.time() + 30.0
        while not cls.track and time.time() < deadline:
            time.sleep(0.1)
        cls.controller = None

    @classmethod
    def tearDownClass(cls):
        cls.stop_pub.set()
        if cls.controller is not None:
            cls.controller.stop()
        for name in sorted(cls.results):
            print('[mpc_closed_loop] %s: %s' % (name, cls.results[name]))
        sys.stdout.flush()

    # -- ROS plumbing -------------------------------------------------------------------------
    @classmethod
    def _on_odom(cls, m):
        p, q, v = m.pose.pose.position, m.pose.pose.orientation, m.twist.twist.linear
        row = (m.header.stamp.to_sec(), p.x, p.y, p.z, math.degrees(yaw_from_quaternion(q.x, q.y, q.z, q.w)),
               math.sqrt(v.x * v.x + v.y * v.y + v.z * v.z))
        with cls.lock:
            cls.track.append(row)

    @classmethod
    def _on_cmd(cls, m):
        with cls.lock:
            cls.commands.append((rospy.get_time(), m.roll, m.pitch, m.yaw, m.gaz))

    @classmethod
    def _on_stats(cls, m):
        with cls.lock:
            cls.stats.append((rospy.get_time(), m.ok, m.status))

    @classmethod
    def _publish_waypoints(cls):
        while not cls.stop_pub.is_set() and not rospy.is_shutdown():
            msg = Waypoint()
            msg.header.stamp = rospy.Time.now()
            msg.header.frame_id = 'world'
            msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz, msg.yaw = cls.wp
            try:
                cls.pub.publish(msg)
                rospy.sleep(0.1)
            except (rospy.ROSException, rospy.ROSInterruptException):
                break

    # -- helpers ------------------------------------------------------------------------------
    def set_waypoint(self, pos, yaw_deg):
        type(self).wp = (pos[0], pos[1], pos[2], 0.0, 0.0, 0.0, float(yaw_deg))

    def sim_sleep(self, seconds):
        """Sleep ``seconds`` of sim time (fails if the simulation stops)."""
        t_end = rospy.get_time() + seconds
        wall_limit = time.time() + 10.0 * seconds + 20.0
        while rospy.get_time() < t_end:
            self.assertLess(time.time(), wall_limit, 'simulation time does not advance')
            time.sleep(0.02)

    def window(self, t0, t1=None):
        with self.lock:
            a = np.array([r for r in self.track if r[0] >= t0 and (t1 is None or r[0] <= t1)])
        return a

    def settle_at(self, pos, yaw_deg, timeout=30.0, tol=0.1):
        """Command ``pos``/``yaw`` and wait (sim time) until the drone holds there for 1 s."""
        self.set_waypoint(pos, yaw_deg)
        t_start = rospy.get_time()
        held_since = None
        while rospy.get_time() - t_start < timeout:
            self.sim_sleep(0.2)
            with self.lock:
                last = self.track[-1]
            ok = (np.linalg.norm(np.array(last[1:4]) - pos) < tol and last[5] < 0.05 and
                  abs(wrap_angle(last[4] - yaw_deg, 360.0)) < 3.0)
            if ok:
                held_since = held_since or rospy.get_time()
                if rospy.get_time() - held_since >= 1.0:
                    return True
            else:
                held_since = None
        self.fail('drone did not settle at %s yaw %s within %.0f s: last %s' % (pos, yaw_deg, timeout, last))

    def switch_to(self, launch):
        if self.controller is not None:
            self.controller.stop()
        type(self).controller = Controller(launch)
        # the controller is up when it commands (the simulator holds position meanwhile)
        deadline = time.time() + 30.0
        n0 = len(self.commands)
        while time.time() < deadline:
            time.sleep(0.2)
            if len(self.commands) > n0 + 5:
                return
        self.fail('%s did not start commanding within 30 s' % launch)

    def static_run(self, name, yaw_deg):
        self.settle_at(START, 0.0)
        t0 = rospy.get_time()
        self.set_waypoint(GOAL, yaw_deg)
        self.sim_sleep(RUN_TIME)
        a = self.window(t0, t0 + RUN_TIME)
        self.assertGreater(len(a), 10 * RUN_TIME, 'too few ground-truth samples')
        per_axis, norm, proj = overshoot(a[:, 1:4], START, GOAL)
        final = a[a[:, 0] >= a[-1, 0] - 1.0]
        final_dist = float(np.linalg.norm(final[:, 1:4].mean(axis=0) - GOAL))
        final_yaw_err = abs(wrap_angle(final[-1, 4] - yaw_deg, 360.0))
        res = {'overshoot_xyz': [round(float(v), 3) for v in per_axis], 'overshoot': round(norm, 3),
               'projection': round(proj, 3), 'final_distance': round(final_dist, 3),
               'final_yaw_error_deg': round(final_yaw_err, 2)}
        self.results[name] = res
        return res

    def check_echo_tool(self):
        """rosrun anafi_sim echo.py decodes drone/rpyt from the publisher's own definition (no olympe_bridge
        needed): 3 messages as YAML, each with the command's fields."""
        out = subprocess.run(['rosrun', 'anafi_sim', 'echo.py', NS + '/drone/rpyt', '-n', '3'],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=60, universal_newlines=True)
        self.assertEqual(out.returncode, 0, out.stderr)
        docs = [d for d in out.stdout.split('---') if d.strip()]
        self.assertEqual(len(docs), 3, out.stdout)
        for doc in docs:
            fields = dict(line.split(':', 1) for line in doc.strip().splitlines() if ':' in line
                          and not line.startswith(' '))
            self.assertTrue({'header', 'roll', 'pitch', 'yaw', 'gaz'} <= set(fields), doc)
            self.assertTrue(all(math.isfinite(float(fields[k])) for k in ('roll', 'pitch', 'yaw', 'gaz')), doc)
        self.results['echo_tool'] = docs[0].strip().replace('\n', '; ')

    # -- tests (run in name order: MPC first, then the PID in the same simulation) -------------
    def test_1_mpc_reaches_static_waypoints(self):
        self.switch_to('mpc.launch')
        self.check_echo_tool()
        for yaw in (0.0, 180.0):
            res = self.static_run('mpc_yaw_%d' % yaw, yaw)
            self.assertLess(res['final_distance'], REACH_TOL, res)
            self.assertLess(res['final_yaw_error_deg'], YAW_TOL, res)
        with self.lock:
            hovered = [s for s in self.stats if not s[1] and not s[2].endswith('received yet')]
        self.assertFalse(hovered, 'MPC hovered for other reasons than waiting: %s' % hovered[:3])

    def test_2_mpc_weight_reconfigured_live(self):
        client = Client(NS + '/mpc_controller', timeout=20.0)
        here = np.array(GOAL)
        target = here + np.array([2.0, 0.0, 0.0])
        # no tracking weight: the optimal input is zero, the drone stays although the waypoint moved
        cfg = client.update_configuration({'q_cum': 0.0, 'q_cum_terminal': 0.0})
        self.assertEqual((cfg['q_cum'], cfg['q_cum_terminal']), (0.0, 0.0))
        t0 = rospy.get_time()
        self.set_waypoint(target, 180.0)
        self.sim_sleep(3.0)
        a = self.window(t0)
        with self.lock:
            tilt = max(max(abs(c[1]), abs(c[2])) for c in self.commands if c[0] >= t0 + 0.3)
        moved = float(np.max(np.linalg.norm(a[:, 1:4] - here, axis=1)))
        self.results['reconfigure_zero_weight'] = {'max_tilt_cmd_deg': round(tilt, 2), 'moved': round(moved, 3)}
        self.assertLess(tilt, 1.0)
        self.assertLess(moved, 0.3)
        # the paper's weights back: the same waypoint is now flown to
        client.update_configuration({'q_cum': 1e-3, 'q_cum_terminal': 5.0})
        t1 = rospy.get_time()
        self.sim_sleep(6.0)
        with self.lock:
            tilt = max(max(abs(c[1]), abs(c[2])) for c in self.commands if c[0] >= t1)
        a = self.window(t1)
        dist = float(np.linalg.norm(a[-1, 1:4] - target))
        self.results['reconfigure_paper_weight'] = {'max_tilt_cmd_deg': round(tilt, 2),
                                                    'final_distance': round(dist, 3)}
        self.assertGreater(tilt, 5.0)
        self.assertLess(dist, REACH_TOL)

    def test_3_pid_overshoots_more_than_mpc(self):
        self.assertIn('mpc_yaw_0', self.results, 'the MPC runs must come first')
        self.settle_at(START, 0.0)      # return with the MPC, then hand over to the PID framework
        self.switch_to('pid.launch')
        for yaw in (0.0, 180.0):
            self.static_run('pid_yaw_%d' % yaw, yaw)
        for yaw in (0, 180):
            mpc, pid = self.results['mpc_yaw_%d' % yaw], self.results['pid_yaw_%d' % yaw]
            self.assertLess(mpc['overshoot'], pid['overshoot'],
                            'yaw %d: MPC overshoot %s not below PID %s' % (yaw, mpc, pid))
        # absolute: the same flights in Sphinx (the shipped reference logs, same start, goal and metric). Yaw 0: within
        # +-35 % of Sphinx's overshoot (CI 2026-11-24: 1.21x MPC, 0.97x PID; in-process 0.87x and 1.13x).
        # Yaw 180 (the drone turns while it flies; a known gap of the stand-in, docs/fidelity.md): no more
        # than twice Sphinx's.
        logs = paths.reference_logs_dir()
        for name in ('mpc_yaw_0', 'pid_yaw_0', 'mpc_yaw_180', 'pid_yaw_180'):
            controller, yaw = name.split('_yaw_')
            sphinx = sphinx_overshoot(os.path.join(logs, 'static_waypoint_yaw_%s_%s.csv' % (yaw, controller)))
            ratio = self.results[name]['overshoot'] / sphinx
            self.results[name]['sphinx_overshoot'] = round(sphinx, 3)
            if yaw == '0':
                self.assertTrue(0.65 <= ratio <= 1.35, '%s: overshoot %.3f m vs Sphinx %.3f m (x%.2f)'
                                % (name, self.results[name]['overshoot'], sphinx, ratio))
            else:
                self.assertLess(ratio, 2.0, '%s: overshoot %.3f m vs Sphinx %.3f m' % (
                    name, self.results[name]['overshoot'], sphinx))


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'test_mpc_closed_loop', TestMpcClosedLoop, sys.argv)
