#!/usr/bin/env python3
"""rostest (compat.test): the paper authors' own nodes on our stand-in, played by minimal clients of ours.

The clients use only the reference implementation's types, names and parameters as the shared interface
notes give them (shared/interfaces/anafi_ros.md, sphinx_telemetry.md): their message classes are built here
from the notes' definitions (not from anafi_sim's wire types) and must have the notes' md5sums, so a
connection that works here works with their packages. Checks, in order:

1. names and types: position_control/state_enu is anafi_control/State, position_control/waypoint (our
   trajectory generator with ~waypoint_type anafi_control) is anafi_control/Waypoint and both connect to
   their classes; state_enu as their bridge fork fills it (frame ids "/world", pose = drone/pose_enu of the
   same step, twist.linear = drone/speed (north-west-up) in ENU, angular 0); /<drone>/sphinx_interface_node/publish_hz = 100;
2. their MPC (a P controller on state_enu and their waypoint, commanding drone/rpyt with header.stamp 0 at
   10 Hz wall, /use_sim_time false) flies the drone to the waypoint: the lockstep takes the unstamped
   commands at their arrival and says so on /diagnostics;
3. their interface runs `tlm-data-logger -r 4 inet:127.0.0.1:PORT` by name, with PATH extended as the
   README says, and reads Sphinx's keys (PORT: Sphinx's 9060 under compat.launch's default; compat.test runs it
   with telemetry_port:=0, so the port the simulator announces on anafi_sim/telemetry_bound_port);
4. their mirror's inputs: tf world -> anafi/body_fixed equals ground_truth/odom; camera/attitude has
   frame_id "/body";
5. our mirror poses the camera model from camera/attitude: at the waypoint's 120 deg heading the camera
   model's world yaw is the bridge's heading and its pitch the gimbal's (0) within 0.5 deg;
6. our controller and evaluator take their waypoint type: commands on compat/our_rpyt, a final summary.
"""
import math
import os
import shutil
import subprocess
import threading
import time
import unittest

import genpy.dynamic
import rospy
import rostest
import tf2_ros
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, QuaternionStamped, Vector3Stamped
from nav_msgs.msg import Odometry
from std_msgs.msg import String

NS = '/anafi/'
WAYPOINT = (1.0, 1.0, 1.5, 120.0)       # test/ros/compat_static.yaml
SEP = '=' * 80 + '\n'

# --- their types, from the shared interface notes --------------------------------------------------------
HEADER = 'MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n'
VECTOR3 = 'MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n'
DEFINITIONS = {
    'anafi_control/Waypoint': ('float64 x\nfloat64 y\nfloat64 z\nfloat64 v_x\nfloat64 v_y\nfloat64 v_z\n'
                               'float64 yaw\n', 'c72c4e4d66b8cdce8f9bcb0dbae36dca'),
    'anafi_control/State': (SEP.join([
        'std_msgs/Header header\ngeometry_msgs/PoseStamped pose\nanafi_control/TwistStampedModified twist\n',
        HEADER,
        'MSG: geometry_msgs/PoseStamped\nstd_msgs/Header header\ngeometry_msgs/Pose pose\n',
        'MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n',
        'MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n',
        'MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n',
        'MSG: anafi_control/TwistStampedModified\nstd_msgs/Header header\nanafi_control/TwistModified twist\n',
        'MSG: anafi_control/TwistModified\ngeometry_msgs/Vector3Stamped linear\ngeometry_msgs/Vector3Stamped '
        'angular\n',
        'MSG: geometry_msgs/Vector3Stamped\nstd_msgs/Header header\ngeometry_msgs/Vector3 vector\n',
        VECTOR3]), 'e65cd25dc6c41d22d5b47104c1dfbd7b'),
    'olympe_bridge/PilotingCommand': (SEP.join([
        'std_msgs/Header header\nfloat32 roll\nfloat32 pitch\nfloat32 yaw\nfloat32 gaz\n', HEADER]),
        '38956f4c725541081234f467b900164a'),
}


def their_class(name):
    text, md5 = DEFINITIONS[name]
    cls = genpy.dynamic.generate_dynamic(name, text)[name]
    assert cls._md5sum == md5, (name, cls._md5sum)
    return cls


Waypoint, State, PilotingCommand = (their_class(n) for n in
                                    ('anafi_control/Waypoint', 'anafi_control/State', 'olympe_bridge/PilotingCommand'))


