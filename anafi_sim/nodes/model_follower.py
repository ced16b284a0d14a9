#!/usr/bin/env python3
"""Model follower node: a Gazebo model's pose (e.g. the airship) -> the drone's waypoint with velocity.

Stage: target -> waypoint (-> PID / MPC controller). Thin node over anafi_sim.mission.model_following.ModelFollower.

- in ~model_states_topic (default /gazebo/model_states, gazebo_msgs/ModelStates: works with Gazebo and
  with anafi_sim's kinematic world); the entry named ~model_name (airship);
- out ~waypoint_topic (default position_control/waypoint relative to the node's namespace /<drone>/,
  anafi_sim/Waypoint, or anafi_control/Waypoint with ~waypoint_type anafi_control: ENU position [m],
  velocity [m/s], yaw [deg]) at ~rate Hz (10) of ROS time, while
  the target is fresh (last seen within ~stale_timeout s, 1.0; else nothing is published, so the
  controllers hover after their waypoint timeout, and a warning says why); /diagnostics at 1 Hz (wall).

Waypoint = target position + ~offset [m] ([-6, 0, -2]: behind and below) in ~offset_frame (heading |
world), yaw by ~yaw_mode (heading | face | fixed) + ~yaw_offset [deg], velocity from ~velocity_source
(auto | twist | difference; ~smoothing [s] of the difference filter). Bad parameters: logfatal, exit 1.
"""
import threading

import rospy

from anafi_sim.mission.model_following import OFFSET_FRAMES, VELOCITY_SOURCES, YAW_MODES, ModelFollower
from anafi_sim import names
from anafi_sim.ros import gazebo_types
from anafi_sim.ros.waypoints import DEFAULT_WAYPOINT_TYPE, WAYPOINT_TYPES, waypoint_class, waypoint_message
from anafi_sim.ros.node import (OK, WARN, diagnostic_status, diagnostics_publisher, private_params, run_node,
                                start_diagnostics_thread, wait_for_clock)


class ModelFollowerNode(object):
    def __init__(self):
        p = private_params()
        self.model_name = p.string('model_name', 'airship', allow_empty=False)
        self.rate = p.positive('rate', 10.0)
        self.stale_timeout = p.positive('stale_timeout', 1.0)
        self.frame_id = p.string('frame_id', 'world')
        self.core = ModelFollower(offset=p.vector('offset', [-6.0, 0.0, -2.0], 3),
                                  offset_frame=p.choice('offset_frame', 'heading', OFFSET_FRAMES),
                                  yaw_mode=p.choice('yaw_mode', 'heading', YAW_MODES),
                                  yaw_offset=p.number('yaw_offset', 0.0),
                                  velocity_source=p.choice('velocity_source', 'auto', VELOCITY_SOURCES),
                                  smoothing=p.number('smoothing', 0.3, minimum=0.0))
        self.lock = threading.Lock()
        self.latest = None          # (t, position, orientation, linear, angular_z)
        self.consumed = None
        self.waypoint = None
        self.missing = 0
        self.published = 0
        self.state_msgs = 0
        self.waypoint_type = p.choice('waypoint_type', DEFAULT_WAYPOINT_TYPE, WAYPOINT_TYPES)
        self.pub = rospy.Publisher(p.string('waypoint_topic', names.WAYPOINT), waypoint_class(self.waypoint_type),
                                   queue_size=10)
        self.pub_diag = diagnostics_publisher(queue_size=5)
        topic = p.string('model_states_topic', names.gazebo(names.MODEL_STATES))
        rospy.Subscriber(topic, gazebo_types.model_states_class(), self._on_model_states, queue_size=1)
        rospy.loginfo('%s: following model %s from %s -> %s at %g Hz, offset %s (%s frame), yaw %s',
                      rospy.get_name(), self.model_name, rospy.resolve_name(topic),
                      rospy.resolve_name(self.pub.name), self.rate, list(self.core.offset), self.core.offset_frame,
                      self.core.yaw_mode)

    def _on_model_states(self, msg):
        self.state_msgs += 1
        try:
            i = list(msg.name).index(self.model_name)
        except ValueError:
            self.missing += 1
            rospy.logwarn_throttle(10.0, '%s: no model %r in model_states (%s)' % (
                rospy.get_name(), self.model_name, ', '.join(msg.name) or 'empty'))
            return
        p, q = msg.pose[i].position, msg.pose[i].orientation
        tw = msg.twist[i] if i < len(msg.twist) else None
        linear = (tw.linear.x, tw.linear.y, tw.linear.z) if tw is not None else None
        with self.lock:
            self.latest = (rospy.get_time(), (p.x, p.y, p.z), (q.x, q.y, q.z, q.w), linear,
                           tw.angular.z if tw is not None else None)

    def tick(self):
        now = rospy.get_time()
        with self.lock:
            latest = self.latest
            if latest is not None and latest is not self.consumed:
                self.consumed = latest
                wp = self.core.update(*latest)
                if wp is not None:
                    self.waypoint = wp
        if latest is None or now - latest[0] > self.stale_timeout or self.waypoint is None:
            rospy.logwarn_throttle(5.0, '%s: target %s %s: no waypoint published' % (
                rospy.get_name(), self.model_name, 'never seen' if latest is None else 'stale'))
            return
        self.pub.publish(waypoint_message(self.waypoint_type, self.waypoint, rospy.Time.from_sec(now), self.frame_id))
        self.published += 1

    def diagnostic_statuses(self):
        with self.lock:
            latest = self.latest
        age = rospy.get_time() - latest[0] if latest is not None else None
        if latest is None or age > self.stale_timeout:
            level, message = WARN, 'target never seen' if latest is None else 'target stale (%.1f s)' % age
        else:
            level, message = OK, 'following'
        return [diagnostic_status('%s: following %s' % (rospy.get_name(), self.model_name), level, message, (
            ('waypoints published', self.published), ('model_states received', self.state_msgs),
            ('model_states without the model', self.missing), ('refused samples', self.core.rejected),
            ('velocity from', 'twist' if self.core.used_twist else 'finite difference'),
            ('target age [s]', '-' if age is None else '%.2f' % age)), hardware_id=self.model_name)]

    def run(self):
        start_diagnostics_thread(1.0, self.diagnostic_statuses, self.pub_diag, first=0.0)
        wait_for_clock()
        rate = rospy.Rate(self.rate)
        while not rospy.is_shutdown():
            self.tick()
            try:
                rate.sleep()
            except rospy.ROSTimeMovedBackwardsException:
                with self.lock:
                    self.core.reset()
            except rospy.ROSInterruptException:
                break


def main():
    run_node('model_follower', ModelFollowerNode)
