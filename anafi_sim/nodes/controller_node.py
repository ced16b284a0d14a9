#!/usr/bin/env python3
"""One tracking-controller node for every implementation of the controller contract (thin node).

Stage: controllers -> piloting command. ``~controller`` picks the implementation (``anafi_control.contract``)
by its name in ``anafi_control.registry`` (any entry with a node adapter): ``mpc`` = the paper's MPC
(``anafi_control.mpc_tracking.MpcTracking``, run as node ``mpc_controller`` by mpc.launch), ``pid`` = the
paper's PID framework in one process (``anafi_control.pid_framework.PidTracking``, node ``pid_framework``,
pid.launch mode single; ``pid_single`` is the same), ``preview_mpc`` = the preview MPC beyond the paper
(``anafi_control.preview_mpc.PreviewMpc``, node ``preview_mpc_controller``, preview_mpc.launch; it also takes
the trajectory generator's preview, ~reference_topic command/trajectory, trajectory_msgs/
MultiDOFJointTrajectory, and publishes preview_mpc/{predicted,reference}_path and preview_mpc/stats; its
parameters: anafi_sim/config/preview_mpc.yaml, ~model_file, ~max_tilt_deg, ~max_vertical_speed,
~max_yaw_rate_deg; cfg/PreviewMpc.cfg). Every 1/~rate s of ROS time one ``cycle``; the command goes
out every cycle, or every 1/~command_rate s for a controller with a command rate (pid: cycles 30 Hz,
commands 10 Hz).

Namespace /<drone> (default /anafi). Topics, relative to the namespace:
- in  ~state_topic (nav_msgs/Odometry, default drone/odom = the drone's estimate as in the paper;
      ground_truth/odom selectable; pose in the world frame, twist in the child frame),
      ~waypoint_topic (default position_control/waypoint: ENU m, m/s, yaw deg; type ~waypoint_type: anafi_sim
      = anafi_sim/Waypoint (default), anafi_control = the reference implementation's anafi_control/Waypoint);
- out ~command_topic (olympe_bridge/PilotingCommand, default drone/rpyt). Failsafes (docs/reliability.md,
      anafi_control.contract): a bad / stale waypoint -> the controller holds the position
      where the hold began with its own loop (commands keep flowing); no / bad / stale state, a clock jump,
      no waypoint yet or a failed controller -> nothing is published, so the firmware's hover brake stops
      and holds the drone;
      /diagnostics (1 Hz of wall time: OK tracking or waiting for the first waypoint, WARN limiting (a limit
      of the flight envelope acted), holding or silent for missing / stale / non-finite input or a clock
      jump, stalled (no cycle for ~stall_timeout s of wall time: ROS time stopped), ERROR the controller failed
      or a second commander; with counters);
- in  ~command_topic too: commands of another node there = a second commander of the drone
      (anafi_control.commanders): ERROR naming it and no command until it is gone (docs/reliability.md).
- mpc only: mpc/predicted_path and mpc/reference_path (nav_msgs/Path in ~frame_id, the drone positions x_k*
      and waypoint positions z_k over the horizon; built only while someone subscribes), mpc/stats
      (anafi_sim/MpcStats), dynamic_reconfigure (cfg/Mpc.cfg: weights, limits, horizon,
      carry_cumulative_errors, applied live).
Parameters: ~controller (a registered name, default mpc), ~rate [Hz] (default the controller's RATE),
~command_rate [Hz] (pid), ~state_timeout, ~waypoint_timeout [s], the flight envelope
(anafi_control.envelope: ~geofence_radius,
~min_altitude, ~max_altitude, ~max_waypoint_jump [m], ~max_reference_speed, ~max_reference_vertical_speed [m/s],
~max_reference_acceleration [m/s^2], ~max_command_tilt_deg [deg]), ~stall_timeout [s of wall time without a
cycle -> WARN 'stalled'], ~state_topic, ~waypoint_topic, ~waypoint_type, ~command_topic; mpc: the keys of
anafi_sim/config/mpc.yaml; pid: ~<loop>/<pid param> of anafi_sim/config/pid.yaml. Bad parameters:
logfatal, then the node stays up in ERROR (not respawned: docs/nodes.md).

A new controller: its ``contract.Controller`` subclass, its YAML and one entry in ``anafi_control.registry``
(docs/architecture.md, "Adding a controller"); the generic ``Adapter`` runs it (its ``from_config`` reads the
~params). Extra topics need an ``Adapter`` subclass in ``ADAPTERS`` (``setup``/``after_cycle``, e.g. the
preview MPC's ``PreviewAdapter``) named by the entry's ``node``.

Hosting (``anafi_sim.ros.context``): ``ControllerNode(controller, ctx)`` runs the instance ``ctx`` names (e.g.
NodeContext('/anafi1/mpc_controller', bus) in a host process): its ~params, topics, dynamic_reconfigure
server and diagnostics are that name's, exactly as the node of that name would have them; ``run()`` works
in any thread, ``shutdown()`` stops its timers (no command after it).
"""
import math
import threading
import time

