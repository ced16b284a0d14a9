"""The simulated Anafi as the node runs it: model + estimate + command inbox + telemetry, on a SimClock
(pure, no ROS).

Stage: piloting command -> **simulated drone** -> (telemetry server, bridge-like estimate topics).

``SimulatedAnafi`` takes piloting commands and take-off / landing requests from any thread
(``on_command``, ``on_event``), applies them before the next physics step, steps the model
(``anafi_sim.sim.drone_model``) and the drone's own estimate (``anafi_sim.sim.state_estimate``) on a
``anafi_sim.sim.clock.SimClock``, sends the decimated ground truth to the telemetry server, and says
what the node publishes after each step (``Step``). ``health(wall)`` sums it up for /diagnostics.
With a ``anafi_sim.sim.clock.Lockstep`` (``~sync``), ``sync(t)`` after a step waits for the controller's
command of the control period when one is due (commands carry their stamps: ``on_command(..., stamp=)``;
an unstamped command, header.stamp 0 as the reference implementation's controllers send, counts at the
simulation time of its arrival, and ``health`` says so). A command stamped more than ``FOREIGN_CLOCK_MARGIN``
ahead of the simulation time comes from a node on another clock (the wall clock: a node without
/use_sim_time, or under compat.launch's /use_sim_time false): the lockstep cannot pace it, so it counts at
its arrival too and ``health`` WARNs once per new such command.
"""
import collections
import math

from anafi_sim.sim.bridge import bridge_estimate
from anafi_sim.sim.clock import lockstep_values, report_values
from anafi_sim.sim.drone_model import FLYING

Step = collections.namedtuple('Step', 't events sample estimate state clock')
"""After one physics step: simulation time t [s]; events applied before it [(event, accepted, flight state
after)]; sample: the ground-truth TelemetrySample to publish (None: decimated); estimate: the
BridgeEstimate to publish (None: decimated or not ready); state: the new flight state (None: unchanged);
clock: publish /clock at t."""

FOREIGN_CLOCK_MARGIN = 1.0
"""s: a command stamp further than this ahead of the simulation time at its arrival is on another clock (a
controller on the simulation clock stamps the /clock tick it fired on, which the simulator has reached)."""

Status = collections.namedtuple('Status', 'warning message values')
"""Health for /diagnostics: warning (bool: WARN, else OK), message, (key, text) values."""

WANTED_RATE_FRACTION = 0.95
"""Physics achieved below this fraction of rate x rtf is a warning."""


