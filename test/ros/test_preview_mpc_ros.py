#!/usr/bin/env python3
"""rostest (preview_mpc.test): ``experiment.launch controller:=preview_mpc`` end to end on the short circle.

The run and its checks are test_experiment.py's (bag, CSV, evaluator summary, monitor figures, the drone on
the r = 1 m circle); on top: the controller is tight on the circle against the ground truth (e_mu < 0.3 m;
the paper's MPC: ~0.3-0.4 m on this circle) and the bag holds the preview MPC's stats (its cycles ran).
"""
import sys

import rospy
import rostest

from test_experiment import TestExperiment  # beside this script (a script's folder is on its path)


class TestPreviewMpcExperiment(TestExperiment):
    def check(self, base):
        self.assertTrue(base.endswith('_preview_mpc'), base)     # the run of ~controller preview_mpc
        TestExperiment.check(self, base)
        summary = self.load_yaml(base + '.yaml')
        self.assertLess(summary['truth']['e_mu'], 0.3, 'preview_mpc e_mu vs ground truth: %s' % summary['truth'])


if __name__ == '__main__':
    rospy.init_node('test_preview_mpc_ros', anonymous=True)
    rostest.rosrun('anafi_sim', 'test_preview_mpc_ros', TestPreviewMpcExperiment, sys.argv)
