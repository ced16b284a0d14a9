#!/usr/bin/env python3
"""Gazebo mirror node: the Sphinx ground truth drives an Anafi and its camera in Gazebo (thin node).

Stage: telemetry -> interface -> **mirror** -> Gazebo (or anafi_sim's kinematic stand-in world).
Pure cores: anafi_sim.gazebo.mirror (Mirror) and anafi_sim.gazebo.spawn (SpawnTracker + SpawnDriver: spawning
and the world-loss rule, shared with the airship node). Runs in /<drone>:

- waits for <gazebo_namespace>/spawn_urdf_model (logs a clear error and retries every ~retry_period while
  it is absent; diagnostics ERROR), spawns the drone model (~urdf_file) and the camera model
  (~camera_urdf_file) as '<drone>' and '<drone>_camera' with robot_namespace /<drone>;
- on every ground_truth/odom sample (nav_msgs/Odometry, twist in the body frame) sends both model states
  (gazebo_msgs/ModelState, pose and world-frame twist), at most ~rate per second, on the asynchronous
  <gazebo_namespace>/set_model_state TOPIC, or with ~use_service the paper's per-cycle synchronous
  set_model_state SERVICE call; the camera pose uses the gimbal angles of ground_truth/drone_data, or with
  ~camera_attitude_source bridge the anafi_ros bridge's ~camera_attitude_topic (camera/attitude,
  geometry_msgs/QuaternionStamped, as the real bridge publishes it: anafi_sim.gazebo.mirror);
- never forwards non-finite or stale (~stale_timeout) samples; when the input goes stale the models
  are held (zero twist) so the world does not extrapolate them away;
- detects a Gazebo restart (spawn service endpoint changed or gone, or a model missing from
  <gazebo_namespace>/model_states) and respawns; deletes its models on shutdown (SIGINT/SIGTERM);
- /diagnostics every ~diagnostics_period: rate, lag (ground-truth stamp -> sent), rejections, spawns.

Parameters: anafi_sim/config/mirror.yaml. Bad parameters or unreadable URDFs: logfatal, then the node
stays up in ERROR (not respawned: docs/nodes.md).
"""
import os
import threading
import time

import rosgraph
import rospy
from geometry_msgs.msg import QuaternionStamped
from nav_msgs.msg import Odometry

from anafi_sim import paths
from anafi_sim.gazebo.mirror import CAMERA_ATTITUDE_SOURCES, Mirror, model_names, model_warnings, namespaced_model_xml
from anafi_sim.gazebo.spawn import SharedCheck, SpawnDriver
from anafi_sim.msg import DroneData
from anafi_sim import names
from anafi_sim.ros import conversions, gazebo_types
from anafi_sim.ros.context import NodeContext
from anafi_sim.ros.node import (diagnostics_publisher, health_status, log_lines, private_params, run_node,
                                run_until_interrupted, start_diagnostics_thread)

LOG_REPEAT = 5.0  # s between repeated "Gazebo not available" log lines
STATE_QUEUE = 100
"""ModelState messages the set_model_state publisher queues: in a fleet host every mirror shares it (rospy has one
publisher per topic and process), 2 per drone per cycle, and a full queue drops the oldest silently."""


def _load_model(path, what, ctx):
    """The model XML of ``path`` (~``what``); its warnings logged through ``ctx`` (a NodeContext)."""
    if not os.path.isfile(path):
        raise ValueError('~%s: no such file: %s' % (what, path))
    with open(path) as f:
        xml = f.read()
    try:
        warnings = model_warnings(xml)
    except ValueError as error:
        raise ValueError('~%s (%s): %s' % (what, path, error))
    for warning in warnings:
        ctx.logwarn('mirror: %s has %s', path, warning)
    return xml


def read_params(ctx):
    """All ~params of the instance ``ctx`` (a NodeContext), validated; raises ValueError with a clear message."""
    r = private_params(ctx)
    namespace = ctx.namespace.strip('/')
    p = {
        'drone_name': r.string('drone_name', namespace.split('/')[-1] if namespace else 'anafi', allow_empty=False),
        'rate': r.positive('rate', 100.0),
        'use_service': r.flag('use_service', False),
        'persistent_service': r.flag('persistent_service', False),
        'stale_timeout': r.positive('stale_timeout', 0.2),
        'retry_period': r.positive('retry_period', 1.0),
        'world_check_period': r.positive('world_check_period', 0.5),
        'missing_grace': r.number('missing_grace', 1.0, minimum=0.0),
        'drone_model_name': r.string('drone_model_name', ''),
        'camera_model_name': r.string('camera_model_name', ''),
        'spawn_camera': r.flag('spawn_camera', True),
        'reference_frame': r.string('reference_frame', 'world'),
        'gazebo_namespace': r.string('gazebo_namespace', names.GAZEBO_NAMESPACE).rstrip('/'),
        'delete_on_shutdown': r.flag('delete_on_shutdown', True),
        'diagnostics_period': r.positive('diagnostics_period', 1.0),
        'odom_topic': r.string('odom_topic', names.GROUND_TRUTH),
        'drone_data_topic': r.string('drone_data_topic', names.DRONE_DATA),
        'camera_offset': r.vector('camera_offset', [0.1, 0.0, 0.0], 3),   # [m]
        'camera_attitude_source': r.choice('camera_attitude_source', 'telemetry', CAMERA_ATTITUDE_SOURCES),
        'camera_attitude_topic': r.string('camera_attitude_topic', names.CAMERA_ATTITUDE),
    }
    p['urdf_file'] = r.string('urdf_file', '') or paths.data_path('urdf', 'anafi.urdf')
    p['camera_urdf_file'] = r.string('camera_urdf_file', '') or paths.data_path('urdf', 'anafi_camera.urdf')
    p['robot_namespace'] = r.string('robot_namespace', '') or '/' + p['drone_name'].strip('/')
    return p


