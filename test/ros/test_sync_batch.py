#!/usr/bin/env python3
"""rostest (sync_batch.test): ``experiment.py batch --engine ros --sync`` produces experiments.yaml and report.md.

Runs ``anafi_lab/cli/experiment.py batch --engine ros --sync --scenarios static_wp0 --controllers mpc
--no-plots --out OUT`` (the ROS batch in lockstep: anafi_lab/cli/ros_batch.py starts experiment.launch
sync:=true on a private master of its own and stops it) and checks OUT/experiments.yaml (the batch schema: meta
with sync true, one record for static_wp0 / mpc, ok, a final evaluator summary with a finite e_mu), that the
simulator ran in lockstep (its "lockstep" diagnostic in the run's bag) and OUT/report.md (names the scenario).
"""
import math
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import rospy
import rostest
import yaml

from anafi_lab.engine import lockstep as lockstep_runs


class TestBatchEngineRos(unittest.TestCase):
    def test_batch_engine_ros_writes_experiments_yaml_and_report(self):
        out = tempfile.mkdtemp(prefix='anafi_batch_ros_')
        log = os.path.join(out, 'batch.log')
        with open(log, 'wb') as f:
            rc = subprocess.call([sys.executable, '-m', 'anafi_lab.cli.experiment', 'batch', '--engine', 'ros',
                                  '--sync', '--scenarios', 'static_wp0', '--controllers', 'mpc', '--no-plots',
                                  '--out', out], stdout=f, stderr=subprocess.STDOUT, timeout=280)
        try:
            self.assertEqual(rc, 0, 'experiment.py batch --engine ros exit %d' % rc)
            with open(os.path.join(out, 'experiments.yaml')) as f:
                data = yaml.safe_load(f)
            self.assertIn('meta', data)
            self.assertIs(data['meta'].get('sync'), True)
            records = data['records']
            self.assertEqual([(r['scenario'], r['controller']) for r in records], [('static_wp0', 'mpc')])
            record = records[0]
            self.assertTrue(record['ok'], record.get('error'))
            self.assertEqual(record['summary']['state'], 'final')
            self.assertTrue(math.isfinite(record['summary']['estimate']['e_mu']))
            lockstep = lockstep_runs.lockstep_figures(os.path.join(out, 'runs', 'static_wp0_mpc.bag'))
            self.assertGreater(int(lockstep.get('lockstep periods waited', 0)), 50, 'simulator: %s' % lockstep)
            with open(os.path.join(out, 'report.md')) as f:
                text = f.read()
            self.assertIn('static_wp0', text)
        except (AssertionError, IOError, KeyError, TypeError):
            with open(log) as f:
                tail = f.read()[-3000:]
            raise AssertionError('%s\n(files in %s; log tail:)\n%s' % (sys.exc_info()[1], out, tail))
        shutil.rmtree(out, ignore_errors=True)


if __name__ == '__main__':
    rospy.init_node('test_sync_batch', anonymous=True)
    rostest.rosrun('anafi_sim', 'test_sync_batch', TestBatchEngineRos, sys.argv)
