#!/usr/bin/env python3
"""Experiment monitor node: starts the scenario when everything is up, prints live progress, ends the run.

Stage: experiment orchestration (experiment.launch, demo.launch). Thin node over
anafi_sim.experiments.monitor.ExperimentMonitor. Topics relative to the node's namespace (/<drone>/):

- in drone/state (std_msgs/String), drone/rpyt (olympe_bridge/PilotingCommand: non-zero commands
  counted, the controller is up and engaged; while the scenario runs, hover (all-zero) commands and
  the largest gap between the commands' header stamps are kept: a disturbed run),
  position_control/waypoint (anafi_sim/Waypoint), drone/odom (nav_msgs/Odometry, the estimate),
  trajectory/status (std_msgs/String YAML), trajectory/begin, trajectory/end (std_msgs/Header),
  evaluation/summary (std_msgs/String YAML), mpc/stats (anafi_sim/MpcStats), /diagnostics (the
  simulator's status: achieved real-time factor, overruns);
- out ~start_topic (default trajectory_generator/command, std_msgs/String, latched): 'start' once the
  drone flies, the controller has sent ~min_commands (5) non-zero commands and every node of
  ~wait_subscribers (names relative to the namespace, e.g. [evaluator, recorder]) subscribes to the
  waypoint topic; until then (with ~hold, true) position_control/waypoint = the scenario's start
  (hold point, zero velocity) every 0.1 s of ROS time, so the controller engages and the drone waits
  there; the generator takes over with the same point.

Every ~progress_period s of wall time (1.0; 0 = quiet) one progress line on stdout. When the
evaluator's summary is final, the node waits (<= ~evaluator_exit_timeout s wall, 15) for
~evaluator_node to exit (it writes ~csv_file and ~summary_file), draws ~plot_file from the CSV
(anafi_sim.experiments.plots; '' = no plot), writes ~info_file (YAML: anafi_sim.experiments.monitor run_info:
durations, achieved real-time factor, simulator overruns, MPC solve times, controller CPU time of the
nodes matching ~controller_nodes, fnmatch patterns of absolute node names), prints the summary and
shuts down (exit 0; 1 on failure: not ready within ~ready_timeout s wall (90), the scenario not ending
within its duration + ~end_margin s (30) of ROS time, no final summary ~final_timeout s (30) wall after
the end); with ~end_launch (false; experiment.launch: true) a run that ended well first ends the
roslaunch that started the node as Ctrl-C does (its exit status 0, no red "REQUIRED process has died";
a failed run still ends as a dead required node). ~scenario / ~scenario_file / ~scenario_dir as the
generator (for the scenario's duration);
~label: the run's name in the output.
"""
import fnmatch
import math
import os
import sys
import threading
import time

import rosgraph
import rospy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from std_msgs.msg import Header, String

from anafi_sim import harness
from anafi_sim.experiments.monitor import FAILED, FINAL, ExperimentMonitor, summary_lines
from anafi_sim.experiments.trajectory import SCENARIO_DIR, load_scenario
from anafi_sim.msg import MpcStats, Waypoint
from anafi_sim.ros import topics
from anafi_sim.ros.node import end_parent_launch, private_params, run_node
from anafi_sim.ros.wire_types import piloting_command_class

try:
    import psutil
except ImportError:   # CPU figures are optional
    psutil = None


def _yaml(msg):
    """The YAML data of a std_msgs/String, None when unreadable."""
    try:
        return yaml.safe_load(msg.data)
    except yaml.YAMLError:
        return None


def _write_yaml(path, data):
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        os.makedirs(directory)
    with open(path, 'w') as f:
        yaml.safe_dump(data, f, default_flow_style=False, sort_keys=False)


