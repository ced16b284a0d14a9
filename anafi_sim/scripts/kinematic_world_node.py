#!/usr/bin/env python3
"""Kinematic world node: our stand-in for Gazebo's ROS API (thin node over anafi_sim.gazebo.kinematic_world).

Stage: mirror -> **world**. Serves, under ~gazebo_namespace (default /gazebo)
with the real gazebo_msgs types (anafi_sim.ros.gazebo_types, wire-identical):

- services spawn_urdf_model, spawn_sdf_model (both accept URDF or minimal SDF),
  delete_model, set_model_state, get_model_state, get_model_properties;
- topic set_model_state (gazebo_msgs/ModelState, subscribed: the mirror's stream);
- topic model_states (gazebo_msgs/ModelStates) every cycle at ~rate [Hz];
- ~contacts_topic (std_msgs/String): one JSON object per contact event,
  {"event": "begin"|"end", "time": s, "model_a", "model_b", "geom_a", "geom_b", "depth": m};
- /clock (rosgraph_msgs/Clock, world time) when ~publish_clock;
- /diagnostics at ~diagnostics_rate: world counters and one status per model
  (gravity links, collision geoms, static, updates, sag, contacts).

The world runs on the wall clock scaled by ~rtf (its own loop, never on
/clock, so it can publish /clock itself). Parameters: see
anafi_sim/config/kinematic_world.yaml. Bad parameters: logfatal, exit code 2.
"""
import json
import math
import sys
import threading
import time

import rospy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from anafi_sim.ros import gazebo_types
from anafi_sim.gazebo.kinematic_world import KinematicWorld, Result
from anafi_sim.ros.params import ParamReader
from anafi_sim.ros import msgs


def read_params():
    """All ~params, validated; raises ValueError with a clear message."""
    r = ParamReader(lambda name, default: rospy.get_param('~' + name, default))
    p = {
        'rate': r.positive('rate', 100.0),
        'max_step': r.positive('max_step', 0.01),
        'max_cycle': r.positive('max_cycle', 0.1),
        'rtf': r.positive('rtf', 1.0),
        'publish_clock': r.flag('publish_clock', False),
        'gravity': r.number('gravity', 9.81, minimum=0.0),
        'ground_plane': r.flag('ground_plane', True),
        'gazebo_namespace': r.ros_name('gazebo_namespace', '/gazebo'),
        'contacts_topic': r.ros_name('contacts_topic', '/gazebo/contacts'),
        'diagnostics_rate': r.positive('diagnostics_rate', 1.0),
    }
    if p['max_cycle'] < p['max_step']:
        raise ValueError('~max_cycle (%g s) must be >= ~max_step (%g s)' % (p['max_cycle'], p['max_step']))
    return p


def _pose_values(pose):
    return ((pose.position.x, pose.position.y, pose.position.z),
            (pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w))


def _twist_values(twist):
    return ((twist.linear.x, twist.linear.y, twist.linear.z), (twist.angular.x, twist.angular.y, twist.angular.z))


def _text(value):
    if isinstance(value, float):
        return '%.6g' % value
    if isinstance(value, (list, tuple)):
        return ','.join(str(v) for v in value)
    return str(value)


