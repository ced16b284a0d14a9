"""Simulation time against wall time: stepping schedule, decimation, real-time pacing (pure: numbers in,
decisions out; the node reads the clocks and sleeps).

Stage: simulated Anafi (the physics loop of anafi_sim_node.py); the kinematic world's loop uses ``Pacer``
too.

- ``Periodic``: when an action with a period is due on some clock (telemetry and estimate decimation on
  simulation time, checks on wall time);
- ``Pacer``: a fixed-period loop on the wall clock: how long to sleep after each cycle, late cycles
  (overruns: more than one period behind) and schedule re-anchors (more than ``max_lag`` behind: the
  schedule restarts from now instead of catching up in a burst);
- ``SimClock``: the simulated Anafi's loop: physics steps of 1/rate s of simulation time paced at
  ``rtf`` x real time, which steps publish telemetry / the estimate / /clock, and the achieved rates;
- ``ScaledSteps``: variable steps of simulated time from wall-time gaps (the kinematic world: rtf x the
  gap, capped);
- ``Lockstep`` and ``StartHold``: the simulated Anafi's lockstep mode (``~sync``): at each control period
  wait (wall time, bounded) for the controller's command of that period before simulation time goes on;
  before the first step, hold simulation time at 0 until the graph's nodes are up (so every node's timers
  start in phase with 0).
"""
import collections
import threading
import time

MAX_LAG = 0.25
"""s of wall time behind schedule before the simulated Anafi's pacing re-anchors (counted)."""

Tick = collections.namedtuple('Tick', 'k t telemetry estimate clock')
"""One physics step done: step count k, simulation time t [s] after it; whether to publish the telemetry
sample (and ground truth), the estimate, /clock at t."""

PacingReport = collections.namedtuple('PacingReport', 'sim_time achieved_rate wanted_rate achieved_rtf overruns '
                                                      'reanchors max_lag')
"""Since the previous report: physics rate achieved and wanted [steps per wall second], real-time factor
achieved (simulated s per wall s); overruns and re-anchors since the start; sim_time [s] now."""


class Periodic(object):
    """Due every ``period`` on the clock the caller passes to ``due(now)``, first at ``first``.

    ``keep_phase``: the next time is one period after the previous due time (kept in phase, at most one
    period of catching up: a gap longer than a period restarts from now); else one period after ``now``.
    ``eps`` absorbs rounding of times built as k * dt.
    """

    def __init__(self, period, first=0.0, keep_phase=True, eps=1e-9):
        if not period > 0:
            raise ValueError('period must be > 0, got %r' % (period,))
        self.period = float(period)
        self.next = float(first)
        self.keep_phase = keep_phase
        self.eps = eps

    def due(self, now):
        """True when the action is due at ``now`` (and schedules the next one)."""
        if now < self.next - self.eps:
            return False
        if self.keep_phase:
            self.next += self.period
            if self.next < now:
                self.next = now + self.period
        else:
            self.next = now + self.period
        return True


class Pacer(object):
    """A loop of ``period`` s of wall time: cycle n should end at start + n * period.

    ``wait(wall)`` after each cycle gives the seconds to sleep. Later than one period is an overrun;
    later than ``max_lag`` re-anchors the schedule on ``wall`` (0: never catch up, the next cycle is one
    period after a late one).
    """

    def __init__(self, period, max_lag=MAX_LAG):
        if not period > 0 or not max_lag >= 0:
            raise ValueError('period must be > 0 and max_lag >= 0, got %r, %r' % (period, max_lag))
        self.period = float(period)
        self.max_lag = float(max_lag)
        self.cycles = 0
        self.overruns = 0
        self.reanchors = 0
        self._anchor = None

    def start(self, wall):
        """The loop starts at wall time ``wall`` [s]."""
        self._anchor = wall
        self.cycles = 0

    def resume(self, wall):
        """Continue from wall time ``wall`` after a deliberate pause (a lockstep wait): no catching up, not
        counted as a re-anchor."""
        self._anchor = wall - self.cycles * self.period

    def wait(self, wall):
        """One cycle done at wall time ``wall``: seconds to sleep before the next one (0 when late)."""
        self.cycles += 1
        delay = self._anchor + self.cycles * self.period - wall
        if delay > 0.0:
            return delay
        if delay < -self.period:
            self.overruns += 1
        if delay < -self.max_lag:
            self.reanchors += 1
            self._anchor = wall - self.cycles * self.period
        return 0.0


