#!/usr/bin/env python3
"""The simulated Anafi: stand-in for Sphinx + firmware + the anafi_ros bridge (thin ROS node).

Stage: piloting command -> simulated drone -> (telemetry server, bridge-like estimate topics).
Wires ROS to ``anafi_sim.sim.simulator.SimulatedAnafi``: the model (``anafi_sim.sim.drone_model``,
physics at ~rate Hz of sim time, paced on the wall clock by ~rtf: ``anafi_sim.sim.clock``), the drone's
own estimate (``anafi_sim.sim.state_estimate``) and the Sphinx-like ground truth on TCP
~telemetry_host:~telemetry_port (``anafi_sim.telemetry.server``).

Namespace /<drone> (default /anafi; if started in the root namespace the
topics are put under /<~drone_name>/). Subscribes: drone/rpyt
(olympe_bridge/PilotingCommand), drone/takeoff, drone/land (std_msgs/Empty).
Publishes: drone/odom (nav_msgs/Odometry of the estimate, world ->
<drone>/base_link, twist in the child frame; angular twist not estimated:
zero), drone/pose_enu, drone/attitude, drone/speed (world ENU), drone/altitude,
drone/rpy (deg), camera/attitude, drone/state (latched), sim/truth (ground
truth Odometry stamped at its sample's time), /diagnostics (1 Hz wall),
/clock when ~publish_clock. Parameters: see anafi_sim/config/sim.yaml; the
fitted model dict is ~model (default: anafi_sim/config/anafi_model.yaml).
Bad parameters: logfatal, exit code 1.
"""
import time

import rospy
from geometry_msgs.msg import PoseStamped, Quaternion, QuaternionStamped, Vector3, Vector3Stamped
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Empty, Float32, String

from anafi_control.frames import euler_to_quaternion
from anafi_sim.ros import conversions, topics
from anafi_sim.ros.node import (OK, WARN, diagnostic_status, diagnostics_publisher, private_params, run_node,
                                start_diagnostics_thread)
from anafi_sim.ros.wire_types import piloting_command_class
from anafi_sim.sim.bridge import MAX_TILT_DEG, MAX_VERTICAL_SPEED, MAX_YAW_RATE_DEG, PilotingMapping
from anafi_sim.sim.clock import SimClock
from anafi_sim.sim.drone_model import DEFAULT_SETTINGS, AnafiModel, load_model_params
from anafi_sim.sim.simulator import SimulatedAnafi
from anafi_sim.sim.state_estimate import StateEstimate
from anafi_sim.telemetry.protocol import DEFAULT_PREFIX
from anafi_sim.telemetry.server import TelemetryServer


