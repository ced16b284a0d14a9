"""The node glue every node uses: ~params, /diagnostics, start-up with fatal bad parameters.

Stage: ROS wiring only. A node reads its parameters with ``private_params()`` (a checked
``ParamReader``), builds its core, wires topics and timers, and starts with ``run_node``: a bad
parameter (``ParamError``, a ValueError) is one ``rospy.logfatal`` line and a non-zero exit, or, for a
node that roslaunch respawns, one FATAL line and an ERROR diagnostic while it stays up (``stay_in_error``).

Diagnostics: ``diagnostic_status`` builds one DiagnosticStatus (values stored as strings),
``health_status`` one from a core's ``Health`` (level, message, values) through the one level table
``LEVELS``; ``start_diagnostics_thread`` publishes them every period of WALL time (1 s in most nodes),
so a node still reports when /clock stops.

Master restart: rospy cannot re-register a running node with a new ROS master (publishers,
subscribers, services and parameters are lost and never come back), so ``run_node`` watches the master
(``MasterWatch``: its pid and ``/run_id``, polled every ``MASTER_POLL`` s of wall time from a daemon thread).
When a different master answers at the same URI the node puts its private parameters (and
``/use_sim_time``) back on the new master where they are missing, logs one FATAL line and exits with
``MASTER_RESTART_EXIT``, so that roslaunch's ``respawn="true"`` starts it again against the new master
with the parameters it had. A master that is only gone (not yet back) changes nothing: the connections
between nodes keep working.

Also: ``log_lines`` (a core's (level, text) log lines), ``wait_for_clock`` (until /clock runs under
/use_sim_time), ``run_until_interrupted`` (the run() of nodes that clean up through ROS on SIGINT /
SIGTERM). Default topic names: ``anafi_sim.names``.
"""
import os
import signal
import socket
import sys
import threading
import time
import xmlrpc.client

import rosgraph
import rospy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from anafi_sim.interface import ground_truth
from anafi_sim import names, processes
from anafi_sim.ros.params import ParamReader
from anafi_sim.sim.clock import aligned_start

OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR

#: the one level table: core health levels (anafi_sim.interface.ground_truth OK / WARN / ERROR, what
#: every core's ``health()`` reports) -> diagnostic_msgs/DiagnosticStatus levels
LEVELS = {ground_truth.OK: OK, ground_truth.WARN: WARN, ground_truth.ERROR: ERROR}

_LOG = {'info': 'loginfo', 'warn': 'logwarn', 'error': 'logerr'}


def private_params(ctx=None):
    """A ParamReader over the node's private parameters (``~name``; ``ctx``: those of a NodeContext)."""
    if ctx is not None:
        return ctx.params()
    return ParamReader(lambda name, default: rospy.get_param('~' + name, default))


def namespace_id(ctx=None):
    """The node's namespace without its slashes, 'anafi' at the root (hardware_id of the PID nodes;
    ``ctx``: a NodeContext's)."""
    if ctx is not None:
        return ctx.namespace_id
    return rospy.get_namespace().strip('/') or 'anafi'


def wait_for_clock(poll=0.05):
    """Under /use_sim_time, wait (wall time) until /clock has started (ROS time > 0) or ROS shuts down."""
    if rospy.get_param('/use_sim_time', False):
        while not rospy.is_shutdown() and rospy.get_time() == 0.0:
            time.sleep(poll)


def sleep_until_aligned(period, phase):
    """Sleep (ROS time) until the first instant phase + k x ``period`` [s] (``anafi_sim.sim.clock.aligned_start``;
    ``phase`` < 0: return at once), so that a timer started next runs on that grid. Waits for /clock first."""
    if phase < 0.0:
        return
    wait_for_clock()
    now = rospy.get_time()
    start = aligned_start(now, period, phase)
    if start > now:
        try:
            rospy.sleep(start - now)
        except rospy.ROSInterruptException:
            pass


def log_lines(lines, ctx=None):
    """Log ``[(level, text)]`` lines of a core (levels 'info', 'warn', 'error'; ``ctx``: through a NodeContext)."""
    log = rospy if ctx is None else ctx
    for level, text in lines:
        getattr(log, _LOG[level])(text)


