#!/usr/bin/env python3
"""Drop-in for the ROS ``pid`` package's ``controller`` node (thin node over anafi_control.pid).

Stage: controllers. Same private parameters and defaults as the pid
package: ~Kp 1, ~Ki 0, ~Kd 0, ~upper_limit 1000, ~lower_limit -1000,
~windup_limit 1000, ~cutoff_frequency -1, ~angle_error false,
~angle_wrap 2*pi, ~topic_from_controller control_effort, ~topic_from_plant
state, ~setpoint_topic setpoint, ~pid_enable_topic pid_enable,
~max_loop_frequency / ~min_loop_frequency (diagnostics only). Topic names
are resolved relative to the node's namespace (not private). Units: those
of the loop (effort = gain x error). Messages: std_msgs/Float64 (setpoint,
state, control_effort), std_msgs/Bool (pid_enable).

One computation (anafi_control.pid.PidController.update, time = rospy time,
i.e. /clock under use_sim_time) after each new state or setpoint message,
once both have been received. Like the pid package's loop (spin, compute if
a message arrived, sleep 1 ms), messages that arrive within the same ~1 ms
of wall time are handled by one computation. Disabled (pid_enable false):
the computation runs, nothing is published, the integral is reset.

dynamic_reconfigure (cfg/Pid.cfg): Kp/Ki/Kd in [-1, 1] x scale 0.1/1/10/100;
the server is seeded from ~Kp/~Ki/~Kd (split_gain) and its first callback
is ignored, as in the pid package. Health on /diagnostics (1 Hz wall).
Bad parameters (lower_limit > upper_limit, non-finite numbers, empty topic
names, ...): logfatal at start-up, then the node stays up in ERROR (not respawned: docs/nodes.md).
"""
import math
import threading
import time

import rospy
from diagnostic_msgs.msg import DiagnosticStatus
from std_msgs.msg import Bool, Float64

import anafi_sim  # noqa: F401 (before anafi_control: checks it is the control library, README)
from anafi_control.pid import PidController, join_gain, split_gain
from anafi_sim.cfg import PidConfig
from anafi_sim.ros.reconfigure import TracedServer
from anafi_sim.ros.node import (diagnostic_status, diagnostics_publisher, private_params, run_node,
                                start_diagnostics_thread)

COALESCE_WINDOW = 0.001     # s of wall time: the pid package's loop sleep
NUMBER_PARAMS = (('Kp', 1.0), ('Ki', 0.0), ('Kd', 0.0), ('upper_limit', 1000.0),
                 ('lower_limit', -1000.0), ('windup_limit', 1000.0), ('cutoff_frequency', -1.0),
                 ('angle_wrap', 2.0 * math.pi))
TOPIC_PARAMS = (('topic_from_controller', 'control_effort'), ('topic_from_plant', 'state'),
                ('setpoint_topic', 'setpoint'), ('pid_enable_topic', 'pid_enable'))


def read_params():
    """(controller kwargs, topics, (min_freq, max_freq)) from ~params; ValueError (ParamError) on bad values."""
    p = private_params()
    kwargs = dict((name, p.number(name, default)) for name, default in NUMBER_PARAMS)
    kwargs['angle_error'] = p.flag('angle_error', False)
    topics = dict((name, p.ros_name(name, default)) for name, default in TOPIC_PARAMS)
    freqs = (p.positive('min_loop_frequency', 1.0), p.positive('max_loop_frequency', 1000.0))
    if freqs[0] > freqs[1]:
        raise ValueError('~min_loop_frequency (%g) must not exceed ~max_loop_frequency (%g)' % freqs)
    return kwargs, topics, freqs