class AnafiSimNode(object):
    def __init__(self):
        p = private_params()
        rate = p.number('rate', 200.0, minimum=200.0)   # physics [Hz]
        rtf = p.positive('rtf', 1.0)
        publish_clock = p.flag('publish_clock', False)
        seed = p.integer('seed', 0, minimum=0)
        telemetry_rate = p.positive('telemetry_rate', 100.0)
        estimate_rate = p.positive('estimate_publish_rate', 30.0)
        host = p.string('telemetry_host', '127.0.0.1')
        port = p.integer('telemetry_port', 9060, minimum=0, maximum=65535)   # 0 = any free port
        prefix = p.string('telemetry_prefix', DEFAULT_PREFIX)
        auto_takeoff = p.flag('auto_takeoff', True)
        mapping = PilotingMapping(p.positive('max_tilt_deg', MAX_TILT_DEG),
                                  p.positive('max_vertical_speed', MAX_VERTICAL_SPEED),
                                  p.positive('max_yaw_rate_deg', MAX_YAW_RATE_DEG))
        settings = dict((k, p.number(k, v)) for k, v in DEFAULT_SETTINGS.items())
        model_params = p.mapping('model')
        if model_params is None:
            model_params = load_model_params()
            rospy.loginfo('anafi_sim: ~model not set, using the packaged anafi_model.yaml')
        model = AnafiModel(model_params, mapping=mapping, seed=seed, settings=settings)

        ns = rospy.get_namespace()
        self.drone = p.string('drone_name', ns.strip('/') or 'anafi')
        base = '/%s/' % self.drone if ns == '/' else ''
        self.child_frame = '%s/base_link' % self.drone

        # Time base.
        use_sim_time = rospy.get_param('/use_sim_time', False)
        self.sim_stamps = bool(use_sim_time) and publish_clock
        if use_sim_time and not publish_clock:
            rospy.loginfo('anafi_sim: /use_sim_time is set and ~publish_clock is false: waiting for /clock')
            try:
                rospy.wait_for_message(topics.CLOCK, Clock, timeout=5.0)
            except (rospy.ROSException, rospy.ROSInterruptException):
                raise ValueError('/use_sim_time is true but nobody publishes /clock: set ~publish_clock '
                                 'true (this node then provides the simulation clock) or unset /use_sim_time')

        self.server = TelemetryServer(host, port, prefix)
        try:
            self.server.start()
        except OSError as error:
            raise ValueError('cannot serve telemetry on %s:%s: %s' % (host, port, error))
        rospy.on_shutdown(self.server.stop)
        rospy.set_param('~telemetry_bound_port', self.server.port)
        self.sim = SimulatedAnafi(model, StateEstimate(model.params),
                                  SimClock(rate, rtf, telemetry_rate, estimate_rate, publish_clock),
                                  server=self.server, auto_takeoff=auto_takeoff)

        pub = rospy.Publisher
        self.pub_clock = pub(topics.CLOCK, Clock, queue_size=10) if publish_clock else None
        self.pub_odom = pub(base + topics.ESTIMATE, Odometry, queue_size=10)
        self.pub_pose = pub(base + topics.POSE_ENU, PoseStamped, queue_size=10)
        self.pub_attitude = pub(base + topics.ATTITUDE, QuaternionStamped, queue_size=10)
        self.pub_speed = pub(base + topics.SPEED, Vector3Stamped, queue_size=10)
        self.pub_altitude = pub(base + topics.ALTITUDE, Float32, queue_size=10)
        self.pub_rpy = pub(base + topics.RPY, Vector3Stamped, queue_size=10)
        self.pub_camera = pub(base + topics.CAMERA_ATTITUDE, QuaternionStamped, queue_size=10)
        self.pub_state = pub(base + topics.DRONE_STATE, String, queue_size=1, latch=True)
        self.pub_truth = pub(base + topics.SIM_TRUTH, Odometry, queue_size=20)
        self.pub_diag = diagnostics_publisher(queue_size=5)

        rospy.Subscriber(base + topics.COMMAND, piloting_command_class(), self._on_rpyt, queue_size=20)
        rospy.Subscriber(base + topics.TAKEOFF, Empty, lambda _: self.sim.on_event('takeoff'), queue_size=5)
        rospy.Subscriber(base + topics.LAND, Empty, lambda _: self.sim.on_event('land'), queue_size=5)
        rospy.loginfo('anafi_sim: drone %s, physics %.0f Hz, rtf %.2f, telemetry on %s:%d (%.0f Hz)%s',
                      self.drone, rate, rtf, host, self.server.port, telemetry_rate,
                      ', publishing /clock' if publish_clock else '')

    # ------------------------------------------------------------ callbacks
    def _on_rpyt(self, msg):
        if not self.sim.on_command(msg.roll, msg.pitch, msg.yaw, msg.gaz):
            rospy.logwarn_throttle(5.0, 'anafi_sim: ignored a non-finite piloting command %r (%d so far)'
                                   % ((msg.roll, msg.pitch, msg.yaw, msg.gaz), self.sim.bad_commands))

    # -------------------------------------------------------------- outputs
    def _stamp(self, t):
        return rospy.Time.from_sec(t) if self.sim_stamps else rospy.Time.now()

    def _header(self, msg, stamp, frame_id='world'):
        msg.header.stamp = stamp
        msg.header.frame_id = frame_id
        return msg

    def _publish_truth(self, s, stamp):
        msg = self._header(Odometry(), stamp)
        msg.child_frame_id = self.child_frame
        msg.pose.pose = conversions.pose((s.x, s.y, s.z), euler_to_quaternion(s.roll, s.pitch, s.yaw))
        msg.twist.twist = conversions.twist((s.body_vx, s.body_vy, s.body_vz), (s.body_wx, s.body_wy, s.body_wz))
        self.pub_truth.publish(msg)

    def _publish_estimate(self, e, stamp):
        pose = conversions.pose(e.position, e.orientation)
        odom = self._header(Odometry(), stamp)
        odom.child_frame_id = self.child_frame
        odom.pose.pose = pose
        odom.twist.twist = conversions.twist(e.body_velocity, (0.0, 0.0, 0.0))
        self.pub_odom.publish(odom)
        self.pub_pose.publish(self._header(PoseStamped(pose=pose), stamp))
        self.pub_attitude.publish(self._header(QuaternionStamped(quaternion=pose.orientation), stamp))
        self.pub_speed.publish(self._header(Vector3Stamped(vector=Vector3(*e.velocity)), stamp))
        self.pub_altitude.publish(Float32(e.position[2]))
        self.pub_rpy.publish(self._header(Vector3Stamped(vector=Vector3(*e.rpy_deg)), stamp))
        self.pub_camera.publish(self._header(QuaternionStamped(quaternion=Quaternion(*e.camera_orientation)), stamp))

    def diagnostic_statuses(self):
        health = self.sim.health(time.monotonic())
        return [diagnostic_status('anafi_sim: simulated Anafi (%s)' % self.drone, WARN if health.warning else OK,
                                  health.message, health.values, hardware_id=self.drone)]

    # ------------------------------------------------------------- main loop
    def run(self):
        sim = self.sim
        clock_msg = Clock()
        sim.start(time.monotonic())
        start_diagnostics_thread(1.0, self.diagnostic_statuses, self.pub_diag,
                                 stamp=lambda: self._stamp(sim.clock.t))
        while not rospy.is_shutdown():
            step = sim.step()
            for event, accepted, state in step.events:
                rospy.loginfo('anafi_sim: %s %s, state now %s', event, 'accepted' if accepted else 'ignored', state)
            if step.clock and self.pub_clock is not None:
                clock_msg.clock = rospy.Time.from_sec(step.t)
                self.pub_clock.publish(clock_msg)
            if step.sample is not None:
                self._publish_truth(step.sample, self._stamp(step.t))
            if step.estimate is not None:
                self._publish_estimate(step.estimate, self._stamp(step.t))
            if step.state is not None:
                self.pub_state.publish(String(step.state))
            delay = sim.pace(time.monotonic())
            if delay > 0.0:
                time.sleep(delay)
        self.server.stop()


if __name__ == '__main__':
    run_node('anafi_sim', AnafiSimNode)