def clamp(v, limit):
    return max(-limit, min(limit, v))


def yaw_of(q):
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def pitch_of(q):
    return math.asin(max(-1.0, min(1.0, 2.0 * (q.w * q.y - q.z * q.x))))


def wrap_deg(a):
    return (a + 180.0) % 360.0 - 180.0


class TheirMpc(object):
    """Stands in for the reference implementation's controller: reads its rate parameter, closes the loop on
    position_control/state_enu and their waypoint, commands drone/rpyt at 10 Hz of wall time (their launch
    files set /use_sim_time false) and leaves header.stamp at 0, as theirs does."""

    def __init__(self):
        self.publish_hz = rospy.get_param(NS + 'sphinx_interface_node/publish_hz', None)
        self.lock = threading.Lock()
        self.state = self.waypoint = None
        self.states = self.waypoints = self.commands = 0
        self.pub = rospy.Publisher(NS + 'drone/rpyt', PilotingCommand, queue_size=5)
        rospy.Subscriber(NS + 'position_control/state_enu', State, self._on_state, queue_size=5)
        rospy.Subscriber(NS + 'position_control/waypoint', Waypoint, self._on_waypoint, queue_size=5)
        self.timer = rospy.Timer(rospy.Duration(0.1), self._cycle)

    def _on_state(self, msg):
        with self.lock:
            self.state = msg
            self.states += 1

    def _on_waypoint(self, msg):
        with self.lock:
            self.waypoint = msg
            self.waypoints += 1

    def _cycle(self, _event):
        with self.lock:
            s, w = self.state, self.waypoint
        if s is None or w is None:
            return
        p, v = s.pose.pose.position, s.twist.twist.linear.vector
        yaw = yaw_of(s.pose.pose.orientation)
        ex, ey, ez = w.x - p.x, w.y - p.y, w.z - p.z
        c, si = math.cos(yaw), math.sin(yaw)
        fwd, left = c * ex + si * ey, -si * ex + c * ey                # error in the stability axes
        v_fwd, v_left = c * v.x + si * v.y, -si * v.x + c * v.y
        cmd = PilotingCommand()                                        # header.stamp stays 0
        cmd.pitch = clamp(6.0 * fwd - 5.0 * v_fwd, 8.0)               # + = nose down = forward
        cmd.roll = -clamp(6.0 * left - 5.0 * v_left, 8.0)             # + = right = -left
        cmd.yaw = clamp(1.5 * wrap_deg(w.yaw - math.degrees(yaw)), 60.0)
        cmd.gaz = clamp(1.0 * ez, 1.0)
        self.pub.publish(cmd)
        self.commands += 1


class Latest(object):
    """The latest message (and all of a few) of some topics."""

    def __init__(self):
        self.lock = threading.Lock()
        self.last = {}
        self.pose_by_stamp = {}
        self.speed_by_stamp = {}
        self.our_commands = 0

    def put(self, key, msg):
        with self.lock:
            self.last[key] = msg
            by_stamp = {'pose_enu': self.pose_by_stamp, 'speed': self.speed_by_stamp}.get(key)
            if by_stamp is not None:
                by_stamp[msg.header.stamp] = msg
                if len(by_stamp) > 200:
                    by_stamp.pop(min(by_stamp))

    def get(self, key):
        with self.lock:
            return self.last.get(key)


def diagnostic_values(status):
    return dict((kv.key, kv.value) for kv in status.values)


