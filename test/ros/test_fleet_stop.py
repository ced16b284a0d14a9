#!/usr/bin/env python3
"""rostest: Ctrl-C of a fleet ends it cleanly, with its summary table (see fleet_stop.test).

For each layout: ``roslaunch -p PORT anafi_sim fleet.launch drones:=4`` (a free port: roslaunch starts the
fleet's own master; ROS home, logs and the fleet's out_dir in a temporary folder), wait until every drone is up
(its ground truth, evaluation summary and commands have a publisher), 5 s more, then SIGINT to roslaunch, as
Ctrl-C.
Checked in roslaunch's output: no escalation ("escalating to SIGTERM" / "SIGKILL", "required SIGKILL"), the
summary table of anafi_sim.mission.fleet_summary with one row per drone, and roslaunch's exit status 0. No
wall-clock figure is asserted (benchmarks/bench_fleet_stop.py measures it)."""
import os
import shutil
import signal
import subprocess
import tempfile
import time
import unittest

import rosgraph
import rostest

from anafi_sim import processes
from anafi_sim.mission.fleet_summary import COLUMNS

PKG = 'anafi_sim'
DRONES = 4
START_TIMEOUT = 400.0   # s until every drone's models are in the world (a loaded machine starts slowly)
STOP_TIMEOUT = 120.0    # s until roslaunch has exited after the SIGINT (a hang, not a figure)
STATES = ('final', 'incomplete', 'measuring', 'waiting', 'error', 'no summary written')


def _up(uri, names):
    """The drones of ``names`` whose ground truth and evaluation summary have a publisher on the master ``uri``
    (every role of the drone is up, in either layout)."""
    try:
        publishers = dict(rosgraph.Master('/fleet_stop_test', master_uri=uri).getSystemState()[0])
    except Exception:        # the master not up yet
        return set()
    return set(n for n in names if publishers.get('/%s/ground_truth/odom' % n)
               and publishers.get('/%s/evaluation/summary' % n) and publishers.get('/%s/drone/rpyt' % n))


class FleetStopTest(unittest.TestCase):
    def stop_fleet(self, layout):
        folder = tempfile.mkdtemp(prefix='fleet_stop_test_')
        self.addCleanup(shutil.rmtree, folder, True)
        port = processes.free_port()
        uri = 'http://127.0.0.1:%d' % port
        env = processes.ros_env(uri, os.path.join(folder, 'ros_home'),
                                os.path.join(folder, 'log'))
        log = os.path.join(folder, 'fleet.log')
        with open(log, 'w') as out:
            launch = subprocess.Popen(['roslaunch', '-p', str(port), 'anafi_sim', 'fleet.launch',
                                       'drones:=%d' % DRONES, 'max_drones:=%d' % DRONES, 'layout:=%s' % layout,
                                       'out_dir:=%s' % os.path.join(folder, 'out')],
                                      stdout=out, stderr=subprocess.STDOUT, env=env, start_new_session=True)
        self.addCleanup(processes.stop, launch, 5.0)
        names = set('anafi%d' % (i + 1) for i in range(DRONES))
        end = time.monotonic() + START_TIMEOUT
        while time.monotonic() < end and launch.poll() is None and not names <= _up(uri, names):
            time.sleep(1.0)
        up = _up(uri, names)
        with open(log) as f:
            text = f.read()
        self.assertTrue(names <= up, '%s: only %s up:\n%s' % (layout, sorted(up), text[-3000:]))
        time.sleep(5.0)          # flying a little
        launch.send_signal(signal.SIGINT)
        code = launch.wait(STOP_TIMEOUT)
        with open(log) as f:
            text = f.read()
        tail = text[-4000:]
        for word in ('escalating to SIGTERM', 'escalating to SIGKILL', 'required SIGKILL'):
            self.assertNotIn(word, text, '%s: %r in roslaunch\'s output:\n%s' % (layout, word, tail))
        lines = text.splitlines()
        titles = [i for i, line in enumerate(lines) if line.startswith('fleet circles stopped: %d drones' % DRONES)]
        self.assertEqual(len(titles), 1, '%s: no (or more than one) summary table:\n%s' % (layout, tail))
        header = lines[titles[0] + 1]
        self.assertEqual(header.split('  ')[0].strip(), COLUMNS[0], tail)
        self.assertTrue(all(column in header for column in COLUMNS), tail)
        rows = lines[titles[0] + 3:titles[0] + 3 + DRONES]
        self.assertEqual([row.split()[0] for row in rows], sorted(names), tail)
        for row in rows:
            state = row.split(None, 2)[2]
            self.assertTrue(state.startswith(STATES), '%s: row %r' % (layout, row))
        self.assertEqual(code, 0, '%s: roslaunch exited with %s:\n%s' % (layout, code, tail))

    def test_per_drone_layout(self):
        self.stop_fleet('per_drone')

    def test_shared_layout(self):
        self.stop_fleet('shared')


if __name__ == '__main__':
    rostest.rosrun(PKG, 'fleet_stop', FleetStopTest)
