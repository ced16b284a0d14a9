#!/usr/bin/env python3
"""Airship node: moves the scene's airship along a scripted path in Gazebo (thin node).

Stage: scene actors (the second robot of the paper's airship demo; the drone's tracking target later).
Pure core: anafi_sim.gazebo.airship_path.AirshipPath (pose and velocity as functions of time) and
anafi_sim.gazebo.mirror.SpawnTracker (spawn bookkeeping). The node spawns ~urdf_file as ~model_name through
<gazebo_namespace>/spawn_urdf_model (waiting and retrying while Gazebo is absent, respawning after a
restart), then at ~rate sends its state on the <gazebo_namespace>/set_model_state topic
(gazebo_msgs/ModelState, world frame) and publishes /<model_name>/odom (nav_msgs/Odometry, frame world ->
<model_name>/base_link, twist in the body frame). Time t = ROS time since start (sim time under
use_sim_time). Deletes the model on shutdown. Parameters: anafi_sim/config/airship.yaml.
"""
import math
import os
import signal
import sys
import time

import rosgraph
import rospkg
import rospy
from geometry_msgs.msg import Pose, Twist
from nav_msgs.msg import Odometry

from anafi_control import frames
from anafi_sim.ros import gazebo_types
from anafi_sim.gazebo.airship_path import SHAPES, AirshipPath
from anafi_sim.gazebo.mirror import SpawnTracker


def read_params():
    """~params, validated (ValueError with a clear message)."""
    get = rospy.get_param
    p = {
        'model_name': str(get('~model_name', 'airship')).strip('/'),
        'shape': get('~shape', 'figure_eight'),
        'rate': get('~rate', 50.0),
        'retry_period': get('~retry_period', 1.0),
        'gazebo_namespace': str(get('~gazebo_namespace', '/gazebo')).rstrip('/'),
        'center': get('~center', [15.0, 0.0]),
    }
    if p['shape'] not in SHAPES:
        raise ValueError('~shape must be one of %s, got %r' % (SHAPES, p['shape']))
    for name in ('rate', 'retry_period'):
        if isinstance(p[name], bool) or not isinstance(p[name], (int, float)) or not p[name] > 0:
            raise ValueError('~%s must be a number > 0, got %r' % (name, p[name]))
    if not isinstance(p['center'], (list, tuple)) or len(p['center']) != 2:
        raise ValueError('~center must be [x, y] in m, got %r' % (p['center'],))
    path_args = dict((k, float(get('~' + k, d))) for k, d in (
        ('size', 20.0), ('period', 120.0), ('altitude', 10.0), ('z_amplitude', 1.0), ('z_period', 60.0),
        ('phase', 0.0)))
    p['path'] = AirshipPath(shape=p['shape'], center=p['center'], **path_args)
    default_urdf = os.path.join(rospkg.RosPack().get_path('anafi_sim'), 'anafi_sim', 'urdf', 'airship.urdf')
    path = get('~urdf_file', '') or default_urdf
    if not os.path.isfile(path):
        raise ValueError('~urdf_file: no such file: %s' % path)
    with open(path) as f:
        p['urdf'] = f.read()
    return p


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt('signal %d' % signum)


