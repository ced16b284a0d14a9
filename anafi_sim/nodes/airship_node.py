#!/usr/bin/env python3
"""Airship node: moves the scene's airship along a scripted path in Gazebo (thin node).

Stage: scene actors (the second robot of the paper's airship demo; the drone's tracking target later).
Pure cores: anafi_sim.gazebo.airship_path.AirshipPath (pose and velocity as functions of time) and
anafi_sim.gazebo.spawn (SpawnTracker + SpawnDriver: spawning, the world-loss rule, as the mirror). The node
spawns ~urdf_file as ~model_name through <gazebo_namespace>/spawn_urdf_model (waiting and retrying while
Gazebo is absent, respawning after a restart), then at ~rate sends its state on the
<gazebo_namespace>/set_model_state topic (gazebo_msgs/ModelState, world frame) and publishes
/<model_name>/odom (nav_msgs/Odometry, frame world -> <model_name>/base_link, twist in the body frame).
Time t = ROS time since start (sim time under use_sim_time). Deletes the model on shutdown.
Parameters: anafi_sim/config/airship.yaml. Bad parameters: logfatal, exit code 2.
"""
import os
import time

import rosgraph
import rospy
from nav_msgs.msg import Odometry

import anafi_sim  # noqa: F401 (before anafi_control: checks it is the control library, README)
from anafi_control import frames
from anafi_sim import paths
from anafi_sim.gazebo.airship_path import SHAPES, AirshipPath
from anafi_sim.gazebo.spawn import SpawnDriver, SpawnTracker
from anafi_sim import names
from anafi_sim.ros import conversions, gazebo_types
from anafi_sim.ros.node import (OK, WARN, diagnostic_status, diagnostics_publisher, log_lines, private_params, run_node,
                                run_until_interrupted, start_diagnostics_thread)


def read_params():
    """~params, validated (ValueError with a clear message)."""
    r = private_params()
    p = {
        'model_name': r.string('model_name', 'airship', allow_empty=False).strip('/'),
        'rate': r.positive('rate', 50.0),
        'retry_period': r.positive('retry_period', 1.0),
        'gazebo_namespace': r.string('gazebo_namespace', names.GAZEBO_NAMESPACE).rstrip('/'),
    }
    path_args = dict((k, r.number(k, d)) for k, d in (
        ('size', 20.0), ('period', 120.0), ('altitude', 10.0), ('z_amplitude', 1.0), ('z_period', 60.0),
        ('phase', 0.0)))
    p['path'] = AirshipPath(shape=r.choice('shape', 'figure_eight', SHAPES), center=r.vector('center', [15.0, 0.0], 2),
                            **path_args)
    path = r.string('urdf_file', '') or paths.data_path('urdf', 'airship.urdf')
    if not os.path.isfile(path):
        raise ValueError('~urdf_file: no such file: %s' % path)
    with open(path) as f:
        p['urdf'] = f.read()
    return p


class AirshipNode(object):
    def __init__(self):
        self.p = p = read_params()
        ns = p['gazebo_namespace']
        self.spawn_service = names.gazebo(names.SPAWN_URDF_MODEL, ns)
        self.delete_service = names.gazebo(names.DELETE_MODEL, ns)
        self.ModelState = gazebo_types.model_state_class()
        master = rosgraph.Master(rospy.get_name())
        self.spawner = SpawnDriver(
            SpawnTracker((p['model_name'],), retry_period=p['retry_period']),
            contact=lambda timeout: rospy.wait_for_service(self.spawn_service, timeout=timeout),
            lookup=lambda: master.lookupService(self.spawn_service), spawn=self._spawn, delete=self._delete,
            service=self.spawn_service, label='airship', check_period=p['retry_period'], absent_log_period=10.0)
        self.state_pub = rospy.Publisher(names.gazebo(names.SET_MODEL_STATE, ns), self.ModelState, queue_size=10,
                                         tcp_nodelay=True)
        self.odom_pub = rospy.Publisher('/%s/odom' % p['model_name'], Odometry, queue_size=10)
        rospy.Subscriber(names.gazebo(names.MODEL_STATES, ns), gazebo_types.model_states_class(),
                         lambda msg: self.spawner.on_model_states(msg.name, time.monotonic()), queue_size=1)
        self.t0 = None
        self.published = 0
        self.diag_pub = diagnostics_publisher()
        rospy.loginfo('airship: %s along a %s (size %.1f m, lap %.0f s, altitude %.1f m) at %g Hz', p['model_name'],
                      p['path'].shape, p['path'].size, p['path'].period, p['path'].altitude, p['rate'])

    def elapsed(self):
        now = rospy.get_time()
        if self.t0 is None or now < self.t0:  # first call, or the clock went back (sim restart)
            self.t0 = now
        return now - self.t0

    def _pose(self, state):
        return conversions.pose(state.position, frames.euler_to_quaternion(0.0, 0.0, state.yaw))

    def _spawn(self, name):
        res = rospy.ServiceProxy(self.spawn_service, gazebo_types.spawn_model_class())(
            model_name=name, model_xml=self.p['urdf'], robot_namespace='/' + name,
            initial_pose=self._pose(self.p['path'].state(self.elapsed())), reference_frame='world')
        return res.success, res.status_message

    def _delete(self, name):
        res = rospy.ServiceProxy(self.delete_service, gazebo_types.delete_model_class())(model_name=name)
        return res.success, res.status_message

    def publish(self):
        s = self.p['path'].state(self.elapsed())
        pose = self._pose(s)
        name = self.p['model_name']
        if self.spawner.tracker.is_spawned(name):
            self.state_pub.publish(self.ModelState(model_name=name, pose=pose,
                                                   twist=conversions.twist(s.velocity, (0.0, 0.0, s.yaw_rate)),
                                                   reference_frame='world'))
        odom = Odometry()
        odom.header.stamp = rospy.Time.now()
        odom.header.frame_id = 'world'
        odom.child_frame_id = name + '/base_link'
        odom.pose.pose = pose
        forward, left = frames.world_to_stability(s.velocity[0], s.velocity[1], s.yaw)   # heading only
        odom.twist.twist = conversions.twist((forward, left, s.velocity[2]), (0.0, 0.0, s.yaw_rate))
        self.odom_pub.publish(odom)
        self.published += 1

    def diagnostic_statuses(self):
        """One status: OK while the airship is spawned in the world, WARN while it is not."""
        name = self.p['model_name']
        spawned = self.spawner.tracker.is_spawned(name)
        return [diagnostic_status('airship: %s' % rospy.get_name(), OK if spawned else WARN,
                                  'moving along its path' if spawned else 'not spawned (no Gazebo world?)',
                                  [('model', name), ('spawned', spawned), ('poses published', self.published),
                                   ('spawn service', self.spawn_service)], name)]

    def spin(self):
        start_diagnostics_thread(1.0, self.diagnostic_statuses, self.diag_pub)
        period = 1.0 / self.p['rate']
        while not rospy.is_shutdown():
            log_lines(self.spawner.poll())
            self.publish()
            time.sleep(period)

    def run(self):
        """spin() until SIGINT / SIGTERM, then delete the model (while ROS still works) and shut down."""
        run_until_interrupted(self.spin, lambda: log_lines(self.spawner.delete_all(timeout=2.0)), 'airship stopped')


def main():
    run_node('airship', AirshipNode, fatal_exit_code=2, disable_signals=True)
