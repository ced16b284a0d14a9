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
anafi_sim/config/kinematic_world.yaml. Bad parameters: logfatal, then the node stays up in ERROR
(not respawned: docs/nodes.md).
"""
import json
import threading
import time

import rospy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from anafi_sim.gazebo.kinematic_world import KinematicWorld, Result, contact_record
from anafi_sim import names
from anafi_sim.ros import conversions, gazebo_types
from anafi_sim.ros.context import NodeContext
from anafi_sim.ros.node import diagnostics_publisher, health_status, private_params, run_node, \
    start_diagnostics_thread
from anafi_sim.sim.clock import Pacer, ScaledSteps

HARDWARE_ID = 'kinematic_world'
STATE_QUEUE = 1000
"""ModelState messages the set_model_state subscriber keeps per read (rospy drops older ones silently): a
fleet's mirror sends 2 per drone per cycle, 4000/s for 20 drones at 100 Hz; 100 held 25 ms of that, and a
world thread kept off the CPU that long on a busy machine lost updates."""


def read_params(ctx):
    """All ~params of the instance ``ctx`` (a NodeContext), validated; raises ValueError with a clear message."""
    r = private_params(ctx)
    p = {
        'rate': r.positive('rate', 100.0),
        'max_step': r.positive('max_step', 0.01),
        'max_cycle': r.positive('max_cycle', 0.1),
        'rtf': r.positive('rtf', 1.0),
        'publish_clock': r.flag('publish_clock', False),
        'gravity': r.number('gravity', 9.81, minimum=0.0),
        'ground_plane': r.flag('ground_plane', True),
        'gazebo_namespace': r.ros_name('gazebo_namespace', names.GAZEBO_NAMESPACE),
        'contacts_topic': r.ros_name('contacts_topic', names.gazebo(names.CONTACTS)),
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


class KinematicWorldNode(object):
    """Wires the KinematicWorld core to the gazebo_ros names; one lock guards the core."""

    def __init__(self, ctx=None):
        self.ctx = ctx = ctx or NodeContext.process()
        self.p = params = read_params(ctx)
        self.world = KinematicWorld(gravity=params['gravity'], ground_plane=params['ground_plane'])
        self.lock = threading.Lock()
        self.steps = ScaledSteps(params['rtf'], params['max_cycle'])
        self.pacer = Pacer(1.0 / params['rate'], max_lag=0.0)   # late: no catching up, the steps grow
        self.cycles = 0
        self.topic_rejected = 0
        self.ModelStates = gazebo_types.model_states_class()
        self.states_msg = self.ModelStates()     # reused every cycle (publish serialises it at once)
        ns = params['gazebo_namespace']
        self.state_pub = ctx.publisher(names.gazebo(names.MODEL_STATES, ns), self.ModelStates, queue_size=1)
        self.contact_pub = ctx.publisher(params['contacts_topic'], String, queue_size=100)
        self.diag_pub = diagnostics_publisher(ctx=ctx)
        self.clock_pub = ctx.publisher(names.CLOCK, Clock, queue_size=1) if params['publish_clock'] else None
        spawn = gazebo_types.spawn_model_class()
        self.services = [
            ctx.service(names.gazebo(names.SPAWN_URDF_MODEL, ns), spawn, self.on_spawn),
            ctx.service(names.gazebo(names.SPAWN_SDF_MODEL, ns), spawn, self.on_spawn),
            ctx.service(names.gazebo(names.DELETE_MODEL, ns), gazebo_types.delete_model_class(), self.on_delete),
            ctx.service(names.gazebo(names.SET_MODEL_STATE, ns), gazebo_types.set_model_state_class(),
                        self.on_set_state),
            ctx.service(names.gazebo(names.GET_MODEL_STATE, ns), gazebo_types.get_model_state_class(),
                        self.on_get_state),
            ctx.service(names.gazebo(names.GET_MODEL_PROPERTIES, ns), gazebo_types.get_model_properties_class(),
                        self.on_properties),
        ]
        self.state_sub = ctx.subscriber(names.gazebo(names.SET_MODEL_STATE, ns), gazebo_types.model_state_class(),
                                        self.on_state_topic, queue_size=STATE_QUEUE)
        self.ctx.loginfo('kinematic_world: serving %s/* at %g Hz (rtf %g, clock %s, ground_plane %s)',
                         ns, params['rate'], params['rtf'], 'on' if params['publish_clock'] else 'off',
                         params['ground_plane'])

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
        (self.ctx.loginfo if result.success else self.ctx.logerr)('%s [%s]' % (result.status_message, req.model_name))
        return gazebo_types.spawn_model_class()._response_class(result.success, result.status_message)

    def on_delete(self, req):
        with self.lock:
            result = self.world.delete(req.model_name)
        (self.ctx.loginfo if result.success else self.ctx.logwarn)('%s [%s]' % (result.status_message, req.model_name))
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
            self.ctx.logwarn_throttle(5.0, result.status_message)
        return gazebo_types.set_model_state_class()._response_class(result.success, result.status_message)

    def on_state_topic(self, msg):
        result = self._set(msg)
        if not result.success:
            self.topic_rejected += 1
            self.ctx.logwarn_throttle(5.0, '%s (topic %s; %d rejected so far)'
                                      % (result.status_message, self.state_sub.name, self.topic_rejected))

    def on_get_state(self, req):
        with self.lock:
            result, state = self.world.get_state(req.model_name, req.relative_entity_name)
            stamp = self._stamp()
        res = gazebo_types.get_model_state_class()._response_class()
        res.header.stamp = stamp
        res.header.frame_id = req.relative_entity_name
        if state is not None:
            res.pose = conversions.pose(state.position, state.orientation)
            res.twist = conversions.twist(state.linear, state.angular)
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
        dt = self.steps.step(wall_dt)
        if dt <= 0.0:
            return
        with self.lock:
            events = self.world.advance(dt, self.p['max_step'])
            now = self.world.time
            states = self.world.states()
        self.cycles += 1
        if self.clock_pub is not None:
            self.clock_pub.publish(Clock(clock=rospy.Time.from_sec(now)))
        self.state_pub.publish(self._fill_states(states))
        for event in events:
            self.contact_pub.publish(String(data=json.dumps(contact_record(event))))
            if event.event == 'begin':
                self.ctx.loginfo('contact: %s/%s touches %s/%s (depth %.3f m)', event.model_a, event.geom_a,
                                 event.model_b, event.geom_b, event.depth)

    def _fill_states(self, states):
        """The reused ModelStates message holding ``states`` [(name, State)]: its Pose and Twist objects are
        updated in place (new ones only when the models changed)."""
        msg = self.states_msg
        names = [name for name, _ in states]
        if names != msg.name:
            msg.name = names
            msg.pose = [conversions.pose(s.position, s.orientation) for _, s in states]
            msg.twist = [conversions.twist(s.linear, s.angular) for _, s in states]
            return msg
        for (_, s), pose, twist in zip(states, msg.pose, msg.twist):
            p, q, v, w = pose.position, pose.orientation, twist.linear, twist.angular
            p.x, p.y, p.z = s.position
            q.x, q.y, q.z, q.w = s.orientation
            v.x, v.y, v.z = s.linear
            w.x, w.y, w.z = s.angular
        return msg

    def diagnostic_statuses(self):
        loop = [('rate', self.p['rate']), ('rtf', self.p['rtf']), ('cycles', self.cycles),
                ('overruns', self.steps.overruns), ('topic_rejected', self.topic_rejected)]
        with self.lock:
            health = self.world.health(loop, self.steps.overruns)
        return [health_status('kinematic_world: %s' % name, h, HARDWARE_ID) for name, h in health]

    def run(self):
        """Wall-clock loop at ~rate (not rospy.Rate: that would wait on /clock, which we may publish)."""
        last = time.monotonic()
        self.pacer.start(last)
        start_diagnostics_thread(1.0 / self.p['diagnostics_rate'], self.diagnostic_statuses, self.diag_pub,
                                 stamp=self._stamp, first=0.0, ctx=self.ctx)
        while not rospy.is_shutdown():
            now = time.monotonic()
            try:
                self.cycle(now - last)
            except rospy.ROSException:
                if rospy.is_shutdown():
                    break
                raise
            last = now
            delay = self.pacer.wait(time.monotonic())
            if delay > 0.0:
                time.sleep(delay)


def main():
    run_node('gazebo', KinematicWorldNode, fatal_exit_code=2, respawned=True)
