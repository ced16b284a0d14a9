#!/usr/bin/env python3
"""The simulated Anafi: stand-in for Sphinx + firmware + the anafi_ros bridge (thin ROS node).

Stage: piloting command -> simulated drone -> (telemetry server, bridge-like estimate topics).
Wires ROS to ``anafi_sim.sim.drone_model.AnafiModel`` (physics at ~rate Hz of
sim time, paced on the wall clock by ~rtf), ``anafi_sim.sim.state_estimate``
(the drone's own estimate) and ``anafi_sim.telemetry.server`` (Sphinx-like
ground truth on TCP ~telemetry_host:~telemetry_port).

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
"""
import collections
import math
import sys
import time

import rospy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, QuaternionStamped, Vector3Stamped
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Empty, Float32, String

from anafi_control.frames import euler_to_quaternion
from anafi_sim.sim.bridge import MAX_TILT_DEG, MAX_VERTICAL_SPEED, MAX_YAW_RATE_DEG, PilotingMapping
from anafi_sim.sim.drone_model import DEFAULT_SETTINGS, AnafiModel, load_model_params
from anafi_sim.ros.params import ParamReader
from anafi_sim.sim.state_estimate import StateEstimate
from anafi_sim.telemetry.protocol import DEFAULT_PREFIX
from anafi_sim.telemetry.server import TelemetryServer
from anafi_sim.ros.wire_types import piloting_command_class

MAX_LAG = 0.25   # s of wall time behind schedule before the pacing re-anchors (counted)