class TestCompat(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('their_nodes', anonymous=True)
        cls.latest = latest = Latest()
        from anafi_sim.ros.wire_types import piloting_command_class     # our controller's output (ours)

        def keep(key):
            return lambda m: latest.put(key, m)

        def count_ours(_msg):
            with latest.lock:
                latest.our_commands += 1
        for key, topic, cls_ in (('pose_enu', 'drone/pose_enu', PoseStamped), ('speed', 'drone/speed', Vector3Stamped),
                                 ('camera', 'camera/attitude', QuaternionStamped),
                                 ('truth', 'ground_truth/odom', Odometry), ('state_enu', 'position_control/state_enu', State),
                                 ('summary', 'evaluation/summary', String)):
            rospy.Subscriber(NS + topic, cls_, keep(key), queue_size=50)
        rospy.Subscriber(NS + 'compat/our_rpyt', piloting_command_class(), count_ours, queue_size=10)
        cls.diagnostics = {}

        def on_diag(msg):
            for status in msg.status:
                cls.diagnostics[status.name] = status
        rospy.Subscriber('/diagnostics', DiagnosticArray, on_diag, queue_size=50)
        cls.tf = tf2_ros.Buffer()
        cls.tf_listener = tf2_ros.TransformListener(cls.tf)
        deadline = time.time() + 30.0
        while time.time() < deadline and not rospy.has_param(NS + 'sphinx_interface_node/publish_hz'):
            time.sleep(0.1)
        cls.mpc = TheirMpc()

    def wait(self, predicate, timeout, what):
        deadline = time.time() + timeout
        while time.time() < deadline and not rospy.is_shutdown():
            if predicate():
                return
            time.sleep(0.05)
        self.fail('timed out after %g s waiting for %s' % (timeout, what))

    def sim_status(self):
        for name, status in self.diagnostics.items():
            if name.startswith('anafi_sim: simulated Anafi'):
                return status
        return None

    # ------------------------------------------------------------------------------------------------
    def test_1_names_types_and_state_enu(self):
        self.assertEqual(self.mpc.publish_hz, 100.0)
        self.wait(lambda: self.mpc.states > 10 and self.mpc.waypoints > 3, 40.0,
                  'state_enu and their waypoint type to connect')
        types = dict(rospy.get_published_topics())
        self.assertEqual(types[NS + 'position_control/state_enu'], 'anafi_control/State')
        self.assertEqual(types[NS + 'position_control/waypoint'], 'anafi_control/Waypoint')
        self.wait(lambda: self.latest.get('state_enu') is not None, 5.0, 'state_enu')
        s = self.latest.get('state_enu')
        for header in (s.header, s.pose.header, s.twist.header, s.twist.twist.linear.header):
            self.assertEqual(header.frame_id, '/world')
        a = s.twist.twist.angular.vector
        self.assertEqual((a.x, a.y, a.z), (0.0, 0.0, 0.0))
        def of_the_step(by_stamp):     # the other topics' messages of the step may arrive after state_enu's
            with self.latest.lock:
                return by_stamp.get(s.header.stamp) is not None
        self.wait(lambda: of_the_step(self.latest.pose_by_stamp) and of_the_step(self.latest.speed_by_stamp), 5.0,
                  'drone/pose_enu and drone/speed of the same step as state_enu')
        with self.latest.lock:
            pose = self.latest.pose_by_stamp.get(s.header.stamp)
        self.assertIsNotNone(pose, 'no drone/pose_enu of the same step as state_enu')
        def numbers(pose):
            return (pose.position.x, pose.position.y, pose.position.z, pose.orientation.x, pose.orientation.y,
                    pose.orientation.z, pose.orientation.w)
        self.assertEqual(numbers(pose.pose), numbers(s.pose.pose))
        with self.latest.lock:
            speed = self.latest.speed_by_stamp.get(s.header.stamp)
        self.assertIsNotNone(speed, 'no drone/speed of the same step as state_enu')
        v = s.twist.twist.linear.vector
        # drone/speed is north-west-up as on the real bridge; state_enu's twist the same velocity in ENU
        self.assertEqual(speed.header.frame_id, '/world')
        self.assertEqual((v.x, v.y, v.z), (-speed.vector.y, speed.vector.x, speed.vector.z))

    def test_2_their_mpc_flies_in_lockstep_on_unstamped_commands(self):
        x, y, z, yaw = WAYPOINT

        def arrived():
            s = self.latest.get('state_enu')
            if s is None:
                return False
            p = s.pose.pose.position
            return (math.sqrt((p.x - x) ** 2 + (p.y - y) ** 2 + (p.z - z) ** 2) < 0.25
                    and abs(wrap_deg(math.degrees(yaw_of(s.pose.pose.orientation)) - yaw)) < 5.0)
        self.wait(arrived, 60.0, 'their MPC to bring the drone to the waypoint')
        self.wait(lambda: self.sim_status() is not None, 5.0, 'the simulator diagnostics')
        status = self.sim_status()
        values = diagnostic_values(status)
        self.assertIn('unstamped commands, taken at their arrival time', status.message)
        self.assertEqual(values['lockstep'], 'lockstep')
        self.assertGreater(int(values['lockstep periods waited']), 10)
        self.assertGreater(int(values['lockstep unstamped commands (taken at arrival)']), 10)

    def test_3_tlm_data_logger_by_name(self):
        libexec = subprocess.check_output(['catkin_find', '--libexec', '--first-only', 'anafi_sim'],
                                          universal_newlines=True).strip()
        path = os.environ.get('PATH', '') + os.pathsep + libexec       # appended: a real Sphinx tool would win
        self.assertEqual(shutil.which('tlm-data-logger', path=path), os.path.join(libexec, 'tlm-data-logger'))
        self.wait(lambda: rospy.has_param(NS + 'anafi_sim/telemetry_bound_port'), 30.0,
                  'the simulator to announce its telemetry port')
        port = rospy.get_param(NS + 'anafi_sim/telemetry_bound_port')
        proc = subprocess.Popen(['tlm-data-logger', '-r', '4', 'inet:127.0.0.1:%d' % port], stdout=subprocess.PIPE,
                                env=dict(os.environ, PATH=path), universal_newlines=True)
        values = {}
        try:
            deadline = time.time() + 10.0
            while time.time() < deadline and 'gimbal_pitch_anafi.motor_angle' not in values:
                line = proc.stdout.readline()
                if not line:
                    break
                if ':' in line:
                    key, _, value = line.partition(':')
                    values[key.strip()] = value.strip()
        finally:
            proc.kill()
            proc.wait()
            proc.stdout.close()
        self.assertIn('omniscient_anafi.worldPosition.z', values)
        self.assertGreater(float(values['omniscient_anafi.worldPosition.z']), 0.5)
        self.assertIn('gimbal_pitch_anafi.motor_angle', values)

    def test_4_body_fixed_and_camera_frame(self):
        truth = self.latest.get('truth')
        self.assertIsNotNone(truth)
        t = self.tf.lookup_transform('world', 'anafi/body_fixed', truth.header.stamp, rospy.Duration(2.0))
        p, q = truth.pose.pose.position, truth.pose.pose.orientation
        tr, rot = t.transform.translation, t.transform.rotation
        self.assertAlmostEqual(tr.x, p.x, places=6)
        self.assertAlmostEqual(tr.y, p.y, places=6)
        self.assertAlmostEqual(tr.z, p.z, places=6)
        self.assertAlmostEqual(abs(rot.x * q.x + rot.y * q.y + rot.z * q.z + rot.w * q.w), 1.0, places=9)
        self.assertEqual(self.latest.get('camera').header.frame_id, '/body')

    def test_5_our_mirror_poses_the_camera_from_camera_attitude(self):
        from anafi_sim.ros import gazebo_types
        get_state = rospy.ServiceProxy('/gazebo/get_model_state', gazebo_types.get_model_state_class())
        rospy.wait_for_service('/gazebo/get_model_state', 10.0)
        # the bridge's heading: the yaw of drone/pose_enu (the estimate the camera attitude comes from)
        camera = get_state(model_name='anafi_camera', relative_entity_name='world')
        drone = get_state(model_name='anafi', relative_entity_name='world')
        estimate = self.latest.get('pose_enu')
        self.assertTrue(camera.success and drone.success)
        cam_yaw = math.degrees(yaw_of(camera.pose.orientation))
        est_yaw = math.degrees(yaw_of(estimate.pose.orientation))
        self.assertLess(abs(wrap_deg(cam_yaw - est_yaw)), 0.5, (cam_yaw, est_yaw))
        self.assertLess(abs(math.degrees(pitch_of(camera.pose.orientation))), 0.5)
        self.assertLess(abs(wrap_deg(cam_yaw - WAYPOINT[3])), 5.0)    # a quarter turn off would be 90 deg
        # the model sits 0.1 m ahead of the drone model's centre, along its heading
        d = camera.pose.position
        dx, dy = d.x - drone.pose.position.x, d.y - drone.pose.position.y
        self.assertAlmostEqual(math.hypot(dx, dy), 0.1, delta=0.02)

    def test_6_our_controller_and_evaluator_take_their_waypoints(self):
        self.assertGreater(self.latest.our_commands, 10)

        def final():
            msg = self.latest.get('summary')
            return msg is not None and yaml.safe_load(msg.data).get('state') == 'final'
        self.wait(final, 60.0, 'the evaluator\'s final summary')
        summary = yaml.safe_load(self.latest.get('summary').data)
        self.assertGreater(summary['samples'], 100)
        self.assertTrue(math.isfinite(summary['estimate']['e_mu']))
        self.assertLess(summary['estimate']['e_mu'], 1.0)


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'test_compat', TestCompat)
