#!/usr/bin/env python3
"""Live tracking-error evaluator node: e = |waypoint - drone position| over the measured segment.

Stage: (waypoint, estimate, ground truth) -> tracking-error summary. Thin
node over anafi_sim.mission.evaluation.LiveEvaluator (same code as evaluate_log.py
for bags and CSV). Topics relative to the node's namespace (/<drone>/):

- in ~waypoint_topic (position_control/waypoint, anafi_sim/Waypoint; with
  ~waypoint_type anafi_control the reference implementation's
  anafi_control/Waypoint, which has no header: timed at receipt),
  ~estimate_topic (drone/odom, nav_msgs/Odometry: the paper's metric),
  ~truth_topic (ground_truth/odom; '' = none), ~begin_topic / ~end_topic
  (trajectory/begin, trajectory/end: std_msgs/Header from the generator);
- out evaluation/summary (std_msgs/String, latched: YAML of the summary with
  'state': waiting | measuring | final | incomplete) every ~publish_period s
  of ROS time (1.0) and at the end; /diagnostics (DiagnosticStatus with
  e_max, e_mu, e_sigma [m] vs estimate and ground truth; WARN on garbage).

At the end of the measured segment (once an estimate sample at or after
the end stamp arrived, or ~finalize_timeout s (2.0) after the end signal)
the final summary is printed, published, written to ~summary_file ('' =
none; *.md = Markdown, else YAML) and the rows of ~csv_window ('measured'
or 'all') to ~csv_file in the reference-log format ('' = none); with
~exit_when_done the node then shuts down. On shutdown before that, an
'incomplete' summary is written (with ~mark_incomplete, as experiment.launch sets it: named
RUN.FAILED.yaml / RUN.FAILED.csv; a fleet's or formation's evaluators, which end with Ctrl-C, keep the
names). Every file is
written to a temporary name and renamed when complete (anafi_sim.run_files): a full disk leaves no
file, never a cut one. Sample times are the header stamps
(~use_header_stamp, true; else the receive time). ~min_altitude [m] (-1):
positions below are excluded as not flying. ~name: label (default: the
scenario name from the begin signal).
"""
import threading

import rospy
import yaml
from nav_msgs.msg import Odometry
from std_msgs.msg import Header, String

from anafi_sim import run_files
from anafi_sim.mission.evaluation import LiveEvaluator, stamp_ns, summary_markdown
from anafi_sim.mission.reference_log import write_log
from anafi_sim import names
from anafi_sim.ros.waypoints import DEFAULT_WAYPOINT_TYPE, WAYPOINT_TYPES, waypoint_class, waypoint_numbers
from anafi_sim.ros.node import (OK, WARN, diagnostic_status, diagnostics_publisher, private_params,
                                publish_diagnostics, run_node)