# ------------------------------------------------------------------ diagnostics
def diagnostic_status(name, level, message, values, hardware_id=''):
    """A DiagnosticStatus; ``values`` are (key, value) pairs, both stored as strings."""
    return DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id,
                            values=[KeyValue(str(k), str(v)) for k, v in values])


def health_status(name, health, hardware_id='', extra_values=()):
    """A DiagnosticStatus of a core's ``Health`` (level via ``LEVELS``, message, values + ``extra_values``)."""
    return diagnostic_status(name, LEVELS[health.level], health.message,
                             list(health.values) + list(extra_values), hardware_id)


def diagnostics_publisher(queue_size=10, ctx=None):
    """The /diagnostics publisher (``ctx``: a NodeContext's)."""
    if ctx is not None:
        return ctx.publisher(names.DIAGNOSTICS, DiagnosticArray, queue_size=queue_size)
    return rospy.Publisher(names.DIAGNOSTICS, DiagnosticArray, queue_size=queue_size)


def publish_diagnostics(pub, statuses, stamp=None):
    """Publish ``statuses`` in one DiagnosticArray stamped ``stamp`` (default now); False once ROS is shut
    down (pub closed)."""
    array = DiagnosticArray(status=list(statuses))
    try:
        array.header.stamp = rospy.Time.now() if stamp is None else stamp
        pub.publish(array)
    except rospy.ROSException:
        return False
    return True


def start_diagnostics_thread(period, make_statuses, pub, stamp=None, first=None, node=None, ctx=None):
    """Daemon thread publishing ``make_statuses()`` on ``pub`` every ``period`` s of wall time until shutdown.

    The first array goes out after ``first`` s (default: one period). ``stamp``: a function giving the
    arrays' stamp (default rospy.Time.now()). An exception in ``make_statuses`` is logged (throttled, naming
    ``node``, default the node of ``ctx``, a NodeContext that logs it, else the process's node) and the thread
    goes on.
    """
    log = rospy if ctx is None else ctx
    node = node or (None if ctx is None else ctx.name)

    def loop():
        delay = period if first is None else first
        while True:
            time.sleep(delay)
            delay = period
            if rospy.is_shutdown():
                return
            try:
                statuses = make_statuses()
            except Exception as error:  # never let diagnostics kill the node, nor stop reporting
                if rospy.is_shutdown():
                    return
                log.logerr_throttle(10.0, '%s: diagnostics failed: %s: %s'
                                    % (node or rospy.get_name(), type(error).__name__, error))
                continue
            if not publish_diagnostics(pub, statuses, None if stamp is None else stamp()):
                return
    thread = threading.Thread(target=loop, name='diagnostics', daemon=True)
    thread.start()
    return thread


# ------------------------------------------------------------------ master restart
#: exit code of a node that saw the ROS master restart (EX_TEMPFAIL: try again; roslaunch respawns it)
MASTER_RESTART_EXIT = 75
MASTER_POLL = 1.0      # [s] wall time between two looks at the master
MASTER_TIMEOUT = 2.0   # [s] of one XML-RPC call to the master
EXIT_GRACE = 5.0       # [s] for the node to end after rospy.signal_shutdown, then it is ended hard


class MasterWatch(object):
    """Tells a restarted ROS master from one that is only gone (pure: the caller asks the master).

    ``update(identity)`` with the master's identity ((pid, run_id), or None when it does not answer):
    'ok' (the first master seen, or the same one), 'gone' (no answer) or 'restarted' (another master answers
    now: a new pid or run id); 'restarted' stays once seen. ``describe()``: old -> new, for the log line."""

    def __init__(self):
        self.first = None       # identity of the master the node registered with
        self.current = None
        self.restarted = False
        self.outages = 0        # polls without an answer

    def update(self, identity):
        if identity is None:
            self.outages += 1
            return 'restarted' if self.restarted else 'gone'
        self.current = identity
        if self.first is None:
            self.first = identity
        elif identity != self.first:
            self.restarted = True
        return 'restarted' if self.restarted else 'ok'

    def describe(self):
        (p0, r0), (p1, r1) = self.first, self.current
        return 'pid %s -> %s, run_id %s -> %s' % (p0, p1, r0 or '?', r1 or '?')


