#!/usr/bin/env python3
"""The paper's MPC tracking controller (Sec. III-E) for one drone (thin node).

Stage: controllers -> piloting command. Wires ROS to ``anafi_control.mpc_tracking.MpcTracking`` (the
cumulative-error MPC on OSQP plus the PID framework's yaw loop). Every 1/~rate s of ROS time (10 Hz) one
cycle: solve, publish the command; the yaw PID steps on every state message.

Namespace /<drone> (default /anafi). Topics, relative to the namespace:
- in  ~state_topic (nav_msgs/Odometry, default drone/odom = the drone's estimate as in the paper;
      ground_truth/odom selectable; pose in the world frame, twist in the child frame),
      ~waypoint_topic (anafi_sim/Waypoint, default position_control/waypoint: ENU m, m/s, yaw deg);
- out ~command_topic (olympe_bridge/PilotingCommand, default drone/rpyt, 10 Hz; hover = all zero),
      mpc/predicted_path and mpc/reference_path (nav_msgs/Path in ~frame_id, the drone positions x_k* and
      waypoint positions z_k over the horizon; built only while someone subscribes),
      mpc/stats (anafi_sim/MpcStats: ok, OSQP status, iterations, solve/run/cycle time, u_0*, counters),
      /diagnostics (1 Hz of wall time: OK / WARN waiting for inputs / ERROR hovering, with counters).
dynamic_reconfigure (cfg/Mpc.cfg): weights, limits, horizon, carry_cumulative_errors, applied live.
Parameters: anafi_sim/config/mpc.yaml. Bad parameters: logfatal, exit code 1.
"""
import math
import threading
import time

import rospy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from dynamic_reconfigure.server import Server
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry, Path

from anafi_control.mpc import DEFAULT_PARAMS as MPC_DEFAULTS
from anafi_control.mpc_tracking import (COUNTER_NAMES, DEFAULTS, RECONFIGURABLE, MpcTracking,
                                        predicted_positions, reference_positions)
from anafi_sim.cfg import MpcConfig
from anafi_sim.msg import MpcStats, Waypoint
from anafi_sim.ros.node import diagnostic_status, private_params, run_node, start_diagnostics_thread
from anafi_sim.ros.wire_types import piloting_command_class

#: flat MPC parameter names read from ~params (v_max split per axis, as the reconfigure server has them)
MPC_PARAM_NAMES = tuple(k for k in MPC_DEFAULTS if k != 'v_max') + ('v_max_x', 'v_max_y', 'v_max_z')

WAITING = ('no_state', 'no_waypoint')   # hover reasons that are normal before the inputs arrive