class PidControllerNode(object):
    def __init__(self):
        kwargs, topics, self.freq_limits = read_params()
        self.pid = PidController(**kwargs)      # raises ValueError (e.g. lower_limit > upper_limit)
        self.name = rospy.get_name()
        if not self.pid.gains_same_sign():
            rospy.logwarn('%s: Kp, Ki, Kd should have the same sign for stability (%g, %g, %g)',
                          self.name, self.pid.Kp, self.pid.Ki, self.pid.Kd)
        self.topics = dict((k, rospy.resolve_name(v)) for k, v in topics.items())
        self.lock = threading.Lock()
        self.wake = threading.Condition(self.lock)
        self.pending = False
        self.setpoint = None
        self.state = None
        self.computations = 0
        self.published = 0
        self.last_effort = float('nan')
        self.first_reconfig = True
        self.rate_count = 0
        self.rate_count_seen = False
        self.pub = rospy.Publisher(self.topics['topic_from_controller'], Float64, queue_size=10)
        self.pub_diag = diagnostics_publisher()
        self.server = TracedServer(PidConfig, self._on_reconfigure)
        rospy.Subscriber(self.topics['topic_from_plant'], Float64, self._on_state, queue_size=10)
        rospy.Subscriber(self.topics['setpoint_topic'], Float64, self._on_setpoint, queue_size=10)
        rospy.Subscriber(self.topics['pid_enable_topic'], Bool, self._on_enable, queue_size=10)
        rospy.loginfo('%s: Kp %g Ki %g Kd %g, limits [%g, %g], windup %g, %s -> %s, setpoint %s, enable %s',
                      self.name, self.pid.Kp, self.pid.Ki, self.pid.Kd, self.pid.lower_limit,
                      self.pid.upper_limit, self.pid.windup_limit, self.topics['topic_from_plant'],
                      self.topics['topic_from_controller'], self.topics['setpoint_topic'],
                      self.topics['pid_enable_topic'])

    # -- callbacks (subscriber threads) --------------------------------------------------
    def _on_state(self, msg):
        with self.wake:
            self.state = msg.data
            self._mark()

    def _on_setpoint(self, msg):
        with self.wake:
            self.setpoint = msg.data
            self._mark()

    def _mark(self):
        if self.state is not None and self.setpoint is not None:
            self.pending = True
            self.wake.notify()

    def _on_enable(self, msg):
        with self.lock:
            self.pid.set_enabled(msg.data)

    def _on_reconfigure(self, config, level):
        with self.lock:
            if self.first_reconfig:
                # seed rqt_reconfigure from ~Kp/~Ki/~Kd and ignore this first call (pid package)
                self.first_reconfig = False
                for gain in ('Kp', 'Ki', 'Kd'):
                    value, scale = split_gain(getattr(self.pid, gain))
                    config[gain] = value
                    config[gain + '_scale'] = scale
                return config
            try:
                gains = [join_gain(config[g], config[g + '_scale']) for g in ('Kp', 'Ki', 'Kd')]
                self.pid.set_gains(*gains)
            except ValueError as error:
                rospy.logerr('%s: reconfigure refused: %s', self.name, error)
                return config
            rospy.loginfo('%s: reconfigured Kp %g Ki %g Kd %g', self.name, *gains)
            if not self.pid.gains_same_sign():
                rospy.logwarn('%s: Kp, Ki, Kd should have the same sign for stability', self.name)
        return config

    # -- computation thread ---------------------------------------------------------------
    def run(self):
        self.diag_time = time.monotonic()       # wall time of the previous diagnostic (rate window)
        start_diagnostics_thread(1.0, self._diagnostic_statuses, self.pub_diag)
        while not rospy.is_shutdown():
            with self.wake:
                if not self.pending:
                    self.wake.wait(0.5)
                if not self.pending:
                    continue
            time.sleep(COALESCE_WINDOW)
            with self.lock:
                self.pending = False
                before = (self.pid.rejected_nonfinite, self.pid.skipped_dt_zero)
                try:
                    now = rospy.get_time()
                except rospy.ROSException:
                    break
                if now <= 0.0:          # use_sim_time and no /clock yet: no time to compute with
                    continue
                effort = self.pid.update(self.setpoint, self.state, now)
                self.computations += 1
                self.rate_count += 1
                rejected = self.pid.rejected_nonfinite > before[0]
                skipped = self.pid.skipped_dt_zero > before[1]
                if effort is not None:
                    self.last_effort = effort
                    self.published += 1
            if rejected:
                rospy.logwarn_throttle(5.0, '%s: non-finite setpoint/state (%r, %r) ignored (%d so far)'
                                       % (self.name, self.setpoint, self.state, self.pid.rejected_nonfinite))
            if skipped:
                rospy.logwarn_throttle(60.0, '%s: delta_t is 0, skipping this computation (%d so far)'
                                       % (self.name, self.pid.skipped_dt_zero))
            if effort is not None:
                self.pub.publish(Float64(effort))

    def _diagnostic_statuses(self):
        now = time.monotonic()
        with self.lock:
            rate = self.rate_count / max(now - self.diag_time, 1e-6)
            self.diag_time = now
            self.rate_count_seen = self.rate_count > 0 or self.rate_count_seen
            self.rate_count = 0
            p = self.pid
            values = [
                ('Kp', '%g' % p.Kp), ('Ki', '%g' % p.Ki), ('Kd', '%g' % p.Kd),
                ('enabled', p.enabled),
                ('computations', self.computations),
                ('efforts published', self.published),
                ('last effort', '%g' % self.last_effort),
                ('computation rate [Hz wall]', '%.1f' % rate),
                ('skipped, delta_t == 0', p.skipped_dt_zero),
                ('ignored, non-finite input', p.rejected_nonfinite),
                ('clock jumps back (restarts)', p.time_jumps_back),
            ]
            problems = []
            if p.rejected_nonfinite:
                problems.append('%d non-finite inputs ignored' % p.rejected_nonfinite)
            if self.rate_count_seen and p.enabled and not self.freq_limits[0] <= rate <= self.freq_limits[1]:
                problems.append('computation rate %.1f Hz outside [%g, %g]'
                                % ((rate,) + self.freq_limits))
            if self.setpoint is None or self.state is None:
                problems.append('waiting for %s' % ('setpoint' if self.setpoint is None else 'state'))
            enabled = p.enabled
        level = DiagnosticStatus.WARN if problems else DiagnosticStatus.OK
        message = '; '.join(problems) if problems else ('running' if enabled else 'disabled')
        return [diagnostic_status('pid_controller: %s' % self.name, level, message, values,
                                  hardware_id=self.name)]


def main():
    run_node('controller', PidControllerNode, respawned=True)