def master_identity(uri, caller, timeout=MASTER_TIMEOUT):
    """(pid, run_id) of the ROS master at ``uri`` (run_id None when unset), or None when it does not answer."""
    proxy = processes.xmlrpc_proxy(uri, timeout)
    try:
        code, _, pid = proxy.getPid(caller)
        if code != 1:
            return None
        code, _, run_id = proxy.getParam(caller, '/run_id')
    except (OSError, socket.error, xmlrpc.client.Error):
        return None
    return pid, (run_id if code == 1 else None)


def saved_params():
    """{name: value} of the node's parameters to put back on a restarted master: its private namespace and
    /use_sim_time (as set now)."""
    saved = {}
    for name in (rospy.get_name(), '/use_sim_time'):
        try:
            if rospy.has_param(name):
                saved[name] = rospy.get_param(name)
        except (rospy.ROSException, OSError, socket.error):
            pass
    return saved


def restore_params(saved):
    """Put ``saved`` parameters back where the (new) master lacks them; names put back."""
    done = []
    for name, value in sorted(saved.items()):
        try:
            if not rospy.has_param(name):
                rospy.set_param(name, value)
                done.append(name)
        except (rospy.ROSException, OSError, socket.error):
            pass
    return done


def start_master_watch(saved, period=MASTER_POLL, exit_code=MASTER_RESTART_EXIT, grace=EXIT_GRACE):
    """Daemon thread: on a master restart (``MasterWatch``) restore ``saved`` params, log FATAL, shut rospy
    down and end the process with ``exit_code`` (hard after ``grace`` s). Returns the MasterWatch."""
    watch = MasterWatch()
    uri = rosgraph.get_master_uri()
    caller = rospy.get_name()

    def loop():
        while not rospy.is_shutdown():
            if watch.update(master_identity(uri, caller)) == 'restarted':
                put_back = restore_params(saved)
                rospy.logfatal('%s: the ROS master at %s restarted (%s); rospy cannot register again with it: '
                               'exiting with code %d so that roslaunch respawns the node%s', caller, uri,
                               watch.describe(), exit_code,
                               ' (parameters put back: %s)' % ', '.join(put_back) if put_back else '')
                rospy.signal_shutdown('ROS master restarted')
                time.sleep(grace)           # run_node exits with exit_code once run() returns
                os._exit(exit_code)
            time.sleep(period)
    thread = threading.Thread(target=loop, name='master_watch', daemon=True)
    thread.start()
    return watch


# ------------------------------------------------------------------ start-up
def run_node(name, factory, fatal_exit_code=1, fatal_errors=(ValueError,), watch_master=True,
             respawned=False, **init_args):
    """init_node(name, **init_args), then ``factory().run()``.

    An exception of ``fatal_errors`` from ``factory`` (a bad parameter: ParamError is a ValueError) is
    logged with rospy.logfatal and ends the process with ``fatal_exit_code``; with ``respawned`` (a node
    that the launch files start with ``respawn="true"``: exiting would only start it again with the same
    parameters, FATAL every second) the node stays up instead, in ERROR (``stay_in_error``). What
    ``run()`` returns is the exit status: None (default) or True -> 0, False -> 1, an int -> that code.
    ``watch_master``: exit with ``MASTER_RESTART_EXIT`` when the ROS master restarts (see the module doc).
    SIGINT / SIGTERM: rospy's own handlers replaced by ``install_shutdown_signals`` (unless the node passes
    ``disable_signals=True`` and handles them itself).
    """
    deferred = not init_args.get('disable_signals')
    if deferred:
        init_args['disable_signals'] = True
    rospy.init_node(name, **init_args)
    shutdown_done = install_shutdown_signals() if deferred else None
    try:
        node = factory()
    except KeyboardInterrupt:       # nodes that handle SIGINT themselves, stopped while starting
        rospy.signal_shutdown('stopped while starting')
        return
    except fatal_errors as error:
        if respawned:
            stay_in_error(error)
        else:
            rospy.logfatal('%s: bad parameters: %s', rospy.get_name(), error)
        if not deferred:
            rospy.signal_shutdown('bad parameters')
        sys.exit(fatal_exit_code)
    watch = start_master_watch(saved_params()) if watch_master else None
    try:
        result = node.run()
    except (rospy.ROSException, KeyboardInterrupt):
        # shutting down beside the main loop (install_shutdown_signals): a publish to a topic rospy closed meanwhile
        if not (rospy.is_shutdown() or rospy.core.is_shutdown_requested()):
            raise
        result = None
    if shutdown_done is not None:
        shutdown_done(SIGNAL_EXIT_GRACE)
    if watch is not None and watch.restarted:
        sys.exit(MASTER_RESTART_EXIT)
    if result is None or result is True:
        return
    sys.exit(1 if result is False else int(result))