class MpcControllerNode(object):
    def __init__(self):
        p = private_params()
        self.rate = p.positive('rate', 10.0)
        state_topic = p.ros_name('state_topic', 'drone/odom')
        waypoint_topic = p.ros_name('waypoint_topic', 'position_control/waypoint')
        command_topic = p.ros_name('command_topic', 'drone/rpyt')
        self.frame_id = p.ros_name('frame_id', 'world')
        mpc_params = dict((k, rospy.get_param('~' + k)) for k in MPC_PARAM_NAMES if rospy.has_param('~' + k))
        yaw_config = rospy.get_param('~yaw', None)
        if yaw_config is not None and not isinstance(yaw_config, dict):
            raise ValueError('~yaw must be a mapping of pid parameters, got %r' % (yaw_config,))
        self.core = MpcTracking(
            mpc_params, yaw_config,
            state_timeout=p.positive('state_timeout', DEFAULTS['state_timeout']),
            waypoint_timeout=p.positive('waypoint_timeout', DEFAULTS['waypoint_timeout']),
            twist_in_child_frame=p.flag('twist_in_child_frame', DEFAULTS['twist_in_child_frame']),
            cum_reset_distance=p.positive('cum_reset_distance', DEFAULTS['cum_reset_distance']))
        if abs(self.rate * self.core.mpc.dt - 1.0) > 1e-6:
            rospy.logwarn('mpc_controller: ~rate %.3g Hz does not match the MPC step dt %.3g s (the model '
                          'assumes one solve per dt)', self.rate, self.core.mpc.dt)
        ns = rospy.get_namespace().strip('/')
        self.drone = ns.split('/')[-1] if ns else 'anafi'
        self.name = '%s/mpc_controller' % self.drone
        self.lock = threading.Lock()
        self.last_key = None
        self.Command = piloting_command_class()

        self.pub_cmd = rospy.Publisher(command_topic, self.Command, queue_size=10)
        self.pub_pred = rospy.Publisher('mpc/predicted_path', Path, queue_size=2)
        self.pub_ref = rospy.Publisher('mpc/reference_path', Path, queue_size=2)
        self.pub_stats = rospy.Publisher('mpc/stats', MpcStats, queue_size=10)
        self.pub_diag = rospy.Publisher('/diagnostics', DiagnosticArray, queue_size=5)
        self.reconfigure_server = Server(MpcConfig, self._on_reconfigure)
        rospy.Subscriber(state_topic, Odometry, self._on_state, queue_size=5, tcp_nodelay=True)
        rospy.Subscriber(waypoint_topic, Waypoint, self._on_waypoint, queue_size=5, tcp_nodelay=True)
        rospy.loginfo('mpc_controller: %s, N=%d, dt=%.2f s, %.1f Hz, state %s, waypoint %s -> %s',
                      self.drone, self.core.mpc.N, self.core.mpc.dt, self.rate,
                      rospy.resolve_name(state_topic), rospy.resolve_name(waypoint_topic),
                      rospy.resolve_name(command_topic))

    # -- inputs ---------------------------------------------------------------------------------
    def _on_state(self, msg):
        p, q, v = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear
        with self.lock:
            self.core.on_state(rospy.get_time(), (p.x, p.y, p.z), (q.x, q.y, q.z, q.w), (v.x, v.y, v.z))

    def _on_waypoint(self, msg):
        with self.lock:
            self.core.on_waypoint(rospy.get_time(), (msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz, msg.yaw))

    def _on_reconfigure(self, config, level):
        with self.lock:
            try:
                before = self.core.config()
                applied = self.core.reconfigure(dict((k, config[k]) for k in RECONFIGURABLE))
                changed = [k for k in RECONFIGURABLE if applied[k] != before[k]]
                if changed:
                    rospy.loginfo('mpc_controller: reconfigured %s', ', '.join(
                        '%s=%s' % (k, applied[k]) for k in changed))
            except ValueError as err:
                rospy.logerr('mpc_controller: reconfiguration refused (%s); keeping the current values', err)
                applied = self.core.config()
        for k in RECONFIGURABLE:
            config[k] = applied[k]
        return config

    # -- cycle ----------------------------------------------------------------------------------
    def cycle(self, _event=None):
        t0 = time.perf_counter()
        now = rospy.Time.now()
        with self.lock:
            out = self.core.cycle(now.to_sec())
            cycles, hovers = self.core.counters['cycles'], self.core.counters['hover']
            horizon, dt = self.core.mpc.N, self.core.mpc.dt
        cmd = self.Command()
        cmd.header.stamp = now
        cmd.roll, cmd.pitch, cmd.yaw, cmd.gaz = out.command
        self.pub_cmd.publish(cmd)
        if out.key != self.last_key:
            if out.ok:
                rospy.loginfo('mpc_controller: tracking the waypoint')
            elif out.key in WAITING:
                rospy.loginfo('mpc_controller: hover: %s', out.reason)
            else:
                rospy.logwarn('mpc_controller: hover: %s', out.reason)
            self.last_key = out.key
        if self.pub_pred.get_num_connections():
            self.pub_pred.publish(self._path(predicted_positions(out.result), now, dt))
        if self.pub_ref.get_num_connections():
            self.pub_ref.publish(self._path(reference_positions(out.result), now, dt))
        res = out.result
        s = MpcStats()
        s.header.stamp = now
        s.header.frame_id = self.frame_id
        s.ok = out.ok
        s.status = res.status if (out.ok and res is not None) else out.reason
        if res is not None:
            s.iterations = res.iterations
            s.solve_time = res.solve_time if math.isfinite(res.solve_time) else 0.0
            s.setup_time, s.run_time = res.setup_time, res.run_time
            s.acceleration.x, s.acceleration.y, s.acceleration.z = res.u0
            s.vz_command = res.vz_command
        s.horizon = horizon
        s.cycles, s.hover_cycles = cycles, hovers
        s.cycle_time = time.perf_counter() - t0
        self.pub_stats.publish(s)

    def _path(self, positions, stamp, dt):
        path = Path()
        path.header.stamp = stamp
        path.header.frame_id = self.frame_id
        if positions is None:
            return path
        for k, (x, y, z) in enumerate(positions):
            ps = PoseStamped()
            ps.header.stamp = stamp + rospy.Duration.from_sec(k * dt)
            ps.header.frame_id = self.frame_id
            ps.pose.position.x, ps.pose.position.y, ps.pose.position.z = float(x), float(y), float(z)
            ps.pose.orientation.w = 1.0
            path.poses.append(ps)
        return path

    # -- diagnostics (own thread, wall clock: reports even when /clock stops) --------------------
    def diagnostic_statuses(self):
        with self.lock:
            last = self.core.last
            counters = dict(self.core.counters)
            config = self.core.config()
        if last.ok:
            level, message = DiagnosticStatus.OK, 'tracking (OSQP %s)' % last.result.status
        elif last.key in WAITING:
            level, message = DiagnosticStatus.WARN, 'hover: ' + last.reason
        else:
            level, message = DiagnosticStatus.ERROR, 'hover: ' + last.reason
        values = [('last_reason', last.reason)]
        if last.result is not None:
            values += [('osqp_status', last.result.status), ('iterations', last.result.iterations),
                       ('solve_time_ms', '%.3f' % (1e3 * last.result.solve_time)),
                       ('run_time_ms', '%.3f' % (1e3 * last.result.run_time))]
        values += [(k, counters[k]) for k in COUNTER_NAMES]
        values += [('N', config['N']), ('r', config['r']), ('q_cum', config['q_cum']),
                   ('q_cum_terminal', config['q_cum_terminal'])]
        return [diagnostic_status(self.name, level, message, values, hardware_id=self.drone)]

    def run(self):
        start_diagnostics_thread(1.0, self.diagnostic_statuses, self.pub_diag)
        timer = rospy.Timer(rospy.Duration.from_sec(1.0 / self.rate), self.cycle)
        try:
            rospy.spin()
        finally:
            timer.shutdown()


if __name__ == '__main__':
    run_node('mpc_controller', MpcControllerNode)
