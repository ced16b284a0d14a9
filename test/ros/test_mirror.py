#!/usr/bin/env python3
"""rostest (mirror.test): simulated Anafi + interface + kinematic world + Gazebo mirror (world.launch).

Checks, in order (unittest runs test_1..test_4 alphabetically):
1. both models spawned; get_model_properties: no collision geometry; world diagnostics: gravity off;
2. while the drone climbs and yaws slowly, the world's model poses (/gazebo/model_states) equal the ground
   truth (ground_truth/odom, linearly interpolated) within 1 cm and 1 deg, for the drone and the camera
   (camera reference: ground_truth.camera_pose with the telemetry's gimbal angles), matched against the
   ground-truth trajectory from 1 s before to 30 ms after the world state's receipt (how old the shown
   sample is depends on the load: the lag is a benchmark figure);
   mirror lag = ground-truth stamp -> receipt of that pose on /gazebo/set_model_state by a subscriber of
   the stream the world subscribes to (matched by the exact position) is printed, not asserted (a speed:
   benchmarks/bench_mirror.py); at least 90 % of the ground-truth samples mirrored;
3. a gravity-on copy of the Anafi model sags between 10 Hz set_model_state updates, the gravity-off
   original does not;
4. the world is killed (SIGKILL) and a new one started: the mirror survives and both models are back
   within 5 s, mirrored again.
"""
import math
import os
import signal
import subprocess
import sys
import threading
import time
import unittest

import numpy as np
import rospkg
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry

from anafi_control import frames
from anafi_sim.processes import node_pid, stop, wait_for
from anafi_sim.ros import conversions, gazebo_types
from anafi_sim.gazebo import urdf_model
from anafi_sim.interface.ground_truth import camera_pose
from anafi_sim.msg import DroneData
from anafi_sim.ros.wire_types import piloting_command_class

DRONE = 'anafi'
MODELS = ('anafi', 'anafi_camera')
PKG = rospkg.RosPack().get_path('anafi_sim')
ANAFI_URDF = os.path.join(PKG, 'anafi_sim', 'urdf', 'anafi.urdf')
MATCH_WINDOW = 0.03  # s after a world state's receipt searched on the ground-truth trajectory (extrapolation)
LAG_WINDOW = 1.0     # s before it: how old the shown sample is depends on the machine's load (on a loaded CI,
                     # 0.026 m at 0.3 m/s = ~90 ms): the lag is benchmarks/bench_mirror.py's figure, not a test's


def pose(x, y, z):
    """Level pose at (x, y, z) [m]."""
    return conversions.pose((x, y, z), (0.0, 0.0, 0.0, 1.0))


def interpolate(samples, t):
    """(position, quaternion, gimbal) of time-sorted samples [(t, pos, q, gimbal)] at t (None outside)."""
    times = [s[0] for s in samples]
    i = int(np.searchsorted(times, t))
    if i == 0 or i >= len(samples):
        return None
    (t0, p0, q0, g0), (t1, p1, q1, _) = samples[i - 1], samples[i]
    if t1 - t0 > 0.05:  # gap in the ground truth: no honest reference
        return None
    a = (t - t0) / (t1 - t0)
    if np.dot(q0, q1) < 0:
        q1 = -q1
    q = (1 - a) * q0 + a * q1
    return (1 - a) * p0 + a * p1, q / np.linalg.norm(q), g0


def angle_between(qa, qb):
    """Angle [rad] between unit quaternions: 2 atan2(|v|, |w|) of the relative quaternion conj(qa) qb (well
    conditioned near 0, unlike 2 acos(|qa . qb|))."""
    x, y, z, w = frames.quaternion_multiply((-qa[0], -qa[1], -qa[2], qa[3]), qb)
    return 2.0 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w))


def errors(models, ref):
    """(drone position error [m], camera position error [m], drone attitude error [rad]) of world models
    against an interpolated ground-truth reference (camera reference: ground_truth.camera_pose)."""
    position, q, gimbal = ref
    roll, pitch, yaw = frames.quaternion_to_euler(*q)
    cam_position, _ = camera_pose(position, roll, pitch, yaw, gimbal[0], gimbal[1])
    return (float(np.linalg.norm(models[DRONE][0] - position)),
            float(np.linalg.norm(models['anafi_camera'][0] - np.array(cam_position))),
            angle_between(models[DRONE][1], q))