#: [s] wall time a node has to end after SIGINT / SIGTERM (an experiment monitor writing its run files and plots
#: included) before it ends itself (os._exit): below the 15 s roslaunch waits before it escalates to SIGTERM and
#: SIGKILL
SIGNAL_EXIT_GRACE = 12.0


def _hard_exit(why, exit_code):
    """End the process at once (os._exit: no cleanup left to wait for) with one line on stderr naming the node."""
    try:
        sys.stderr.write('%s: %s; ending now\n' % (rospy.get_name(), why))
        sys.stderr.flush()
    finally:
        os._exit(exit_code)


def install_shutdown_signals(grace=SIGNAL_EXIT_GRACE, exit_code=0):
    """SIGINT / SIGTERM -> ``rospy.signal_shutdown`` on a thread of its own, instead of rospy's handler, which runs
    it inside the signal handler on top of whatever the main thread was doing: a signal that lands while the main
    thread is in a call to the master (reading its parameters at start-up, a get_param later) deadlocks there, the
    shutdown waiting for the master proxy's lock that the interrupted call holds; rospy also swallows SIGTERM, so
    roslaunch can only SIGKILL it. Here the main thread finishes its call, sees ``rospy.is_shutdown()`` and ends
    (rospy.spin, ``while not rospy.is_shutdown()`` loops). A node still running ``grace`` s after the first signal,
    or at SIGTERM after the first signal (roslaunch's escalation), ends at once (``exit_code``) with one line on
    stderr naming it; another SIGINT meanwhile changes nothing (the fleet launcher signals every node of a fleet at
    once, its roslaunch again later). Returns ``wait(timeout)``: after a signal, waits until rospy's shutdown has
    returned (the node unregistered), so that the main thread does not end the process in the middle of it."""
    state = {'signals': 0, 'start': None}
    done = threading.Event()       # rospy's shutdown (unregistering from the master) has returned

    def hard_exit(why):
        _hard_exit(why, exit_code)

    def shut_down(signum):
        try:
            rospy.signal_shutdown('signal-%d' % signum)
        finally:
            done.set()
        left = grace - (time.monotonic() - state['start'])
        if left > 0.0:
            time.sleep(left)
        hard_exit('still running %g s after signal %d' % (grace, signum))

    def handler(signum, _frame):
        state['signals'] += 1
        if state['signals'] > 1:
            if signum == signal.SIGINT:
                return
            hard_exit('signal %d during shutdown' % signum)
        state['start'] = time.monotonic()
        threading.Thread(target=shut_down, args=(signum,), name='signal_shutdown', daemon=True).start()

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, handler)
    return lambda timeout: done.wait(timeout) if state['signals'] else True


#: [s] wall time between the ERROR diagnostics of a node that stays up with bad parameters
BAD_PARAMS_PERIOD = 1.0


def stay_in_error(error):
    """A node with bad parameters that roslaunch would respawn: one FATAL line, then an ERROR diagnostic
    ``<node>: bad parameters`` every ``BAD_PARAMS_PERIOD`` s (message: the error) until shutdown; nothing
    else runs (no topic, no timer, no subprocess)."""
    node = rospy.get_name()
    message = 'bad parameters: %s' % (error,)
    rospy.logfatal('%s: %s; staying up in ERROR without running (not exiting: roslaunch would respawn the '
                   'node with the same parameters); fix the parameter and start it again', node, message)
    status = diagnostic_status('%s: bad parameters' % node, ERROR, message,
                               [('action', 'not running; fix the parameter and restart the node')])
    start_diagnostics_thread(BAD_PARAMS_PERIOD, lambda: [status], diagnostics_publisher(), first=0.2)
    try:
        while not rospy.is_shutdown():
            time.sleep(0.2)
    except KeyboardInterrupt:   # nodes started with disable_signals
        pass


