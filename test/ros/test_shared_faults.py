#!/usr/bin/env python3
"""rostest (shared_faults.test): failure isolation in a fleet's shared layout (fleet_host.py processes).

A two-drone fleet, layout shared, on a private master of this test (world kinematic): anafi1 with the MPC on
a static waypoint; anafi2 told to serve its telemetry on a port this test holds, so anafi2's simulator share
fails in the drones host. Checked, in order:

1. share_failed: the drones host reports the failed instance (its status WARN "1 failed: /anafi2/anafi_sim",
   '/anafi2/anafi_sim: hosted instance' ERROR naming the port), anafi2's interface ERROR (no telemetry) and
   its controller not tracking, while anafi1 (same host processes) reaches its waypoint with its ground truth
   at >= 97 Hz and its mirror sending.
2. ground_truth_host_killed: the ground-truth host (every interface and mirror) killed with SIGKILL: anafi1
   keeps holding its waypoint (its simulator and controller are in the other host, on the drone's estimate);
   roslaunch respawns the host and anafi1's ground truth flows again.
The rows observed are written to test_results/shared_faults.json (docs/reliability.md quotes them).
"""
import json
import math
import os
import shutil
import signal
import socket
import tempfile
import threading
import time
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry

from anafi_sim import paths, processes

RESULTS = os.path.join(paths.package_dir(), 'test_results', 'shared_faults.json')
GOAL = (1.0, 0.5, 2.0)     # m, anafi1's waypoint
REACH = 0.3                # m
FLEET = """name: shared_faults
layout: shared
defaults: {{controller: mpc}}
drones:
  - {{name: anafi1, waypoint: [{x}, {y}, {z}, 0.0]}}
  - {{name: anafi2, start: {{x: 0.0, y: 6.0}}, waypoint: [0.0, 6.0, 2.0, 0.0], telemetry_port: {port}}}
"""


class Watch(object):
    """/diagnostics by status name, and the ground truth and simulator truth of anafi1."""

    def __init__(self):
        self.lock = threading.Lock()
        self.diag = {}       # name -> (wall time, level, message, values)
        self.truth = []      # wall times of /anafi1/ground_truth/odom
        self.sim = None      # (wall time, x, y, z) of /anafi1/sim/truth
        rospy.Subscriber('/diagnostics', DiagnosticArray, self.on_diag, queue_size=50)
        rospy.Subscriber('/anafi1/ground_truth/odom', Odometry, self.on_truth, queue_size=20)
        rospy.Subscriber('/anafi1/sim/truth', Odometry, self.on_sim, queue_size=1)

    def on_diag(self, msg):
        now = time.time()
        with self.lock:
            for s in msg.status:
                self.diag[s.name] = (now, s.level, s.message, dict((kv.key, kv.value) for kv in s.values))

    def on_truth(self, msg):
        with self.lock:
            self.truth.append(time.time())
            del self.truth[:-500]

    def on_sim(self, msg):
        p = msg.pose.pose.position
        with self.lock:
            self.sim = (time.time(), p.x, p.y, p.z)

    def status(self, name, since=0.0):
        with self.lock:
            entry = self.diag.get(name)
        return entry if entry is not None and entry[0] >= since else None

    def truth_rate(self, window=2.0):
        now = time.time()
        with self.lock:
            return sum(1 for t in self.truth if t > now - window) / window

    def distance(self):
        with self.lock:
            s = self.sim
        if s is None or time.time() - s[0] > 1.0:
            return None
        return math.sqrt(sum((a - b) ** 2 for a, b in zip(s[1:], GOAL)))


