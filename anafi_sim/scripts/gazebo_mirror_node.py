#!/usr/bin/env python3
"""Gazebo mirror node: the Sphinx ground truth drives an Anafi and its camera in Gazebo (thin node).

Stage: telemetry -> interface -> **mirror** -> Gazebo (or anafi_sim's kinematic stand-in world).
Pure core: anafi_sim.gazebo.mirror (Mirror, SpawnTracker). Runs in /<drone>:

- waits for <gazebo_namespace>/spawn_urdf_model (logs a clear error and retries every ~retry_period while
  it is absent; diagnostics ERROR), spawns the drone model (~urdf_file) and the camera model
  (~camera_urdf_file) as '<drone>' and '<drone>_camera' with robot_namespace /<drone>;
- on every ground_truth/odom sample (nav_msgs/Odometry, twist in the body frame) sends both model states
  (gazebo_msgs/ModelState, pose and world-frame twist), at most ~rate per second, on the asynchronous
  <gazebo_namespace>/set_model_state TOPIC, or with ~use_service the paper's per-cycle synchronous
  set_model_state SERVICE call; the camera pose uses the gimbal angles of sphinx/drone_data;
- never forwards non-finite or stale (~stale_timeout) samples; when the input goes stale the models
  are held (zero twist) so the world does not extrapolate them away;
- detects a Gazebo restart (spawn service endpoint changed or gone, or a model missing from
  <gazebo_namespace>/model_states) and respawns; deletes its models on shutdown (SIGINT/SIGTERM);
- /diagnostics every ~diagnostics_period: rate, lag (ground-truth stamp -> sent), rejections, spawns.

Parameters: anafi_sim/config/mirror.yaml. Bad parameters or unreadable URDFs: logfatal, exit code 2.
"""
import os
import signal
import sys
import threading
import time

import rosgraph
import rospkg
import rospy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry

from anafi_sim.ros import gazebo_types

from anafi_sim.gazebo import urdf_model
from anafi_sim.interface.ground_truth import ERROR, OK, WARN
from anafi_sim.gazebo.mirror import Mirror, model_names, namespaced_model_xml
from anafi_sim.msg import DroneData
from anafi_sim.ros.params import ParamReader
from anafi_sim.ros import msgs

_LEVELS = {OK: DiagnosticStatus.OK, WARN: DiagnosticStatus.WARN, ERROR: DiagnosticStatus.ERROR}
LOG_REPEAT = 5.0  # s between repeated "Gazebo not available" log lines


def _load_model(path, what):
    if not os.path.isfile(path):
        raise ValueError('~%s: no such file: %s' % (what, path))
    with open(path) as f:
        xml = f.read()
    try:
        model = urdf_model.parse_urdf(xml)
    except urdf_model.UrdfError as error:
        raise ValueError('~%s (%s): %s' % (what, path, error))
    if model.has_gravity:
        rospy.logwarn('mirror: %s has gravity ON for links %s: it will sag between updates (the paper '
                      'switches gravity off)', path, ', '.join(model.gravity_links))
    if model.has_collisions:
        rospy.logwarn('mirror: %s has collision geometry on links %s: contacts in Gazebo cannot act on '
                      'Sphinx (the paper switches collisions off)', path, ', '.join(model.collision_links))
    return xml


def read_params():
    """All ~params, validated; raises ValueError with a clear message."""
    r = ParamReader(lambda name, default: rospy.get_param('~' + name, default))
    namespace = rospy.get_namespace().strip('/')
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
        'gazebo_namespace': r.string('gazebo_namespace', '/gazebo').rstrip('/'),
        'delete_on_shutdown': r.flag('delete_on_shutdown', True),
        'diagnostics_period': r.positive('diagnostics_period', 1.0),
        'odom_topic': r.string('odom_topic', 'ground_truth/odom'),
        'drone_data_topic': r.string('drone_data_topic', 'sphinx/drone_data'),
        'camera_offset': r.vector('camera_offset', [0.1, 0.0, 0.0], 3),   # [m]
    }
    urdf_dir = os.path.join(rospkg.RosPack().get_path('anafi_sim'), 'anafi_sim', 'urdf')
    p['urdf_file'] = r.string('urdf_file', '') or os.path.join(urdf_dir, 'anafi.urdf')
    p['camera_urdf_file'] = r.string('camera_urdf_file', '') or os.path.join(urdf_dir, 'anafi_camera.urdf')
    p['robot_namespace'] = r.string('robot_namespace', '') or '/' + p['drone_name'].strip('/')
    return p


