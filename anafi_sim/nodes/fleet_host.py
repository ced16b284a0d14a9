#!/usr/bin/env python3
"""Fleet host node: every drone's instance of some nodes in one process (the shared layout of a fleet).

Stage: wiring only, like a roscpp nodelet manager. ``~instances`` lists the node instances this process runs,
each as the node it replaces: ``{name: /anafi1/interface, type: interface_node.py}`` (the types in
anafi_sim.mission.fleet_layout.HOSTABLE). Each instance is the same node class as in the per-drone layout,
built with a NodeContext of its own name (anafi_sim/ros/context.py): its ~params are read from the master under its name (fleet_launcher.py
writes them, from the same launch files as the per-drone layout), and it keeps its own topics, services,
telemetry port and stream id and /diagnostics statuses. Messages between the instances of this host go through
its LocalBus (in the process; other processes still get every topic they subscribe to). /rosout names this
process as the node of every line: an instance's lines start with its name in square brackets, and its throttled
lines are throttled per instance (NodeContext's log functions).

Every simulator that runs without lockstep is stepped by one loop of the host (one wake-up per physics step for
all drones, instead of one per drone); the other instances run their own run().

Failure isolation: an instance whose parameters are bad is not started (one FATAL line naming it, its drone's
status ERROR on /diagnostics); an instance whose run() raises stops alone (ERROR line and status, counter), as
does a failing callback (counted, logged; the bus goes on). The others fly on: a drone whose simulator share
stopped has no telemetry (its interface goes stale, its mirror holds its models), a drone whose controller
share stopped gets no command (the simulated firmware hovers after its command time-out).

Parameters: ~instances (list of {name, type}; required), ~diagnostics_period (1.0 s). Sets ~wiring: per instance
the global names of the topics it publishes and subscribes and its services (the master sees them as the
host's; tests and users see here which drone's instance uses which).
Publishes /diagnostics: '<host>: fleet host' (instances running / failed, bus deliveries, callback errors and
deliveries waiting for the bus's delivery thread), '<host>: real time' (WARN "behind real time: RTF 0.93
(anafi3) / ground truth 89 Hz (anafi7); 2 of 10 drones" when a hosted simulator's RTF or a hosted interface's
ground-truth rate over the last 5 s falls under anafi_sim.mission.fleet_realtime's thresholds, else OK with the
minima) and, for an instance that failed, '<instance>: hosted instance' ERROR.
"""
import importlib
import threading
import time
import traceback

import rospy

from anafi_sim.mission.fleet_layout import HOSTABLE, drone_of, read_instances
from anafi_sim.mission.fleet_realtime import RateWindow, real_time_status
from anafi_sim.ros.context import LocalBus, NodeContext
from anafi_sim.ros.node import (ERROR, OK, WARN, diagnostic_status, diagnostics_publisher, private_params, run_node,
                                run_until_interrupted, start_diagnostics_thread)


class Instance(object):
    """One hosted node instance and what became of it."""

    def __init__(self, name, kind):
        self.name, self.kind = name, kind
        self.node = None
        self.ctx = None
        self.error = ''          # why it is not running ('' while it runs)
        self.thread = None