class SimClock(object):
    """The simulated Anafi's loop: physics at ``rate`` Hz of simulation time, paced at ``rtf`` x real time.

    telemetry_rate / estimate_rate [Hz of simulation time]: decimation of the ground-truth telemetry and
    of the bridge's estimate topics; publish_clock: /clock after every step. Use: ``start(wall)``, then
    per step ``tick()`` (after the physics step) and ``pace(wall)`` (seconds to sleep); ``report(wall)``
    (any thread) gives the achieved rates since the previous report.
    """

    def __init__(self, rate, rtf=1.0, telemetry_rate=100.0, estimate_rate=30.0, publish_clock=False,
                 max_lag=MAX_LAG):
        for name, value in (('rate', rate), ('rtf', rtf), ('telemetry_rate', telemetry_rate),
                            ('estimate_rate', estimate_rate)):
            if not value > 0:
                raise ValueError('%s must be > 0, got %r' % (name, value))
        self.rate = float(rate)
        self.rtf = float(rtf)
        self.dt = 1.0 / self.rate
        self.publish_clock = bool(publish_clock)
        self.pacer = Pacer(self.dt / self.rtf, max_lag)
        self.k = 0
        self.t = 0.0
        self._telemetry = Periodic(1.0 / telemetry_rate)
        self._estimate = Periodic(1.0 / estimate_rate)
        self._report = (0, None)   # (k, wall) of the previous report

    @property
    def wanted_rate(self):
        """Physics steps per wall second asked for: rate x rtf."""
        return self.rate * self.rtf

    def start(self, wall):
        """Simulation time 0 at wall time ``wall`` [s]."""
        self.pacer.start(wall)
        self._report = (self.k, wall)

    def tick(self):
        """One physics step of ``dt`` done: the new time and what to publish at it."""
        self.k += 1
        self.t = t = self.k * self.dt
        return Tick(self.k, t, self._telemetry.due(t), self._estimate.due(t), self.publish_clock)

    def pace(self, wall):
        """Seconds to sleep after the step just done, at wall time ``wall`` (0 when behind)."""
        return self.pacer.wait(wall)

    def resume(self, wall):
        """Pace on from wall time ``wall`` after a lockstep wait (``Pacer.resume``)."""
        self.pacer.resume(wall)

    def report(self, wall):
        """PacingReport since the previous report (or the start), at wall time ``wall``."""
        k = self.k
        k0, wall0 = self._report
        self._report = (k, wall)
        span = wall - wall0 if wall0 is not None else 0.0
        steps = k - k0
        rate = steps / span if span > 0.0 else 0.0
        return PacingReport(k * self.dt, rate, self.wanted_rate, rate * self.dt, self.pacer.overruns,
                            self.pacer.reanchors, self.pacer.max_lag)


class ScaledSteps(object):
    """Simulated time per cycle of a variable-step loop: ``rtf`` x the wall time since the previous cycle,
    at most ``max_step`` s (a longer stall is capped and counted in ``overruns``: the simulation then runs
    slower than rtf, as Gazebo does)."""

    def __init__(self, rtf, max_step):
        if not rtf > 0 or not max_step > 0:
            raise ValueError('rtf and max_step must be > 0, got %r, %r' % (rtf, max_step))
        self.rtf = float(rtf)
        self.max_step = float(max_step)
        self.overruns = 0

    def step(self, wall_dt):
        """Simulated seconds for ``wall_dt`` s of wall time (<= 0 when the wall clock did not advance)."""
        dt = wall_dt * self.rtf
        if dt > self.max_step:
            self.overruns += 1
            return self.max_step
        return dt


POKE_PERIOD = 0.005
"""s of wall time between repeats of the held /clock tick while the lockstep waits."""

LockstepReport = collections.namedtuple('LockstepReport', 'state waits timeouts disarms wait_wall_max '
                                                        'wait_wall_mean')
"""Lockstep figures since the start: state ('waiting for the first command', 'lockstep' or 'free-running:
controller silent'), waits (control periods waited for), timeouts, disarms (times the controller fell silent
for max_missed periods), longest and mean wait [s wall]."""