def _call_with_timeout(function, timeout):
    """Run ``function()`` in a daemon thread; (True, result) or (False, error text) (also on timeout)."""
    box = {}

    def run():
        try:
            box['result'] = function()
        except Exception as error:  # service exceptions, shutdown, ...
            box['error'] = '%s: %s' % (type(error).__name__, error)

    thread = threading.Thread(target=run)
    thread.daemon = True
    thread.start()
    thread.join(timeout)
    if thread.is_alive():
        return False, 'no answer within %.1f s' % timeout
    if 'error' in box:
        return False, box['error']
    return True, box['result']


class GazeboMirrorNode(object):
    """Wires the Mirror core to ROS; one lock guards the core (callbacks and the main loop share it)."""

    def __init__(self, params, models):
        self.p = params
        self.models = models  # {model name: xml}
        self.core = Mirror(drone_name=params['drone_name'], rate=params['rate'],
                           stale_timeout=params['stale_timeout'], camera_offset=params['camera_offset'],
                           drone_model_name=params['drone_model_name'],
                           camera_model_name=params['camera_model_name'], spawn_camera=params['spawn_camera'],
                           retry_period=params['retry_period'], missing_grace=params['missing_grace'],
                           reference_frame=params['reference_frame'])
        self.lock = threading.Lock()
        ns = params['gazebo_namespace']
        self.spawn_service = ns + '/spawn_urdf_model'
        self.delete_service = ns + '/delete_model'
        self.state_service = ns + '/set_model_state'
        self.ModelState = gazebo_types.model_state_class()
        self.SpawnModel = gazebo_types.spawn_model_class()
        self.DeleteModel = gazebo_types.delete_model_class()
        self.SetModelState = gazebo_types.set_model_state_class()
        self.master = rosgraph.Master(rospy.get_name())
        self.service_failures = 0
        self._set_proxy = None
        self._last_absent_log = None
        self._world_missed = False
        self._last_pose = None  # spawn pose: the latest ground-truth pose
        self.state_pub = None
        if not params['use_service']:
            self.state_pub = rospy.Publisher(self.state_service, self.ModelState, queue_size=10, tcp_nodelay=True)
        self.diag_pub = rospy.Publisher('/diagnostics', DiagnosticArray, queue_size=10)
        self.odom_sub = rospy.Subscriber(params['odom_topic'], Odometry, self.on_odom, queue_size=1,
                                         tcp_nodelay=True)
        self.data_sub = rospy.Subscriber(params['drone_data_topic'], DroneData, self.on_drone_data, queue_size=1,
                                         tcp_nodelay=True)
        self.states_sub = rospy.Subscriber(ns + '/model_states', gazebo_types.model_states_class(),
                                           self.on_model_states, queue_size=1)
        self._last_model_states = 0.0

    # ------------------------------------------------------------------ callbacks
    def on_drone_data(self, msg):
        with self.lock:
            self.core.on_gimbal(msg.gimbalRollMotorAngle, msg.gimbalPitchMotorAngle, msg.header.stamp.to_sec(),
                                rospy.get_time())

    def on_model_states(self, msg):
        now = time.monotonic()
        if now - self._last_model_states < 0.1:  # 10 Hz is plenty for presence checks
            return
        self._last_model_states = now
        with self.lock:
            self.core.spawn.on_model_states(msg.name, now)

    def on_odom(self, msg):
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        v, w = msg.twist.twist.linear, msg.twist.twist.angular
        stamp = msg.header.stamp.to_sec()
        with self.lock:
            states = self.core.on_ground_truth((p.x, p.y, p.z), (q.x, q.y, q.z, q.w), (v.x, v.y, v.z),
                                               (w.x, w.y, w.z), stamp, rospy.get_time())
            if self.core.last_states:
                self._last_pose = [(s.position, s.orientation) for s in self.core.last_states]
        if states and self.send(states):
            with self.lock:
                self.core.record_sent(stamp, rospy.get_time())

    def _message(self, state):
        return self.ModelState(model_name=state.model_name, pose=msgs.pose(state.position, state.orientation),
                               twist=msgs.twist(state.linear, state.angular), reference_frame=state.reference_frame)

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
                    rospy.logwarn_throttle(5.0, 'mirror: set_model_state(%s) failed: %s'
                                           % (state.model_name, res.status_message))
            except (rospy.ServiceException, rospy.ROSException, OSError) as error:
                ok = False
                self.service_failures += 1
                self._set_proxy = None
                rospy.logwarn_throttle(5.0, 'mirror: set_model_state service call failed (%d so far): %s'
                                       % (self.service_failures, error))
        return ok

    # ------------------------------------------------------------------ world / spawning
    def world_endpoint(self):
        """URI of the reachable spawn service, or None.

        The service is contacted first and its URI looked up after: the other order can return the URI of a
        world that was killed without unregistering while the contact already reaches its successor, and the
        next check would then take that successor for one more restart.
        """
        try:
            rospy.wait_for_service(self.spawn_service, timeout=0.5)
        except rospy.ROSException:
            return None  # not registered, or registered but dead (killed without unregistering)
        try:
            return self.master.lookupService(self.spawn_service)
        except Exception:  # rosgraph.MasterError (no provider), master unreachable, ...
            return None

    def check_world(self):
        uri = self.world_endpoint()
        now = time.monotonic()
        with self.lock:
            available = self.core.spawn.world_available
        if uri is None and available and not self._world_missed:
            self._world_missed = True   # one missed check of a busy world is not a loss: confirm it next time
            return
        self._world_missed = False
        with self.lock:
            was = self.core.spawn.world_available
            restarts = self.core.spawn.world_restarts
            self.core.spawn.on_world(uri is not None, uri, now)
            restarted = self.core.spawn.world_restarts > restarts
        if uri is None:
            if was:
                rospy.logerr('mirror: Gazebo went away (%s no longer reachable); will respawn the models '
                             'when it is back', self.spawn_service)
                self._last_absent_log = now
            elif self._last_absent_log is None or now - self._last_absent_log >= LOG_REPEAT:
                rospy.logerr('mirror: Gazebo not available: service %s does not exist or does not answer. '
                             'Start Gazebo (gazebo_ros) or the kinematic world (roslaunch anafi_sim world.launch);'
                             ' retrying every %.1f s', self.spawn_service, self.p['retry_period'])
                self._last_absent_log = now
        elif restarted:
            rospy.logwarn('mirror: Gazebo restarted (%s now at %s); respawning', self.spawn_service, uri)
        elif not was:
            rospy.loginfo('mirror: Gazebo available at %s', uri)

    def do_spawn_actions(self):
        with self.lock:
            actions = self.core.spawn.due_actions(time.monotonic())
            poses = dict(zip(self.core.spawn.names, self._last_pose or []))
        for action, name in actions:
            if action == 'delete':
                ok, result = _call_with_timeout(
                    lambda n=name: rospy.ServiceProxy(self.delete_service, self.DeleteModel)(model_name=n), 5.0)
                success = ok and result.success
                message = (result.status_message if ok else result)
                with self.lock:
                    self.core.spawn.on_delete_result(name, success, message, time.monotonic())
                rospy.loginfo('mirror: deleted the existing model %s before spawning ours (%s)', name, message)
                continue
            position, orientation = poses.get(name, ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)))
            request = self.SpawnModel._request_class(
                model_name=name, model_xml=self.models[name], robot_namespace=self.p['robot_namespace'],
                initial_pose=msgs.pose(position, orientation), reference_frame=self.p['reference_frame'])
            ok, result = _call_with_timeout(
                lambda r=request: rospy.ServiceProxy(self.spawn_service, self.SpawnModel)(r), 30.0)
            success = ok and result.success
            message = result.status_message if ok else result
            with self.lock:
                before = self.core.spawn.respawns
                self.core.spawn.on_spawn_result(name, success, message, time.monotonic())
                respawn = self.core.spawn.respawns > before
            if success:
                rospy.loginfo('mirror: %s %s (%s)', 'respawned' if respawn else 'spawned', name, message)
            else:
                rospy.logwarn('mirror: spawning %s failed: %s; retrying', name, message)

    def delete_models(self):
        with self.lock:
            names = self.core.spawn.spawned_names()
        for name in names:
            ok, result = _call_with_timeout(
                lambda n=name: rospy.ServiceProxy(self.delete_service, self.DeleteModel)(model_name=n), 2.0)
            if ok and result.success:
                rospy.loginfo('mirror: deleted %s', name)
            else:
                rospy.logwarn('mirror: could not delete %s on shutdown: %s', name,
                              result.status_message if ok else result)

    # ------------------------------------------------------------------ housekeeping
    def check_stale(self):
        with self.lock:
            held = self.core.check_stale(rospy.get_time())
        if held:
            rospy.logwarn('mirror: ground truth stale for more than %.2f s: holding the models (zero twist)',
                          self.p['stale_timeout'])
            self.send(held)

    def publish_diagnostics(self):
        with self.lock:
            health = self.core.health(rospy.get_time())
        status = DiagnosticStatus(name='%s: gazebo mirror' % rospy.get_name(), hardware_id=self.p['drone_name'],
                                  level=_LEVELS[health.level], message=health.message)
        values = list(health.values) + [
            ('mode', 'service (synchronous, per cycle)' if self.p['use_service'] else 'topic (asynchronous)'),
            ('service call failures', str(self.service_failures))]
        status.values = [KeyValue(key=k, value=v) for k, v in values]
        array = DiagnosticArray(status=[status])
        array.header.stamp = rospy.Time.now()
        self.diag_pub.publish(array)

    def spin(self):
        """Main loop (wall clock): world checks, spawns, stale holds, diagnostics. Returns on shutdown."""
        next_world = next_diag = time.monotonic()
        while not rospy.is_shutdown():
            now = time.monotonic()
            if now >= next_world:
                self.check_world()
                self.do_spawn_actions()
                with self.lock:
                    available = self.core.spawn.world_available
                next_world = time.monotonic() + (self.p['world_check_period'] if available
                                                 else self.p['retry_period'])
            self.check_stale()
            if now >= next_diag:
                self.publish_diagnostics()
                next_diag = now + self.p['diagnostics_period']
            time.sleep(0.05)


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt('signal %d' % signum)