class Recorder(object):
    """Collects ground truth, gimbal angles, the mirror's stream and the world's model states."""

    def __init__(self):
        self.lock = threading.Lock()
        self.recording = False
        self.gt = []            # (stamp, position, quaternion, gimbal)
        self.gt_by_position = {}  # exact position tuple -> stamp
        self.gimbal = (0.0, 0.0)
        self.sent = []          # (exact drone position sent by the mirror, receipt time)
        self.world = []         # (receipt time, {name: (position, quaternion)})
        self.latest_world = {}
        self.diag = {}
        rospy.Subscriber('/%s/ground_truth/odom' % DRONE, Odometry, self.on_odom, tcp_nodelay=True)
        rospy.Subscriber('/%s/ground_truth/drone_data' % DRONE, DroneData, self.on_data, tcp_nodelay=True)
        rospy.Subscriber('/gazebo/set_model_state', gazebo_types.model_state_class(), self.on_set,
                         tcp_nodelay=True, queue_size=200)
        rospy.Subscriber('/gazebo/model_states', gazebo_types.model_states_class(), self.on_states,
                         tcp_nodelay=True, queue_size=200)
        rospy.Subscriber('/diagnostics', DiagnosticArray, self.on_diag, queue_size=50)

    def on_odom(self, msg):
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        stamp = msg.header.stamp.to_sec()
        with self.lock:
            self.gt_by_position[(p.x, p.y, p.z)] = stamp
            if self.recording:
                self.gt.append((stamp, np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w]), self.gimbal))

    def on_data(self, msg):
        with self.lock:
            self.gimbal = (msg.gimbalRollMotorAngle, msg.gimbalPitchMotorAngle)

    def on_set(self, msg):
        now = rospy.get_time()
        if msg.model_name != DRONE:
            return
        key = (msg.pose.position.x, msg.pose.position.y, msg.pose.position.z)
        with self.lock:
            if self.recording:  # matched afterwards: the odom callback may run after this one
                self.sent.append((key, now))

    def on_states(self, msg):
        now = rospy.get_time()
        models = dict((n, (np.array([p.position.x, p.position.y, p.position.z]),
                           np.array([p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w])))
                      for n, p in zip(msg.name, msg.pose))
        with self.lock:
            self.latest_world = models
            if self.recording:
                self.world.append((now, models))

    def on_diag(self, msg):
        with self.lock:
            for status in msg.status:
                self.diag[status.name] = status

    def names(self):
        with self.lock:
            return set(self.latest_world)

    def status(self, fragment):
        with self.lock:
            for name, status in self.diag.items():
                if fragment in name:
                    return status
        return None