class GazeboMirrorNode(object):
    """Wires the Mirror core to ROS; one lock guards the core (callbacks, the main loop and diagnostics)."""

    def __init__(self, ctx=None):
        self.ctx = ctx = ctx or NodeContext.process()
        self.p = params = read_params(ctx)
        drone_model, camera_model = model_names(params['drone_name'], params['drone_model_name'],
                                                params['camera_model_name'])
        self.models = {drone_model: namespaced_model_xml(_load_model(params['urdf_file'], 'urdf_file', ctx),
                                                         params['drone_name'])}   # {model name: xml}
        if params['spawn_camera']:
            self.models[camera_model] = namespaced_model_xml(
                _load_model(params['camera_urdf_file'], 'camera_urdf_file', ctx), params['drone_name'])
        self.core = Mirror(drone_name=params['drone_name'], rate=params['rate'],
                           stale_timeout=params['stale_timeout'], camera_offset=params['camera_offset'],
                           drone_model_name=params['drone_model_name'],
                           camera_model_name=params['camera_model_name'], spawn_camera=params['spawn_camera'],
                           retry_period=params['retry_period'], missing_grace=params['missing_grace'],
                           reference_frame=params['reference_frame'],
                           camera_attitude_source=params['camera_attitude_source'])   # validates the remaining ones
        self.lock = threading.Lock()
        ns = params['gazebo_namespace']
        self.spawn_service = names.gazebo(names.SPAWN_URDF_MODEL, ns)
        self.delete_service = names.gazebo(names.DELETE_MODEL, ns)
        self.state_service = names.gazebo(names.SET_MODEL_STATE, ns)
        self.ModelState = gazebo_types.model_state_class()
        self.SpawnModel = gazebo_types.spawn_model_class()
        self.DeleteModel = gazebo_types.delete_model_class()
        self.SetModelState = gazebo_types.set_model_state_class()
        master = rosgraph.Master(ctx.name)
        self.spawner = SpawnDriver(
            self.core.spawn, contact=lambda timeout: rospy.wait_for_service(self.spawn_service, timeout=timeout),
            lookup=lambda: master.lookupService(self.spawn_service), spawn=self._spawn, delete=self._delete,
            service=self.spawn_service, label='mirror', check_period=params['world_check_period'],
            absent_log_period=LOG_REPEAT, lock=self.lock)
        if ctx.hosted:     # the host's mirrors share one world check (the same service, master and process)
            self.spawner.shared_check = ctx.bus.shared(
                ('world check', self.spawn_service),
                lambda: SharedCheck(self.spawner.probe, 0.5 * params['world_check_period']))
        self.service_failures = 0
        self._set_proxy = None
        self.state_pub = None
        if not params['use_service']:
            self.state_pub = ctx.publisher(self.state_service, self.ModelState, queue_size=STATE_QUEUE,
                                           tcp_nodelay=True)
        self.diag_pub = diagnostics_publisher()
        self.odom_sub = ctx.subscriber(params['odom_topic'], Odometry, self.on_odom, queue_size=1, tcp_nodelay=True)
        if params['camera_attitude_source'] == 'bridge':
            self.data_sub = ctx.subscriber(params['camera_attitude_topic'], QuaternionStamped,
                                           self.on_camera_attitude, queue_size=1, tcp_nodelay=True)
        else:
            self.data_sub = ctx.subscriber(params['drone_data_topic'], DroneData, self.on_drone_data,
                                           queue_size=1, tcp_nodelay=True)
        self.states_sub = ctx.subscriber(names.gazebo(names.MODEL_STATES, ns), gazebo_types.model_states_class(),
                                         self.on_model_states, queue_size=1)
        self._last_model_states = 0.0
        self.ctx.loginfo('mirror: %s -> models %s at up to %g Hz via the %s %s', params['odom_topic'],
                         ', '.join(sorted(self.models)), params['rate'],
                         'service' if params['use_service'] else 'topic', self.state_service)

    # ------------------------------------------------------------------ callbacks
    def on_drone_data(self, msg):
        with self.lock:
            self.core.on_gimbal(msg.gimbalRollMotorAngle, msg.gimbalPitchMotorAngle, msg.header.stamp.to_sec(),
                                rospy.get_time())

    def on_camera_attitude(self, msg):
        q = msg.quaternion
        with self.lock:
            self.core.on_camera_attitude((q.x, q.y, q.z, q.w), msg.header.stamp.to_sec(), rospy.get_time())

    def on_model_states(self, msg):
        now = time.monotonic()
        if now - self._last_model_states < 0.1:  # 10 Hz is plenty for presence checks
            return
        self._last_model_states = now
        self.spawner.on_model_states(msg.name, now)

    def on_odom(self, msg):
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        v, w = msg.twist.twist.linear, msg.twist.twist.angular
        stamp = msg.header.stamp.to_sec()
        with self.lock:
            states = self.core.on_ground_truth((p.x, p.y, p.z), (q.x, q.y, q.z, q.w), (v.x, v.y, v.z),
                                               (w.x, w.y, w.z), stamp, rospy.get_time())
        if states and self.send(states):
            with self.lock:
                self.core.record_sent(stamp, rospy.get_time())

    def _message(self, state):
        return self.ModelState(model_name=state.model_name,
                               pose=conversions.pose(state.position, state.orientation),
                               twist=conversions.twist(state.linear, state.angular),
                               reference_frame=state.reference_frame)

    def send(self, states):
        """Topic: publish; service: one synchronous call per model. True when everything went out."""
        if self.state_pub is not None:
            for state in states:
                self.state_pub.publish(self._message(state))
            return True
        ok = True
        for state in states:
            try:
                if self._set_proxy is None:
                    self._set_proxy = rospy.ServiceProxy(self.state_service, self.SetModelState,
                                                         persistent=self.p['persistent_service'])
                res = self._set_proxy(self._message(state))
                if not res.success:
                    ok = False
                    self.ctx.logwarn_throttle(5.0, 'mirror: set_model_state(%s) failed: %s'
                                              % (state.model_name, res.status_message))
            except (rospy.ServiceException, rospy.ROSException, OSError) as error:
                ok = False
                self.service_failures += 1
                self._set_proxy = None
                self.ctx.logwarn_throttle(5.0, 'mirror: set_model_state service call failed (%d so far): %s'
                                          % (self.service_failures, error))
        return ok

    # ------------------------------------------------------------------ spawn calls (for the SpawnDriver)
    def _spawn(self, name):
        with self.lock:
            position, orientation = self.core.spawn_pose(name)
        request = self.SpawnModel._request_class(
            model_name=name, model_xml=self.models[name], robot_namespace=self.p['robot_namespace'],
            initial_pose=conversions.pose(position, orientation), reference_frame=self.p['reference_frame'])
        res = rospy.ServiceProxy(self.spawn_service, self.SpawnModel)(request)
        return res.success, res.status_message

    def _delete(self, name):
        res = rospy.ServiceProxy(self.delete_service, self.DeleteModel)(model_name=name)
        return res.success, res.status_message

    # ------------------------------------------------------------------ housekeeping
    def check_stale(self):
        with self.lock:
            held = self.core.check_stale(rospy.get_time())
        if held:
            self.ctx.logwarn('mirror: ground truth stale for more than %.2f s: holding the models (zero twist)',
                             self.p['stale_timeout'])
            self.send(held)

    def diagnostic_statuses(self):
        with self.lock:
            health = self.core.health(rospy.get_time())
        mode = 'service (synchronous, per cycle)' if self.p['use_service'] else 'topic (asynchronous)'
        return [health_status('%s: gazebo mirror' % self.ctx.name, health, self.p['drone_name'],
                              [('mode', mode), ('service call failures', str(self.service_failures))])]

    def spin(self):
        """Main loop (wall clock): world checks and spawns, stale holds. Returns on shutdown."""
        start_diagnostics_thread(self.p['diagnostics_period'], self.diagnostic_statuses, self.diag_pub, first=0.0,
                                 ctx=self.ctx)
        while not rospy.is_shutdown():
            log_lines(self.spawner.poll(), self.ctx)
            self.check_stale()
            time.sleep(0.05)

    def run(self):
        """spin() until SIGINT / SIGTERM, then delete the models (while ROS still works) and shut down; hosted:
        spin() only (the host calls shutdown() before ROS shuts down)."""
        if self.ctx.hosted:
            self.spin()
        else:
            run_until_interrupted(self.spin, self.delete_models, 'mirror stopped')

    def shutdown(self):
        self.delete_models()

    def delete_models(self):
        if self.p['delete_on_shutdown']:
            log_lines(self.spawner.delete_all(timeout=2.0), self.ctx)


def main():
    # Own signal handling (run()) so the models can still be deleted through ROS before rospy shuts down.
    run_node('gazebo_mirror', GazeboMirrorNode, fatal_exit_code=2, disable_signals=True, respawned=True)