import rospy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path

import anafi_sim  # noqa: F401 (before anafi_control: checks it is the control library, README)
from anafi_control.commanders import DOWN, LISTEN, RESUMED
from anafi_control.contract import LEVEL_ERROR, OK, STALL_TIMEOUT, Controller, TIMEOUT_DEFAULTS, WAITING, health, \
    stalled
from anafi_control import registry
from anafi_control.mpc_tracking import (DEFAULTS as MPC_TRACKING_DEFAULTS, PARAM_NAMES, RECONFIGURABLE,
                                        predicted_positions, reference_positions)
from anafi_control.pid_framework import DEFAULTS as PID_DEFAULTS, LOOP_NAMES
from anafi_control.preview_mpc import DEFAULTS as PREVIEW_DEFAULTS, RECONFIGURABLE as PREVIEW_RECONFIGURABLE, \
    PredictionModel
from anafi_control.contract import ReferenceSample
from anafi_control.frames import yaw_from_quaternion
from anafi_sim.cfg import MpcConfig
from anafi_sim.sim.bridge import MAX_TILT_DEG, MAX_VERTICAL_SPEED, MAX_YAW_RATE_DEG
from anafi_sim.sim.drone_model import DEFAULT_MODEL_FILE, load_model_params, model_file_path
from anafi_sim.msg import MpcStats
from anafi_sim.ros.reconfigure import TracedServer
from anafi_sim import names
from anafi_sim.ros.conversions import amend_health, subscribe_inputs, waypoint_admission, waypoint_limits
from anafi_sim.ros.waypoints import DEFAULT_WAYPOINT_TYPE, WAYPOINT_TYPES
from anafi_sim.ros.commander_watch import CommandTopicWatch
from anafi_sim.ros.context import NodeContext
from anafi_sim.ros.node import (Timer, diagnostics_publisher, health_status, namespace_id, private_params, run_node,
                                sleep_until_aligned, start_diagnostics_thread)
from anafi_sim.sim.clock import TIMER_PHASES
from anafi_sim.ros.wire_types import piloting_command_class


def _mapping_param(ctx, name):
    """~name of the NodeContext ``ctx`` as a dict ({} when unset); ValueError when it is something else."""
    value = ctx.get_param(name, {})
    if not isinstance(value, dict):
        raise ValueError('~%s must be a mapping of pid parameters, got %r' % (name, value))
    return value


class Adapter(object):
    """What the node does for one kind of controller (the registry entry's ``node``: ``contract`` = this
    generic one, enough for any controller of the contract): ``build`` it from the ~params, and, optionally,
    extra publishers (``setup``), per-cycle output (``cycle_info`` under the node's lock, ``after_cycle``) and
    diagnostic values. The default builds the entry's core with its ``from_config`` (the reader of its YAML
    the engine uses too) over the ~params of its ``CONFIG_KEYS``, ~state_timeout and ~waypoint_timeout
    checked here."""
    label = None              # diagnostics name prefix and log prefix (None: the registry name)
    controller_class = Controller   # the contract.Controller subclass (an instance's: its entry's core)

    def __init__(self, node, entry):
        self.node = node
        self.entry = entry
        self.controller_class = entry.core_class()   # the contract.Controller subclass
        self.label = self.label or entry.name

    def build(self, p):
        """The contract.Controller, from the node's ParamReader ``p`` (and the context's get_param for
        mappings)."""
        ctx = self.node.ctx
        config = dict((k, ctx.get_param(k)) for k in self.controller_class.CONFIG_KEYS if ctx.has_param(k))
        config.update(state_timeout=p.positive('state_timeout', TIMEOUT_DEFAULTS['state_timeout']),
                      waypoint_timeout=p.number('waypoint_timeout', TIMEOUT_DEFAULTS['waypoint_timeout'],
                                                minimum=0.0))
        return self.controller_class.from_config(config, limits=waypoint_limits(p))

    def setup(self):
        """Extra publishers, servers (the core exists, subscribers are not yet connected)."""

    def cycle_info(self):
        """Anything ``after_cycle`` needs from the core, read under the node's lock right after the cycle."""

    def after_cycle(self, out, stamp, info, started):
        """Extra output of a cycle (``started``: time.perf_counter() at its start)."""

    def diagnostic_values(self):
        """[(key, value)] added to the diagnostic status (called under the node's lock)."""
        return []


