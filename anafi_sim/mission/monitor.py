"""Experiment monitor core (pure Python, no ROS): start gate, live progress and end of one experiment run.

Stage: experiment orchestration, beside trajectory -> waypoint -> controller -> drone -> evaluator.
Used by anafi_sim/nodes/experiment_monitor.py (experiment.launch, demo.launch). Units: positions [m]
in the ENU world frame, ROS time [s] (simulation time under /use_sim_time), wall time [s] (monotonic).

``ExperimentMonitor`` is fed by the node (drone state, controller commands, waypoints, estimates,
generator status, evaluator summaries, the simulator's diagnostics) and decides, in ``tick``:

- when to start the scenario: once the drone is flying, the controller has sent ``min_commands``
  non-zero piloting commands (it is up and engaged: every loop of the distributed PID has its
  input, the MPC solves; a hover command is all zero) and the node reports the recorder /
  evaluator subscribed ('start' action). Meanwhile the node holds the drone at the scenario's
  start with a waypoint of its own (while ``holding``), so the controller has something to engage
  on. This keeps a simulator that runs faster than real time from flying the scenario's first
  phases while the other nodes are still starting;
- failures: not ready within ``ready_timeout`` s of wall time, the scenario not ending within its
  duration + ``end_margin`` s of ROS time, no final evaluator summary ``final_timeout`` s of wall
  time after the end ('fail' action with the reason);
- the end: the evaluator's summary with state 'final' ('done' action); ``result_problem`` then says
  whether that summary is a measurement at all (ground truth present, the drone flew the scenario).

A run that measured may still have been disturbed by the machine's load; ``disturbed`` says so from
measured facts, each with its figure: the controller fell back to hovering (> ``max_hover_commands``
all-zero commands) or stopped (a gap > ``max_command_gap`` s of ROS time between commands), the ground-truth
reader woke up more than ``max_reader_lag`` s late (READER_LAG_LIMIT: the evaluator's interpolation gap,
0.5 s: a reader that late can leave the evaluator without ground truth and the interface's subscribers with
a stale one; below it the figure is still printed: ``reader_line``), or the evaluator found
no ground truth within its interpolation gap at some samples (its summary's ``truth_missing``).

``progress_line`` gives the one-line live status (phase, current e against the estimate, the
evaluator's statistics so far, the simulator's achieved real-time factor); ``run_info`` the figures
of the run (wall / sim durations, achieved real-time factor, simulator overruns, MPC solve times,
controller CPU time) for the batch report.
"""
import math

from anafi_sim.interface.supervisor import READER_LAG_KEY
from anafi_sim.mission.evaluation import DEFAULT_MAX_TRUTH_GAP
from anafi_sim.numeric import fmt, summary_stats

WAITING, STARTED, MEASURING, MEASURED, FINAL, FAILED = (
    'waiting', 'started', 'measuring', 'measured', 'final', 'failed')

# keys of the simulator's diagnostic status (anafi_sim_node.py) read by ``on_sim_diagnostics``
SIM_RTF_KEY = 'real-time factor achieved'
SIM_RATE_KEY = 'physics rate achieved [Hz wall]'
SIM_WANTED_KEY = 'physics rate wanted [Hz wall]'
SIM_OVERRUNS_KEY = 'overruns (steps late by > 1 period)'
SIM_REANCHOR_PREFIX = 'schedule re-anchors'
#: the interface's diagnostic status: its name ends so (interface_node.py); READER_LAG_KEY in its values
INTERFACE_STATUS_SUFFIX = ': ground truth interface'
#: [s] the ground-truth reader's wake-up lag beyond which a run is disturbed (see the module doc)
READER_LAG_LIMIT = DEFAULT_MAX_TRUTH_GAP


def _stats(values):
    """{'mean', 'max', 'min', 'n'} of the finite values (None entries when there are none)."""
    stats = summary_stats(values)
    return dict(stats) if stats else {'mean': None, 'max': None, 'min': None, 'n': 0}


