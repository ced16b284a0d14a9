#!/usr/bin/env python3
"""rostest (experiment.test): one short scenario end to end per controller (~controller: mpc | pid).

Starts ``roslaunch anafi_sim experiment.launch`` with the test scenario experiment_short.yaml (10 s of
simulation time, rtf 2, kinematic world + mirror, record) as a subprocess on its own private ROS master
(free port, own ROS_HOME) and waits for the experiment monitor (the launch's required node) to end it;
every process of the run is stopped by id afterwards. Then checks the run's files:

- RUN.bag: a readable bag with the waypoint, the estimate, ground truth, the commands, /tf, /tf_static, /clock and the
  begin/end signals recorded;
- RUN.csv: reference-log columns, one row per estimate sample, finite waypoint and positions;
- RUN.yaml (evaluator summary): state final, e_max, e_mu, e_sigma finite (vs estimate and vs ground
  truth), the measured window 4 s long, e_mu < 2 m (the drone did track the 1 m circle);
- RUN.run.yaml (monitor): state final, the simulator's real-time factor and the scenario durations.
"""
import math
import os
import shutil
import sys
import tempfile
import time
import unittest

import rospy
import rostest
import yaml

from anafi_sim import processes

HERE = os.path.dirname(os.path.abspath(__file__))
SCENARIO = os.path.join(HERE, 'experiment_short.yaml')
RUN_TIMEOUT = 130.0       # s wall for the whole launch
#: live tuning during the run (`rosrun dynamic_reconfigure dynparam set`): node, request, the expected records
#: (parameter, old, new, outcome). Harmless to the flight: a_max 5 -> 5.5 m/s^2; q_cum_vel asked -1, clamped to
#: its minimum 0 (its value already); the PID's x_outer Kd_scale asked 0.01, clamped to 0.1 (Kd is 0); the preview
#: MPC's yaw gain 1.5 -> 1.6, its tilt margin asked 5, clamped to its maximum 1 (from 0.95).
TUNING = {
    'mpc': ('/anafi/mpc_controller', "{'a_max': 5.5, 'q_cum_vel': -1.0}",
            [('a_max', 5.0, 5.5, 'applied'), ('q_cum_vel', 0.0, 0.0, 'clamped')]),
    'pid': ('/anafi/pid/x_outer', "{'Kd_scale': 0.01}", [('Kd_scale', None, 0.1, 'clamped')]),
    'preview_mpc': ('/anafi/preview_mpc_controller', "{'yaw_gain': 1.6, 'tilt_margin': 5.0}",
                    [('yaw_gain', 1.5, 1.6, 'applied'), ('tilt_margin', 0.95, 1.0, 'clamped')]),
}