#: phases [s] of the periodic nodes' first cycles against simulation time (``~timer_phase``): a node starts its
#: timer at the first instant phase + k x period, so the waypoint is as old at the controller's cycle in every
#: run. controller 30 ms: the MPC cycled at 30/35 ms past every 100 ms in a recorded ROS run of circle_r1_v1;
#: generator 80 ms: with it the 10 Hz waypoint is 50 ms old at the controller's cycle, the mean over a random
#: phase (before the alignment each ROS start-up drew one: 15 and 95 ms were recorded); the in-process engine's
#: schedule (anafi_lab/engine/engine.py) uses the same two.
TIMER_PHASES = {'controller': 0.030, 'generator': 0.080}


def aligned_start(now, period, phase):
    """The first instant >= ``now`` [s] of the grid phase + k x ``period`` (``phase`` < 0: ``now``, no grid)."""
    if phase < 0.0 or not period > 0.0:
        return now
    k = -(-(now - phase) // period)          # ceil without float surprises on exact multiples
    t = phase + k * period
    return t if t >= now - 1e-9 else t + period


#: defaults of the lockstep (anafi_sim_node.py ~sync_*: the node reads them from here)
SYNC_DEFAULTS = {
    'sync_period': 0.1,         # s sim, the controller's command period (10 Hz)
    'sync_timeout': 1.0,        # s wall to wait for a period's command (experiment.launch passes its own, 5)
    'sync_max_missed': 5,       # time-outs in a row -> the controller is taken for silent, free-running
    'sync_settle': 3.0,         # s wall the number of /clock subscribers must stay the same before time starts
    'sync_start_timeout': 60.0,  # s wall at most before time starts anyway
}


class Lockstep(object):
    """Lockstep of the simulated Anafi with a controller (``~sync``): thread-safe, wall-clock waits.

    The controller commands every ``period`` s of simulation time and stamps each command with the ROS
    time of its cycle (``header.stamp``: the /clock tick its timer fired on). ``on_command(stamp)`` (any
    thread, after the command is queued) records it. The first command arms the lockstep; from then on
    the period's command is due at the first physics tick t >= last + period - dt / 2 (last: stamp of the
    previous period's command); ``due(t)`` says so and ``wait()`` blocks until a command newer than
    ``last`` arrives (True) or ``timeout`` s of wall time passed (False, counted: the period goes on
    without a command, the firmware's behaviour applies). After ``max_missed`` timeouts in a row the
    controller is taken for silent (failsafe, dead node): free-running until its next command re-arms.
    ``close()`` ends any wait (shutdown).
    """

    def __init__(self, period, dt, timeout=SYNC_DEFAULTS['sync_timeout'], max_missed=SYNC_DEFAULTS['sync_max_missed']):
        if not period > 0 or not dt > 0 or not timeout > 0 or not max_missed >= 1:
            raise ValueError('need period, dt, timeout > 0 and max_missed >= 1, got %r, %r, %r, %r'
                             % (period, dt, timeout, max_missed))
        self.period, self.dt, self.timeout, self.max_missed = float(period), float(dt), float(timeout), int(max_missed)
        self._cond = threading.Condition()
        self.armed = False
        self.closed = False
        self.last = None          # stamp of the command that ended the previous period [s sim]
        self.newest = None        # newest command stamp received [s sim]
        self.missed = 0           # timeouts in a row
        self.waits = self.timeouts = self.disarms = 0
        self.wait_wall_max = self.wait_wall_sum = 0.0

    def on_command(self, stamp):
        """A command stamped ``stamp`` [s sim] was received (and queued for the next step)."""
        with self._cond:
            stamp = float(stamp)
            if self.newest is None or stamp > self.newest:
                self.newest = stamp
            if not self.armed:
                self.armed = True
                self.last = stamp
                self.missed = 0
            self._cond.notify_all()

    def due(self, t):
        """True when the step that ended at simulation time ``t`` [s] must wait for the period's command."""
        with self._cond:
            return self.armed and not self.closed and t >= self.last + self.period - 0.5 * self.dt

    def _arrived(self):
        return self.newest is not None and self.newest > self.last + 0.5 * self.dt

    def wait(self, poke=None, clock=time.monotonic):
        """Block until the period's command arrived (True) or the wall time-out (False, counted).

        ``poke()`` is called every ``POKE_PERIOD`` s of wall time while waiting: the node publishes the
        same /clock tick again, because rospy.sleep under /use_sim_time can miss the one notification of
        a tick (it checks the time outside the lock it waits on, then waits up to 0.5 s) and, with the
        clock stopped, its timer would fire up to 0.5 s late."""
        with self._cond:
            start = clock()
            deadline = start + self.timeout
            while not self._arrived() and not self.closed:
                remaining = deadline - clock()
                if remaining <= 0.0:
                    break
                self._cond.wait(min(remaining, POKE_PERIOD) if poke is not None else remaining)
                if poke is not None and not self._arrived():
                    poke()
            waited = clock() - start
            self.waits += 1
            self.wait_wall_sum += waited
            self.wait_wall_max = max(self.wait_wall_max, waited)
            if self._arrived():
                self.last = self.newest
                self.missed = 0
                return True
            if self.closed:
                return False
            self.timeouts += 1
            self.missed += 1
            self.last += self.period
            if self.missed >= self.max_missed:
                self.armed = False
                self.disarms += 1
            return False

    def close(self):
        """End waits for good (shutdown)."""
        with self._cond:
            self.closed = True
            self._cond.notify_all()

    def report(self):
        """``LockstepReport`` since the start."""
        with self._cond:
            if self.armed:
                state = 'lockstep'
            elif self.disarms:
                state = 'free-running: controller silent'
            else:
                state = 'waiting for the first command'
            mean = self.wait_wall_sum / self.waits if self.waits else 0.0
            return LockstepReport(state, self.waits, self.timeouts, self.disarms, self.wait_wall_max, mean)


class StartHold(object):
    """Simulation time held at 0 until the graph is up: ``ready(wall, count)`` with the number of /clock
    subscribers is True once that number is >= 1 and has not changed for ``settle`` s of wall time, or
    ``timeout`` s after the first call (``timed_out`` then True). Nodes that create their timers while time
    is 0 run them in phase with 0 (rospy.Timer and rospy.Rate count periods from their creation)."""

    def __init__(self, settle=SYNC_DEFAULTS['sync_settle'], timeout=SYNC_DEFAULTS['sync_start_timeout']):
        if not settle >= 0 or not timeout > 0:
            raise ValueError('need settle >= 0 and timeout > 0, got %r, %r' % (settle, timeout))
        self.settle, self.timeout = float(settle), float(timeout)
        self.start = self.changed = None
        self.count = None
        self.timed_out = False

    def ready(self, wall, count):
        """True when simulation time may start, at wall time ``wall`` [s] with ``count`` /clock subscribers."""
        if self.start is None:
            self.start = wall
        if count != self.count:
            self.count, self.changed = count, wall
        if wall - self.start >= self.timeout:
            self.timed_out = True
            return True
        return count >= 1 and wall - self.changed >= self.settle


def lockstep_values(report):
    """(key, text) pairs of a LockstepReport for /diagnostics."""
    return [
        ('lockstep', report.state),
        ('lockstep periods waited', str(report.waits)),
        ('lockstep timeouts (period went on without a command)', str(report.timeouts)),
        ('lockstep controller silent (free-running)', str(report.disarms)),
        ('lockstep wait max [s wall]', '%.3f' % report.wait_wall_max),
        ('lockstep wait mean [s wall]', '%.4f' % report.wait_wall_mean),
    ]


def report_values(report):
    """(key, text) pairs of a PacingReport for /diagnostics (keys read by the experiment monitor)."""
    return [
        ('sim time [s]', '%.3f' % report.sim_time),
        ('physics rate achieved [Hz wall]', '%.1f' % report.achieved_rate),
        ('physics rate wanted [Hz wall]', '%.1f' % report.wanted_rate),
        ('real-time factor achieved', '%.3f' % report.achieved_rtf),
        ('overruns (steps late by > 1 period)', str(report.overruns)),
        ('schedule re-anchors (> %.2f s behind)' % report.max_lag, str(report.reanchors)),
    ]