class SimulatedAnafi(object):
    """Steps an ``AnafiModel`` and its ``StateEstimate`` on a ``SimClock``.

    Piloting commands are mapped to PCMD percents with the model's ``PilotingMapping`` (the bridge's);
    server: the ``TelemetryServer`` the ground truth goes to (None: none); auto_takeoff: take off at 0 s;
    lockstep: a ``Lockstep`` (None: free-running on the clock's pacing).
    """

    def __init__(self, model, estimate, clock, server=None, auto_takeoff=True, max_commands=1000, lockstep=None):
        self.model, self.estimate, self.clock = model, estimate, clock
        self.server = server
        self.auto_takeoff = auto_takeoff
        self.commands = collections.deque(maxlen=max_commands)   # PCMD tuples from the callback thread
        self.events = collections.deque(maxlen=100)              # 'takeoff' / 'land'
        self.commands_received = 0
        self.bad_commands = 0
        self._bad_reported = 0
        self._last_state = None
        self.lockstep = lockstep
        self._timeouts_reported = 0
        self.unstamped_commands = 0      # lockstep: commands without a stamp, taken at their arrival time
        self.foreign_clock_commands = 0  # lockstep: commands stamped on another clock, taken at their arrival time
        self._foreign_reported = 0

    # ------------------------------------------------------------ inputs (any thread)
    def on_command(self, roll_deg, pitch_deg, yaw_rate_deg, gaz, stamp=None):
        """A piloting command (ROS units) of the controller's cycle at ``stamp`` [s sim] (None or 0: unknown);
        False when refused (non-finite), counted. Either way it answers the lockstep's period: an unknown
        stamp is replaced by the simulation time of the command's arrival (counted; at time 0, before the
        simulation starts, it does not arm the lockstep), and so is a stamp on another clock (more than
        ``FOREIGN_CLOCK_MARGIN`` ahead of the simulation time: counted apart, WARN in ``health``)."""
        values = (roll_deg, pitch_deg, yaw_rate_deg, gaz)
        ok = all(math.isfinite(v) for v in values)
        if ok:
            self.commands_received += 1
            self.commands.append(self.model.mapping.to_pcmd(*values))
        else:
            self.bad_commands += 1
        if self.lockstep is not None:
            arrival = self.clock.t
            if stamp is not None and math.isfinite(stamp) and 0.0 < stamp <= arrival + FOREIGN_CLOCK_MARGIN:
                self.lockstep.on_command(stamp)
            else:
                if stamp is not None and math.isfinite(stamp) and stamp > 0.0:
                    self.foreign_clock_commands += 1
                else:
                    self.unstamped_commands += 1
                if arrival > 0.0:
                    self.lockstep.on_command(arrival)
        return ok

    def on_event(self, event):
        """'takeoff' or 'land', applied before the next step."""
        if event not in ('takeoff', 'land'):
            raise ValueError("event must be 'takeoff' or 'land', got %r" % (event,))
        self.events.append(event)

    def translate(self, dx, dy, dz=0.0):
        """Move the drone and its estimate by (dx, dy, dz) [m] (``AnafiModel.translate``,
        ``StateEstimate.translate``): call between steps (same thread as ``step``)."""
        z0 = self.model.z
        self.model.translate(dx, dy, dz)
        self.estimate.translate(dx, dy, self.model.z - z0)      # the model keeps z >= 0

    # ------------------------------------------------------------ loop
    def start(self, wall):
        """Time 0 at wall time ``wall`` [s] (takes off with ``auto_takeoff``)."""
        if self.auto_takeoff:
            self.model.takeoff(0.0)
        self.clock.start(wall)

    def step(self):
        """Apply the pending inputs, one physics step, the estimate; returns the ``Step``."""
        model, t = self.model, self.clock.t
        applied = []
        events = self.events
        while events:
            event = events.popleft()
            accepted = model.takeoff(t) if event == 'takeoff' else model.land(t)
            applied.append((event, accepted, model.state))
        commands = self.commands
        while commands:
            pcmd = commands.popleft()
            model.set_command(pcmd[0], pcmd[1], pcmd[2], pcmd[3], t)
        model.step(self.clock.dt, t)
        tick = self.clock.tick()
        t = tick.t
        self.estimate.update(t, model.x, model.y, model.z, model.vx, model.vy, model.vz,
                             model.roll, model.pitch, model.yaw)
        sample = None
        if tick.telemetry:
            sample = model.truth_sample(t)
            if self.server is not None:
                self.server.publish(sample)
        estimate = None
        if tick.estimate:
            values = self.estimate.values()
            if values is not None:
                estimate = bridge_estimate(values, model.gimbal_pitch_command)
        state = None
        if model.state != self._last_state:
            state = self._last_state = model.state
        return Step(t, applied, sample, estimate, state, tick.clock)

    def sync(self, t, poke=None):
        """Lockstep after the step that ended at ``t`` [s sim]: None when nothing is due (or no lockstep),
        else whether the period's command came before the wall time-out (blocks; ``poke()``: repeat /clock,
        see ``Lockstep.wait``). Publish /clock at ``t`` before, the step's outputs after (the controller's
        cycle at ``t`` sees the messages of the steps before it, as the in-process engine schedules it)."""
        lockstep = self.lockstep
        if lockstep is None or not lockstep.due(t):
            return None
        return lockstep.wait(poke)

    def pace(self, wall):
        """Seconds to sleep after a step at wall time ``wall`` (real-time pacing)."""
        return self.clock.pace(wall)

    # ------------------------------------------------------------ health
    def health(self, wall):
        """``Status`` since the previous call: achieved rates, flight state, commands, telemetry clients."""
        report = self.clock.report(wall)
        model = self.model
        problems = []
        lockstep = self.lockstep.report() if self.lockstep is not None else None
        if lockstep is not None:     # the controller sets the pace: no wanted rate
            if lockstep.timeouts > self._timeouts_reported:
                problems.append('%d lockstep timeouts (periods without the command)'
                                % (lockstep.timeouts - self._timeouts_reported))
            self._timeouts_reported = lockstep.timeouts
            if lockstep.disarms and not self.lockstep.armed:
                problems.append('lockstep: controller silent, free-running')
            if self.foreign_clock_commands > self._foreign_reported:
                problems.append('lockstep cannot pace a node on another clock (the wall clock?): %d commands '
                                'stamped ahead of the simulation, taken at their arrival time'
                                % (self.foreign_clock_commands - self._foreign_reported))
            self._foreign_reported = self.foreign_clock_commands
        elif report.achieved_rate < WANTED_RATE_FRACTION * report.wanted_rate:
            problems.append('physics %.0f Hz of wall time, wanted %.0f' % (report.achieved_rate, report.wanted_rate))
        bad = self.bad_commands
        if bad > self._bad_reported:
            problems.append('%d non-finite commands ignored' % (bad - self._bad_reported))
        self._bad_reported = bad
        state = model.state
        if problems:
            message = '; '.join(problems)
        elif state == FLYING and not model.commanding:
            message = 'flying, hovering (no piloting command)'
        else:
            message = state
        if lockstep is not None and self.unstamped_commands:
            message += '; lockstep on unstamped commands, taken at their arrival time (%d)' % self.unstamped_commands
        age = model.command_age(report.sim_time)
        values = report_values(report) + [
            ('flight state', state),
            ('commanding', str(model.commanding)),
            ('command age [s sim]', 'none' if math.isinf(age) else '%.3f' % age),
            ('commands received', str(self.commands_received)),
            ('bad commands (non-finite, ignored)', str(bad)),
        ]
        if lockstep is not None:
            values += lockstep_values(lockstep)
            values.append(('lockstep unstamped commands (taken at arrival)', str(self.unstamped_commands)))
            values.append(('lockstep commands on another clock (taken at arrival)', str(self.foreign_clock_commands)))
        server = self.server
        if server is not None:
            values += [
                ('telemetry clients', str(server.client_count)),
                ('telemetry clients dropped (slow)', str(server.clients_dropped_slow)),
                ('telemetry clients disconnected', str(server.clients_disconnected)),
                ('telemetry port', str(server.port)),
            ]
        return Status(bool(problems), message, values)
