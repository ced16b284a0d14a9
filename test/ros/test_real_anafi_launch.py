#!/usr/bin/env python3
"""rostest (real_anafi_launch.test): ``roslaunch anafi_sim real_anafi.launch`` typed as docs/launch.md gives it.

Each roslaunch runs in a ROS home of its own (ROS_HOME, ROS_LOG_DIR in a temporary folder) on a free port
(ROS_MASTER_URI, ``-p``), and is stopped by its process id.

1. Without the fence arguments: roslaunch exits non-zero, one line of its output names the missing argument
   (``requires the 'fence_radius' arg to be set``), no other line mentions the fence, no master and no node
   started. A fence in the wrong order (fence_max_altitude below fence_min_altitude): refused, the launch check's
   one line names it (roslaunch then prints the failed command's XML).
2. With the fence and no bridge: the launch keeps running, the controller sends nothing (the pre-flight check
   never passes) and preflight_check.py says what it waits for: the state on drone/odom from
   position_control/state_enu, drone/state flying and the first waypoint within reach.
"""
import os
import shutil
import subprocess
import tempfile
import time
import unittest

import rostest

from anafi_sim import processes

FENCE = ['fence_radius:=5', 'fence_min_altitude:=1', 'fence_max_altitude:=4']
WAIT_TIMEOUT = 180.0   # s wall at most for the first "waiting for" line (the nodes' start-up on a loaded machine)


class TestRealAnafiLaunch(unittest.TestCase):
    def setUp(self):
        self.home = tempfile.mkdtemp(prefix='real_anafi_launch_')
        self.port = processes.free_port()
        self.env = processes.ros_env('http://127.0.0.1:%d' % self.port, ros_home=self.home,
                                     log_dir=os.path.join(self.home, 'log'))
        self.addCleanup(shutil.rmtree, self.home, ignore_errors=True)

    def roslaunch(self, *args):
        return ['roslaunch', '-p', str(self.port), 'anafi_sim', 'real_anafi.launch'] + list(args)

    def refusal(self, *args):
        out = subprocess.run(self.roslaunch(*args), env=self.env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, universal_newlines=True, timeout=120.0)
        lines = out.stdout.splitlines()
        self.assertNotEqual(out.returncode, 0, out.stdout)
        self.assertFalse([l for l in lines if 'auto-starting new master' in l or 'started with pid' in l], out.stdout)
        return [l for l in lines if 'fence' in l]

    def test_without_a_fence_roslaunch_refuses_with_one_line(self):
        lines = self.refusal()
        self.assertEqual(len(lines), 1, lines)
        self.assertIn("requires the 'fence_radius' arg to be set", lines[0])
        # a bad value: the launch check's one line (roslaunch then prints the failed command's XML)
        lines = [l for l in self.refusal('fence_radius:=5', 'fence_min_altitude:=4', 'fence_max_altitude:=1')
                 if l.startswith('launch argument')]
        self.assertEqual(len(lines), 1, lines)
        self.assertIn('fence_max_altitude:=1', lines[0])

    def test_with_a_fence_and_no_bridge_it_waits_and_says_what_for(self):
        log = os.path.join(self.home, 'launch.log')
        proc = processes.start(self.roslaunch(*(FENCE + ['record:=false'])), env=self.env, log=log)
        try:
            waiting = processes.wait_for(lambda: self.waiting_line(log), WAIT_TIMEOUT, step=0.5)
            running = proc.poll() is None
        finally:
            processes.stop(proc, grace=20.0)
        with open(log) as f:
            text = f.read()
        self.assertTrue(waiting, 'no "waiting for" line from the pre-flight check:\n%s' % text[-3000:])
        self.assertTrue(running, text[-3000:])
        line = self.waiting_line(log)
        for part in ('a state on drone/odom', 'position_control/state_enu', 'drone/state flying',
                     'the first waypoint (2.00, 0.00, 5.00)'):
            self.assertIn(part, line)
        self.assertNotIn('pre-flight check passed', text)

    @staticmethod
    def waiting_line(log):
        """The pre-flight check's first "waiting for" line naming the drone's state, flying and the waypoint."""
        try:
            with open(log) as f:
                for line in f:
                    if 'preflight_check: waiting for' in line and 'drone/state flying' in line \
                            and 'first waypoint' in line:
                        return line
        except IOError:
            pass
        return None


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'test_real_anafi_launch', TestRealAnafiLaunch)