class ExperimentMonitorNode(object):
    def __init__(self):
        p = private_params()
        scenario_dir = p.string('scenario_dir', '') or SCENARIO_DIR
        scenario_file = p.string('scenario_file', '')
        self.scenario = load_scenario(scenario_file or p.string('scenario', 'circle_r2_v1'), scenario_dir)
        self.label = p.text('label') or self.scenario.name
        self.core = ExperimentMonitor(self.scenario.duration, min_commands=p.integer('min_commands', 5, minimum=0),
                                      ready_timeout=p.number('ready_timeout', 90.0, minimum=0.0),
                                      end_margin=p.number('end_margin', 30.0, minimum=0.0),
                                      final_timeout=p.number('final_timeout', 30.0, minimum=0.0))
        self.progress_period = p.number('progress_period', 1.0, minimum=0.0)
        self.evaluator_exit_timeout = p.number('evaluator_exit_timeout', 15.0, minimum=0.0)
        self.wait_subscribers = [rospy.resolve_name(n) for n in p.names('wait_subscribers', [])]
        self.controller_patterns = p.names('controller_nodes', [])
        self.evaluator_node = rospy.resolve_name(p.string('evaluator_node', 'evaluator'))
        self.files = dict((k, p.string('%s_file' % k, '')) for k in ('summary', 'csv', 'plot', 'info', 'bag'))
        self.hold = p.flag('hold', True)
        self.end_launch = p.flag('end_launch', False)
        self.waypoint_topic = rospy.resolve_name(topics.WAYPOINT)
        self.lock = threading.Lock()
        self.master = rosgraph.Master(rospy.get_name())
        self.controller_pids = []
        self.evaluator_pid = None
        self.pub_start = rospy.Publisher(p.string('start_topic', topics.TRAJECTORY_COMMAND), String, queue_size=1,
                                         latch=True)
        rospy.Subscriber(topics.DRONE_STATE, String, self._on_state, queue_size=5)
        self.hold_point = self.scenario.waypoint(0.0)
        self.pub_waypoint = rospy.Publisher(topics.WAYPOINT, Waypoint, queue_size=5)
        self.last_hold = None
        rospy.Subscriber(topics.COMMAND, piloting_command_class(), self._on_command, queue_size=5)
        rospy.Subscriber(topics.WAYPOINT, Waypoint, self._on_waypoint, queue_size=1)
        rospy.Subscriber(topics.ESTIMATE, Odometry, self._on_estimate, queue_size=1)
        rospy.Subscriber(topics.TRAJECTORY_STATUS, String, self._on_status, queue_size=5)
        rospy.Subscriber(topics.TRAJECTORY_BEGIN, Header, self._on_begin, queue_size=5)
        rospy.Subscriber(topics.TRAJECTORY_END, Header, self._on_end, queue_size=5)
        rospy.Subscriber(topics.EVALUATION_SUMMARY, String, self._on_summary, queue_size=5)
        rospy.Subscriber(topics.MPC_STATS, MpcStats, self._on_mpc_stats, queue_size=20)
        rospy.Subscriber(topics.DIAGNOSTICS, DiagnosticArray, self._on_diagnostics, queue_size=20)
        self.sim_status_prefix = 'anafi_sim: simulated Anafi'
        self._say('%s: scenario %s (%.1f s of simulation time); waiting for the drone, the controller and %s'
                  % (self.label, self.scenario.name, self.scenario.duration,
                     ', '.join(self.wait_subscribers) or 'nothing else'))

    # ------------------------------------------------------------ callbacks
    def _on_state(self, msg):
        with self.lock:
            self.core.on_drone_state(msg.data)

    def _on_command(self, msg):
        with self.lock:
            stamp = msg.header.stamp.to_sec()          # the controller's own cycle time, else receipt
            self.core.on_command((msg.roll, msg.pitch, msg.yaw, msg.gaz), stamp if stamp > 0 else rospy.get_time())

    def _on_waypoint(self, msg):
        with self.lock:
            self.core.on_waypoint((msg.x, msg.y, msg.z))

    def _on_estimate(self, msg):
        p = msg.pose.pose.position
        with self.lock:
            self.core.on_estimate((p.x, p.y, p.z))

    def _on_status(self, msg):
        d = _yaml(msg)
        if isinstance(d, dict):
            with self.lock:
                self.core.on_status(d.get('phase', ''), d.get('state', ''))

    def _on_begin(self, msg):
        with self.lock:
            self.core.on_begin(msg.stamp.to_sec())

    def _on_end(self, msg):
        with self.lock:
            self.core.on_end(msg.stamp.to_sec(), time.monotonic())

    def _on_summary(self, msg):
        d = _yaml(msg)     # the core ignores anything but a dict
        with self.lock:
            self.core.on_summary(d, time.monotonic())

    def _on_mpc_stats(self, msg):
        with self.lock:
            self.core.on_mpc_stats(msg.solve_time, msg.cycle_time, msg.cycles, msg.hover_cycles)

    def _on_diagnostics(self, msg):
        for status in msg.status:
            if status.name.startswith(self.sim_status_prefix):
                with self.lock:
                    self.core.on_sim_diagnostics(dict((kv.key, kv.value) for kv in status.values))

    # ------------------------------------------------------------ helpers
    def _say(self, text):
        sys.stdout.write(text + '\n')
        sys.stdout.flush()

    def _subscribers_ok(self):
        if not self.wait_subscribers:
            return True
        try:
            _, subs, _ = self.master.getSystemState()
        except Exception:       # master busy or gone: not ready yet
            return False
        nodes = set()
        for topic, names in subs:
            if topic == self.waypoint_topic:
                nodes.update(names)
        return all(n in nodes for n in self.wait_subscribers)

    def _node_pid(self, name):
        """Process id of node ``name`` (its getPid XML-RPC call), None when unknown."""
        return harness.node_pid(name, master_uri=rosgraph.get_master_uri(), caller=rospy.get_name())

    def _find_controller_pids(self):
        if not self.controller_patterns or psutil is None:
            return []
        try:
            pubs, subs, srvs = self.master.getSystemState()
        except Exception:
            return []
        names = set()
        for group in (pubs, subs, srvs):
            for _, nodes in group:
                names.update(nodes)
        pids = [self._node_pid(n) for n in sorted(names)
                if any(fnmatch.fnmatch(n, p) for p in self.controller_patterns)]
        return sorted(set(p for p in pids if p is not None))

    def _controller_cpu(self):
        if not self.controller_pids or psutil is None:
            return None
        seconds = [harness.cpu_seconds(pid) for pid in self.controller_pids]
        return sum(c for c in seconds if math.isfinite(c))

    def _wait_for_evaluator_exit(self):
        """Wait until the evaluator's process has exited (it writes its files first); False on timeout."""
        deadline = time.monotonic() + self.evaluator_exit_timeout
        while time.monotonic() < deadline:
            if self.evaluator_pid is not None and psutil is not None:
                try:
                    if psutil.Process(self.evaluator_pid).status() == psutil.STATUS_ZOMBIE:
                        return True
                except psutil.NoSuchProcess:
                    return True
                except psutil.Error:
                    pass
            elif self._node_pid(self.evaluator_node) is None:    # node no longer answers
                return True
            time.sleep(0.1)
        return False

    def _finish(self, ok):
        with self.lock:
            self.core.on_controller_cpu(self._controller_cpu())
            info = self.core.run_info()
            summary = self.core.summary
        info['label'] = self.label
        info['scenario'] = self.scenario.name
        exited = True
        if ok:
            exited = self._wait_for_evaluator_exit()
            if not exited:
                rospy.logwarn('%s did not exit within %.0f s: reading its files anyway', self.evaluator_node,
                              self.evaluator_exit_timeout)
        if self.files['plot'] and self.files['csv']:
            if os.path.isfile(self.files['csv']):
                try:
                    from anafi_sim.experiments.plots import plot_run
                    plot_run(self.files['csv'], self.files['plot'], summary=summary, title=self.label)
                    info['plot'] = self.files['plot']
                except Exception as e:    # a plot problem must not hide the result
                    rospy.logerr('plot failed: %s', e)
            else:
                rospy.logerr('no CSV %s: no plot', self.files['csv'])
        if self.files['info']:
            try:
                _write_yaml(self.files['info'], info)
            except (IOError, OSError) as e:
                rospy.logerr('cannot write %s: %s', self.files['info'], e)
        lines = ['', '=' * 78, 'RESULT %s  (%s)' % (self.label, 'ok' if ok else 'FAILED: ' + info['reason'])]
        lines += summary_lines(summary, self.label)[1:] if summary else ['  no evaluator summary']
        if info.get('achieved_rtf') is not None:
            lines.append('  simulation: %.1f s in %.1f s wall (real-time factor %.2f), simulator overruns %s, '
                         're-anchors %s' % (info['scenario_sim_s'], info['scenario_wall_s'], info['achieved_rtf'],
                                            info['sim_overruns'], info['sim_reanchors']))
        if info.get('mpc_solve_time_mean_ms') is not None:
            lines.append('  MPC solve time: mean %.2f ms, max %.2f ms' % (info['mpc_solve_time_mean_ms'],
                                                                          info['mpc_solve_time_max_ms']))
        for key in ('bag', 'csv', 'summary', 'plot', 'info'):
            path = self.files[key]
            if path and (key in ('info', 'bag') or os.path.exists(path)):
                lines.append('  %-8s %s' % (key + ':', path))
        lines.append('=' * 78)
        self._say('\n'.join(lines))

    def _publish_hold(self):
        """The scenario's start as the waypoint (zero velocity), every 0.1 s of ROS time."""
        now = rospy.get_time()
        if now == 0.0 or (self.last_hold is not None and 0.0 <= now - self.last_hold < 0.1):
            return
        self.last_hold = now
        msg = Waypoint()
        msg.header.stamp = rospy.Time.from_sec(now)
        msg.header.frame_id = 'world'
        wp = self.hold_point
        msg.x, msg.y, msg.z, msg.yaw = wp.x, wp.y, wp.z, wp.yaw
        try:
            self.pub_waypoint.publish(msg)
        except rospy.ROSException:
            pass

    # ------------------------------------------------------------ main loop
    def run(self):
        next_progress = time.monotonic() + self.progress_period
        next_subs = 0.0
        subs_ok = False
        ok = False
        while not rospy.is_shutdown():
            wall = time.monotonic()
            if self.core.state == 'waiting' and wall >= next_subs:
                subs_ok = self._subscribers_ok()
                next_subs = wall + 0.5
            with self.lock:
                actions = self.core.tick(rospy.get_time(), wall, subs_ok, time.time())
            finished = False
            for action, text in actions:
                if action == 'start':
                    self.controller_pids = self._find_controller_pids()
                    self.evaluator_pid = self._node_pid(self.evaluator_node)
                    with self.lock:
                        self.core.on_controller_cpu(self._controller_cpu())
                    self.pub_start.publish(String(data='start'))
                    self._say('%s: everything up (%s): starting %s' % (self.label, text, self.scenario.name))
                elif action == 'fail':
                    rospy.logerr('%s: %s', self.label, text)
                    finished = True
                elif action == 'done':
                    ok = True
                    finished = True
            if finished:
                break
            if self.progress_period > 0 and wall >= next_progress:
                next_progress = wall + self.progress_period
                with self.lock:
                    line = self.core.progress_line(self.label)
                self._say(line)
            if self.hold and self.core.holding:
                self._publish_hold()
                time.sleep(0.01)
            else:
                time.sleep(0.1)
        if rospy.is_shutdown() and self.core.state not in (FINAL, FAILED):
            self.core.reason = 'shut down before the end (state %s)' % self.core.state
        self._finish(ok)
        if ok and self.end_launch:
            self._say('%s: finished: ending the launch' % self.label)
            end_parent_launch()
        rospy.signal_shutdown('experiment finished')
        return ok


if __name__ == '__main__':
    run_node('experiment_monitor', ExperimentMonitorNode)
