"""The trajectory generator core: a scenario run against a clock -> the paper's waypoint (pure Python, no ROS).

Stage: trajectory -> waypoint (-> PID / MPC controller). ``TrajectoryGenerator`` runs a ``Scenario`` of
``anafi_sim.mission.trajectory`` (start / stop / switch, ``update(now)`` per tick) and reports its ``Event``s;
the trajectory generator node and the in-process engine drive it.
"""
import collections
import math

from anafi_sim.mission.waypoint import WaypointSample

Event = collections.namedtuple('Event', 'kind time scenario phase')
Event.__doc__ = ("A generator event: kind 'start' | 'phase' | 'begin' | 'end' | 'abort' | 'done' | 'stop', "
                 "time [s, the clock of update()] at which it happened exactly (a phase boundary, not the "
                 "tick that noticed it), scenario name, phase name ('' when none).")

IDLE, RUNNING, DONE, STOPPED = 'idle', 'running', 'done', 'stopped'


class TrajectoryGenerator(object):
    """Runs a ``Scenario`` against a clock: start / stop / switch, and ``update(now)`` per tick.

    ``update(now)`` returns (waypoint or None, [Event]): the waypoint to
    publish at ``now`` [s] and the events since the last update in time order
    ('begin' / 'end' carry the exact boundary time of the measured phase, so
    an evaluator can cut its window precisely). Before start nothing is
    published (None); after the scenario ends (state 'done') or after
    ``stop`` (state 'stopped') the last position is held with zero velocity
    when ``hold_when_idle`` (else None). ``switch`` aborts a running
    measurement ('abort' event) and starts the new scenario at once.
    """

    def __init__(self, scenario, hold_when_idle=True):
        self.scenario = scenario
        self.hold_when_idle = bool(hold_when_idle)
        self.state = IDLE
        self.t0 = None
        self._last_phase = None
        self._hold = None
        self._pending = []

    def _event(self, kind, time, phase=''):
        self._pending.append(Event(kind, float(time), self.scenario.name, phase))

    def start(self, now):
        """Start (or restart) the scenario at clock time ``now`` [s]."""
        if self.state == RUNNING:
            self._abort(now)
        self.state = RUNNING
        self.t0 = float(now)
        self._last_phase = None
        self._event('start', now)

    def stop(self, now):
        """Stop: hold the current position (zero velocity); a running measurement is aborted."""
        if self.state == RUNNING:
            self._advance(now)
            wp = self.scenario.waypoint(float(now) - self.t0)
            self._hold = WaypointSample(wp.x, wp.y, wp.z, 0.0, 0.0, 0.0, wp.yaw)
            self._abort(now)
            self.state = STOPPED
            self._event('stop', now)

    def switch(self, scenario, now, start=True):
        """Replace the scenario (aborting a running one) and start it at ``now`` (or go idle)."""
        if self.state == RUNNING:
            self._advance(now)
            self._abort(now)
        self.scenario = scenario
        self.reset()
        if start:
            self.start(now)

    def reset(self):
        """Back to 'idle' (nothing published until the next start), e.g. after the clock jumped back."""
        self.state = IDLE
        self.t0 = None
        self._last_phase = None
        self._hold = None

    def _abort(self, now):
        if self._last_phase is not None and self._last_phase == self.scenario.measure_index:
            self._event('abort', now, self.scenario.measured_phase.name)

    def _advance(self, now):
        """Emit the phase / begin / end / done events between the last update and ``now``."""
        t = float(now) - self.t0
        sc = self.scenario
        current = sc.phase_at(t).index
        first = 0 if self._last_phase is None else self._last_phase + 1
        last = len(sc.phases) - 1 if current is None else current
        if self._last_phase is not None and current == self._last_phase:
            return
        for i in range(first, last + 1):
            start = self.t0 + sc._bounds[i][0]
            if i - 1 == sc.measure_index and i >= 1:
                self._event('end', self.t0 + sc._bounds[i - 1][1], sc.phases[i - 1].name)
            self._event('phase', start, sc.phases[i].name)
            if i == sc.measure_index:
                self._event('begin', start, sc.phases[i].name)
        if current is None:
            if sc.measure_index == len(sc.phases) - 1:
                self._event('end', self.t0 + sc.duration, sc.phases[-1].name)
            self._event('done', self.t0 + sc.duration)
            self.state = DONE
            self._hold = sc.final
        self._last_phase = current if current is not None else len(sc.phases)

    def update(self, now):
        """(waypoint or None, [Event]) at clock time ``now`` [s]."""
        if self.state == RUNNING:
            self._advance(now)
        events, self._pending = self._pending, []
        if self.state == RUNNING:
            return self.scenario.waypoint(float(now) - self.t0), events
        if self.state in (DONE, STOPPED) and self.hold_when_idle:
            return self._hold, events
        return None, events

    def preview(self, now, horizon, step):
        """The upcoming reference: [(time [s, the clock of update()], (x, y, z), (vx, vy, vz), (ax, ay, az),
        yaw_deg)] at now, now + step, ... up to now + ``horizon`` [s] inclusive, as ``update`` would publish
        it at those times (hold phases, the end's hold included); [] when not running and not holding."""
        if not (step > 0.0 and horizon >= 0.0):
            raise ValueError('preview needs step > 0 and horizon >= 0, got %r, %r' % (step, horizon))
        n = int(math.floor(horizon / step + 1e-9)) + 1
        now = float(now)
        out = []
        if self.state == RUNNING:
            for i in range(n):
                t = now + i * step
                wp, acc = self.scenario.reference(t - self.t0)
                out.append((t, (wp.x, wp.y, wp.z), (wp.vx, wp.vy, wp.vz), tuple(acc), wp.yaw))
        elif self.state in (DONE, STOPPED) and self.hold_when_idle and self._hold is not None:
            h = self._hold
            out = [(now + i * step, (h.x, h.y, h.z), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), h.yaw) for i in range(n)]
        return out

    def phase_name(self, now):
        """Name of the phase at ``now`` ('' when not running)."""
        if self.state != RUNNING:
            return ''
        state = self.scenario.phase_at(float(now) - self.t0)
        return state.phase.name if state.phase else ''