def _seconds(value):
    """A time as a 6-wide column with one decimal ('%6.1f'); '-' when missing."""
    text = fmt(value, 1)
    return text if text == '-' else '%6s' % text


class ExperimentMonitor(object):
    """State machine of one run; see the module doc.

    ``scenario_duration``: total scenario time [s] (``trajectory.Scenario.duration``);
    ``min_commands``: controller commands to see before starting; ``ready_timeout``: wall s to become
    ready; ``end_margin``: ROS s after the scenario's nominal end before declaring it stuck;
    ``final_timeout``: wall s between the measured segment's end and the evaluator's final summary;
    ``max_hover_commands``, ``max_command_gap`` [s], ``max_reader_lag`` [s]: limits of ``disturbed``.
    """

    def __init__(self, scenario_duration, min_commands=5, ready_timeout=90.0, end_margin=30.0,
                 final_timeout=30.0, max_samples=100000, max_hover_commands=2, max_command_gap=0.5,
                 max_reader_lag=READER_LAG_LIMIT):
        for name, value in (('scenario_duration', scenario_duration), ('ready_timeout', ready_timeout),
                            ('end_margin', end_margin), ('final_timeout', final_timeout)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or value <= 0:
                raise ValueError('%s must be a finite number > 0, got %r' % (name, value))
        if isinstance(min_commands, bool) or not isinstance(min_commands, int) or min_commands < 0:
            raise ValueError('min_commands must be an integer >= 0, got %r' % (min_commands,))
        self.scenario_duration = float(scenario_duration)
        self.min_commands = min_commands
        self.ready_timeout = float(ready_timeout)
        self.end_margin = float(end_margin)
        self.final_timeout = float(final_timeout)
        self.max_samples = int(max_samples)
        self.state = WAITING
        self.reason = ''
        self.drone_state = ''
        self.commands = 0
        self.phase = ''
        self.generator_state = ''
        self.waypoint = None           # (x, y, z) [m]
        self.estimate = None           # (x, y, z) [m]
        self.summary = None            # the evaluator's latest summary dict
        self.wall_created = None
        self.wall_start = self.wall_end = self.wall_final = None
        self.ros_start = self.ros_begin = self.ros_end = None
        self.ros_now = None
        self.sim = {}                  # latest simulator diagnostics values (floats)
        self.sim_at_start = None
        self.sim_rtf_samples = []      # achieved real-time factors reported while the scenario ran
        self.solve_times = []          # MPC solve times [s, wall]
        self.cycle_times = []          # MPC node cycle times [s, wall]
        self.mpc_hover_cycles = None
        self.mpc_cycles = None
        self.cpu_start = None          # controller CPU seconds at the start
        self.cpu_end = None
        self.epoch = {}                # wall-clock (epoch) seconds of created / started / ended / final
        self.scenario_commands = 0     # controller commands while the scenario ran
        self.hover_commands = 0        # ... of which all zero (hover)
        self.max_command_gap = 0.0     # s of ROS time
        self._last_command_time = None
        self.drone_travel = 0.0        # m the estimate moved while the scenario ran
        self.target_travel = 0.0       # m the waypoint moved meanwhile
        self.max_hover_commands = int(max_hover_commands)
        self.max_command_gap_limit = float(max_command_gap)
        self.max_reader_lag = float(max_reader_lag)
        self.reader_lag = None         # [s] the ground-truth reader's largest wake-up lag while the scenario ran
        self.interface_counts = {}     # the interface's latest 'hangs' / 'starved' counters

    # ------------------------------------------------------------ inputs
    def on_drone_state(self, text):
        self.drone_state = str(text)

    def on_command(self, values=None, ros_time=None, hover=None):
        """A piloting command (roll, pitch, yaw, gaz) from the controller at ROS time ``ros_time`` [s].

        Before the start only engaged (non-zero, finite) commands count toward ``min_commands``
        (``values`` None: counted as engaged). While the scenario runs (start .. end of the measured
        segment) every command is counted, hover commands apart (the controller fell back to hovering:
        stale or missing input), and the largest gap between commands in ROS time is kept. ``hover``: the
        controller says whether this is a failsafe command (the in-process engine knows it from the
        contract's ``ok``); None = all-zero commands are taken as hover (a ROS graph only sees the
        command) - a controller whose quantised command is exactly zero on target (preview_mpc) is then
        miscounted."""
        engaged = True
        if values is not None:
            vals = [float(v) for v in values]
            engaged = all(math.isfinite(v) for v in vals) and any(abs(v) > 1e-9 for v in vals)
        if hover is not None:
            engaged = not hover and (values is None or all(math.isfinite(float(v)) for v in values))
        if self.state in (STARTED, MEASURING):
            self.scenario_commands += 1
            if not engaged:
                self.hover_commands += 1
            if ros_time is not None:
                t = float(ros_time)
                if self._last_command_time is not None and t >= self._last_command_time:
                    self.max_command_gap = max(self.max_command_gap, t - self._last_command_time)
                self._last_command_time = t
        if engaged:
            self.commands += 1

    def disturbed(self):
        """'' when the controller ran undisturbed during the scenario, else why not: more than
        ``max_hover_commands`` hover (all-zero) commands or a gap between commands longer than
        ``max_command_gap`` s of ROS time (e.g. CPU starvation of a controller node)."""
        reasons = []
        if self.hover_commands > self.max_hover_commands:
            reasons.append('%d hover commands' % self.hover_commands)
        if self.max_command_gap > self.max_command_gap_limit:
            reasons.append('commands stopped for %.2f s' % self.max_command_gap)
        if self.reader_lag is not None and self.reader_lag > self.max_reader_lag:
            reasons.append('ground-truth reader %.2f s late (limit %.2f s)' % (self.reader_lag, self.max_reader_lag))
        missing = self.truth_missing()
        if missing:
            reasons.append('ground truth missing at %d samples' % missing)
        return ', '.join(reasons)

    def truth_missing(self):
        """Samples of the measured segment without ground truth (the evaluator's summary; 0 when unknown)."""
        summary = self.summary if isinstance(self.summary, dict) else {}
        try:
            return max(0, int(summary.get('truth_missing') or 0))
        except (TypeError, ValueError):
            return 0

    def on_interface_diagnostics(self, values):
        """{key: text} of the ground-truth interface's diagnostic status: its reader's wake-up lag is kept
        (the largest while the scenario runs), and its watchdog's counters of the whole run (telemetry process
        killed as hung, silences waited for as starved)."""
        for key, name in (('process hangs', 'hangs'), ('process starved', 'starved')):
            try:
                self.interface_counts[name] = int(values[key])
            except (KeyError, TypeError, ValueError):
                pass
        try:
            lag = float(values.get(READER_LAG_KEY))
        except (TypeError, ValueError):
            return
        if math.isfinite(lag) and self.state in (STARTED, MEASURING):
            self.reader_lag = lag if self.reader_lag is None else max(self.reader_lag, lag)

    @property
    def holding(self):
        """True while the node should publish the hold waypoint (before the start)."""
        return self.state == WAITING

    def on_waypoint(self, position):
        new = tuple(float(v) for v in position[:3])
        self.target_travel += self._travel(self.waypoint, new)
        self.waypoint = new

    def on_estimate(self, position):
        new = tuple(float(v) for v in position[:3])
        self.drone_travel += self._travel(self.estimate, new)
        self.estimate = new

    def _travel(self, old, new):
        """Distance from ``old`` to ``new`` while the scenario runs (0 otherwise, or for non-finite points)."""
        if old is None or self.state not in (STARTED, MEASURING):
            return 0.0
        d = math.sqrt(sum((a - b) ** 2 for a, b in zip(old, new)))
        return d if math.isfinite(d) else 0.0

    def result_problem(self, require_truth=True, min_travel_fraction=0.1, min_target_travel=1.0):
        """Why the final summary is not a measurement ('' when it is): no ground truth (with
        ``require_truth``), or the drone did not fly the scenario (it moved less than
        ``min_travel_fraction`` of the waypoint's travel, when the waypoint moved at least
        ``min_target_travel`` m)."""
        summary = self.summary if isinstance(self.summary, dict) else {}
        if not summary.get('samples'):
            return 'no evaluated samples'
        truth = summary.get('truth')
        if require_truth and not (isinstance(truth, dict) and truth.get('e_mu') is not None):
            return 'no ground truth: the interface published none for the measured segment (see its diagnostics)'
        if self.target_travel >= min_target_travel and self.drone_travel < min_travel_fraction * self.target_travel:
            return 'the drone did not fly the scenario: it moved %.2f m while the target moved %.2f m' % (
                self.drone_travel, self.target_travel)
        return ''

    def on_status(self, phase, state=''):
        """Generator status (trajectory/status): current phase name and generator state."""
        self.phase = str(phase or '')
        self.generator_state = str(state or '')

    def on_begin(self, ros_time):
        self.ros_begin = float(ros_time)
        if self.state in (STARTED, WAITING):
            self.state = MEASURING

    def on_end(self, ros_time, wall_now):
        self.ros_end = float(ros_time)
        self.wall_end = float(wall_now)
        if self.state in (STARTED, MEASURING, WAITING):
            self.state = MEASURED

    def on_summary(self, summary, wall_now):
        """The evaluator's summary dict (evaluation/summary); state 'final' ends the run."""
        if not isinstance(summary, dict):
            return
        self.summary = summary
        if summary.get('state') == 'final' and self.state not in (FINAL, FAILED):
            self.state = FINAL
            self.wall_final = float(wall_now)

    def on_sim_diagnostics(self, values):
        """{key: text} of the simulator's diagnostic status; numbers are kept (see SIM_* keys)."""
        parsed = {}
        for key, text in values.items():
            try:
                parsed[key] = float(text)
            except (TypeError, ValueError):
                continue
        reanchor = [v for k, v in parsed.items() if k.startswith(SIM_REANCHOR_PREFIX)]
        if reanchor:
            parsed['reanchors'] = reanchor[0]
        self.sim = parsed
        if self.state in (STARTED, MEASURING, MEASURED) and SIM_RTF_KEY in parsed:
            if len(self.sim_rtf_samples) < self.max_samples:
                self.sim_rtf_samples.append(parsed[SIM_RTF_KEY])

    def on_mpc_stats(self, solve_time, cycle_time, cycles=None, hover_cycles=None):
        if self.state in (STARTED, MEASURING, MEASURED) and len(self.solve_times) < self.max_samples:
            self.solve_times.append(float(solve_time))
            self.cycle_times.append(float(cycle_time))
        if cycles is not None:
            self.mpc_cycles = int(cycles)
        if hover_cycles is not None:
            self.mpc_hover_cycles = int(hover_cycles)

    def on_controller_cpu(self, seconds):
        """Total CPU seconds of the controller's processes now (the node samples at start and end)."""
        if seconds is None:
            return
        if self.cpu_start is None:
            self.cpu_start = float(seconds)
        else:
            self.cpu_end = float(seconds)

    # ------------------------------------------------------------ decisions
    def ready(self, subscribers_ok=True):
        """True when the scenario may start (see the module doc)."""
        return self.drone_state == 'flying' and self.commands >= self.min_commands and bool(subscribers_ok)

    def waiting_for(self, subscribers_ok=True):
        """Text: what the start still waits for ('' when ready)."""
        missing = []
        if self.drone_state != 'flying':
            missing.append('drone flying (state %r)' % (self.drone_state or 'none'))
        if self.commands < self.min_commands:
            missing.append('engaged controller commands (%d of %d)' % (self.commands, self.min_commands))
        if not subscribers_ok:
            missing.append('recorder / evaluator subscriptions')
        return ', '.join(missing)

    def tick(self, ros_now, wall_now, subscribers_ok=True, epoch=None):
        """[(action, text)] with action 'start' | 'fail' | 'done'; call regularly. ``epoch``: the wall
        clock (time.time()) for the run_info timestamps (optional)."""
        previous = self.state
        self.ros_now = float(ros_now)
        if self.wall_created is None:
            self.wall_created = float(wall_now)
        actions = []
        if self.state == WAITING:
            if self.ready(subscribers_ok):
                self.state = STARTED
                self.wall_start = float(wall_now)
                self.ros_start = float(ros_now)
                self.sim_at_start = dict(self.sim)
                actions.append(('start', 'ready after %.1f s wall' % (wall_now - self.wall_created)))
            elif wall_now - self.wall_created > self.ready_timeout:
                actions.append(self._fail('not ready after %.0f s wall: waiting for %s'
                                          % (self.ready_timeout, self.waiting_for(subscribers_ok))))
        elif self.state in (STARTED, MEASURING):
            if ros_now - self.ros_start > self.scenario_duration + self.end_margin:
                actions.append(self._fail('the measured segment did not end within %.0f s of ROS time '
                                          '(scenario %.1f s)' % (self.scenario_duration + self.end_margin,
                                                                 self.scenario_duration)))
        elif self.state == MEASURED:
            if wall_now - self.wall_end > self.final_timeout:
                actions.append(self._fail('no final evaluator summary %.0f s after the end' % self.final_timeout))
        if self.state == FINAL:
            actions.append(('done', 'final summary received'))
        if epoch is not None:
            self.epoch.setdefault('created', float(epoch))
            if self.state != previous or self.state in (MEASURED, FINAL):
                for state, key in ((STARTED, 'started'), (MEASURED, 'ended'), (FINAL, 'final')):
                    if self.state == state or (key == 'ended' and self.state == FINAL):
                        self.epoch.setdefault(key, float(epoch))
                if self.state in (MEASURING, MEASURED, FINAL):
                    self.epoch.setdefault('started', float(epoch))
        return actions

    def _fail(self, reason):
        self.state = FAILED
        self.reason = reason
        return ('fail', reason)

    # ------------------------------------------------------------ outputs
    def current_error(self):
        """|waypoint - estimate| [m] of the latest samples, None before both arrived."""
        if self.waypoint is None or self.estimate is None:
            return None
        return math.sqrt(sum((a - b) ** 2 for a, b in zip(self.waypoint, self.estimate)))

    def progress_line(self, label=''):
        """One line: ROS time since start, phase, positions, current e, statistics so far, rtf."""
        t = (self.ros_now - self.ros_start) if (self.ros_start is not None and self.ros_now is not None) else None
        head = '%s%s' % (label + ' ' if label else '', '[%s]' % self.state)
        if self.state == WAITING:
            return '%s waiting for %s' % (head, self.waiting_for(True) or 'subscriptions')
        parts = [head, 't %s s' % _seconds(t), 'phase %-8s' % (self.phase or '-')]
        if self.waypoint is not None:
            parts.append('wp (%s)' % ', '.join('%5.2f' % v for v in self.waypoint))
        if self.estimate is not None:
            parts.append('drone (%s)' % ', '.join('%5.2f' % v for v in self.estimate))
        parts.append('e %s m' % fmt(self.current_error()))
        est = (self.summary or {}).get('estimate') if (self.summary or {}).get('state') in ('measuring', 'final',
                                                                                           'ended') else None
        if est:
            parts.append('measured so far: e_mu %s e_max %s' % (fmt(est.get('e_mu')), fmt(est.get('e_max'))))
        if SIM_RTF_KEY in self.sim:
            parts.append('rtf %s' % fmt(self.sim[SIM_RTF_KEY]))
        return '  '.join(parts)

    def run_info(self):
        """Figures of the run (plain dict, YAML ready): state, reason, durations, sim keeping up, MPC, CPU."""
        def r(v, n=4):
            return None if v is None or not math.isfinite(v) else round(float(v), n)
        sim_s = wall_s = None
        if self.ros_start is not None and self.ros_end is not None:
            sim_s = self.ros_end - self.ros_start
        if self.wall_start is not None and self.wall_end is not None:
            wall_s = self.wall_end - self.wall_start
        start = self.sim_at_start or {}
        overruns = reanchors = None
        if SIM_OVERRUNS_KEY in self.sim:
            overruns = self.sim[SIM_OVERRUNS_KEY] - start.get(SIM_OVERRUNS_KEY, 0.0)
        if 'reanchors' in self.sim:
            reanchors = self.sim['reanchors'] - start.get('reanchors', 0.0)
        rtf = _stats(self.sim_rtf_samples)
        solve = _stats(self.solve_times)
        cycle = _stats(self.cycle_times)
        cpu = None
        if self.cpu_start is not None and self.cpu_end is not None:
            cpu = self.cpu_end - self.cpu_start
        info = {
            'state': self.state,
            'wall_clock': dict((k, r(v, 3)) for k, v in (('created', self.epoch.get('created')),
                                                          ('started', self.epoch.get('started')),
                                                          ('ended', self.epoch.get('ended')),
                                                          ('final', self.epoch.get('final')))),
            'reason': self.reason,
            'startup_wall_s': r(self.wall_start - self.wall_created) if self.wall_start is not None
            and self.wall_created is not None else None,
            'scenario_sim_s': r(sim_s, 3),
            'scenario_wall_s': r(wall_s, 3),
            'achieved_rtf': r(sim_s / wall_s, 3) if sim_s and wall_s else None,
            'sim_reported_rtf_mean': r(rtf['mean'], 3),
            'sim_reported_rtf_min': r(rtf['min'], 3),
            'sim_overruns': int(overruns) if overruns is not None else None,
            'sim_reanchors': int(reanchors) if reanchors is not None else None,
            'sim_physics_rate_hz': r(self.sim.get(SIM_RATE_KEY), 1),
            'sim_physics_rate_wanted_hz': r(self.sim.get(SIM_WANTED_KEY), 1),
            'mpc_solve_time_mean_ms': r(solve['mean'] * 1e3, 3) if solve['n'] else None,
            'mpc_solve_time_max_ms': r(solve['max'] * 1e3, 3) if solve['n'] else None,
            'mpc_cycle_time_mean_ms': r(cycle['mean'] * 1e3, 3) if cycle['n'] else None,
            'mpc_cycles': self.mpc_cycles,
            'mpc_hover_cycles': self.mpc_hover_cycles,
            'scenario_commands': self.scenario_commands,
            'hover_commands': self.hover_commands,
            'max_command_gap_s': r(self.max_command_gap, 3),
            'reader_lag_max_s': r(self.reader_lag, 3),
            'interface_hangs': self.interface_counts.get('hangs'),
            'interface_starved': self.interface_counts.get('starved'),
            'truth_missing': self.truth_missing(),
            'disturbed': self.disturbed(),
            'controller_cpu_s': r(cpu, 3),
            'controller_cpu_per_sim_s': r(cpu / sim_s, 4) if cpu is not None and sim_s else None,
            'drone_travel_m': r(self.drone_travel, 3),
            'target_travel_m': r(self.target_travel, 3),
            'measured_window': [r(self.ros_begin, 6), r(self.ros_end, 6)] if self.ros_begin is not None
            and self.ros_end is not None else None,
        }
        return info


MAX_TUNING_NAMED = 3
"""The RESULT line names at most this many tuning changes of the measured window (then '+N more')."""


def tuning_in_window(info):
    """The live tuning changes of the run info (``tuning``: anafi_sim/ros/reconfigure.py's records) stamped
    inside its ``measured_window`` [begin, end] (ROS time) that changed a value (new != old), in time order,
    each a copy with ``t`` = its seconds since the window's begin; [] without a window."""
    window = info.get('measured_window')
    if not isinstance(window, (list, tuple)) or len(window) != 2 or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in window):
        return []
    out = []
    for record in info.get('tuning') or []:
        stamp = record.get('stamp') if isinstance(record, dict) else None
        if not isinstance(stamp, (int, float)) or isinstance(stamp, bool) or not window[0] <= stamp <= window[1]:
            continue
        if record.get('new') == record.get('old'):
            continue
        out.append(dict(record, t=round(float(stamp) - float(window[0]), 6)))
    return sorted(out, key=lambda c: c['t'])