class AnafiSimNode(object):
    def __init__(self):
        p = ParamReader(lambda name, default: rospy.get_param('~' + name, default))
        self.rate = p.number('rate', 200.0, minimum=200.0)   # physics [Hz]
        self.rtf = p.positive('rtf', 1.0)
        self.publish_clock = p.flag('publish_clock', False)
        seed = p.integer('seed', 0, minimum=0)
        self.telemetry_rate = p.positive('telemetry_rate', 100.0)
        self.estimate_publish_rate = p.positive('estimate_publish_rate', 30.0)
        host = p.string('telemetry_host', '127.0.0.1')
        port = p.integer('telemetry_port', 9060, minimum=0, maximum=65535)   # 0 = any free port
        prefix = p.string('telemetry_prefix', DEFAULT_PREFIX)
        self.auto_takeoff = p.flag('auto_takeoff', True)
        mapping = PilotingMapping(p.positive('max_tilt_deg', MAX_TILT_DEG),
                                  p.positive('max_vertical_speed', MAX_VERTICAL_SPEED),
                                  p.positive('max_yaw_rate_deg', MAX_YAW_RATE_DEG))
        settings = dict((k, p.number(k, v)) for k, v in DEFAULT_SETTINGS.items())
        model_params = rospy.get_param('~model', None)
        if model_params is None:
            model_params = load_model_params()
            rospy.loginfo('anafi_sim: ~model not set, using the packaged anafi_model.yaml')
        self.mapping = mapping
        self.model = AnafiModel(model_params, mapping=mapping, seed=seed, settings=settings)
        self.estimate = StateEstimate(self.model.params)

        ns = rospy.get_namespace()
        self.drone = p.string('drone_name', ns.strip('/') or 'anafi')
        base = '/%s/' % self.drone if ns == '/' else ''
        self.child_frame = '%s/base_link' % self.drone

        # Time base.
        use_sim_time = rospy.get_param('/use_sim_time', False)
        self.sim_stamps = bool(use_sim_time) and self.publish_clock
        if use_sim_time and not self.publish_clock:
            rospy.loginfo('anafi_sim: /use_sim_time is set and ~publish_clock is false: waiting for /clock')
            try:
                rospy.wait_for_message('/clock', Clock, timeout=5.0)
            except (rospy.ROSException, rospy.ROSInterruptException):
                raise ValueError('/use_sim_time is true but nobody publishes /clock: set ~publish_clock '
                                 'true (this node then provides the simulation clock) or unset /use_sim_time')

        self.server = TelemetryServer(host, port, prefix)
        try:
            self.server.start()
        except OSError as error:
            raise ValueError('cannot serve telemetry on %s:%s: %s' % (host, port, error))
        rospy.set_param('~telemetry_bound_port', self.server.port)

        pub = rospy.Publisher
        self.pub_clock = pub('/clock', Clock, queue_size=10) if self.publish_clock else None
        self.pub_odom = pub(base + 'drone/odom', Odometry, queue_size=10)
        self.pub_pose = pub(base + 'drone/pose_enu', PoseStamped, queue_size=10)
        self.pub_attitude = pub(base + 'drone/attitude', QuaternionStamped, queue_size=10)
        self.pub_speed = pub(base + 'drone/speed', Vector3Stamped, queue_size=10)
        self.pub_altitude = pub(base + 'drone/altitude', Float32, queue_size=10)
        self.pub_rpy = pub(base + 'drone/rpy', Vector3Stamped, queue_size=10)
        self.pub_camera = pub(base + 'camera/attitude', QuaternionStamped, queue_size=10)
        self.pub_state = pub(base + 'drone/state', String, queue_size=1, latch=True)
        self.pub_truth = pub(base + 'sim/truth', Odometry, queue_size=20)
        self.pub_diag = pub('/diagnostics', DiagnosticArray, queue_size=5)

        self.commands = collections.deque(maxlen=1000)     # PCMD tuples from the callback thread
        self.events = collections.deque(maxlen=100)        # 'takeoff' / 'land'
        self.bad_commands = 0
        self.commands_received = 0
        rospy.Subscriber(base + 'drone/rpyt', piloting_command_class(), self._on_rpyt, queue_size=20)
        rospy.Subscriber(base + 'drone/takeoff', Empty, lambda _: self.events.append('takeoff'), queue_size=5)
        rospy.Subscriber(base + 'drone/land', Empty, lambda _: self.events.append('land'), queue_size=5)
        rospy.loginfo('anafi_sim: drone %s, physics %.0f Hz, rtf %.2f, telemetry on %s:%d (%.0f Hz)%s',
                      self.drone, self.rate, self.rtf, host, self.server.port, self.telemetry_rate,
                      ', publishing /clock' if self.publish_clock else '')

    # ------------------------------------------------------------ callbacks
    def _on_rpyt(self, msg):
        values = (msg.roll, msg.pitch, msg.yaw, msg.gaz)
        if not all(math.isfinite(v) for v in values):
            self.bad_commands += 1
            rospy.logwarn_throttle(5.0, 'anafi_sim: ignored a non-finite piloting command %r (%d so far)'
                                   % (values, self.bad_commands))
            return
        self.commands_received += 1
        self.commands.append(self.mapping.to_pcmd(*values))

    # -------------------------------------------------------------- helpers
    def _stamp(self, t):
        return rospy.Time.from_sec(t) if self.sim_stamps else rospy.Time.now()

    def _publish_truth(self, sample, stamp):
        msg = Odometry()
        msg.header.stamp = stamp
        msg.header.frame_id = 'world'
        msg.child_frame_id = self.child_frame
        p = msg.pose.pose
        p.position.x, p.position.y, p.position.z = sample.x, sample.y, sample.z
        q = euler_to_quaternion(sample.roll, sample.pitch, sample.yaw)
        p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = q
        tw = msg.twist.twist
        tw.linear.x, tw.linear.y, tw.linear.z = sample.body_vx, sample.body_vy, sample.body_vz
        tw.angular.x, tw.angular.y, tw.angular.z = sample.body_wx, sample.body_wy, sample.body_wz
        self.pub_truth.publish(msg)

    def _publish_estimate(self, stamp):
        values = self.estimate.values()
        if values is None:
            return
        x, y, z, vx, vy, vz, roll, pitch, yaw = values
        q = euler_to_quaternion(roll, pitch, yaw)
        cr, sr = math.cos(roll), math.sin(roll)
        cp, sp = math.cos(pitch), math.sin(pitch)
        cy, sy = math.cos(yaw), math.sin(yaw)
        bvx = cy * cp * vx + sy * cp * vy - sp * vz
        bvy = (cy * sp * sr - sy * cr) * vx + (sy * sp * sr + cy * cr) * vy + cp * sr * vz
        bvz = (cy * sp * cr + sy * sr) * vx + (sy * sp * cr - cy * sr) * vy + cp * cr * vz

        odom = Odometry()
        odom.header.stamp = stamp
        odom.header.frame_id = 'world'
        odom.child_frame_id = self.child_frame
        pp = odom.pose.pose
        pp.position.x, pp.position.y, pp.position.z = x, y, z
        pp.orientation.x, pp.orientation.y, pp.orientation.z, pp.orientation.w = q
        odom.twist.twist.linear.x, odom.twist.twist.linear.y, odom.twist.twist.linear.z = bvx, bvy, bvz
        self.pub_odom.publish(odom)

        pose = PoseStamped()
        pose.header.stamp = stamp
        pose.header.frame_id = 'world'
        pose.pose = pp
        self.pub_pose.publish(pose)

        att = QuaternionStamped()
        att.header.stamp = stamp
        att.header.frame_id = 'world'
        att.quaternion = pp.orientation
        self.pub_attitude.publish(att)

        speed = Vector3Stamped()
        speed.header.stamp = stamp
        speed.header.frame_id = 'world'
        speed.vector.x, speed.vector.y, speed.vector.z = vx, vy, vz
        self.pub_speed.publish(speed)

        self.pub_altitude.publish(Float32(z))

        rpy = Vector3Stamped()
        rpy.header.stamp = stamp
        rpy.header.frame_id = 'world'
        rpy.vector.x, rpy.vector.y, rpy.vector.z = math.degrees(roll), math.degrees(pitch), math.degrees(yaw)
        self.pub_rpy.publish(rpy)

        cam = QuaternionStamped()
        cam.header.stamp = stamp
        cam.header.frame_id = 'world'
        cq = euler_to_quaternion(0.0, self.model.gimbal_pitch_command, yaw)
        cam.quaternion.x, cam.quaternion.y, cam.quaternion.z, cam.quaternion.w = cq
        self.pub_camera.publish(cam)

    def _publish_diagnostics(self, t, achieved_rate, achieved_rtf, overruns, lag_resets):
        status = DiagnosticStatus()
        status.name = 'anafi_sim: simulated Anafi (%s)' % self.drone
        status.hardware_id = self.drone
        wanted = self.rate * self.rtf
        problems = []
        if achieved_rate < 0.95 * wanted:
            problems.append('physics %.0f Hz of wall time, wanted %.0f' % (achieved_rate, wanted))
        if self.bad_commands > self._bad_reported:
            problems.append('%d non-finite commands ignored' % (self.bad_commands - self._bad_reported))
        self._bad_reported = self.bad_commands
        age = self.model.command_age(t)
        state = self.model.state
        if problems:
            status.level = DiagnosticStatus.WARN
            status.message = '; '.join(problems)
        else:
            status.level = DiagnosticStatus.OK
            if state == 'flying' and not self.model.commanding:
                status.message = 'flying, hovering (no piloting command)'
            else:
                status.message = state
        status.values = [KeyValue(k, v) for k, v in (
            ('sim time [s]', '%.3f' % t),
            ('physics rate achieved [Hz wall]', '%.1f' % achieved_rate),
            ('physics rate wanted [Hz wall]', '%.1f' % wanted),
            ('real-time factor achieved', '%.3f' % achieved_rtf),
            ('overruns (steps late by > 1 period)', str(overruns)),
            ('schedule re-anchors (> %.2f s behind)' % MAX_LAG, str(lag_resets)),
            ('flight state', state),
            ('commanding', str(self.model.commanding)),
            ('command age [s sim]', 'none' if math.isinf(age) else '%.3f' % age),
            ('commands received', str(self.commands_received)),
            ('bad commands (non-finite, ignored)', str(self.bad_commands)),
            ('telemetry clients', str(self.server.client_count)),
            ('telemetry clients dropped (slow)', str(self.server.clients_dropped_slow)),
            ('telemetry clients disconnected', str(self.server.clients_disconnected)),
            ('telemetry port', str(self.server.port)),
        )]
        array = DiagnosticArray()
        array.header.stamp = self._stamp(t)
        array.status = [status]
        self.pub_diag.publish(array)

    # ------------------------------------------------------------- main loop
    def run(self):
        model, estimate, server = self.model, self.estimate, self.server
        dt = 1.0 / self.rate
        wall_period = dt / self.rtf
        tlm_period = 1.0 / self.telemetry_rate
        est_period = 1.0 / self.estimate_publish_rate
        eps = 1e-9
        k = 0
        t = 0.0
        next_tlm = 0.0
        next_est = 0.0
        last_state = None
        overruns = lag_resets = 0
        self._bad_reported = 0
        if self.auto_takeoff:
            model.takeoff(0.0)
        start = time.monotonic()
        next_diag = start + 1.0
        diag_k, diag_wall, diag_t = 0, start, 0.0
        clock_msg = Clock()
        while not rospy.is_shutdown():
            events = self.events
            while events:
                event = events.popleft()
                accepted = model.takeoff(t) if event == 'takeoff' else model.land(t)
                rospy.loginfo('anafi_sim: %s %s, state now %s', event,
                              'accepted' if accepted else 'ignored', model.state)
            commands = self.commands
            while commands:
                pcmd = commands.popleft()
                model.set_command(pcmd[0], pcmd[1], pcmd[2], pcmd[3], t)
            model.step(dt, t)
            k += 1
            t = k * dt
            estimate.update(t, model.x, model.y, model.z, model.vx, model.vy, model.vz,
                            model.roll, model.pitch, model.yaw)
            if self.pub_clock is not None:
                clock_msg.clock = rospy.Time.from_sec(t)
                self.pub_clock.publish(clock_msg)
            if t >= next_tlm - eps:
                next_tlm += tlm_period
                if next_tlm < t:
                    next_tlm = t + tlm_period
                sample = model.truth_sample(t)
                server.publish(sample)
                self._publish_truth(sample, self._stamp(t))
            if t >= next_est - eps:
                next_est += est_period
                if next_est < t:
                    next_est = t + est_period
                self._publish_estimate(self._stamp(t))
            if model.state != last_state:
                last_state = model.state
                self.pub_state.publish(String(last_state))

            now = time.monotonic()
            if now >= next_diag:
                span = now - diag_wall
                self._publish_diagnostics(t, (k - diag_k) / span, (t - diag_t) / span, overruns, lag_resets)
                diag_k, diag_wall, diag_t = k, now, t
                next_diag = now + 1.0
            delay = start + k * wall_period - now
            if delay > 0.0:
                time.sleep(delay)
            elif delay < -wall_period:
                overruns += 1
                if delay < -MAX_LAG:
                    lag_resets += 1
                    start = now - k * wall_period
        server.stop()


def main():
    rospy.init_node('anafi_sim')
    try:
        node = AnafiSimNode()
    except ValueError as error:
        rospy.logfatal('anafi_sim: %s', error)
        sys.exit(1)
    rospy.on_shutdown(node.server.stop)
    node.run()


if __name__ == '__main__':
    main()