class MpcAdapter(Adapter):
    """The paper's MPC: mpc.yaml parameters, dynamic_reconfigure, mpc/stats and the predicted/reference paths."""
    label = 'mpc_controller'
    #: the parameters dynamic_reconfigure sets (cfg/Mpc.cfg)
    reconfigurable = RECONFIGURABLE

    def build(self, p):
        ctx = self.node.ctx
        config = dict((k, ctx.get_param(k)) for k in PARAM_NAMES if ctx.has_param(k))
        yaw_config = ctx.get_param('yaw', None)
        if yaw_config is not None and not isinstance(yaw_config, dict):
            raise ValueError('~yaw must be a mapping of pid parameters, got %r' % (yaw_config,))
        d = MPC_TRACKING_DEFAULTS
        self.frame_id = p.ros_name('frame_id', 'world')
        config.update(yaw=yaw_config, state_timeout=p.positive('state_timeout', d['state_timeout']),
                      waypoint_timeout=p.number('waypoint_timeout', d['waypoint_timeout'], minimum=0.0),
                      twist_in_child_frame=p.flag('twist_in_child_frame', d['twist_in_child_frame']),
                      cum_reset_distance=p.positive('cum_reset_distance', d['cum_reset_distance']))
        return self.controller_class.from_config(config, limits=waypoint_limits(p))

    def setup(self):
        core, ctx = self.node.core, self.node.ctx
        if abs(self.node.rate * core.mpc.dt - 1.0) > 1e-6:
            ctx.logwarn('%s: ~rate %.3g Hz does not match the MPC step dt %.3g s (the model assumes one '
                        'solve per dt)', self.node.who, self.node.rate, core.mpc.dt)
        self.pub_pred = ctx.publisher('mpc/predicted_path', Path, queue_size=2)
        self.pub_ref = ctx.publisher('mpc/reference_path', Path, queue_size=2)
        self.pub_stats = ctx.publisher(names.MPC_STATS, MpcStats, queue_size=10)
        self.reconfigure_server = TracedServer(MpcConfig, self._on_reconfigure, ctx=ctx)
        ctx.loginfo('%s: N=%d, dt=%.2f s', self.node.who, core.mpc.N, core.mpc.dt)

    def _on_reconfigure(self, config, level):
        core, keys = self.node.core, self.reconfigurable
        with self.node.lock:
            try:
                before = core.config()
                applied = core.reconfigure(dict((k, config[k]) for k in keys))
                changed = [k for k in keys if applied[k] != before[k]]
                if changed:
                    self.node.ctx.loginfo('%s: reconfigured %s', self.node.who,
                                          ', '.join('%s=%s' % (k, applied[k]) for k in changed))
            except ValueError as err:
                self.node.ctx.logerr('%s: reconfiguration refused (%s); keeping the current values', self.node.who,
                                     err)
                applied = core.config()
        for k in keys:
            config[k] = applied[k]
        return config

    def cycle_info(self):
        core = self.node.core
        return core.counters['cycles'], core.counters['hover'], core.mpc.N, core.mpc.dt

    def paths(self, result):
        """(predicted, reference) positions of a cycle's result (None when there is none)."""
        return predicted_positions(result), reference_positions(result)

    def after_cycle(self, out, stamp, info, started):
        """Publish the predicted and reference paths (when subscribed) and the MPC's statistics of the cycle."""
        cycles, hovers, horizon, dt = info
        predicted, reference = self.paths(out.result)
        if self.pub_pred.get_num_connections():
            self.pub_pred.publish(self._path(predicted, stamp, dt))
        if self.pub_ref.get_num_connections():
            self.pub_ref.publish(self._path(reference, stamp, dt))
        res = out.result
        s = MpcStats()
        s.header.stamp = stamp
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
        s.cycle_time = time.perf_counter() - started
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

    def diagnostic_values(self):
        core = self.node.core
        values = []
        res = core.last.result
        if res is not None:
            values += [('osqp_status', res.status), ('iterations', res.iterations),
                       ('solve_time_ms', '%.3f' % (1e3 * res.solve_time)),
                       ('run_time_ms', '%.3f' % (1e3 * res.run_time))]
        config = core.config()
        return values + [(k, config[k]) for k in ('N', 'r', 'q_cum', 'q_cum_terminal')]


