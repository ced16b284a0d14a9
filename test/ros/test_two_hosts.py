#!/usr/bin/env python3
"""Across machines: the ground truth crosses hosts at 100 Hz, the mirror follows it and a controller flies a
short scenario across the link (tools/two_hosts.sh, the probe test/ros/two_hosts_probe.py on the Gazebo host).

Skipped (with the script's reason) where network namespaces cannot be made: not root, no iproute2, no
CAP_NET_ADMIN in a container. Speeds (latency, lag, rates per wall second) are printed, not asserted: they
depend on the machine's load and are benchmarks/bench_two_hosts.py's (results/two_hosts.md). The checks are
behaviour: every sample of the 100 Hz ground truth crosses (>= 90 samples per second of their own stamps, so
none is lost whatever the load), most of it is mirrored, the world's model is at the drone (not at the
origin: the drone flies 5 m up), commands cross back, and the drone climbs to the circle at 5 m and flies it
(hovering at the take-off height of 1 m would leave e_mu >= 4 m).
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import rostest

from anafi_sim import paths

SKIP = 77
SCENARIO = os.path.join(paths.package_dir(), 'test', 'ros', 'experiment_short.yaml')


class TestTwoHosts(unittest.TestCase):
    result = None
    skip_reason = None

    @classmethod
    def setUpClass(cls):
        root = paths.package_dir()
        cls.tmp = tempfile.mkdtemp(prefix='two_hosts_test_')
        out = os.path.join(cls.tmp, 'probe.json')
        cmd = [os.path.join(root, 'tools', 'two_hosts.sh'), '--controller', 'mpc', '--scenario-file', SCENARIO,
               '--log-dir', os.path.join(cls.tmp, 'logs'), '--',
               sys.executable, os.path.join(root, 'test', 'ros', 'two_hosts_probe.py'),
               '--window', '8', '--wait-summary', '40', '--json', out]
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True,
                              timeout=280)
        print(proc.stdout[-3000:])
        if proc.returncode == SKIP:
            cls.skip_reason = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else 'skipped'
            return
        cls.rc = proc.returncode
        cls.output = proc.stdout
        if os.path.exists(out):
            with open(out) as f:
                cls.result = json.load(f)
            print(json.dumps(cls.result, indent=1, sort_keys=True))

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def setUp(self):
        if self.skip_reason:
            self.skipTest(self.skip_reason)
        self.assertEqual(self.rc, 0, 'two_hosts.sh failed:\n' + self.output[-2000:])
        self.assertIsNotNone(self.result, 'the probe wrote no result')

    def test_1_nodes_run_on_their_host(self):
        hosts = self.result['node_hosts']
        for node in ('/anafi/anafi_sim', '/anafi/interface'):
            self.assertEqual(hosts.get(node), '10.213.0.1', '%s not on the Sphinx host: %s' % (node, hosts))
        for node in ('/gazebo', '/anafi/gazebo_mirror', '/anafi/mpc_controller', '/anafi/evaluator'):
            self.assertEqual(hosts.get(node), '10.213.0.2', '%s not on the Gazebo host: %s' % (node, hosts))

    def test_2_ground_truth_crosses_at_100_hz(self):
        r = self.result
        print('ground truth across the link: %.1f Hz of wall time, latency %s ms' % (r['gt_rate_hz'],
                                                                                r['gt_latency_ms']))
        self.assertGreaterEqual(r['gt_stamp_rate_hz'], 90.0, r)

    def test_3_mirror_follows(self):
        r = self.result
        self.assertTrue(r['world_has_drone_and_camera'], 'models missing from /gazebo/model_states')
        # most samples mirrored (a starved mirror forwards the newest sample and skips the older ones: 86 % seen
        # at load average 30 on 2 cores; the rate at the world is a benchmark figure, bench_two_hosts.py)
        self.assertGreater(r['mirrored_share'], 0.5, 'share of ground-truth samples mirrored: %s' % r['mirrored_share'])
        print('mirror lag %s ms, world error %s mm' % (r['mirror_lag_ms'], r['world_error_mm']))
        self.assertLess(r['world_error_mm']['p50'], 500.0, r['world_error_mm'])

    def test_4_controller_flies_across_the_link(self):
        r = self.result
        print('MPC commands %.1f Hz, xy span %s m, top %s m, e_mu vs ground truth %s m'
              % (r['command_rate_hz'], r.get('gt_xy_span_m'), r.get('gt_z_max_m'),
                 ((r['summary'] or {}).get('truth') or {}).get('e_mu')))
        self.assertGreater(r['command_rate_hz'], 0.0, 'no MPC command crossed the link')
        summary = r['summary']
        self.assertIsNotNone(summary, 'no evaluator summary')
        self.assertEqual(summary.get('state'), 'final', summary)
        self.assertGreater(r['gt_xy_span_m'], 1.0, 'the drone did not fly the circle (xy span %s m)' % r['gt_xy_span_m'])
        self.assertGreater(r['gt_z_max_m'], 4.0, 'the drone did not climb to the circle at 5 m')
        self.assertLess(summary['truth']['e_mu'], 3.0, summary['truth'])


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'test_two_hosts', TestTwoHosts, sys.argv)