class Timer(object):
    """``rospy.Timer`` that survives ROS time jumping backwards, and says so.

    rospy's Timer thread dies with ROSTimeMovedBackwardsException when /clock goes back under
    /use_sim_time (the simulator respawned, a bag looped): the node keeps running with no cycle at all.
    This one is started with ``reset=True`` (the period restarts from the new time) and counts the jumps
    (``jumps_back``; ``last_jump`` [s], how far back): one WARN line per jump naming the node and the
    timer. ``callback(event)`` as rospy's; an exception from it is logged (throttled) and counted
    (``callback_errors``), the timer goes on. ``node``: the name the log lines give (default the node of
    ``ctx``, a NodeContext that logs them, else the process's node)."""

    def __init__(self, period, callback, name='timer', node=None, ctx=None):
        self.name = name
        self.node = node or (None if ctx is None else ctx.name)
        self.log = rospy if ctx is None else ctx
        self.jumps_back = 0
        self.last_jump = 0.0
        self.callback_errors = 0
        self._callback = callback
        self._last = None
        self._timer = rospy.Timer(rospy.Duration.from_sec(period), self._on_event, reset=True)

    def _on_event(self, event):
        now = event.current_real
        if self._last is not None and now < self._last:
            self.jumps_back += 1
            self.last_jump = (self._last - now).to_sec()
            self.log.logwarn('%s: ROS time moved backwards by %.3f s (%d times): %s timer kept running',
                             self.node or rospy.get_name(), self.last_jump, self.jumps_back, self.name)
        self._last = now
        try:
            self._callback(event)
        except Exception as error:   # a cycle that failed must not end the timer thread
            self.callback_errors += 1
            # shutting down: rospy closes the topics before is_shutdown() turns true (publish() to a closed topic)
            if not (rospy.is_shutdown() or rospy.core.is_shutdown_requested()):
                self.log.logerr_throttle(5.0, '%s: %s timer callback failed (%d times): %s: %s' % (
                    self.node or rospy.get_name(), self.name, self.callback_errors, type(error).__name__, error))

    def shutdown(self):
        self._timer.shutdown()


def end_parent_launch(wait=15.0):
    """End the roslaunch that started this node as Ctrl-C would (SIGINT to the parent process, only if it
    is roslaunch), then wait up to ``wait`` s of wall time for roslaunch to stop this node. For a required
    node that finished its job: roslaunch then exits 0 without its red "REQUIRED process has died".
    Returns False (nothing sent) when the parent is not roslaunch."""
    parent = os.getppid()
    try:
        with open('/proc/%d/cmdline' % parent, 'rb') as f:
            words = f.read().split(b'\0')
    except OSError:
        return False
    if not any(os.path.basename(w) == b'roslaunch' for w in words[:2]):
        return False
    os.kill(parent, signal.SIGINT)
    end = time.monotonic() + wait
    while not rospy.is_shutdown() and time.monotonic() < end:
        time.sleep(0.05)
    return True


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt('signal %d' % signum)


def _exit_when_signalled_again(grace=SIGNAL_EXIT_GRACE, exit_code=0):
    """After the first SIGINT / SIGTERM of a node that cleans up itself: SIGINT ignored, SIGTERM (roslaunch's
    escalation) or ``grace`` s more end the process at once (one line on stderr)."""
    def hard_exit(why):
        _hard_exit(why, exit_code)

    def later():
        time.sleep(grace)
        hard_exit('still cleaning up %g s after the signal' % grace)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, lambda signum, _frame: hard_exit('signal %d while cleaning up' % signum))
    threading.Thread(target=later, name='exit_grace', daemon=True).start()


def run_until_interrupted(spin, cleanup, reason, grace=SIGNAL_EXIT_GRACE):
    """The ``run()`` of a node started with ``disable_signals=True`` that must clean up through ROS (delete
    its Gazebo models): SIGINT or SIGTERM ends ``spin()``, ``cleanup()`` runs while ROS still works, then
    rospy shuts down with ``reason``. Meanwhile another SIGINT is ignored; SIGTERM, or cleaning up longer than
    ``grace`` s, ends the process at once."""
    signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        spin()
    except KeyboardInterrupt:
        pass
    finally:
        _exit_when_signalled_again(grace)
        if not rospy.is_shutdown():
            cleanup()
        rospy.signal_shutdown(reason)