def tuning_clause(info):
    """'tuning changed at t=12.3 s: mpc_controller r 0.1 -> 0.5' for the measured window's tuning changes
    (``tuning_in_window``; t since the window's begin, several joined by '; '), '' without any."""
    changes = tuning_in_window(info)
    if not changes:
        return ''
    named = ['t=%.1f s: %s%s %s -> %s' % (c['t'], '%s ' % c['node'] if c.get('node') else '', c.get('parameter'),
                                          c.get('old'), c.get('new')) for c in changes[:MAX_TUNING_NAMED]]
    more = len(changes) - MAX_TUNING_NAMED
    return 'tuning changed at ' + '; '.join(named) + (' (+%d more)' % more if more > 0 else '')


def result_status(ok, info):
    """The RESULT line's verdict: 'ok' (measured, undisturbed), 'disturbed: <what, with its figure>' (measured
    while the machine's load disturbed the run: anafi_sim.mission.monitor.ExperimentMonitor.disturbed) or
    'FAILED: <reason>' (could not measure); a live tuning change inside the measured window is said after it
    (``tuning_clause``: 'ok, tuning changed at t=12.3 s: ...'): its figures are not those of one tuning."""
    if not ok:
        status = 'FAILED: ' + str(info.get('reason') or 'unknown')
    else:
        status = 'disturbed: ' + info['disturbed'] if info.get('disturbed') else 'ok'
    clause = tuning_clause(info)
    return status + ('%s %s' % (',' if status == 'ok' else ';', clause) if clause else '')