class TestExperiment(unittest.TestCase):
    def test_short_scenario_end_to_end(self):
        controller = rospy.get_param('~controller', 'mpc')
        out = tempfile.mkdtemp(prefix='anafi_experiment_%s_' % controller)
        name = 'short_%s' % controller
        port = processes.free_port()
        env = dict(os.environ, ROS_MASTER_URI='http://127.0.0.1:%d' % port, ROS_HOME=os.path.join(out, 'ros_home'))
        processes.add_module_paths(env, 'osqp')  # nodes started through /usr/bin/python3 relay scripts need it too
        cmd = ['roslaunch', '-p', str(port), 'anafi_sim', 'experiment.launch', 'controller:=' + controller,
               'scenario:=experiment_short', 'scenario_file:=' + SCENARIO, 'rtf:=2.0', 'mirror:=true',
               'record:=true', 'out_dir:=' + out, 'run_name:=' + name, 'unique:=false', 'plot:=false',
               'progress_period:=0',
               'telemetry_port:=0']   # a free port, announced to the interface
        log_path = os.path.join(out, 'launch.log')
        proc = processes.start(cmd, env=env, log=log_path)
        node, request, self.expected_tuning = TUNING[controller]
        tuner = processes.start(['rosrun', 'dynamic_reconfigure', 'dynparam', 'set', '--timeout=60', node, request],
                              env=env, log=os.path.join(out, 'dynparam.log'))
        self.tuned_node, self.ros_home = node, env['ROS_HOME']
        base = os.path.join(out, name)
        deadline = time.monotonic() + RUN_TIMEOUT
        try:
            while time.monotonic() < deadline and proc.poll() is None:
                if os.path.exists(base + '.run.yaml') and os.path.exists(base + '.bag'):
                    break          # results complete; skip the slow rest of roslaunch's shutdown
                time.sleep(0.5)
            time.sleep(0.5)
        finally:
            processes.stop(tuner, grace=2.0)
            processes.stop(proc, grace=20.0)
        try:
            self.check(base)
        except AssertionError:
            with open(log_path) as f:
                tail = f.read()[-3000:]
            raise AssertionError('%s\n(run files in %s; launch log tail:)\n%s' % (sys.exc_info()[1], out, tail))
        shutil.rmtree(out, ignore_errors=True)

    def check(self, base):
        info = self.load_yaml(base + '.run.yaml')
        self.assertEqual(info.get('state'), 'final', 'monitor: %s' % info)
        self.assertGreater(info['scenario_sim_s'], 9.0)
        # the simulator's rtf (experiment.launch default 2) is a ceiling: simulation time never runs faster
        self.assertGreater(info['achieved_rtf'], 0.0)
        self.assertLessEqual(info['achieved_rtf'], 2.0 * 1.05)

        self.check_tuning(info)
        # the run names its conditions (none here) and keeps its measured window (ROS time) for the RESULT line
        self.assertEqual(info.get('conditions'), {'name': 'none', 'settings': {}}, info)
        window = info.get('measured_window')
        self.assertTrue(isinstance(window, list) and len(window) == 2 and window[0] < window[1], window)

        summary = self.load_yaml(base + '.yaml')
        self.assertEqual(summary.get('state'), 'final')
        for source in ('estimate', 'truth'):
            res = summary.get(source)
            self.assertIsInstance(res, dict, '%s missing in %s' % (source, summary))
            for key in ('e_max', 'e_mu', 'e_sigma'):
                self.assertTrue(isinstance(res.get(key), float) and math.isfinite(res[key]),
                                '%s %s = %r' % (source, key, res.get(key)))
            self.assertGreater(res['n_valid'], 40)                 # 4 s of the estimate at 30 Hz
            self.assertLessEqual(res['e_mu'], res['e_max'])
        # after only 3 s of settling both controllers still lag the target in phase on the r = 1 m circle
        # (measured 2026-11-23: MPC e_mu 0.66 m, PID 1.24 m, i.e. 40 and 77 deg behind), so e_mu cannot tell a
        # follower from a drone parked at the centre (1 m): it only bounds a lost drone (opposite phase: 2 m);
        # the geometric checks below show that the drone flies the circle
        self.assertLess(summary['estimate']['e_mu'], 1.6)
        self.assertLess(summary['truth']['e_mu'], 1.6)
        w = summary['window']
        self.assertAlmostEqual(w[1] - w[0], 4.0, delta=0.2)

        from anafi_sim.mission.reference_log import COLUMNS, read_log
        with open(base + '.csv') as f:
            self.assertEqual(f.readline().strip().split(','), list(COLUMNS))
        log = read_log(base + '.csv')
        self.assertGreater(len(log), 150)                          # >= 10 s at 30 Hz incl. the hold
        for column in ('wp_x', 'x_anafi', 'z_anafi'):
            values = log.columns[column]
            self.assertGreater(sum(1 for v in values if math.isfinite(v)), 0.9 * len(values), column)
        # ground truth may start after the estimate (the telemetry CLI connects first; at rtf 2 that is
        # visible in simulation time), but inside the measured window every row has it
        inside = [v for t, v in zip(log.time, log.columns['x_sphinx']) if w[0] <= t <= w[1]]
        self.assertGreater(len(inside), 100, 'rows in the measured window')
        self.assertTrue(all(math.isfinite(v) for v in inside), 'x_sphinx missing in the measured window')
        # and the drone flies the circle (centre (0, 0), r = 1 m, 1 rad/s): on its radius, going round
        xy = [(x, y) for t, x, y in zip(log.time, log.columns['x_sphinx'], log.columns['y_sphinx'])
              if w[0] <= t <= w[1] and math.isfinite(x) and math.isfinite(y)]
        radii = [math.hypot(x, y) for x, y in xy]
        self.assertTrue(0.5 < sum(radii) / len(radii) < 1.8, 'mean radius %.2f m' % (sum(radii) / len(radii)))
        angles = [math.atan2(y, x) for x, y in xy]
        turned = sum(abs(math.atan2(math.sin(b - a), math.cos(b - a))) for a, b in zip(angles, angles[1:]))
        self.assertGreater(turned, 2.0, 'turned %.2f rad in the 4 s window (1 rad/s expected)' % turned)

        import rosbag
        with rosbag.Bag(base + '.bag') as bag:
            topics = bag.get_type_and_topic_info().topics
        for topic in ('position_control/waypoint', 'drone/odom', 'ground_truth/odom', 'drone/rpyt',
                      'trajectory/begin', 'trajectory/end'):
            self.assertIn('/anafi/' + topic, topics, 'bag topics: %s' % sorted(topics))
            self.assertGreater(topics['/anafi/' + topic].message_count, 0, topic)
        self.assertGreater(topics['/anafi/drone/odom'].message_count, 200)
        # replayable into rviz: the drone's tf (the interface's world -> anafi/... frames, the static camera
        # frames) and the simulation clock
        for topic in ('/tf', '/tf_static', '/clock'):
            self.assertIn(topic, topics, 'bag topics: %s' % sorted(topics))
            self.assertGreater(topics[topic].message_count, 0, topic)
        # the frames rviz needs (docs/nodes.md#frames): the estimate's map -> anafi/odom -> anafi/base_link (the
        # model), the ground truth's world -> stability axes -> base_link_gt -> camera, on the simulation clock of
        # the bag's /clock
        import tf2_ros
        buffer = tf2_ros.Buffer(rospy.Duration(3600.0), debug=False)
        clock, parents = [], {}
        with rosbag.Bag(base + '.bag') as bag:
            for topic, msg, _ in bag.read_messages(topics=['/tf', '/tf_static', '/clock']):
                if topic == '/clock':
                    clock.append(msg.clock.to_sec())
                    continue
                for t in msg.transforms:
                    parents.setdefault(t.child_frame_id, set()).add(t.header.frame_id)
                    if topic == '/tf_static':
                        buffer.set_transform_static(t, 'bag')
                    else:
                        buffer.set_transform(t, 'bag')
        self.assertTrue(clock and clock[-1] > clock[0], 'the bag\'s /clock does not advance')
        middle = rospy.Time.from_sec(0.5 * (clock[0] + clock[-1]))
        for parent, frame in (('world', 'anafi/base_link_gt'), ('world', 'anafi/camera'), ('world', 'anafi/camera_optical'),
                              ('map', 'anafi/base_link'), ('anafi/odom', 'anafi/base_link'), ('world', 'map')):
            self.assertTrue(buffer.can_transform(parent, frame, middle), '%s -> %s at %.2f s of the bag\'s clock: %s'
                            % (parent, frame, middle.to_sec(), buffer.all_frames_as_string()))
        # REP-105: the estimate's base_link hangs under odom (map -> anafi/odom -> anafi/base_link), the ground
        # truth's body is its own frame (the two differ by the estimate's error: close, not equal)
        self.assertEqual(parents.get('anafi/base_link'), {'anafi/odom'}, parents)
        self.assertEqual(parents.get('anafi/odom'), {'map'}, parents)
        est = buffer.lookup_transform('map', 'anafi/base_link', middle).transform.translation
        truth = buffer.lookup_transform('world', 'anafi/base_link_gt', middle).transform.translation
        self.assertLess(math.dist((est.x, est.y, est.z), (truth.x, truth.y, truth.z)), 0.5, (est, truth))

    def check_tuning(self, info):
        """The dynparam request is in the run info (time, parameter, old, new, requested, outcome) and on
        /rosout: the node's log holds the INFO line of an applied change and the WARN of a clamped one."""
        records = info.get('tuning')
        self.assertIsInstance(records, list, 'no tuning list in the run info: %s' % info)
        got = [(r['parameter'], r['old'], r['new'], r['outcome']) for r in records if r['node'] == self.tuned_node]
        for parameter, old, new, outcome in self.expected_tuning:
            match = [g for g in got if g[0] == parameter and g[3] == outcome and g[2] == new
                     and (old is None or g[1] == old)]
            self.assertTrue(match, '%s %s -> %s (%s) not in the run\'s tuning records %s'
                            % (parameter, old, new, outcome, records))
        for r in records:
            self.assertTrue(r['stamp'] >= 0.0 and r['wall'] > 0.0 and 'requested' in r, r)
        logs = []
        for folder, _, files in os.walk(os.path.join(self.ros_home, 'log')):
            logs += [os.path.join(folder, f) for f in files if f.endswith('.log')]
        text = ''.join(open(path, errors='replace').read() for path in logs)
        for parameter, _, new, outcome in self.expected_tuning:
            self.assertIn('tuning %s: %s' % (self.tuned_node, parameter), text, 'no tuning line in the node logs')
        self.assertRegex(text, r'INFO.*tuning %s' % self.tuned_node if any(
            e[3] == 'applied' for e in self.expected_tuning) else r'WARN.*tuning %s' % self.tuned_node)
        self.assertRegex(text, r'WARN.*tuning %s: .*clamped' % self.tuned_node)

    def load_yaml(self, path):
        self.assertTrue(os.path.exists(path), '%s not written' % path)
        with open(path) as f:
            data = yaml.safe_load(f)
        self.assertIsInstance(data, dict, path)
        return data


if __name__ == '__main__':
    rospy.init_node('test_experiment', anonymous=True)
    rostest.rosrun('anafi_sim', 'test_experiment', TestExperiment, sys.argv)
