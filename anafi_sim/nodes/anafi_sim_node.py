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
Publishes: drone/odom (nav_msgs/Odometry of the estimate, <drone>/odom ->
<drone>/base_link, twist in the child frame; angular twist not estimated:
zero), with ~publish_tf (true) the same pose on /tf (<drone>/odom -> <drone>/base_link) and on /tf_static
the identities world -> map -> <drone>/odom (REP-105: docs/nodes.md#frames), drone/pose_enu (ENU),
drone/attitude and drone/speed (as the real bridge: frame_id "/world",
north-west-up referenced), drone/altitude,
drone/rpy (deg), camera/attitude and camera/base/attitude (as the real bridge: frame_id "/body",
north-west-up referenced, anafi_sim.sim.bridge), drone/state (latched), sim/truth (ground
truth Odometry stamped at its sample's time, world -> <drone>/base_link_gt), /diagnostics (1 Hz wall),
/clock when ~publish_clock; with ~publish_state_enu (true) also position_control/state_enu
(anafi_control/State, the reference implementation's bridge fork: frame ids "/world",
pose = drone/pose_enu, twist.linear = the ENU velocity (drone/speed turned to east, north, up), twist.angular = 0;
wire-identical class from anafi_sim.ros.wire_types).
Sets ~telemetry_bound_port (the port it serves on: ~telemetry_port, or a free one for 0) and
~telemetry_stream_id (a new random id per start, printed in every telemetry sample) for the interface (its
~simulator_node). Parameters: see anafi_sim/config/sim.yaml; the
fitted model dict is ~model if set, else read from ~model_file (default anafi_model.yaml, a name in
anafi_sim/config such as anafi_model_fitted.yaml, or an absolute path).
~sync (with ~publish_clock): lockstep with the controller
(anafi_sim.sim.clock.Lockstep): simulation time held at 0 until the graph is
up (~sync_settle), then at each control period (~sync_period) /clock stops at
the period's tick until the command stamped at it arrives on drone/rpyt (at
most ~sync_timeout s wall, counted on /diagnostics); a command with header.stamp 0 (the reference
implementation's controllers) counts at its time of arrival (counted and named on /diagnostics).
Bad parameters: logfatal, then the node stays up in ERROR (not respawned: docs/nodes.md).
"""
import time

import rospy
from geometry_msgs.msg import PoseStamped, Quaternion, QuaternionStamped, Vector3, Vector3Stamped
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from tf2_msgs.msg import TFMessage
from std_msgs.msg import Empty, Float32, String

import anafi_sim  # noqa: F401 (before anafi_control: checks it is the control library, README)
from anafi_control.frames import euler_to_quaternion
from anafi_sim import names
from anafi_sim.ros import conversions
from anafi_sim.ros.context import NodeContext
from anafi_sim.ros.node import (OK, WARN, diagnostic_status, diagnostics_publisher, private_params, run_node,
                                start_diagnostics_thread)
from anafi_sim.ros.wire_types import paper_state_class, piloting_command_class
from anafi_sim.sim.bridge import CAMERA_FRAME_ID, WORLD_FRAME_ID, MAX_TILT_DEG, MAX_VERTICAL_SPEED, MAX_YAW_RATE_DEG, PilotingMapping
from anafi_sim.sim.clock import SYNC_DEFAULTS, Lockstep, SimClock, StartHold
from anafi_sim.sim.drone_model import DEFAULT_SETTINGS, AnafiModel, load_model_params, model_file_path
from anafi_sim.sim.simulator import SimulatedAnafi
from anafi_sim.sim.state_estimate import StateEstimate
from anafi_sim.telemetry.protocol import DEFAULT_PREFIX, new_stream_id
from anafi_sim.telemetry.server import TelemetryServer, checked_bind_host



FIRST_TICK_HOLD = 1.0
"""s of wall time the lockstep holds the first step's /clock tick: nodes that wait for /clock to start
(anafi_sim.ros.node.wait_for_clock polls every 50 ms of wall time, e.g. the trajectory generator's Rate loop)
all start at that tick, not wherever the simulation got to when they looked."""


def sim_time(t):
    """rospy.Time of simulation time ``t`` [s], rounded to the nanosecond (rospy.Time.from_sec truncates: the
    step at 1.2 s, computed as 240 x 0.005, would read 1.199999999 and a 10 Hz timer due at 1.2 s would
    fire one step late)."""
    return rospy.Time(*divmod(int(round(t * 1e9)), 1000000000))


class AnafiSimNode(object):
    """One simulated Anafi (``ctx``: the NodeContext it runs in; None: the process's node)."""

    def __init__(self, ctx=None):
        self.ctx = ctx = ctx or NodeContext.process()
        p = private_params(ctx)
        rate = p.number('rate', 200.0, minimum=200.0)   # physics [Hz]
        rtf = p.positive('rtf', 1.0)
        publish_clock = p.flag('publish_clock', False)
        seed = p.integer('seed', 0, minimum=0)
        telemetry_rate = p.positive('telemetry_rate', 100.0)
        estimate_rate = p.positive('estimate_publish_rate', 30.0)
        host = checked_bind_host(p.string('telemetry_host', '127.0.0.1'), p.flag('allow_remote_telemetry', False))
        port = p.integer('telemetry_port', 0, minimum=0, maximum=65535)   # 0 = any free port
        prefix = p.string('telemetry_prefix', DEFAULT_PREFIX)
        auto_takeoff = p.flag('auto_takeoff', True)
        publish_state_enu = p.flag('publish_state_enu', True)
        publish_tf = p.flag('publish_tf', True)
        sync = self._sync_settings(p, publish_clock)
        model = self._model(p, seed)

        ns = ctx.namespace
        self.drone = p.string('drone_name', ns.strip('/') or 'anafi')
        base = '/%s/' % self.drone if ns == '/' else ''
        self.odom_frame = names.odom_frame(self.drone)
        self.child_frame = names.base_link_frame(self.drone)
        self.truth_frame = names.ground_truth_frame(self.drone)
        self._time_base(publish_clock)
        self._serve_telemetry(host, port, prefix)
        # lockstep: no catching up after a late step (it would squeeze the graph's hops into less sim time)
        clock = SimClock(rate, rtf, telemetry_rate, estimate_rate, publish_clock, **({'max_lag': 0.0} if sync else {}))
        lockstep = Lockstep(sync['period'], 1.0 / rate, sync['timeout'], sync['max_missed']) if sync else None
        self.start_hold = StartHold(sync['settle'], sync['start_timeout']) if sync else None
        self.sim = SimulatedAnafi(model, StateEstimate(model.params), clock, server=self.server,
                                  auto_takeoff=auto_takeoff, lockstep=lockstep)
        if lockstep is not None:
            rospy.on_shutdown(lockstep.close)
        self._connect(base, publish_clock, publish_state_enu, publish_tf)
        self.ctx.loginfo('anafi_sim: drone %s, physics %.0f Hz, rtf %.2f, telemetry on %s:%d (%.0f Hz, stream id '
                         '%d)%s%s', self.drone, rate, rtf, host, self.server.port, telemetry_rate, self.stream_id,
                         ', publishing /clock' if publish_clock else '',
                         ', lockstep with the controller every %g s (time-out %g s wall)'
                         % (sync['period'], sync['timeout']) if sync else '')

    @staticmethod
    def _sync_settings(p, publish_clock):
        """The lockstep's settings ({'period', 'timeout', 'max_missed', 'settle', 'start_timeout'}), None without
        ~sync."""
        sync = p.flag('sync', False)
        d = SYNC_DEFAULTS
        settings = {
            'period': p.positive('sync_period', d['sync_period']),            # s sim, the controller's period
            'timeout': p.positive('sync_timeout', d['sync_timeout']),         # s wall per period
            'max_missed': p.integer('sync_max_missed', d['sync_max_missed'], minimum=1),
            'settle': p.number('sync_settle', d['sync_settle'], minimum=0.0),  # s wall
            'start_timeout': p.positive('sync_start_timeout', d['sync_start_timeout'])}
        if sync and not publish_clock:
            raise ValueError('~sync needs ~publish_clock true (lockstep holds the simulation clock)')
        return settings if sync else None

    def _model(self, p, seed):
        """The drone model: ~model (a mapping) or ~model_file, the bridge's limits, the model settings."""
        mapping = PilotingMapping(p.positive('max_tilt_deg', MAX_TILT_DEG),
                                  p.positive('max_vertical_speed', MAX_VERTICAL_SPEED),
                                  p.positive('max_yaw_rate_deg', MAX_YAW_RATE_DEG))
        settings = dict((k, p.number(k, v)) for k, v in DEFAULT_SETTINGS.items())
        model_params = p.mapping('model')
        model_file = p.string('model_file', 'anafi_model.yaml', allow_empty=False)
        if model_params is None:     # a name in anafi_sim/config (e.g. anafi_model_fitted.yaml) or a path
            model_path = model_file_path(model_file)     # a parameter: only files in the config folders
            model_params = load_model_params(model_path)
            self.ctx.loginfo('anafi_sim: model parameters from %s', model_path)
        return AnafiModel(model_params, mapping=mapping, seed=seed, settings=settings)

    def _time_base(self, publish_clock):
        """Stamps in simulation time when this node publishes /clock; under someone else's /clock, wait for it."""
        use_sim_time = rospy.get_param('/use_sim_time', False)
        self.sim_stamps = bool(use_sim_time) and publish_clock
        if use_sim_time and not publish_clock:
            self.ctx.loginfo('anafi_sim: /use_sim_time is set and ~publish_clock is false: waiting for /clock')
            try:
                rospy.wait_for_message(names.CLOCK, Clock, timeout=5.0)
            except (rospy.ROSException, rospy.ROSInterruptException):
                raise ValueError('/use_sim_time is true but nobody publishes /clock: set ~publish_clock '
                                 'true (this node then provides the simulation clock) or unset /use_sim_time')

    def _serve_telemetry(self, host, port, prefix):
        # Every start gets a new stream id; the interface reads it (and the bound port) from these parameters
        # and refuses a stream with another id (another simulator's drone, a stale port).
        self.stream_id = new_stream_id()
        self.server = TelemetryServer(host, port, prefix, stream_id=self.stream_id)
        try:
            self.server.start()
        except OSError as error:
            raise ValueError('cannot serve telemetry on %s:%s (~telemetry_port): %s%s' % (
                host, port, error, '; another simulator uses it: give another port, or 0 for any free one'
                if port else ''))
        rospy.on_shutdown(self.server.stop)
        self.ctx.set_param('telemetry_stream_id', self.stream_id)
        self.ctx.set_param('telemetry_bound_port', self.server.port)

    def _connect(self, base, publish_clock, publish_state_enu, publish_tf):
        """The anafi_ros-like topics (under ``base``; with ``publish_state_enu`` also position_control/state_enu),
        /clock, /diagnostics, the estimate's tf (``publish_tf``) and the command subscriptions."""
        pub = self.ctx.publisher
        self.pub_tf = pub(names.TF, TFMessage, queue_size=100) if publish_tf else None
        if publish_tf:
            identity = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
            self.ctx.send_static_transforms([
                conversions.transform(rospy.Time(0), names.WORLD_FRAME, names.MAP_FRAME, *identity),
                conversions.transform(rospy.Time(0), names.MAP_FRAME, self.odom_frame, *identity)])
        self.pub_clock = pub(names.CLOCK, Clock, queue_size=10) if publish_clock else None
        self.pub_odom = pub(base + names.ESTIMATE, Odometry, queue_size=10)
        self.pub_pose = pub(base + names.POSE_ENU, PoseStamped, queue_size=10)
        self.pub_attitude = pub(base + names.ATTITUDE, QuaternionStamped, queue_size=10)
        self.pub_speed = pub(base + names.SPEED, Vector3Stamped, queue_size=10)
        self.pub_altitude = pub(base + names.ALTITUDE, Float32, queue_size=10)
        self.pub_rpy = pub(base + names.RPY, Vector3Stamped, queue_size=10)
        self.pub_camera = pub(base + names.CAMERA_ATTITUDE, QuaternionStamped, queue_size=10)
        self.pub_camera_base = pub(base + names.CAMERA_BASE_ATTITUDE, QuaternionStamped, queue_size=10)
        self.State = paper_state_class() if publish_state_enu else None
        self.pub_state_enu = pub(base + names.STATE_ENU, self.State, queue_size=10) if publish_state_enu else None
        self.pub_state = pub(base + names.DRONE_STATE, String, queue_size=1, latch=True)
        self.pub_truth = pub(base + names.SIM_TRUTH, Odometry, queue_size=20)
        self.pub_diag = diagnostics_publisher(queue_size=5)
        sub = self.ctx.subscriber
        sub(base + names.COMMAND, piloting_command_class(), self._on_rpyt, queue_size=20)
        sub(base + names.TAKEOFF, Empty, lambda _: self.sim.on_event('takeoff'), queue_size=5)
        sub(base + names.LAND, Empty, lambda _: self.sim.on_event('land'), queue_size=5)

    # ------------------------------------------------------------ callbacks
    def _on_rpyt(self, msg):
        if not self.sim.on_command(msg.roll, msg.pitch, msg.yaw, msg.gaz, stamp=msg.header.stamp.to_sec()):
            self.ctx.logwarn_throttle(5.0, 'anafi_sim: ignored a non-finite piloting command %r (%d so far)'
                                      % ((msg.roll, msg.pitch, msg.yaw, msg.gaz), self.sim.bad_commands))

    # -------------------------------------------------------------- outputs
    def _stamp(self, t):
        return sim_time(t) if self.sim_stamps else rospy.Time.now()

    def _header(self, msg, stamp, frame_id):
        msg.header.stamp = stamp
        msg.header.frame_id = frame_id
        return msg

    def _publish_truth(self, s, stamp):
        if not self.pub_truth.get_num_connections():
            return
        msg = self._header(Odometry(), stamp, names.WORLD_FRAME)
        msg.child_frame_id = self.truth_frame
        msg.pose.pose = conversions.pose((s.x, s.y, s.z), euler_to_quaternion(s.roll, s.pitch, s.yaw))
        msg.twist.twist = conversions.twist((s.body_vx, s.body_vy, s.body_vz), (s.body_wx, s.body_wy, s.body_wz))
        self.pub_truth.publish(msg)

    def _publish_estimate(self, e, stamp):
        """The bridge's estimate topics; a message nobody subscribes to is not built."""
        def wanted(pub):
            return pub is not None and pub.get_num_connections() > 0
        pose = conversions.pose(e.position, e.orientation)
        if wanted(self.pub_odom):
            odom = self._header(Odometry(), stamp, self.odom_frame)
            odom.child_frame_id = self.child_frame
            odom.pose.pose = pose
            odom.twist.twist = conversions.twist(e.body_velocity, (0.0, 0.0, 0.0))
            self.pub_odom.publish(odom)
        if wanted(self.pub_tf):
            self.pub_tf.publish(TFMessage(transforms=[
                conversions.transform(stamp, self.odom_frame, self.child_frame, e.position, e.orientation)]))
        if wanted(self.pub_pose):
            self.pub_pose.publish(self._header(PoseStamped(pose=pose), stamp, WORLD_FRAME_ID))
        if wanted(self.pub_attitude):
            self.pub_attitude.publish(self._header(QuaternionStamped(quaternion=Quaternion(*e.attitude_nwu)), stamp,
                                                   WORLD_FRAME_ID))
        if wanted(self.pub_speed):
            self.pub_speed.publish(self._header(Vector3Stamped(vector=Vector3(*e.speed_nwu)), stamp, WORLD_FRAME_ID))
        if wanted(self.pub_altitude):
            self.pub_altitude.publish(Float32(e.position[2]))
        if wanted(self.pub_rpy):
            self.pub_rpy.publish(self._header(Vector3Stamped(vector=Vector3(*e.rpy_deg)), stamp, names.WORLD_FRAME))
        if wanted(self.pub_camera):
            self.pub_camera.publish(self._header(QuaternionStamped(quaternion=Quaternion(*e.camera_orientation)),
                                                 stamp, CAMERA_FRAME_ID))
        if wanted(self.pub_camera_base):
            self.pub_camera_base.publish(self._header(
                QuaternionStamped(quaternion=Quaternion(*e.camera_base_orientation)), stamp, CAMERA_FRAME_ID))
        if wanted(self.pub_state_enu):
            self.pub_state_enu.publish(self._state_enu(pose, e.velocity, stamp))

    def _state_enu(self, pose, velocity, stamp):
        """anafi_control/State as the reference implementation's bridge fills it: frame ids "/world", pose =
        drone/pose_enu, twist.linear = the velocity (east, north, up), twist.angular = 0."""
        msg = self.State()
        for header in (msg.header, msg.pose.header, msg.twist.header, msg.twist.twist.linear.header,
                       msg.twist.twist.angular.header):
            header.stamp = stamp
            header.frame_id = WORLD_FRAME_ID
        msg.pose.pose = pose
        v = msg.twist.twist.linear.vector
        v.x, v.y, v.z = velocity
        return msg

    def diagnostic_statuses(self):
        health = self.sim.health(time.monotonic())
        return [diagnostic_status('anafi_sim: simulated Anafi (%s)' % self.drone, WARN if health.warning else OK,
                                  health.message, health.values, hardware_id=self.drone)]

    # ------------------------------------------------------------- main loop
    def _hold_at_zero(self, clock_msg):
        """Lockstep: simulation time 0 until the /clock subscribers settled (the nodes' timers start at 0)."""
        hold = self.start_hold
        while not rospy.is_shutdown():
            self.pub_clock.publish(clock_msg)
            if hold.ready(time.monotonic(), self.pub_clock.get_num_connections()):
                break
            time.sleep(0.05)
        (self.ctx.logwarn if hold.timed_out else self.ctx.loginfo)(
            'anafi_sim: lockstep: %d /clock subscribers%s, starting simulation time', hold.count or 0,
            ' (start hold timed out)' if hold.timed_out else '')

    @property
    def steps_alone(self):
        """True when this simulator needs a loop of its own (lockstep); else a host may step it with others."""
        return self.sim.lockstep is not None

    def start_stepping(self, wall):
        """Diagnostics, then simulation time 0 at wall time ``wall`` [s] (a host starts its simulators at one
        instant, so that their steps fall due together: one wake-up per step for all)."""
        start_diagnostics_thread(1.0, self.diagnostic_statuses, self.pub_diag, ctx=self.ctx,
                                 stamp=lambda: self._stamp(self.sim.clock.t))
        self.sim.start(wall)

    def tick(self):
        """One step without lockstep and its outputs; the wall time [s] until the next step is due."""
        step = self.sim.step()
        self._log_events(step)
        if step.clock and self.pub_clock is not None:
            self.pub_clock.publish(Clock(clock=sim_time(step.t)))
        self._publish_step(step)
        return self.sim.pace(time.monotonic())

    def _log_events(self, step):
        for event, accepted, state in step.events:
            self.ctx.loginfo('anafi_sim: %s %s %s, state now %s', self.drone, event,
                             'accepted' if accepted else 'ignored', state)

    def _publish_step(self, step):
        if step.sample is not None:
            self._publish_truth(step.sample, self._stamp(step.t))
        if step.estimate is not None:
            self._publish_estimate(step.estimate, self._stamp(step.t))
        if step.state is not None:
            self.pub_state.publish(String(step.state))

    def run(self):
        sim = self.sim
        clock_msg = Clock()
        start_diagnostics_thread(1.0, self.diagnostic_statuses, self.pub_diag, ctx=self.ctx,
                                 stamp=lambda: self._stamp(sim.clock.t))
        if self.start_hold is not None:
            self._hold_at_zero(clock_msg)
        sim.start(time.monotonic())

        def poke():
            self.pub_clock.publish(clock_msg)
        first_hold = self.start_hold is not None
        while not rospy.is_shutdown():
            step = sim.step()
            self._log_events(step)
            if step.clock and self.pub_clock is not None:
                clock_msg.clock = sim_time(step.t)
                self.pub_clock.publish(clock_msg)
            if first_hold:              # lockstep: nodes polling for /clock > 0 start at the first step
                first_hold = False
                hold_until = time.monotonic() + FIRST_TICK_HOLD
                while time.monotonic() < hold_until and not rospy.is_shutdown():
                    time.sleep(0.01)
                    poke()
                sim.clock.resume(time.monotonic())
            waited = sim.sync(step.t, poke)     # lockstep: the controller's command of the period at step.t
            if waited is not None:
                if not waited and not rospy.is_shutdown():
                    self.ctx.logwarn_throttle(5.0, 'anafi_sim: lockstep: no command within %g s wall at t = %.3f '
                                              's (%d timeouts)' % (sim.lockstep.timeout, step.t,
                                                                   sim.lockstep.timeouts))
                sim.clock.resume(time.monotonic())
            self._publish_step(step)
            delay = sim.pace(time.monotonic())
            if delay > 0.0:
                time.sleep(delay)
        if sim.lockstep is not None:
            r = sim.lockstep.report()
            self.ctx.loginfo('anafi_sim: lockstep: %d periods waited, %d timeouts, %d times silent; wait mean '
                             '%.4f s, max %.3f s wall', r.waits, r.timeouts, r.disarms, r.wait_wall_mean,
                             r.wait_wall_max)
        self.server.stop()

    def shutdown(self):
        """Stop serving telemetry (the host calls it before ROS shuts down)."""
        self.server.stop()


def main():
    run_node('anafi_sim', AnafiSimNode, respawned=True)
