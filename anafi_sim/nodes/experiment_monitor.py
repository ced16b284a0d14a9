#!/usr/bin/env python3
"""Experiment monitor node: starts the scenario when everything is up, prints live progress, ends the run.

Stage: experiment orchestration (experiment.launch, demo.launch). Thin node over
anafi_sim.mission.monitor.ExperimentMonitor and anafi_sim.mission.run_end (the run's files at its end). Topics
relative to the node's namespace (/<drone>/):

- in drone/state (std_msgs/String), drone/rpyt (olympe_bridge/PilotingCommand: non-zero commands
  counted, the controller is up and engaged; while the scenario runs, hover (all-zero) commands and
  the largest gap between the commands' header stamps are kept: a disturbed run),
  position_control/waypoint (anafi_sim/Waypoint), drone/odom (nav_msgs/Odometry, the estimate),
  trajectory/status (std_msgs/String YAML), trajectory/begin, trajectory/end (std_msgs/Header),
  evaluation/summary (std_msgs/String YAML), mpc/stats (anafi_sim/MpcStats), /diagnostics (the
  simulator's status: achieved real-time factor, overruns), tuning/changes (std_msgs/String YAML: the
  live tuning history of each node of anafi_sim/ros/reconfigure.py, latched; kept in the run info as
  ``tuning``, every change in time order);
- out ~start_topic (default trajectory_generator/command, std_msgs/String, latched): 'start' once the
  drone flies, the controller has sent ~min_commands (5) non-zero commands and every node of
  ~wait_subscribers (names relative to the namespace, e.g. [evaluator, recorder]) subscribes to the
  waypoint topic; until then (with ~hold, true) position_control/waypoint = the scenario's start
  (hold point, zero velocity) every 0.1 s of ROS time, so the controller engages and the drone waits
  there; the generator takes over with the same point.

Every ~progress_period s of wall time (1.0; 0 = quiet) one progress line on stdout. When the
evaluator's summary is final, the node waits (<= ~evaluator_exit_timeout s wall, 15) for
~evaluator_node to exit (it writes ~csv_file and ~summary_file), draws ~plot_file from the CSV
(anafi_sim.mission.plots; '' = no plot; its extension .png, .svg or .pdf the format, ~plot_dpi its dpi;
FAILED and the reason in the title of a failed run), writes ~info_file (YAML: anafi_sim.mission.monitor run_info:
durations, achieved real-time factor, simulator overruns, MPC solve times, controller CPU time of the
nodes matching ~controller_nodes, fnmatch patterns of absolute node names), prints the summary and
shuts down: the RESULT line says "ok", "disturbed: <what, with the measured figure>" (a run that measured
while the machine's load disturbed it: the controller starved, the ground-truth reader late by more than
0.5 s - the interface's diagnostics; its lag is printed in any case -, ground truth missing;
anafi_sim.mission.monitor) or "FAILED: <reason>"
(exit 0; also when disturbed; 1 on failure: not ready within ~ready_timeout s wall (90), the scenario not ending
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
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from std_msgs.msg import Header, String

from anafi_sim import processes, run_files
from anafi_sim.numeric import PARAMETER_RANGES
from anafi_sim.mission.monitor import FAILED, FINAL, INTERFACE_STATUS_SUFFIX, ExperimentMonitor
from anafi_sim.mission.run_end import conditions_info, finish_run, result_lines, run_title
from anafi_sim.mission.trajectory import SCENARIO_DIR, load_scenario
from anafi_sim.msg import MpcStats, Waypoint
from anafi_sim import names
from anafi_sim.ros.node import end_parent_launch, private_params, run_node
from anafi_sim.ros.wire_types import piloting_command_class
from anafi_sim.sim.conditions_profile import load_conditions, parameter_folders
from anafi_sim.safe_yaml import load_yaml_text

try:
    import psutil
except ImportError:   # CPU figures are optional
    psutil = None


def _yaml(msg):
    """The YAML data of a std_msgs/String, None when unreadable."""
    try:
        return load_yaml_text(msg.data, 'message')
    except ValueError:
        return None




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
        self.plot_dpi = p.number('plot_dpi', run_files.FIGURE_DPI, *PARAMETER_RANGES['plot_dpi'])
        self.end_launch = p.flag('end_launch', False)
        # the flight conditions the simulator flies in (sim.launch conditions:=NAME): shown on the plot
        self.conditions = conditions = p.string('conditions', '')
        try:
            self.wind = load_conditions(conditions, parameter_folders()) if conditions else None
        except ValueError as error:
            rospy.logwarn('conditions %r: %s (the plot will not show the wind)', conditions, error)
            self.wind = None
        self.require_truth = p.flag('require_truth', True)
        self.run_dir = run_dir = p.string('run_dir', '')
        latest_link = p.string('latest_link', '')
        if run_dir:
            os.makedirs(run_dir, exist_ok=True)
            if latest_link:
                run_files.update_latest(os.path.dirname(os.path.abspath(latest_link)), run_dir)
        if p.flag('remove_previous', False):
            removed = run_files.remove_previous([self.files[k] for k in ('summary', 'csv', 'plot', 'info', 'bag')])
            if removed:
                rospy.logwarn('removed the previous run\'s files %s', ', '.join(removed))
        if self.files['info']:      # a run that never ends (killed) leaves this: RUN.FAILED.run.yaml, state running
            run_files.write_yaml(run_files.failed_name(self.files['info']), {
                'state': 'running', 'label': self.label,
                'reason': 'the run did not end (killed?): its files are partial'})
        self.waypoint_topic = rospy.resolve_name(names.WAYPOINT)
        self.lock = threading.Lock()
        self.master = rosgraph.Master(rospy.get_name())
        self.controller_pids = []
        self.evaluator_pid = None
        self.pub_start = rospy.Publisher(p.string('start_topic', names.TRAJECTORY_COMMAND), String, queue_size=1,
                                         latch=True)
        rospy.Subscriber(names.DRONE_STATE, String, self._on_state, queue_size=5)
        self.hold_point = self.scenario.waypoint(0.0)
        self.pub_waypoint = rospy.Publisher(names.WAYPOINT, Waypoint, queue_size=5)
        self.last_hold = None
        rospy.Subscriber(names.COMMAND, piloting_command_class(), self._on_command, queue_size=5)
        rospy.Subscriber(names.WAYPOINT, Waypoint, self._on_waypoint, queue_size=1)
        rospy.Subscriber(names.ESTIMATE, Odometry, self._on_estimate, queue_size=1)
        rospy.Subscriber(names.TRAJECTORY_STATUS, String, self._on_status, queue_size=5)
        rospy.Subscriber(names.TRAJECTORY_BEGIN, Header, self._on_begin, queue_size=5)
        rospy.Subscriber(names.TRAJECTORY_END, Header, self._on_end, queue_size=5)
        rospy.Subscriber(names.EVALUATION_SUMMARY, String, self._on_summary, queue_size=5)
        rospy.Subscriber(names.MPC_STATS, MpcStats, self._on_mpc_stats, queue_size=20)
        rospy.Subscriber(names.DIAGNOSTICS, DiagnosticArray, self._on_diagnostics, queue_size=20)
        self.tuning = {}     # node -> its live tuning changes (ros/reconfigure.py), kept in the run info
        rospy.Subscriber(names.TUNING_CHANGES, String, self._on_tuning, queue_size=50)
        self.sim_status_prefix = 'anafi_sim: simulated Anafi'
        self.drone = rospy.get_namespace().strip('/').split('/')[-1]     # the interface's hardware id ('' = any)
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

    def _on_tuning(self, msg):
        d = _yaml(msg)      # {node, changes: the node's whole history} (latched)
        if isinstance(d, dict) and isinstance(d.get('changes'), list):
            with self.lock:
                self.tuning[str(d.get('node'))] = [c for c in d['changes'] if isinstance(c, dict)]

    def _on_diagnostics(self, msg):
        for status in msg.status:
            if status.name.startswith(self.sim_status_prefix):
                with self.lock:
                    self.core.on_sim_diagnostics(dict((kv.key, kv.value) for kv in status.values))
            elif status.name.endswith(INTERFACE_STATUS_SUFFIX) and (not self.drone or status.hardware_id == self.drone):
                with self.lock:
                    self.core.on_interface_diagnostics(dict((kv.key, kv.value) for kv in status.values))

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
        for topic, subscribers in subs:
            if topic == self.waypoint_topic:
                nodes.update(subscribers)
        return all(n in nodes for n in self.wait_subscribers)

    def _node_pid(self, name):
        """Process id of node ``name`` (its getPid XML-RPC call), None when unknown."""
        return processes.node_pid(name, master_uri=rosgraph.get_master_uri(), caller=rospy.get_name())

    def _find_controller_pids(self):
        if not self.controller_patterns or psutil is None:
            return []
        try:
            pubs, subs, srvs = self.master.getSystemState()
        except Exception:
            return []
        found = set()
        for group in (pubs, subs, srvs):
            for _, nodes in group:
                found.update(nodes)
        pids = [self._node_pid(n) for n in sorted(found)
                if any(fnmatch.fnmatch(n, p) for p in self.controller_patterns)]
        return sorted(set(p for p in pids if p is not None))

    def _controller_cpu(self):
        if not self.controller_pids or psutil is None:
            return None
        seconds = [processes.cpu_seconds(pid) for pid in self.controller_pids]
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
        info['conditions'] = conditions_info(self.conditions, self.wind)
        with self.lock:
            info['tuning'] = sorted((c for changes in self.tuning.values() for c in changes),
                                    key=lambda c: c.get('wall', 0.0))      # [] = no live tuning
        problem = None
        if ok:
            if not self._wait_for_evaluator_exit():
                rospy.logwarn('%s did not exit within %.0f s: reading its files anyway', self.evaluator_node,
                              self.evaluator_exit_timeout)
            with self.lock:
                problem = self.core.result_problem(self.require_truth)

        def plot(csv, out, failed):
            from anafi_sim.mission.plots import plot_run
            plot_run(csv, out, summary=summary, title=run_title(self.label, self.conditions), wind=self.wind,
                     dpi=self.plot_dpi, failed=failed)

        finished = finish_run(ok, info, self.files, plot, problem)
        if ok and finished.problems:
            with self.lock:
                self.core.state = FAILED
                self.core.reason = '; '.join(finished.problems)
        for error in finished.errors:
            rospy.logerr(error)
        self.files = finished.files
        self._say('\n'.join(result_lines(finished, summary, self.label, self.run_dir)))
        return finished.ok

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
        ok = self._finish(ok)
        if ok and self.end_launch:
            self._say('%s: finished: ending the launch' % self.label)
            end_parent_launch()
        rospy.signal_shutdown('experiment finished')
        return ok


def main():
    run_node('experiment_monitor', ExperimentMonitorNode)