class AirshipNode(object):
    def __init__(self, p):
        self.p = p
        ns = p['gazebo_namespace']
        self.spawn_service, self.delete_service = ns + '/spawn_urdf_model', ns + '/delete_model'
        self.ModelState = gazebo_types.model_state_class()
        self.tracker = SpawnTracker((p['model_name'],), retry_period=p['retry_period'])
        self.master = rosgraph.Master(rospy.get_name())
        self.state_pub = rospy.Publisher(ns + '/set_model_state', self.ModelState, queue_size=10, tcp_nodelay=True)
        self.odom_pub = rospy.Publisher('/%s/odom' % p['model_name'], Odometry, queue_size=10)
        rospy.Subscriber(ns + '/model_states', gazebo_types.model_states_class(), self.on_model_states,
                         queue_size=1)
        self.t0 = None
        self._last_absent_log = None

    def on_model_states(self, msg):
        self.tracker.on_model_states(msg.name, time.monotonic())

    def check_world(self):
        try:
            uri = self.master.lookupService(self.spawn_service)
            rospy.wait_for_service(self.spawn_service, timeout=0.5)
        except Exception:
            uri = None
        now = time.monotonic()
        self.tracker.on_world(uri is not None, uri, now)
        if uri is None and (self._last_absent_log is None or now - self._last_absent_log > 10.0):
            rospy.logerr('airship: Gazebo not available (%s); retrying every %.1f s', self.spawn_service,
                         self.p['retry_period'])
            self._last_absent_log = now
        for action, name in self.tracker.due_actions(now):
            if action == 'delete':
                try:
                    rospy.ServiceProxy(self.delete_service, gazebo_types.delete_model_class())(model_name=name)
                    ok, msg = True, ''
                except Exception as error:
                    ok, msg = False, str(error)
                self.tracker.on_delete_result(name, ok, msg, time.monotonic())
                continue
            state = self.p['path'].state(self.elapsed())
            pose = Pose()
            pose.position.x, pose.position.y, pose.position.z = state.position
            (pose.orientation.x, pose.orientation.y, pose.orientation.z,
             pose.orientation.w) = frames.euler_to_quaternion(0.0, 0.0, state.yaw)
            try:
                res = rospy.ServiceProxy(self.spawn_service, gazebo_types.spawn_model_class())(
                    model_name=name, model_xml=self.p['urdf'], robot_namespace='/' + name, initial_pose=pose,
                    reference_frame='world')
                ok, msg = res.success, res.status_message
            except Exception as error:
                ok, msg = False, str(error)
            self.tracker.on_spawn_result(name, ok, msg, time.monotonic())
            (rospy.loginfo if ok else rospy.logwarn)('airship: spawn %s: %s', name, msg or 'ok')

    def elapsed(self):
        now = rospy.get_time()
        if self.t0 is None or now < self.t0:  # first call, or the clock went back (sim restart)
            self.t0 = now
        return now - self.t0

    def publish(self):
        s = self.p['path'].state(self.elapsed())
        q = frames.euler_to_quaternion(0.0, 0.0, s.yaw)
        pose = Pose()
        pose.position.x, pose.position.y, pose.position.z = s.position
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = q
        name = self.p['model_name']
        if self.tracker.is_spawned(name):
            twist = Twist()
            twist.linear.x, twist.linear.y, twist.linear.z = s.velocity
            twist.angular.z = s.yaw_rate
            self.state_pub.publish(self.ModelState(model_name=name, pose=pose, twist=twist,
                                                   reference_frame='world'))
        odom = Odometry()
        odom.header.stamp = rospy.Time.now()
        odom.header.frame_id = 'world'
        odom.child_frame_id = name + '/base_link'
        odom.pose.pose = pose
        c, sn = math.cos(s.yaw), math.sin(s.yaw)  # world -> body (heading only)
        odom.twist.twist.linear.x = c * s.velocity[0] + sn * s.velocity[1]
        odom.twist.twist.linear.y = -sn * s.velocity[0] + c * s.velocity[1]
        odom.twist.twist.linear.z = s.velocity[2]
        odom.twist.twist.angular.z = s.yaw_rate
        self.odom_pub.publish(odom)

    def spin(self):
        period = 1.0 / self.p['rate']
        next_check = time.monotonic()
        while not rospy.is_shutdown():
            if time.monotonic() >= next_check:
                self.check_world()
                next_check = time.monotonic() + self.p['retry_period']
            self.publish()
            time.sleep(period)

    def delete(self):
        if self.tracker.is_spawned(self.p['model_name']):
            try:
                rospy.ServiceProxy(self.delete_service, gazebo_types.delete_model_class())(
                    model_name=self.p['model_name'])
            except Exception as error:
                rospy.logwarn('airship: could not delete %s: %s', self.p['model_name'], error)


def main():
    rospy.init_node('airship', disable_signals=True)
    signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        p = read_params()
    except (ValueError, TypeError, rospkg.ResourceNotFound) as error:
        rospy.logfatal('airship: bad parameter: %s', error)
        rospy.signal_shutdown('bad parameter')
        sys.exit(2)
    node = AirshipNode(p)
    rospy.loginfo('airship: %s along a %s (size %.1f m, lap %.0f s, altitude %.1f m) at %g Hz', p['model_name'],
                  p['shape'], p['path'].size, p['path'].period, p['path'].altitude, p['rate'])
    try:
        node.spin()
    except KeyboardInterrupt:
        pass
    finally:
        if not rospy.is_shutdown():
            node.delete()
        rospy.signal_shutdown('airship stopped')


if __name__ == '__main__':
    main()
