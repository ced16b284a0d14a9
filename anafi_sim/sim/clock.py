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
  gap, capped).
"""
import collections

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
