#!/usr/bin/env python3
"""Visualisation node: a drone's flown trail, reference, predicted path and waypoint for rviz.

Stage: (ground truth, waypoint, controller's predicted path) -> rviz markers. Thin node over
anafi_sim.mission.visualisation (Trail, markers, COLOURS). Run one per drone, in its namespace
(/<drone>/; the drone name = the namespace); anafi_sim/launch/rviz.launch starts it with
anafi_sim/config/visualisation.yaml.

- in ~trail_topic (ground_truth/odom, nav_msgs/Odometry: the flown positions), ~waypoint_topic
  (position_control/waypoint, anafi_sim/Waypoint: the reference), ~predicted_path_topics (list of
  nav_msgs/Path topics, default [mpc/predicted_path, preview_mpc/predicted_path]: the controller's
  prediction, whichever controller publishes one);
- out ~markers_topic (/visualisation/markers, visualization_msgs/MarkerArray shared by every drone: marker
  namespaces <drone>/trail, <drone>/reference, <drone>/predicted, <drone>/waypoint) at ~rate Hz (5) of ROS
  time; visualisation/trail and visualisation/reference_path (nav_msgs/Path in ~frame_id, world).

Trail: a point every ~trail_spacing m (0.02), the last ~trail_length s (60) of motion, at most ~max_points
(5000); ~line_width [m] (0.04), ~waypoint_size [m] (0.12). Non-finite positions are refused and counted
(warning, throttled); a predicted path older than 2 s is not drawn. Bad parameters: logfatal, exit 1.
"""
import math
import threading

import rospy
from geometry_msgs.msg import Point, PoseStamped
from nav_msgs.msg import Odometry, Path
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from anafi_sim.mission.visualisation import DEFAULTS, Trail, markers
from anafi_sim.msg import Waypoint
from anafi_sim import names
from anafi_sim.ros.node import namespace_id, private_params, run_node, wait_for_clock

PREDICTION_TIMEOUT = 2.0   # s of ROS time


class VisualisationNode(object):
    def __init__(self):
        p = private_params()
        self.drone = namespace_id()
        self.rate = p.positive('rate', DEFAULTS['rate'])
        self.frame_id = p.string('frame_id', 'world')
        self.line_width = p.positive('line_width', DEFAULTS['line_width'])
        self.waypoint_size = p.positive('waypoint_size', DEFAULTS['waypoint_size'])
        spacing = p.number('trail_spacing', DEFAULTS['trail_spacing'], minimum=0.0)
        length = p.positive('trail_length', DEFAULTS['trail_length'])
        max_points = p.integer('max_points', DEFAULTS['max_points'], minimum=2)
        self.trail = Trail(spacing, length, max_points)
        self.reference = Trail(spacing, length, max_points)
        self.lock = threading.Lock()
        self.waypoint = None            # (position, yaw [rad])
        self.predicted = None           # (receipt time, [positions])
        self.refused_waypoints = 0
        self.pub_markers = rospy.Publisher(p.string('markers_topic', '/visualisation/markers'), MarkerArray,
                                           queue_size=2)
        self.pub_trail = rospy.Publisher('visualisation/trail', Path, queue_size=2)
        self.pub_reference = rospy.Publisher('visualisation/reference_path', Path, queue_size=2)
        rospy.Subscriber(p.string('trail_topic', names.GROUND_TRUTH), Odometry, self._on_odom, queue_size=20)
        rospy.Subscriber(p.string('waypoint_topic', names.WAYPOINT), Waypoint, self._on_waypoint, queue_size=10)
        for topic in p.names('predicted_path_topics', ['mpc/predicted_path', 'preview_mpc/predicted_path']):
            rospy.Subscriber(topic, Path, self._on_predicted, queue_size=2)

    def _on_odom(self, msg):
        position = msg.pose.pose.position
        with self.lock:
            kept = self.trail.add(rospy.get_time(), (position.x, position.y, position.z))
            refused = self.trail.refused
        if not kept and refused and not all(map(math.isfinite, (position.x, position.y, position.z))):
            rospy.logwarn_throttle(10.0, '%s: non-finite position refused (%d so far)' % (rospy.get_name(), refused))

    def _on_waypoint(self, msg):
        position = (msg.x, msg.y, msg.z)
        yaw = math.radians(msg.yaw)
        if not all(map(math.isfinite, position + (yaw,))):
            self.refused_waypoints += 1
            rospy.logwarn_throttle(10.0, '%s: non-finite waypoint refused (%d so far)'
                                   % (rospy.get_name(), self.refused_waypoints))
            return
        with self.lock:
            self.reference.add(rospy.get_time(), position)
            self.waypoint = (position, yaw)

    def _on_predicted(self, msg):
        points = [(s.pose.position.x, s.pose.position.y, s.pose.position.z) for s in msg.poses]
        with self.lock:
            self.predicted = (rospy.get_time(), points)

    def _path(self, stamp, points):
        path = Path()
        path.header.stamp, path.header.frame_id = stamp, self.frame_id
        for x, y, z in points:
            pose = PoseStamped()
            pose.header = path.header
            pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = x, y, z
            pose.pose.orientation.w = 1.0
            path.poses.append(pose)
        return path

    def _marker(self, stamp, spec):
        m = Marker()
        m.header.stamp, m.header.frame_id = stamp, self.frame_id
        m.ns, m.id, m.action = spec.ns, spec.id, Marker.ADD
        m.color = ColorRGBA(*spec.colour)
        m.pose.orientation.w = 1.0
        if spec.kind == 'sphere':
            m.type = Marker.SPHERE
            m.pose.position.x, m.pose.position.y, m.pose.position.z = spec.points[0]
            m.scale.x = m.scale.y = m.scale.z = spec.scale
        else:
            m.type = Marker.LINE_STRIP if spec.kind == 'line' else Marker.ARROW
            m.points = [Point(*p) for p in spec.points]
            m.scale.x = spec.scale
            if spec.kind == 'arrow':
                m.scale.y, m.scale.z = 2.0 * spec.scale, 3.0 * spec.scale
        return m

    def publish(self):
        now = rospy.get_time()
        stamp = rospy.Time.now()
        with self.lock:
            predicted = None
            if self.predicted is not None and now - self.predicted[0] <= PREDICTION_TIMEOUT:
                predicted = self.predicted[1]
            specs = markers(self.drone, self.trail, self.reference, predicted, self.waypoint,
                            self.line_width, self.waypoint_size)
            trail, reference = self.trail.points(), self.reference.points()
        present = set(s.ns for s in specs)
        array = MarkerArray(markers=[self._marker(stamp, s) for s in specs])
        for kind in ('trail', 'reference', 'predicted'):    # nothing to draw: remove the old strip
            ns = '%s/%s' % (self.drone, kind)
            if ns not in present:
                gone = Marker(ns=ns, id=0, action=Marker.DELETE)
                gone.header.frame_id = self.frame_id
                array.markers.append(gone)
        self.pub_markers.publish(array)
        self.pub_trail.publish(self._path(stamp, trail))
        self.pub_reference.publish(self._path(stamp, reference))

    def run(self):
        wait_for_clock()
        rate = rospy.Rate(self.rate)
        while not rospy.is_shutdown():
            self.publish()
            try:
                rate.sleep()
            except rospy.ROSTimeMovedBackwardsException:   # simulation restarted: the trail clears itself
                continue
            except rospy.ROSInterruptException:
                break


def main():
    run_node('visualisation', VisualisationNode)
