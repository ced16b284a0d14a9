#!/usr/bin/env python3
"""Trajectory generator node: a scenario (anafi_sim/config/scenarios/*.yaml) -> the paper's waypoint.

Stage: trajectory -> waypoint (-> PID / MPC). Thin node over
anafi_sim.mission.trajectory (Scenario, TrajectoryGenerator). Topics relative to the
node's namespace (/<drone>/):

- out ~waypoint_topic (default position_control/waypoint, anafi_sim/Waypoint:
  ENU position [m], velocity [m/s], yaw [deg]; header.frame_id ~frame_id) at
  ~rate Hz (10) of ROS time (simulation time under /use_sim_time); with
  ~waypoint_type anafi_control the reference implementation's
  anafi_control/Waypoint instead (no header; anafi_sim.ros.waypoints);
- out trajectory/begin, trajectory/end (std_msgs/Header, latched): stamp =
  the exact start / end of the measured phase, frame_id = scenario name;
  trajectory/status (std_msgs/String, latched YAML: scenario, state, phase);
- out ~preview_topic (default command/trajectory, trajectory_msgs/MultiDOFJointTrajectory, mav_control_rw's
  name): with every waypoint, while someone subscribes, the upcoming reference from now to now +
  ~preview_horizon s (3.0) every ~preview_step s (0.05): position, velocity, acceleration, yaw (the
  preview MPC's reference, anafi_control/preview_mpc.py); header.stamp = now, frame ~frame_id;
- in drone/state (std_msgs/String; ~wait_for_flying: start only once 'flying');
- in ~command (std_msgs/String): 'start', 'stop', 'restart', 'switch NAME'
  (NAME = scenario name or YAML path inside the scenario folders: ~scenario_dir, the package's
  config/scenarios, the folder of ~scenario_file; any other file is refused unread); services ~start, ~stop
  (std_srvs/Trigger) when std_srvs is installed.

Parameters: ~scenario (name, default circle_r2_v1) or ~scenario_file
(path, wins), ~scenario_dir (default: the package's config/scenarios),
~rate (10 Hz), ~preview_topic, ~preview_horizon [s], ~preview_step [s], ~autostart (true), ~wait_for_flying (true), ~start_timeout
(s of ROS time, 0 = wait forever), ~hold_when_idle (true: after the end or a
stop keep publishing the last position with zero velocity), ~exit_when_done
(false: true shuts the node down ~exit_delay s (1.0) after the scenario ends,
exit code 0; 1 when the drone never flew within ~start_timeout), ~frame_id
(world). A bad scenario or parameter: logfatal and exit 1.

Hosting (``anafi_sim.ros.context``): ``TrajectoryGeneratorNode(ctx)`` runs the instance ``ctx`` names (e.g.
NodeContext('/anafi1/trajectory_generator', bus) in a host process) with that name's parameters, topics,
services and diagnostics; its log lines start with the name in square brackets (the context's, as every hosted
instance's). ``run()`` works in any thread; hosted, ~exit_when_done ends the instance's ``run()`` only (the host
goes on); ``shutdown()`` ends the loop.
"""
import math
import os
import threading

import rospy
import yaml
from geometry_msgs.msg import Transform, Twist
from std_msgs.msg import Header, String
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint

import anafi_sim  # noqa: F401 (before anafi_control: checks it is the control library, README)
from anafi_control.frames import euler_to_quaternion

from anafi_sim.mission.trajectory import (SCENARIO_DIR, list_scenarios, load_scenario, scenario_folders,
                                          scenario_in_folders)
from anafi_sim.trusted import within
from anafi_sim.untrusted import clip
from anafi_sim.mission.generator import DONE, IDLE, RUNNING, TrajectoryGenerator
from anafi_sim import names
from anafi_sim.ros.context import NodeContext
from anafi_sim.ros.waypoints import DEFAULT_WAYPOINT_TYPE, WAYPOINT_TYPES, waypoint_class, waypoint_message
from anafi_sim.ros.node import (OK, WARN, diagnostic_status, diagnostics_publisher, namespace_id, private_params,
                                run_node, sleep_until_aligned, start_diagnostics_thread, wait_for_clock)