class FleetHost(object):
    def __init__(self):
        ctx = NodeContext.process()
        p = private_params(ctx)
        self.period = p.positive('diagnostics_period', 1.0)
        self.instances = [Instance(n, k) for n, k in read_instances(ctx.get_param('instances'))]
        self.callback_errors = {}
        self.bus = LocalBus(rospy.get_name(), on_error=self._on_callback_error)
        self.pub_diag = diagnostics_publisher()
        self.rates = RateWindow()
        for inst in self.instances:
            self._build(inst)
        rospy.set_param('~wiring', dict((i.name, i.ctx.wiring) for i in self.instances if i.ctx is not None))
        running = [i.name for i in self.instances if not i.error]
        rospy.loginfo('fleet host: %d of %d instances built: %s', len(running), len(self.instances),
                      ', '.join(running))

    def _build(self, inst):
        module, cls, args = HOSTABLE[inst.kind]
        try:
            node_class = getattr(importlib.import_module(module), cls)
            inst.ctx = NodeContext(inst.name, self.bus)
            inst.node = node_class(*(args + (inst.ctx,)))
        except Exception as error:   # bad parameters (ValueError) or anything else: this instance only
            inst.error = 'not started: %s: %s' % (type(error).__name__, error)
            rospy.logfatal('fleet host: %s (%s) %s', inst.name, inst.kind, inst.error)
            if not isinstance(error, ValueError):
                rospy.logerr('fleet host: %s', traceback.format_exc())

    def _on_callback_error(self, topic, error):
        self.callback_errors[topic] = self.callback_errors.get(topic, 0) + 1
        rospy.logerr_throttle(5.0, 'fleet host: a callback on %s failed (%d times): %s: %s' % (
            topic, self.callback_errors[topic], type(error).__name__, error))

    def _run_instance(self, inst):
        try:
            inst.node.run()
        except Exception as error:
            if not rospy.is_shutdown():
                inst.error = 'stopped: %s: %s' % (type(error).__name__, error)
                rospy.logerr('fleet host: %s %s\n%s', inst.name, inst.error, traceback.format_exc())

    def diagnostic_statuses(self):
        failed = [i for i in self.instances if i.error]
        level = OK if not failed else (WARN if len(failed) < len(self.instances) else ERROR)
        statuses = [diagnostic_status(
            '%s: fleet host' % rospy.get_name(), level,
            '%d instances running' % (len(self.instances) - len(failed)) + (
                ', %d failed: %s' % (len(failed), ', '.join(i.name for i in failed)) if failed else ''),
            [('instances', str(len(self.instances))), ('failed', str(len(failed))),
             ('bus deliveries', str(self.bus.delivered)),
             ('callback errors', str(self.bus.callback_errors)),
             ('deliveries waiting', str(self.bus.pending()))])]
        try:
            statuses.append(self.real_time_status(time.monotonic()))
        except Exception as error:     # an instance without the counters read: the other statuses still go out
            statuses.append(diagnostic_status('%s: real time' % rospy.get_name(), WARN, 'real time: not measured: '
                                              '%s: %s' % (type(error).__name__, error), []))
        for inst in failed:
            statuses.append(diagnostic_status('%s: hosted instance' % inst.name, ERROR, inst.error,
                                              [('type', inst.kind), ('host', rospy.get_name())],
                                              hardware_id=inst.name.strip('/').split('/')[0]))
        return statuses

    def real_time_status(self, now):
        """'<host>: real time': whether this host's drones keep real time (anafi_sim.mission.fleet_realtime):
        the RTF of its simulators and the ground-truth rate of its interfaces over the last seconds."""
        rtf, truth, expected = {}, {}, {}
        for inst in self.instances:
            drone = drone_of(inst.name) or inst.name
            key = (inst.kind, inst.name)
            if inst.error or inst.node is None:
                self.rates.forget(key)
                continue
            if inst.kind == 'anafi_sim_node.py':
                self.rates.add(key, now, inst.node.sim.clock.t)
                rtf[drone] = self.rates.rate(key)
            elif inst.kind == 'interface_node.py':
                self.rates.add(key, now, inst.node.core.published)
                truth[drone] = self.rates.rate(key)
                expected[drone] = inst.node.core.publish_rate
        status = real_time_status(rtf, truth, expected)
        return diagnostic_status('%s: real time' % rospy.get_name(), WARN if status.behind else OK, status.message,
                                 status.values)

    def _step_together(self, group):
        """One loop steps every simulator of ``group`` (started at one instant: their steps fall due together,
        one wake-up for all); a simulator whose step raises leaves the loop alone (its instance failed)."""
        start = time.monotonic()
        due = {}
        for inst in group:
            inst.node.start_stepping(start)
            due[inst] = start
        while due and not rospy.is_shutdown():
            now = time.monotonic()
            for inst in list(due):
                if due[inst] > now:
                    continue
                try:
                    due[inst] = now + inst.node.tick()
                except Exception as error:
                    del due[inst]
                    if not rospy.is_shutdown():
                        inst.error = 'stopped: %s: %s' % (type(error).__name__, error)
                        rospy.logerr('fleet host: %s %s\n%s', inst.name, inst.error, traceback.format_exc())
            if due:
                delay = min(due.values()) - time.monotonic()
                if delay > 0.0:
                    time.sleep(delay)

    def spin(self):
        together = [i for i in self.instances if i.node is not None and not getattr(i.node, 'steps_alone', True)]
        if together:
            threading.Thread(target=self._step_together, args=(together,), name='simulators', daemon=True).start()
        for inst in self.instances:
            if inst.node is not None and inst not in together:
                inst.thread = threading.Thread(target=self._run_instance, args=(inst,), name=inst.name, daemon=True)
                inst.thread.start()
        start_diagnostics_thread(self.period, self.diagnostic_statuses, self.pub_diag, first=0.0)
        while not rospy.is_shutdown():
            time.sleep(0.2)

    def shutdown(self):
        """Every instance's clean-up through ROS (e.g. the mirrors delete their models), in reverse launch order as
        roslaunch stops nodes (the world, first in its host, still serves the mirrors' deletions: stopped first, each
        deletion would wait for its timeout), then ROS stops."""
        for inst in reversed(self.instances):
            cleanup = getattr(inst.node, 'shutdown', None)
            if cleanup is not None:
                try:
                    cleanup()
                except Exception as error:
                    rospy.logerr('fleet host: %s shutdown: %s: %s', inst.name, type(error).__name__, error)

    def run(self):
        run_until_interrupted(self.spin, self.shutdown, 'fleet host stopped')


def main():
    run_node('fleet_host', FleetHost, fatal_exit_code=2, disable_signals=True)