class PidAdapter(Adapter):
    """The paper's PID framework in one process: loop parameters ~<loop>/<pid param> (pid.yaml)."""
    label = 'pid_framework'

    def build(self, p):
        config = dict((loop, _mapping_param(self.node.ctx, loop)) for loop in LOOP_NAMES)
        config.update(state_timeout=p.positive('state_timeout', PID_DEFAULTS['state_timeout']),
                      waypoint_timeout=p.number('waypoint_timeout', PID_DEFAULTS['waypoint_timeout'], minimum=0.0))
        return self.controller_class.from_config(config, limits=waypoint_limits(p))

    def diagnostic_values(self):
        fw = self.node.core.framework
        return [('framework refused inputs', fw.rejected_inputs)] + [
            ('%s effort' % loop, '%g' % fw.efforts[loop]) for loop in LOOP_NAMES]


def reference_samples(msg):
    """trajectory_msgs/MultiDOFJointTrajectory -> [contract.ReferenceSample] (first transform of each point:
    time = header.stamp + time_from_start [s], translation, linear velocity and acceleration, yaw [deg] of
    the rotation; a missing velocity / acceleration is zero)."""
    t0 = msg.header.stamp.to_sec()
    out = []
    for point in msg.points:
        tf = point.transforms[0]
        v = point.velocities[0].linear if point.velocities else None
        a = point.accelerations[0].linear if point.accelerations else None
        r = tf.rotation
        out.append(ReferenceSample(t0 + point.time_from_start.to_sec(),
                                   (tf.translation.x, tf.translation.y, tf.translation.z),
                                   (v.x, v.y, v.z) if v is not None else (0.0, 0.0, 0.0),
                                   (a.x, a.y, a.z) if a is not None else (0.0, 0.0, 0.0),
                                   math.degrees(yaw_from_quaternion(r.x, r.y, r.z, r.w))))
    return out


class PreviewAdapter(MpcAdapter):
    """The preview MPC: preview_mpc.yaml parameters, the prediction model of ~model_file (anafi_model.yaml) and
    the bridge limits (~max_tilt_deg, ~max_vertical_speed, ~max_yaw_rate_deg), the reference preview on
    ~reference_topic (trajectory_msgs/MultiDOFJointTrajectory, default command/trajectory), dynamic_reconfigure
    (cfg/PreviewMpc.cfg), preview_mpc/stats (anafi_sim/MpcStats) and preview_mpc/{predicted,reference}_path."""
    label = 'preview_mpc'
    reconfigurable = PREVIEW_RECONFIGURABLE

    def build(self, p):
        ctx = self.node.ctx
        config = dict((k, ctx.get_param(k)) for k in PREVIEW_DEFAULTS if ctx.has_param(k))
        model = PredictionModel.from_params(load_model_params(model_file_path(p.string('model_file', '') or DEFAULT_MODEL_FILE)),
                                            p.positive('max_tilt_deg', MAX_TILT_DEG),
                                            p.positive('max_vertical_speed', MAX_VERTICAL_SPEED),
                                            p.positive('max_yaw_rate_deg', MAX_YAW_RATE_DEG))
        self.frame_id = p.ros_name('frame_id', 'world')
        self.reference_topic = p.ros_name('reference_topic', names.REFERENCE_PREVIEW)
        return self.controller_class.from_config(config, limits=waypoint_limits(p), model=model)

    def setup(self):
        from trajectory_msgs.msg import MultiDOFJointTrajectory
        from anafi_sim.cfg import PreviewMpcConfig
        core, ctx = self.node.core, self.node.ctx
        self.pub_pred = ctx.publisher('preview_mpc/predicted_path', Path, queue_size=2)
        self.pub_ref = ctx.publisher('preview_mpc/reference_path', Path, queue_size=2)
        self.pub_stats = ctx.publisher('preview_mpc/stats', MpcStats, queue_size=10)
        ctx.subscriber(self.reference_topic, MultiDOFJointTrajectory, self._on_reference, queue_size=2)
        self.reconfigure_server = TracedServer(PreviewMpcConfig, self._on_reconfigure, ctx=ctx)
        ctx.loginfo('%s: N=%d, dt=%.3f s, preview on %s', self.node.who, core.N, core.dt,
                    ctx.resolve(self.reference_topic))

    def _on_reference(self, msg):
        try:
            samples = reference_samples(msg)
        except (IndexError, AttributeError):
            samples = None
        with self.node.lock:
            ok = self.node.core.on_reference(rospy.get_time(), samples)
        if not ok:
            self.node.ctx.logwarn_throttle(5.0, '%s: unusable preview refused (%d so far)' % (
                self.node.ctx.name, self.node.core.counters['rejected_previews']))

    def cycle_info(self):
        core = self.node.core
        return core.counters['cycles'], core.counters['hover'], core.N, core.dt

    def paths(self, result):
        return (None, None) if result is None else (result.predicted, result.reference)

    def diagnostic_values(self):
        core = self.node.core
        res = core.last.result
        values = [('previews', core.counters['previews']), ('preview cycles', core.counters['preview_cycles']),
                  ('estimator cycles', core.counters['estimator_cycles'])]
        if res is not None:
            values += [('osqp_status', res.status), ('iterations', res.iterations), ('source', res.source),
                       ('disturbance', '%.3f %.3f %.3f' % tuple(res.disturbance))]
        return values