from anafi_sim.sim.clock import TIMER_PHASES

try:
    from std_srvs.srv import Trigger, TriggerResponse
except ImportError:   # std_srvs missing: the ~command topic still works
    Trigger = TriggerResponse = None


class TrajectoryGeneratorNode(object):
    """The node instance ``ctx`` (a NodeContext; None: the process's node)."""

    def __init__(self, ctx=None):
        self.ctx = ctx = ctx or NodeContext.process()
        self.stopped = False
        p = private_params(ctx)
        self.rate = p.positive('rate', 10.0)
        self.timer_phase = p.number('timer_phase', TIMER_PHASES['generator'])
        self.autostart = p.flag('autostart', True)
        self.wait_for_flying = p.flag('wait_for_flying', True)
        self.hold_when_idle = p.flag('hold_when_idle', True)
        self.exit_when_done = p.flag('exit_when_done', False)
        self.start_timeout = p.number('start_timeout', 0.0, minimum=0.0)
        self.exit_delay = p.number('exit_delay', 1.0, minimum=0.0)
        self.frame_id = p.string('frame_id', 'world')
        allowed = scenario_folders()     # parameters anyone may set: only files in these folders are read
        self.scenario_dir = p.string('scenario_dir', '') or SCENARIO_DIR
        if not within(self.scenario_dir, allowed):
            raise ValueError('scenario_dir %r: not inside the scenario folders (%s)'
                             % (self.scenario_dir[:200], ', '.join(allowed)))
        scenario_file = p.string('scenario_file', '')
        try:
            scenario = load_scenario(scenario_in_folders(scenario_file or p.string('scenario', 'circle_r2_v1'),
                                                         [self.scenario_dir] + allowed))
        except ValueError as e:
            raise ValueError('%s: %s (scenarios in %s: %s)'
                             % ('scenario_file' if scenario_file else 'scenario', e, self.scenario_dir,
                                ', '.join(list_scenarios(self.scenario_dir))))
        # 'switch' reads scenarios from ~scenario_dir, the package's scenarios and ~scenario_file's folder
        self.switch_folders = [self.scenario_dir, SCENARIO_DIR] + (
            [os.path.dirname(os.path.abspath(scenario_file))] if scenario_file else [])
        self.gen = TrajectoryGenerator(scenario, hold_when_idle=self.hold_when_idle)
        self.lock = threading.Lock()
        self.drone_state = ''
        self.pending_start = self.autostart
        self.done_time = None
        self.failed = False
        self.published = 0
        self.waypoint_type = p.choice('waypoint_type', DEFAULT_WAYPOINT_TYPE, WAYPOINT_TYPES)
        self.pub = ctx.publisher(p.string('waypoint_topic', names.WAYPOINT), waypoint_class(self.waypoint_type),
                                 queue_size=10)
        self.pub_begin = ctx.publisher(names.TRAJECTORY_BEGIN, Header, queue_size=2, latch=True)
        self.pub_end = ctx.publisher(names.TRAJECTORY_END, Header, queue_size=2, latch=True)
        self.pub_status = ctx.publisher(names.TRAJECTORY_STATUS, String, queue_size=5, latch=True)
        self.preview_horizon = p.number('preview_horizon', 3.0, minimum=0.0)
        self.preview_step = p.positive('preview_step', 0.05)
        self.pub_preview = ctx.publisher(p.string('preview_topic', names.REFERENCE_PREVIEW), MultiDOFJointTrajectory,
                                         queue_size=2)
        ctx.subscriber(names.DRONE_STATE, String, self._on_state, queue_size=5)
        ctx.subscriber('~command', String, self._on_command, queue_size=10)
        if Trigger is not None:
            ctx.service('~start', Trigger, lambda _: self._service('start'))
            ctx.service('~stop', Trigger, lambda _: self._service('stop'))
        self.pub_diag = diagnostics_publisher(ctx=ctx)
        for line in scenario.describe():
            self.ctx.loginfo('%s', line)
        self._status('')

    def diagnostic_statuses(self):
        """One status: the scenario, its state, waypoints published; WARN when the drone never flew."""
        with self.lock:
            name, state, published = self.gen.scenario.name, self.gen.state, self.published
        level, message = (WARN, 'drone never flying: scenario not started') if self.failed else (OK, state)
        return [diagnostic_status('trajectory_generator: %s' % self.ctx.name, level, message,
                                  [('scenario', name), ('state', state), ('waypoints published', published),
                                   ('drone state', self.drone_state or 'none')], namespace_id(self.ctx))]

    # ------------------------------------------------------------ inputs
    def _on_state(self, msg):
        self.drone_state = msg.data

    def _service(self, command):
        ok, text = self.command(command)
        self.ctx.loginfo('service %s: %s', command, text)
        return TriggerResponse(success=ok, message=text)

    def _on_command(self, msg):
        ok, text = self.command(msg.data)     # a topic anyone may publish on: its text clipped, the lines throttled
        (self.ctx.loginfo_throttle if ok else self.ctx.logwarn_throttle)(1.0, 'command %s: %s', clip(msg.data),
                                                                         clip(text))

    def command(self, text):
        """Apply 'start' | 'stop' | 'restart' | 'switch NAME'; returns (ok, message)."""
        words = str(text).strip().split(None, 1)
        if not words:
            return False, 'empty command'
        verb = words[0].lower()
        with self.lock:
            now = rospy.get_time()
            if verb in ('start', 'restart'):
                if verb == 'start' and self.gen.state == RUNNING:
                    return True, 'already running %s' % self.gen.scenario.name
                self.pending_start = True
                self.done_time = None
                return True, 'starting %s' % self.gen.scenario.name
            if verb == 'stop':
                self.pending_start = False
                self.gen.stop(now)
                return True, 'stopped'
            if verb == 'switch' and len(words) == 2:
                try:     # a topic anyone can publish on: only files in the scenario folders are read
                    scenario = load_scenario(scenario_in_folders(words[1].strip(), self.switch_folders))
                except ValueError as e:
                    return False, str(e)
                running = self.gen.state == RUNNING
                self.gen.switch(scenario, now, start=running)
                self.pending_start = not running
                self.done_time = None
                return True, 'switched to %s' % scenario.name
        return False, "unknown command (use 'start', 'stop', 'restart' or 'switch NAME')"

    # ------------------------------------------------------------ outputs
    def _status(self, phase):
        self.pub_status.publish(String(data=yaml.safe_dump(
            {'scenario': self.gen.scenario.name, 'state': self.gen.state, 'phase': phase},
            default_flow_style=True).strip()))

    def _header(self, t, name):
        h = Header()
        h.stamp = rospy.Time.from_sec(t)
        h.frame_id = name
        return h

    def _publish_events(self, events):
        for ev in events:
            if ev.kind == 'begin':
                self.pub_begin.publish(self._header(ev.time, ev.scenario))
                self.ctx.loginfo('%s: measured segment begins (t = %.3f s)', ev.scenario, ev.time)
            elif ev.kind == 'end':
                self.pub_end.publish(self._header(ev.time, ev.scenario))
                self.ctx.loginfo('%s: measured segment ends (t = %.3f s)', ev.scenario, ev.time)
            elif ev.kind == 'abort':
                self.ctx.logwarn('%s: measured segment aborted (t = %.3f s)', ev.scenario, ev.time)
            elif ev.kind == 'phase':
                self.ctx.loginfo('%s: phase %s', ev.scenario, ev.phase)
            elif ev.kind == 'done':
                self.ctx.loginfo('%s: scenario done', ev.scenario)
            if ev.kind in ('phase', 'done', 'stop', 'start'):
                self._status(ev.phase)

    def tick(self):
        now = rospy.get_time()
        with self.lock:
            if self.pending_start and (not self.wait_for_flying or self.drone_state == 'flying'):
                self.pending_start = False
                self.gen.start(now)
            wp, events = self.gen.update(now)
            if self.gen.state == DONE and self.done_time is None:
                self.done_time = now
        self._publish_events(events)
        if wp is not None:
            self.pub.publish(waypoint_message(self.waypoint_type, wp, rospy.Time.from_sec(now), self.frame_id))
            self.published += 1
            if self.pub_preview.get_num_connections():
                with self.lock:
                    samples = self.gen.preview(now, self.preview_horizon, self.preview_step)
                self.pub_preview.publish(self.preview_message(now, samples))

    def preview_message(self, now, samples):
        """trajectory_msgs/MultiDOFJointTrajectory of the generator's preview samples (one transform per point)."""
        traj = MultiDOFJointTrajectory()
        traj.header.stamp = rospy.Time.from_sec(now)
        traj.header.frame_id = self.frame_id
        traj.joint_names = ['base_link']
        for t, p, v, a, yaw in samples:
            point = MultiDOFJointTrajectoryPoint()
            tf = Transform()
            tf.translation.x, tf.translation.y, tf.translation.z = p
            q = euler_to_quaternion(0.0, 0.0, math.radians(yaw))
            tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w = q
            vel, acc = Twist(), Twist()
            vel.linear.x, vel.linear.y, vel.linear.z = v
            acc.linear.x, acc.linear.y, acc.linear.z = a
            point.transforms, point.velocities, point.accelerations = [tf], [vel], [acc]
            point.time_from_start = rospy.Duration.from_sec(t - now)
            traj.points.append(point)
        return traj

    def run(self):
        """Publish until rospy shuts down (any thread), ``shutdown()`` or, with ~exit_when_done, the end."""
        start_diagnostics_thread(1.0, self.diagnostic_statuses, self.pub_diag, ctx=self.ctx)
        wait_for_clock()
        sleep_until_aligned(1.0 / self.rate, self.timer_phase)      # ticks at timer_phase + k / rate
        t_start = rospy.get_time()
        warned = False
        rate = rospy.Rate(self.rate)
        while not rospy.is_shutdown() and not self.stopped:
            self.tick()
            now = rospy.get_time()
            if self.gen.state == IDLE and self.pending_start and self.start_timeout > 0 \
                    and now - t_start > self.start_timeout and not warned:
                warned = True
                self.ctx.logerr('drone not flying after %.1f s (drone/state %r)', self.start_timeout,
                                self.drone_state)
                if self.exit_when_done:
                    self.failed = True
                    self._end('drone never flying')
                    break
            if self.exit_when_done and self.done_time is not None and now - self.done_time >= self.exit_delay:
                self.ctx.loginfo('%s done, %d waypoints published: exiting', self.gen.scenario.name,
                                 self.published)
                self._end('scenario done')
                break
            try:
                rate.sleep()
            except rospy.ROSTimeMovedBackwardsException:
                self.ctx.logwarn('ROS time moved backwards: restarting %s', self.gen.scenario.name)
                with self.lock:
                    self.gen.reset()
                    self.pending_start = True
                    self.done_time = None
            except rospy.ROSInterruptException:
                break
        return not self.failed

    def _end(self, reason):
        """~exit_when_done: the process's node shuts rospy down; a hosted instance only ends (not its host)."""
        if not self.ctx.hosted:
            rospy.signal_shutdown(reason)

    def shutdown(self):
        """End ``run()``'s loop at its next tick (the host calls it before rospy shuts down)."""
        self.stopped = True


def main():
    run_node('trajectory_generator', TrajectoryGeneratorNode)