class EvaluatorNode(object):
    def __init__(self):
        p = private_params()
        self.publish_period = p.positive('publish_period', 1.0)
        self.finalize_timeout = p.positive('finalize_timeout', 2.0)
        self.min_altitude = p.number('min_altitude', -1.0)
        self.use_header_stamp = p.flag('use_header_stamp', True)
        self.exit_when_done = p.flag('exit_when_done', False)
        self.summary_file = p.string('summary_file', '')
        self.csv_file = p.string('csv_file', '')
        self.csv_window = p.choice('csv_window', 'measured', ('measured', 'all'))
        self.mark_incomplete = p.flag('mark_incomplete', False)
        self.name = p.text('name')
        self.core = LiveEvaluator(name=self.name, min_altitude=self.min_altitude,
                                  max_samples=p.integer('max_samples', 500000, minimum=1))
        self.lock = threading.Lock()
        self.end_seen_at = None
        self.finished = False
        self.errors = 0
        self.pub = rospy.Publisher(names.EVALUATION_SUMMARY, String, queue_size=2, latch=True)
        self.pub_diag = diagnostics_publisher(queue_size=5)
        inputs = dict((k, p.string('%s_topic' % k, d, allow_empty=(k == 'truth'))) for k, d in (
            ('waypoint', names.WAYPOINT), ('estimate', names.ESTIMATE), ('truth', names.GROUND_TRUTH),
            ('begin', names.TRAJECTORY_BEGIN), ('end', names.TRAJECTORY_END)))
        self.waypoint_type = p.choice('waypoint_type', DEFAULT_WAYPOINT_TYPE, WAYPOINT_TYPES)
        rospy.Subscriber(inputs['waypoint'], waypoint_class(self.waypoint_type), self._on_waypoint, queue_size=50)
        rospy.Subscriber(inputs['estimate'], Odometry, self._on_estimate, queue_size=100)
        if inputs['truth']:
            rospy.Subscriber(inputs['truth'], Odometry, self._on_truth, queue_size=100)
        rospy.Subscriber(inputs['begin'], Header, self._on_begin, queue_size=5)
        rospy.Subscriber(inputs['end'], Header, self._on_end, queue_size=5)
        rospy.loginfo('%s: waypoint %s, estimate %s, truth %s, window %s .. %s', rospy.get_name(),
                      *[rospy.resolve_name(inputs[k]) if inputs[k] else '(none)'
                        for k in ('waypoint', 'estimate', 'truth', 'begin', 'end')])

    def _t(self, msg):
        return stamp_ns(msg, rospy.get_rostime(), self.use_header_stamp) * 1e-9

    def _on_waypoint(self, msg):
        with self.lock:     # anafi_control/Waypoint has no header: _t is its time of receipt
            self.core.add_waypoint(self._t(msg), waypoint_numbers(msg))

    def _on_estimate(self, msg):
        with self.lock:
            self.core.add_estimate(self._t(msg), msg)

    def _on_truth(self, msg):
        with self.lock:
            self.core.add_truth(self._t(msg), msg)

    def _on_begin(self, msg):
        with self.lock:
            if not self.name and msg.frame_id:
                self.core.name = msg.frame_id
            self.core.begin(self._t(msg))
            self.end_seen_at = None
            self.finished = False
        rospy.loginfo('measured segment begins at %.3f s', self._t(msg))

    def _on_end(self, msg):
        with self.lock:
            self.core.end(self._t(msg))
            self.end_seen_at = rospy.get_time()
        rospy.loginfo('measured segment ends at %.3f s', self._t(msg))

    def summary(self, state):
        with self.lock:
            try:
                result = self.core.evaluate(rospy.get_time())
            except Exception as e:    # never let one bad evaluation kill the node: report it
                self.errors += 1
                rospy.logerr_throttle(10.0, 'evaluation failed (%d times): %s' % (self.errors, e))
                return None, {'name': self.core.name, 'state': 'error', 'error': str(e), 'samples': 0}
        if result is None:
            return None, {'name': self.core.name, 'state': 'waiting', 'samples': 0, 'counts': self.core.counts()}
        d = result.as_dict()
        d['state'] = state
        return result, d

    def publish(self, result, d):
        try:
            self._publish(result, d)
        except rospy.ROSException as e:     # after shutdown: the files and the log still get the summary
            rospy.logdebug('summary not published: %s', e)

    def _publish(self, result, d):
        self.pub.publish(String(data=yaml.safe_dump(dict(d), default_flow_style=False, sort_keys=False)))
        level, message, values = OK, d.get('state', ''), []
        if result is not None:
            if result.garbage or result.warnings:
                level = WARN
                message += ': ' + '; '.join(result.garbage.summary() + result.warnings)
            for key in ('estimate', 'truth'):
                r = d.get(key)
                if r:
                    values += [('%s_%s' % (key, k), r[k]) for k in ('e_max', 'e_mu', 'e_sigma')]
            values.append(('samples', d.get('samples')))
        publish_diagnostics(self.pub_diag, [diagnostic_status('%s: tracking error' % rospy.get_name(), level, message,
                                                              values, hardware_id=d.get('name') or '')])

    def finalize(self, state):
        result, d = self.summary(state)
        self.finished = True
        self.publish(result, d)
        if result is None:
            rospy.logwarn('no waypoint / estimate received: nothing to evaluate')
        else:
            for line in result.lines():
                rospy.loginfo('%s', line)
        try:
            self.write(result, d)
        except (IOError, OSError, ValueError) as e:
            rospy.logerr('cannot write the evaluation files: %s', e)
        return result

    def write(self, result, d):
        """Each file written to a temporary name and renamed when complete; with ~mark_incomplete an unfinished
        evaluation's files carry .FAILED in their names (RUN.FAILED.yaml, state incomplete)."""
        final = d.get('state') == 'final' or not self.mark_incomplete
        if self.summary_file:
            path = self.summary_file if final else run_files.failed_name(self.summary_file)
            text = summary_markdown(d) if path.endswith('.md') else yaml.safe_dump(
                dict(d), default_flow_style=False, sort_keys=False)
            run_files.atomic_write_text(path, text)
            rospy.loginfo('summary written to %s', path)
        if self.csv_file and result is not None:
            path = self.csv_file if final else run_files.failed_name(self.csv_file)
            with run_files.atomic_path(path) as tmp:
                write_log(tmp, result.log if self.csv_window == 'measured' else result.full_log)
            rospy.loginfo('reference-log CSV written to %s', path)

    def run(self):
        rate_period = self.publish_period
        last = -1e18
        while not rospy.is_shutdown():
            now = rospy.get_time()
            with self.lock:
                ended = self.core.state == 'ended'
                complete = self.core.complete()
                timed_out = self.end_seen_at is not None and now - self.end_seen_at >= self.finalize_timeout
            if ended and not self.finished and (complete or timed_out):
                self.finalize('final')
                if self.exit_when_done:
                    rospy.signal_shutdown('evaluation done')
                    break
            elif now - last >= rate_period or now < last:
                last = now
                if not self.finished:
                    result, d = self.summary(self.core.state)
                    self.publish(result, d)
            try:
                rospy.sleep(min(0.1, rate_period))
            except rospy.ROSInterruptException:
                break
        if not self.finished:
            self.finalize('incomplete')



def main():
    run_node('evaluator', EvaluatorNode)
