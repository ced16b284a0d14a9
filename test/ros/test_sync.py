#!/usr/bin/env python3
"""rostest (sync.test): experiment.launch sync:=true on a short scenario matches the in-process engine.

~controller: mpc | pid. Runs ``roslaunch anafi_sim experiment.launch sync:=true`` with the test scenario
experiment_short.yaml (10 s of simulation time, rtf 0.5 as a ceiling, no mirror, bag recorded) on its own
private ROS master (``anafi_lab.engine.lockstep.run_sync``: every process stopped by id afterwards), then the
same scenario and seed in-process with the lockstep's schedule (``experiment.py run --engine inprocess
--sync-schedule``). Checks: the evaluator's summary is final; the simulator's /diagnostics (in the bag) show
the lockstep engaged (control periods waited for) with no timeout; e_mu vs estimate and vs ground truth
within 10 % of the in-process run's.
"""
import os
import shutil
import sys
import tempfile
import unittest

import rospy
import rostest

from anafi_lab.engine import lockstep as lockstep_runs

SHORT_SCENARIO = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'experiment_short.yaml')

TOLERANCE = 0.10


class TestSync(unittest.TestCase):
    def test_lockstep_run_matches_the_inprocess_engine(self):
        controller = rospy.get_param('~controller', 'mpc')
        out = tempfile.mkdtemp(prefix='anafi_sync_%s_' % controller)
        run = lockstep_runs.run_sync(controller, out, SHORT_SCENARIO, rtf=0.5, timeout=180.0)
        try:
            self.check(controller, run, out)
        except AssertionError:
            with open(run['log']) as f:
                tail = f.read()[-3000:]
            raise AssertionError('%s\n(run files in %s; launch log tail:)\n%s' % (sys.exc_info()[1], out, tail))
        shutil.rmtree(out, ignore_errors=True)

    def check(self, controller, run, out):
        summary = run['summary']
        self.assertIsInstance(summary, dict, 'no evaluator summary')
        self.assertEqual(summary.get('state'), 'final')
        lockstep = run['lockstep']
        self.assertIn('lockstep periods waited', lockstep, 'simulator diagnostics: %s' % lockstep)
        # ~14 s of simulation at 10 Hz: the simulator waited for (nearly) every command
        self.assertGreater(int(lockstep['lockstep periods waited']), 100, lockstep)
        self.assertEqual(lockstep['lockstep timeouts (period went on without a command)'], '0', lockstep)
        reference = lockstep_runs.run_inprocess(controller, os.path.join(out, 'inprocess'), SHORT_SCENARIO)
        self.assertEqual(reference.get('state'), 'final')
        for source in ('estimate', 'truth'):
            ros, ref = lockstep_runs.e_mu(summary, source), lockstep_runs.e_mu(reference, source)
            self.assertIsNotNone(ros, source)
            self.assertLess(abs(ros - ref), TOLERANCE * ref,
                            '%s e_mu vs %s: ROS lockstep %.4f, in-process %.4f' % (controller, source, ros, ref))


if __name__ == '__main__':
    rospy.init_node('test_sync', anonymous=True)
    rostest.rosrun('anafi_sim', 'test_sync', TestSync, sys.argv)