class KinematicWorldNode(object):
    """Wires the KinematicWorld core to the gazebo_ros names; one lock guards the core."""

    def __init__(self, params):
        self.p = params
        self.world = KinematicWorld(gravity=params['gravity'], ground_plane=params['ground_plane'])
        self.lock = threading.Lock()
        self.overruns = 0
        self.cycles = 0
        self.topic_rejected = 0
        self.ModelStates = gazebo_types.model_states_class()
        ns = params['gazebo_namespace'].rstrip('/')
        self.state_pub = rospy.Publisher(ns + '/model_states', self.ModelStates, queue_size=1)
        self.contact_pub = rospy.Publisher(params['contacts_topic'], String, queue_size=100)
        self.diag_pub = rospy.Publisher('/diagnostics', DiagnosticArray, queue_size=10)
        self.clock_pub = rospy.Publisher('/clock', Clock, queue_size=1) if params['publish_clock'] else None
        spawn = gazebo_types.spawn_model_class()
        self.services = [
            rospy.Service(ns + '/spawn_urdf_model', spawn, self.on_spawn),
            rospy.Service(ns + '/spawn_sdf_model', spawn, self.on_spawn),
            rospy.Service(ns + '/delete_model', gazebo_types.delete_model_class(), self.on_delete),
            rospy.Service(ns + '/set_model_state', gazebo_types.set_model_state_class(), self.on_set_state),
            rospy.Service(ns + '/get_model_state', gazebo_types.get_model_state_class(), self.on_get_state),
            rospy.Service(ns + '/get_model_properties', gazebo_types.get_model_properties_class(),
                          self.on_properties),
        ]
        self.state_sub = rospy.Subscriber(ns + '/set_model_state', gazebo_types.model_state_class(),
                                          self.on_state_topic, queue_size=100)

    # ------------------------------------------------------------------ services and topic
    def _stamp(self):
        return rospy.Time.from_sec(self.world.time) if self.p['publish_clock'] else rospy.Time.now()

    def on_spawn(self, req):
        position, orientation = _pose_values(req.initial_pose)
        with self.lock:
            try:
                result = self.world.spawn(req.model_name, req.model_xml, position, orientation,
                                          req.reference_frame)
            except Exception as error:  # a parser corner we did not foresee must not kill the service
                self.world.counters['rejected'] += 1
                result = Result(False, 'SpawnModel: Failure - unreadable model_xml (%s: %s)'
                                % (type(error).__name__, error))
        (rospy.loginfo if result.success else rospy.logerr)('%s [%s]' % (result.status_message, req.model_name))
        return spawn_response(result)

    def on_delete(self, req):
        with self.lock:
            result = self.world.delete(req.model_name)
        (rospy.loginfo if result.success else rospy.logwarn)('%s [%s]' % (result.status_message, req.model_name))
        return gazebo_types.delete_model_class()._response_class(result.success, result.status_message)

    def _set(self, state):
        position, orientation = _pose_values(state.pose)
        linear, angular = _twist_values(state.twist)
        with self.lock:
            return self.world.set_state(state.model_name, position, orientation, linear, angular,
                                        state.reference_frame)

    def on_set_state(self, req):
        result = self._set(req.model_state)
        if not result.success:
            rospy.logwarn_throttle(5.0, result.status_message)
        return gazebo_types.set_model_state_class()._response_class(result.success, result.status_message)

    def on_state_topic(self, msg):
        result = self._set(msg)
        if not result.success:
            self.topic_rejected += 1
            rospy.logwarn_throttle(5.0, '%s (topic %s; %d rejected so far)'
                                   % (result.status_message, self.state_sub.name, self.topic_rejected))

    def on_get_state(self, req):
        with self.lock:
            result, state = self.world.get_state(req.model_name, req.relative_entity_name)
            stamp = self._stamp()
        res = gazebo_types.get_model_state_class()._response_class()
        res.header.stamp = stamp
        res.header.frame_id = req.relative_entity_name
        if state is not None:
            res.pose = msgs.pose(state.position, state.orientation)
            res.twist = msgs.twist(state.linear, state.angular)
        res.success, res.status_message = result.success, result.status_message
        return res

    def on_properties(self, req):
        with self.lock:
            result, props = self.world.properties(req.model_name)
        res = gazebo_types.get_model_properties_class()._response_class()
        if props is not None:
            for field in props._fields:
                setattr(res, field, getattr(props, field))
        res.success, res.status_message = result.success, result.status_message
        return res

    # ------------------------------------------------------------------ cycle
    def cycle(self, wall_dt):
        """Advance the world by wall_dt * rtf (capped, substepped) and publish states, contacts, clock."""
        dt = wall_dt * self.p['rtf']
        if dt > self.p['max_cycle']:
            dt = self.p['max_cycle']
            self.overruns += 1
        if dt <= 0.0:
            return
        substeps = max(1, int(math.ceil(dt / self.p['max_step'] - 1e-9)))
        events = []
        with self.lock:
            for _ in range(substeps):
                begun, ended = self.world.step(dt / substeps)
                events.extend(('begin', c.model_a, c.model_b, c.geom_a, c.geom_b, c.depth) for c in begun)
                events.extend(('end', a, b, '', '', 0.0) for a, b in ended)
                now = self.world.time
            states = self.world.states()
        self.cycles += 1
        if self.clock_pub is not None:
            self.clock_pub.publish(Clock(clock=rospy.Time.from_sec(now)))
        msg = self.ModelStates()
        msg.name = [name for name, _ in states]
        msg.pose = [msgs.pose(s.position, s.orientation) for _, s in states]
        msg.twist = [msgs.twist(s.linear, s.angular) for _, s in states]
        self.state_pub.publish(msg)
        for event, model_a, model_b, geom_a, geom_b, depth in events:
            self.contact_pub.publish(String(data=json.dumps({
                'event': event, 'time': round(now, 6), 'model_a': model_a, 'model_b': model_b,
                'geom_a': geom_a, 'geom_b': geom_b, 'depth': round(depth, 6)})))
            if event == 'begin':
                rospy.loginfo('contact: %s/%s touches %s/%s (depth %.3f m)', model_a, geom_a, model_b, geom_b,
                              depth)

    def publish_diagnostics(self):
        with self.lock:
            counters = dict(self.world.counters)
            names = self.world.names()
            reports = [(name, self.world.report(name)) for name in names]
            contacts = len(self.world.contacts())
            now = self.world.time
        world = DiagnosticStatus(name='kinematic_world: world', hardware_id='kinematic_world')
        world.level = DiagnosticStatus.WARN if self.overruns else DiagnosticStatus.OK
        world.message = '%d models, %d contacts now, %d contact events%s' % (
            len(names), contacts, counters['contact_events'],
            ', %d overruns (running slower than rtf)' % self.overruns if self.overruns else '')
        values = [('time', now), ('rate', self.p['rate']), ('rtf', self.p['rtf']), ('cycles', self.cycles),
                  ('overruns', self.overruns), ('current_contacts', contacts),
                  ('topic_rejected', self.topic_rejected), ('models', names)] + sorted(counters.items())
        world.values = [KeyValue(key=k, value=_text(v)) for k, v in values]
        statuses = [world]
        for name, report in reports:
            status = DiagnosticStatus(name='kinematic_world: model %s' % name, hardware_id='kinematic_world',
                                      level=DiagnosticStatus.OK)
            status.message = '%s, %s%s' % (
                'gravity ON (%s)' % ','.join(report['gravity_links']) if report['gravity_links']
                else 'gravity off', 'collision geoms %s' % ','.join(report['geom_names'])
                if report['geom_names'] else 'no collision geometry', ', static' if report['is_static'] else '')
            status.values = [KeyValue(key=k, value=_text(v)) for k, v in report.items()]
            statuses.append(status)
        array = DiagnosticArray(status=statuses)
        array.header.stamp = self._stamp()
        self.diag_pub.publish(array)

    def spin(self):
        """Wall-clock loop at ~rate (not rospy.Rate: that would wait on /clock, which we may publish)."""
        period = 1.0 / self.p['rate']
        diag_period = 1.0 / self.p['diagnostics_rate']
        last = time.monotonic()
        next_cycle = last + period
        next_diag = last
        while not rospy.is_shutdown():
            now = time.monotonic()
            try:
                self.cycle(now - last)
                if now >= next_diag:
                    self.publish_diagnostics()
                    next_diag = now + diag_period
            except rospy.ROSException:
                if rospy.is_shutdown():
                    break
                raise
            last = now
            delay = next_cycle - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
                next_cycle += period
            else:
                next_cycle = time.monotonic() + period  # behind: do not try to catch up in a burst


def spawn_response(result):
    """gazebo_msgs/SpawnModelResponse of a core Result."""
    return gazebo_types.spawn_model_class()._response_class(result.success, result.status_message)


def main():
    rospy.init_node('gazebo')
    try:
        params = read_params()
    except ValueError as error:
        rospy.logfatal('kinematic_world: bad parameter: %s', error)
        sys.exit(2)
    node = KinematicWorldNode(params)
    rospy.loginfo('kinematic_world: serving %s/* at %g Hz (rtf %g, clock %s, ground_plane %s)',
                  params['gazebo_namespace'], params['rate'], params['rtf'],
                  'on' if params['publish_clock'] else 'off', params['ground_plane'])
    node.spin()


if __name__ == '__main__':
    main()