def main():
    # Own signal handling so the models can still be deleted through ROS before rospy shuts down.
    rospy.init_node('gazebo_mirror', disable_signals=True)
    signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        params = read_params()
        drone_model, camera_model = model_names(params['drone_name'], params['drone_model_name'],
                                                params['camera_model_name'])
        models = {drone_model: namespaced_model_xml(_load_model(params['urdf_file'], 'urdf_file'),
                                                    params['drone_name'])}
        if params['spawn_camera']:
            models[camera_model] = namespaced_model_xml(_load_model(params['camera_urdf_file'], 'camera_urdf_file'),
                                                        params['drone_name'])
        node = GazeboMirrorNode(params, models)  # the core validates the remaining parameters
    except (ValueError, rospkg.ResourceNotFound) as error:
        rospy.logfatal('mirror: bad parameter: %s', error)
        rospy.signal_shutdown('bad parameter')
        sys.exit(2)
    rospy.loginfo('mirror: %s -> models %s at up to %g Hz via the %s %s', params['odom_topic'],
                  ', '.join(sorted(models)), params['rate'],
                  'service' if params['use_service'] else 'topic', node.state_service)
    try:
        node.spin()
    except KeyboardInterrupt:
        pass
    finally:
        if params['delete_on_shutdown'] and not rospy.is_shutdown():
            node.delete_models()
        rospy.signal_shutdown('mirror stopped')


if __name__ == '__main__':
    main()