class TestMirror(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_mirror')
        cls.rec = Recorder()
        cls.rpyt = rospy.Publisher('/%s/drone/rpyt' % DRONE, piloting_command_class(), queue_size=10)
        cls.new_world = None
        rospy.wait_for_service('/gazebo/get_model_properties', timeout=30.0)
        cls.properties = rospy.ServiceProxy('/gazebo/get_model_properties',
                                            gazebo_types.get_model_properties_class())

    @classmethod
    def tearDownClass(cls):
        if cls.new_world is not None:
            stop(cls.new_world, grace=10.0)

    def command(self, gaz=0.0, yaw_rate_deg=0.0):
        msg = piloting_command_class()()
        msg.header.stamp = rospy.Time.now()
        msg.gaz, msg.yaw = gaz, yaw_rate_deg
        self.rpyt.publish(msg)

    def fly(self, seconds, gaz, yaw_rate_deg):
        end = time.time() + seconds
        while time.time() < end:
            self.command(gaz, yaw_rate_deg)
            time.sleep(0.1)

    # ------------------------------------------------------------------------------------------
    def test_1_models_spawned_without_gravity_or_collisions(self):
        self.assertTrue(wait_for(lambda: set(MODELS) <= self.rec.names(), 30.0),
                        'models not in /gazebo/model_states: %s' % self.rec.names())
        for name in MODELS:
            res = self.properties(model_name=name)
            self.assertTrue(res.success, res.status_message)
            self.assertEqual(list(res.geom_names), [], '%s has collision geometry' % name)
            self.assertTrue(res.body_names, name)
            self.assertFalse(res.is_static)
            # the world's own report of the spawned model (diagnostics, 1 Hz)
            self.assertTrue(wait_for(lambda: self.rec.status('kinematic_world: model %s' % name) is not None, 5.0))
            status = self.rec.status('kinematic_world: model %s' % name)
            values = dict((kv.key, kv.value) for kv in status.values)
            self.assertEqual(values['gravity_links'], '', status.message)
            self.assertEqual(values['geom_names'], '', status.message)
            self.assertIn('gravity off', status.message)
        # the mirror reports itself healthy
        self.assertTrue(wait_for(lambda: self.rec.status('gazebo mirror') is not None
                                 and self.rec.status('gazebo mirror').level == 0, 10.0),
                        getattr(self.rec.status('gazebo mirror'), 'message', 'no mirror diagnostics'))

    def test_2_mirrored_poses_equal_ground_truth_and_every_sample_is_forwarded(self):
        self.assertTrue(wait_for(lambda: set(MODELS) <= self.rec.names(), 30.0))
        self.fly(2.0, 0.0, 0.0)  # settle (take-off done)
        with self.rec.lock:
            self.rec.recording = True
        self.fly(6.0, 0.3, 30.0)  # climb at 0.3 m/s while yawing at 30 deg/s
        with self.rec.lock:
            self.rec.recording = False
        self.command(0.0, 0.0)
        gt = sorted(self.rec.gt, key=lambda s: s[0])
        self.assertGreater(len(gt), 400, 'too little ground truth: %d samples in 6 s' % len(gt))
        climb = gt[-1][1][2] - gt[0][1][2]
        self.assertGreater(climb, 0.5, 'the drone did not move (climbed %.2f m)' % climb)

        # Each world state is compared with the ground-truth trajectory from LAG_WINDOW before its receipt to
        # MATCH_WINDOW after (the world shows the pose of a sample some ms old, extrapolated with its twist;
        # how old depends on the load: a performance figure, bench_mirror.py's): the mirrored pose must BE a
        # ground-truth pose (behaviour: no offset, no frame error); the error at the same instant is printed.
        # The best instant by the drone's position (vectorised, 1 ms grid), then the full errors there +-2 ms.
        gt_t = np.array([s[0] for s in gt])
        gt_p = np.array([s[1] for s in gt])
        best, aligned = [], []
        for t, models in self.rec.world:
            if DRONE not in models or 'anafi_camera' not in models:
                continue
            grid = np.arange(t - LAG_WINDOW, t + MATCH_WINDOW, 0.001)
            grid = grid[(grid > gt_t[0]) & (grid < gt_t[-1])]
            if not len(grid):
                continue
            path = np.stack([np.interp(grid, gt_t, gt_p[:, k]) for k in range(3)], axis=1)
            t_best = grid[int(np.argmin(np.linalg.norm(path - models[DRONE][0], axis=1)))]
            candidates = [errors(models, ref) for ref in (interpolate(gt, t_best + 0.001 * j) for j in range(-2, 3))
                          if ref is not None]
            ref = interpolate(gt, t)
            if ref is not None:
                aligned.append(errors(models, ref))
            if candidates:
                best.append(min(candidates, key=lambda e: e[0]))
        self.assertGreater(len(best), 400, 'too few world states compared: %d' % len(best))
        best, aligned = np.array(best), np.array(aligned)
        print('mirrored vs ground truth (best match -%.0f..+%.0f ms): drone max %.2f mm, camera max %.2f mm, '
              'attitude max %.3f deg over %d world states; same instant: drone max %.2f mm, p99 %.2f mm'
              % (1e3 * LAG_WINDOW, 1e3 * MATCH_WINDOW, 1e3 * best[:, 0].max(), 1e3 * best[:, 1].max(),
                 math.degrees(best[:, 2].max()), len(best), 1e3 * aligned[:, 0].max(),
                 1e3 * np.percentile(aligned[:, 0], 99)))
        self.assertLess(best[:, 0].max(), 0.01)
        self.assertLess(best[:, 1].max(), 0.01)
        self.assertLess(math.degrees(best[:, 2].max()), 1.0)

        with self.rec.lock:
            lags = np.array([t - self.rec.gt_by_position[key] for key, t in self.rec.sent
                             if key in self.rec.gt_by_position])
            unmatched = len(self.rec.sent) - len(lags)
        self.assertGreater(len(lags), 400, 'too few mirrored samples matched: %d (%d unmatched)'
                           % (len(lags), unmatched))
        p99 = float(np.percentile(lags, 99))
        print('mirror lag (ground-truth stamp -> /gazebo/set_model_state receipt): p50 %.2f ms, p99 %.2f ms, '
              'max %.2f ms, n %d, %.1f Hz' % (1e3 * np.percentile(lags, 50), 1e3 * p99, 1e3 * lags.max(),
                                              len(lags), len(lags) / 6.0))
        # The lag is a performance figure (benchmarks/bench_mirror.py, results/mirror.md), printed above, not
        # asserted: on a loaded machine it grows. The behaviour: every ground-truth sample (100 Hz) is forwarded
        # (not decimated to an update cycle), bar a few dropped under load
        self.assertGreater(len(lags), 0.9 * len(gt), '%d of %d ground-truth samples mirrored' % (len(lags), len(gt)))

    def test_3_gravity_on_copy_sags_gravity_off_does_not(self):
        with open(ANAFI_URDF) as f:
            xml_off = f.read()
        xml_on = urdf_model.set_gravity(xml_off, True)
        self.assertTrue(urdf_model.parse_urdf(xml_on).has_gravity)
        spawn = rospy.ServiceProxy('/gazebo/spawn_urdf_model', gazebo_types.spawn_model_class())
        delete = rospy.ServiceProxy('/gazebo/delete_model', gazebo_types.delete_model_class())
        ModelState = gazebo_types.model_state_class()
        pub = rospy.Publisher('/gazebo/set_model_state', ModelState, queue_size=10)
        copies = {'anafi_gravity_on': (xml_on, (5.0, 5.0, 5.0)), 'anafi_gravity_off': (xml_off, (6.0, 5.0, 5.0))}
        for name, (xml, xyz) in copies.items():
            res = spawn(model_name=name, model_xml=xml, robot_namespace='/test', initial_pose=pose(*xyz),
                        reference_frame='world')
            self.assertTrue(res.success, res.status_message)
        try:
            self.assertTrue(wait_for(lambda: set(copies) <= self.rec.names(), 5.0))
            with self.rec.lock:
                self.rec.world = []
                self.rec.recording = True
            for _ in range(20):  # 10 Hz updates for 2 s, like a slow mirror
                for name, (_, xyz) in copies.items():
                    pub.publish(ModelState(model_name=name, pose=pose(*xyz), twist=Twist(), reference_frame='world'))
                time.sleep(0.1)
            with self.rec.lock:
                self.rec.recording = False
            sag = {}
            for name, (_, xyz) in copies.items():
                zs = [models[name][0][2] for _, models in self.rec.world if name in models]
                self.assertGreater(len(zs), 100)
                sag[name] = xyz[2] - min(zs)
            print('sag between 10 Hz updates: gravity on %.1f mm, gravity off %.3f mm'
                  % (1e3 * sag['anafi_gravity_on'], 1e3 * sag['anafi_gravity_off']))
            self.assertGreater(sag['anafi_gravity_on'], 0.02)   # 0.5 g (0.1 s)^2 = 49 mm at most
            self.assertLess(abs(sag['anafi_gravity_off']), 1e-4)
            status = self.rec.status('kinematic_world: model anafi_gravity_on')
            if status is not None:
                self.assertIn('gravity ON', status.message)
        finally:
            for name in copies:
                delete(model_name=name)

    def test_4_mirror_survives_world_restart_and_respawns(self):
        self.assertTrue(wait_for(lambda: set(MODELS) <= self.rec.names(), 10.0))
        mirror_pid = node_pid('/%s/gazebo_mirror' % DRONE)
        world_pid = node_pid('/gazebo')
        self.assertIsNotNone(mirror_pid)
        self.assertIsNotNone(world_pid)
        os.kill(world_pid, signal.SIGKILL)  # the world started by this test's launch file
        with self.rec.lock:
            self.rec.latest_world = {}
        time.sleep(1.5)
        self.assertEqual(node_pid('/%s/gazebo_mirror' % DRONE), mirror_pid, 'the mirror died with the world')
        started = time.time()
        # world.launch respawns the world (respawn="true", 1 s); a launch without respawn: start one ourselves
        # (never both: two nodes named /gazebo would kill each other)
        if not wait_for(lambda: node_pid('/gazebo') not in (None, world_pid), 6.0):
            script = os.path.join(PKG, 'anafi_sim', 'scripts', 'kinematic_world_node.py')
            type(self).new_world = subprocess.Popen([sys.executable, script, '__name:=gazebo'])
        # the clock starts when the new world serves spawn_urdf_model (its own start-up is not the mirror's)
        rospy.wait_for_service('/gazebo/spawn_urdf_model', timeout=30.0)
        serving = time.time()
        back = wait_for(lambda: set(MODELS) <= self.rec.names(), 10.0)
        elapsed = time.time() - serving
        print('models back %.2f s after the new world served spawn_urdf_model (%.2f s after its start)'
              % (elapsed, time.time() - started))
        self.assertTrue(back, 'models not respawned: %s' % self.rec.names())
        self.assertLess(elapsed, 5.0)
        self.assertEqual(node_pid('/%s/gazebo_mirror' % DRONE), mirror_pid)
        # and mirroring resumed: the world's drone follows the ground truth again
        self.fly(1.0, 0.3, 0.0)
        with self.rec.lock:
            world = dict(self.rec.latest_world)
            stamps = sorted(self.rec.gt_by_position.items(), key=lambda kv: kv[1])
        self.assertIn(DRONE, world)
        self.assertLess(np.linalg.norm(world[DRONE][0] - np.array(stamps[-1][0])), 0.05)


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'test_mirror', TestMirror, sys.argv)