def reader_line(info):
    """The RESULT block's line on the ground-truth reader (its largest wake-up lag while the scenario ran, the
    telemetry processes killed as hung / waited for as starved), None when the run info has none of it."""
    if info.get('reader_lag_max_s') is None and info.get('interface_hangs') is None:
        return None
    return '  ground-truth reader: wake-up lag max %s s (disturbed beyond %.2f s), telemetry process hung %s, ' \
        'starved %s' % (fmt(info.get('reader_lag_max_s'), 3), READER_LAG_LIMIT,
                        fmt(info.get('interface_hangs'), 0), fmt(info.get('interface_starved'), 0))


def summary_lines(summary, label=''):
    """Human-readable lines of an evaluator summary dict (evaluation/summary YAML)."""
    if not isinstance(summary, dict):
        return ['%s: no evaluator summary' % (label or 'run')]
    lines = ['%s: %s samples, state %s' % (label or summary.get('name') or 'run', summary.get('samples'),
                                          summary.get('state'))]
    for key, text in (('estimate', 'vs drone estimate (paper)'), ('truth', 'vs ground truth')):
        res = summary.get(key)
        if not res:
            lines.append('  %-26s absent' % text)
            continue
        lines.append('  %-26s e_max %s  e_mu %s  e_sigma %s m' % (
            text, fmt(res.get('e_max'), 3), fmt(res.get('e_mu'), 3), fmt(res.get('e_sigma'), 3)))
    garbage, warnings = summary.get('garbage') or [], summary.get('warnings') or []
    if garbage or warnings:     # the evaluator logs them, once: counted here, not repeated
        bad = summary.get('garbage_samples')
        lines.append('  %s%d warning(s) (named in the evaluator\'s log)' % (
            'GARBAGE excluded: %s samples, ' % (bad if bad is not None else '%d line(s) of' % len(garbage))
            if garbage else '', len(warnings)))
    return lines