class SharedFaults(unittest.TestCase):
    rows = []

    @classmethod
    def setUpClass(cls):
        cls.workdir = tempfile.mkdtemp(prefix='shared_faults_')
        cls.procs = processes.Processes(cls.workdir, grace=10.0)
        cls.uri, cls.env = processes.private_master(cls.procs, os.path.join(cls.workdir, 'ros_home'),
                                                  os.path.join(cls.workdir, 'log'), join=True)
        cls.held = socket.socket()          # the port anafi2's simulator is told to serve on: taken
        cls.held.bind(('127.0.0.1', 0))
        cls.held.listen(1)
        cls.taken = cls.held.getsockname()[1]
        fleet = os.path.join(cls.workdir, 'fleet.yaml')
        with open(fleet, 'w') as f:
            f.write(FLEET.format(x=GOAL[0], y=GOAL[1], z=GOAL[2], port=cls.taken))
        cls.procs.start('roslaunch', ['roslaunch', '--port', cls.uri.rsplit(':', 1)[1], 'anafi_sim', 'fleet.launch',
                                      'fleet:=' + fleet, 'evaluate:=false',
                                      'out_dir:=' + os.path.join(cls.workdir, 'fleet')], cls.env)
        rospy.init_node('shared_faults', anonymous=True)
        cls.w = Watch()

    @classmethod
    def tearDownClass(cls):
        try:
            os.makedirs(os.path.dirname(RESULTS), exist_ok=True)
            tmp = RESULTS + '.tmp'
            with open(tmp, 'w') as f:
                json.dump({'rows': cls.rows, 'date': time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, f,
                          indent=1)
            os.replace(tmp, RESULTS)
        finally:
            cls.procs.stop_all()
            cls.held.close()
            shutil.rmtree(cls.workdir, ignore_errors=True)

    def require(self, predicate, timeout, what):
        processes.require(predicate, timeout, what, lambda: self.procs.log_tail('roslaunch', 30))

    def test_1_share_failed(self):
        w = self.w
        self.require(lambda: (w.distance() or 99.0) < REACH, 90.0, 'anafi1 at its waypoint')
        host = w.status('/fleet_drones: fleet host')
        failed = w.status('/anafi2/anafi_sim: hosted instance')
        interface2 = w.status('/anafi2/interface: ground truth interface')
        self.assertIsNotNone(host)
        self.assertEqual(host[1], 1, host)      # WARN: some instances failed
        self.assertIn('/anafi2/anafi_sim', host[2])
        self.assertIsNotNone(failed)
        self.assertEqual(failed[1], 2, failed)
        self.assertIn(str(self.taken), failed[2])
        self.assertIsNotNone(interface2)
        self.assertEqual(interface2[1], 2, interface2)
        rate = w.truth_rate()
        self.assertGreaterEqual(rate, 97.0)
        # each host says whether its drones keep real time; a drone without telemetry is not 'behind' (its own
        # statuses say why), so anafi2 is not named whatever the machine's load does to anafi1
        self.require(lambda: w.status('/fleet_ground_truth: real time') is not None and
                     w.status('/fleet_drones: real time') is not None, 10.0, 'the hosts\' real time statuses')
        for name in ('/fleet_ground_truth: real time', '/fleet_drones: real time'):
            self.assertNotIn('anafi2', w.status(name)[2], w.status(name))
        mirror1 = w.status('/anafi1/gazebo_mirror: gazebo mirror')
        self.assertIsNotNone(mirror1)
        self.assertEqual(mirror1[1], 0, mirror1)
        self.rows.append({'fault': 'share_failed', 'observed': {
            'host': host[2], 'failed instance': failed[2], 'anafi2 interface': interface2[2],
            'anafi1 ground truth Hz': round(rate, 1), 'anafi1 at its waypoint': True,
            'anafi1 mirror': mirror1[2]}})

    def test_2_ground_truth_host_killed(self):
        w = self.w
        self.require(lambda: w.truth_rate() >= 90.0, 30.0, 'anafi1 ground truth')
        pid = processes.node_pid('/fleet_ground_truth', self.uri)
        os.kill(pid, signal.SIGKILL)
        killed = time.time()
        self.require(lambda: w.truth_rate(0.5) == 0.0, 5.0, 'ground truth stopped')
        worst = 0.0
        while time.time() - killed < 3.0:       # the drone without interfaces and mirrors
            worst = max(worst, w.distance() or 99.0)
            time.sleep(0.05)
        self.assertLess(worst, REACH, 'anafi1 left its waypoint while the ground-truth host was down')
        self.require(lambda: w.truth_rate(1.0) >= 90.0, 30.0, 'ground truth back')
        back = time.time() - killed
        new_pid = processes.node_pid('/fleet_ground_truth', self.uri)
        self.assertNotEqual(new_pid, pid)
        self.assertLess(w.distance() or 99.0, REACH)
        self.rows.append({'fault': 'ground_truth_host_killed', 'observed': {
            'anafi1 farthest from its waypoint while down [m]': round(worst, 3),
            'ground truth back after [s]': round(back, 1), 'host respawned': True}})


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'test_shared_faults', SharedFaults)