#: node adapters by kind (a registry entry's ``node``; the controllers themselves: anafi_control.registry)
ADAPTERS = {registry.GENERIC: Adapter, 'mpc_paths': MpcAdapter, 'pid_framework': PidAdapter,
            'preview_paths': PreviewAdapter}


class ControllerNode(object):
    """The node instance ``ctx`` (a NodeContext; None: the process's node) running the controller ~controller
    (default ``controller``, else mpc)."""

    def __init__(self, controller=None, ctx=None):
        self.ctx = ctx = ctx or NodeContext.process()
        self.timers = []
        self.stopped = False
        p = private_params(ctx)
        kind = p.choice('controller', controller or 'mpc', registry.node_names())
        entry = registry.get(kind)
        self.adapter = ADAPTERS[entry.node](self, entry)
        #: the name the adapter's log lines give: its label (the node is named on /rosout, or, hosted, by the
        #: context's prefix)
        self.who = self.adapter.label
        self.core = self.adapter.build(p)
        self.rate = p.positive('rate', self.core.RATE)
        self.command_rate = None if self.core.COMMAND_RATE is None else \
            p.positive('command_rate', self.core.COMMAND_RATE)
        self.timer_phase = p.number('timer_phase', TIMER_PHASES['controller'])
        self.stall_timeout = p.positive('stall_timeout', STALL_TIMEOUT)
        self.last_cycle_wall = None      # time.monotonic() of the last cycle timer (None: none yet)
        state_topic = p.ros_name('state_topic', names.ESTIMATE)
        waypoint_topic = p.ros_name('waypoint_topic', names.WAYPOINT)
        command_topic = p.ros_name('command_topic', names.COMMAND)
        waypoint_type = p.choice('waypoint_type', DEFAULT_WAYPOINT_TYPE, WAYPOINT_TYPES)
        self.lock = threading.Lock()
        self.last_key = None
        self.commands = self.hover_commands = self.silent_cycles = 0
        self.Command = piloting_command_class()
        self.pub_cmd = ctx.publisher(command_topic, self.Command, queue_size=10)
        self.commanders = CommandTopicWatch(command_topic, self.Command, ctx=ctx)   # one drone, one commander
        self.pub_diag = diagnostics_publisher(ctx=ctx)
        self.adapter.setup()
        self.admission = waypoint_admission(p)
        self.state_topic, self.waypoint_topic = subscribe_inputs(self.core, self.lock, state_topic, waypoint_topic,
                                                                  waypoint_type, self.admission, ctx=ctx)
        ctx.loginfo('%s: %s controller, state %s, waypoint %s (%s/Waypoint) -> %s; cycle %g Hz, command %g Hz',
                    ctx.name, kind, self.state_topic, self.waypoint_topic, waypoint_type,
                    ctx.resolve(command_topic), self.rate, self.command_rate or self.rate)

    # -- cycle and command ----------------------------------------------------------------------
    def _on_cycle(self, _event=None):
        self.last_cycle_wall = time.monotonic()
        commanders = self.commanders.check()
        if commanders in (DOWN, LISTEN):   # another node commands this drone, or listening first: no command
            return
        if commanders == RESUMED:
            with self.lock:
                self.core.reset()
        started = time.perf_counter()
        stamp = rospy.Time.now()
        with self.lock:
            out = self.core.cycle(stamp.to_sec())
            info = self.adapter.cycle_info()
        if out.key != self.last_key:
            if out.key == OK:
                self.ctx.loginfo('%s: tracking the waypoint', self.ctx.name)
            elif out.key in WAITING:
                self.ctx.loginfo('%s: %s', self.ctx.name, health(out.key, out.reason).message)
            else:
                self.ctx.logwarn('%s: %s', self.ctx.name, health(out.key, out.reason).message)
            self.last_key = out.key
        if self.command_rate is None:
            self._publish(out.command, stamp)
        self.adapter.after_cycle(out, stamp, info, started)

    def _on_command(self, _event=None):
        stamp = rospy.Time.now()
        with self.lock:
            command = self.core.last.command
        self._publish(command, stamp)

    def _publish(self, command, stamp):
        if command is None or self.commanders.silent:
            # failsafe SILENT (or warming up), or a second commander: nothing, the firmware's hover brake acts
            with self.lock:
                self.silent_cycles += 1
            return
        msg = self.Command()
        msg.header.stamp = stamp
        msg.roll, msg.pitch, msg.yaw, msg.gaz = command
        with self.lock:
            self.commands += 1
            self.hover_commands += not any(command)
        self.commanders.sent(msg)
        self.pub_cmd.publish(msg)

    # -- diagnostics (own thread, wall clock: reports even when /clock stops) --------------------
    def diagnostic_statuses(self):
        with self.lock:
            health = amend_health(self.core.health(), self.admission)
            if self.last_cycle_wall is not None:    # ROS time stopped (/clock): the cycles are frozen
                health = stalled(health, time.monotonic() - self.last_cycle_wall, self.stall_timeout)
            extra = [('commands sent', self.commands), ('hover commands', self.hover_commands),
                     ('command periods without a command (silent)', self.silent_cycles),
                     ('state topic', self.state_topic), ('waypoint topic', self.waypoint_topic),
                     ('ROS time jumps back (timers kept running)',
                      max([t.jumps_back for t in self.timers] or [0]))]
            gate = getattr(self.core, 'gate', None)
            if gate is not None:        # the flight envelope's fence: where it is, how large
                extra += [('geofence centre (take-off point) [m]', 'none yet' if gate.centre is None else
                           '%.3f %.3f' % tuple(gate.centre)),
                          ('geofence radius [m]', gate.envelope.geofence_radius)]
            extra += self.adapter.diagnostic_values()
        self.commanders.check_presence()
        extra += self.commanders.values()
        second = self.commanders.message()
        if second is not None:
            health = health._replace(level=LEVEL_ERROR, message=second)
        return [health_status('%s: %s' % (self.adapter.label, self.ctx.name), health, namespace_id(self.ctx),
                              extra)]

    def run(self):
        """Cycle until rospy shuts down (any thread)."""
        start_diagnostics_thread(1.0, self.diagnostic_statuses, self.pub_diag, ctx=self.ctx)
        sleep_until_aligned(1.0 / self.rate, self.timer_phase)      # cycles at timer_phase + k / rate
        # survive /clock going back (simulator respawned): the core sees the jump and goes SILENT, then tracks
        timers = [Timer(1.0 / self.rate, self._on_cycle, 'control', ctx=self.ctx)]
        if self.command_rate is not None:
            timers.append(Timer(1.0 / self.command_rate, self._on_command, 'command', ctx=self.ctx))
        self.timers = timers
        if self.stopped:        # shut down while waiting for the first cycle
            self.shutdown()
        try:
            rospy.spin()
        finally:
            self.shutdown()

    def shutdown(self):
        """Stop the cycles (no command after it); the host calls it before rospy shuts down."""
        self.stopped = True
        for timer in self.timers:
            timer.shutdown()


def main(controller=None, name='controller'):
    """Run the node (``controller``: the default of ~controller; ``name``: the default node name)."""
    run_node(name, lambda: ControllerNode(controller), respawned=True)
