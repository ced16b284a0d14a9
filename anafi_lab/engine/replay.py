"""Fidelity of the stand-in: closed-loop replay of the shared Sphinx reference logs (pure, no ROS).

Stage: experiments (on top of ``anafi_lab.engine.engine``). For one reference log (format of
anafi_sim/data/reference_logs, ``anafi_sim.mission.reference_log``) named ``<scenario>_<pid|mpc>``:

1. ``replay_plan``: the log's waypoint stream as the 10 Hz stream the controller saw. The waypoint columns
   change at 10 Hz (every other 20 Hz sample); each change becomes one generator tick (consecutive changes
   counted in ticks, so a phase slip of the logger does not skip or repeat a waypoint). The log time of a
   tick is the median of (change time - tick / rate) minus ``latency`` (default half a log sample: the
   waypoint was published somewhere in the 50 ms before the logger first shows it). Rows that are all zero
   (the static PID logs hold wp = (0, 0, 0) while the drone hovers at 1 m before the step: "no waypoint
   yet") are replaced by the hover point (the logged estimate's first position and yaw). A log that starts
   in motion (the straight lines: a steady-state segment) gets a lead-in: the first waypoint extrapolated
   backwards at its own velocity for ``lead`` s, so the controller has settled on the moving target when
   the log begins (no further back than it stays between 1 and 40 m up: ``straight_lead_limit``); a stream
   that repeats itself (a circle, a periodic vertical motion: ``stream_period``) repeats its first period
   backwards instead. The ``Scenario`` (``anafi_sim.mission.trajectory``): hover at the start for
   ``approach`` s, the lead-in, then the replay (zero-order hold of the ticks), measured.
2. ``run_replay``: the scenario on the in-process engine (``anafi_lab.engine.engine.Engine``) with the
   log's controller and the given model / controller parameters / schedule, and the stand-in's estimate
   (as a 20 Hz logger sees it on average, ``standin_log``) and ground truth (interpolated, 100 Hz)
   resampled at the log's own sample times:
   ``standin_log`` has the log's time and waypoint columns, so both are evaluated by the same function.
   The drone takes off at the heading at which its estimate shows the log's first estimated yaw
   (``initial_yaw``). Just before log time 0 the replay is put in the log's initial state
   (``log_initial_state``, ``initial_state_action``; ``replay_plan(initial_state=False)``: not): the truth at
   the log's position and, as far as the model has the states, the estimate's position and velocity errors
   at the log's (Sphinx's lines start with errors their approach left, which decay within the log).
   The replay also holds the stand-in's published estimate where the log's estimate stream stalled
   (``log_stalls``, ``stall_actions``: one 0.2-0.25 s stall in each of x_straight_2/3/5_mpc, which the MPC saw
   and reacted to: a condition of the run, replayed like its waypoint stream; ``replay_plan(stalls=False)``:
   not).
   The stand-in's columns are stored as the logger stored Sphinx's (half floats, ``reference_log.as_logged``;
   ``replay_plan(stored=False)``: unrounded), so both logs are measured alike.
3. ``cells``: e_mu and e_max against the estimate and against ground truth with
   ``reference_log.tracking_error`` (the function the paper's Table 3 recomputation uses, garbage excluded);
   in a log whose 3-D estimate error is all garbage (x_straight_2/3_pid: z_anafi wrapped at 16 bit, the drone
   sank below the ground under it) the horizontal error is the cell for both sources (``horizontal_sources``). ``history_rms``: rms difference of the ground-truth roll, pitch and
   vertical speed of the stand-in against Sphinx over the log (same time base: log time, t = 0 at the log's
   first sample; the replay starts the motion at the same log time as the log).
4. ``compare``: per cell the stand-in value, Sphinx's and their ratio; ``within`` a band.

Variants (``Variant``): a model dict (``anafi_sim/config/anafi_model.yaml`` = effects off, the fitted one =
effects on, or one effect at a time: ``variants.effect_variants``), MPC parameters (e.g. ``paper_timing``), engine
schedule overrides (timer phases). ``replay_all`` runs them side by side. ``run_log``: the stand-in's own runs
recorded as the paper's logger recorded Sphinx (replayed by ``variants.self_replay_runs``: the method's own error).
The rest of the fidelity room: ``variants`` (effect variants, timer phases, the paper's scenarios on the engine,
self-replays, fusion-gain variants), ``held_out`` (what the comparison with Sphinx's held-out runs implies),
``scores`` (cells within a band), ``plot`` (one figure per log); the report is ``anafi_lab.reports.fidelity_report``
(anafi_lab/cli/measure_fidelity.py is the command line).

Units: positions [m], velocities [m/s] (ENU world), attitude [rad], waypoint yaw [deg], time [s].
"""
import collections
import glob
import math
import os
import re

import numpy as np

from anafi_lab.engine.engine import Engine
from anafi_lab.paper import CONTROLLERS
from anafi_sim.mission.evaluation import interpolate
from anafi_sim.mission.reference_log import (COLUMNS, INITIAL_WINDOW, STATE_NAMES, VELOCITY_ERROR_AXES,
                                                 WAYPOINT_COLUMNS, ReferenceLog, as_logged, detect_garbage,
                                                 initial_velocity_error, line_value, read_log, tracking_error,
                                                 velocity_lag)
from anafi_sim.mission.trajectory import Phase, Scenario
from anafi_sim.mission.waypoint import WaypointSample
from anafi_sim.sim.drone_model import load_model_params

LOG_NAME = re.compile(r'^(?P<scenario>.+)_(?P<controller>%s)$' % '|'.join(CONTROLLERS))   # the paper's logs
SOURCES = ('estimate', 'truth')
STATS = ('e_mu', 'e_max')
CELLS = tuple((s, k) for s in SOURCES for k in STATS)      # (source, stat), the order of every table
SOURCE_COLUMN = {'estimate': 'anafi', 'truth': 'sphinx'}
HISTORIES = ('roll', 'pitch', 'vz')                          # ground-truth histories compared by rms
DEFAULT_RATE = 10.0          # Hz, the waypoint stream (the generator's rate in the logs)
DEFAULT_LEAD = 20.0          # s, lead-in of a log that starts in motion (PID at 5 m/s settles in ~15 s)
APPROACH_MOVING = 10.0       # s, hover at the line's start before the lead-in (climb from take-off to 7 m)
APPROACH_STATIC = 5.0        # s, hover at the hover point before the log's own hover
TAIL = 0.3                   # s, replay beyond the log's last sample (the evaluator needs an estimate after it)

INITIAL_AHEAD = 0.1          # s, the initial state is set this long before log time 0: the stand-in's estimate
                             # is read half a 20 Hz period back between its samples, so every sample that
                             # enters log time 0 (>= 1.5 periods back) comes after it

ReplayPlan = collections.namedtuple('ReplayPlan', 'log name controller scenario tick_log_time tick_tau '
                                                  'scenario_offset ticks slips markers moving shift initial_state '
                                                  'stalls stored period')
ReplayPlan.__doc__ = ('How a log is replayed: log (ReferenceLog), name, controller (pid|mpc), scenario (Scenario), '
                      'tick_log_time (log time [s] of tick 0), tick_tau (trajectory time [s] of tick 0), '
                      'scenario_offset (scenario time [s] of log time 0), ticks (number of waypoint changes '
                      'replayed), slips (changes not a whole number of periods after the previous one: the logger\'s phase '
                      'slipped; counted to the nearest tick, at least one), markers '
                      '(all-zero rows replaced by the hover point), moving (the log starts in motion), shift ((x, y) [m] '
                      'subtracted from the waypoints for the replay and added back to the stand-in\'s positions), '
                      'initial_state (``InitialState`` the replay is put in at log time 0, or None), stalls '
                      '(((start, end) log times [s] of the estimate stalls the replay reproduces, ``log_stalls``; () '
                      'when the log has none or the plan leaves them out), stored (``standin_log`` stores the '
                      'stand-in\'s columns as the logs store theirs: half floats, ``reference_log.as_logged``), '
                      'period (ticks of a periodic stream whose lead-in repeats its first period, ``stream_period``; '
                      'None: a straight lead-in).')

InitialState = collections.namedtuple('InitialState', 'truth estimate velocity_error')
InitialState.__doc__ = ('A log\'s state at log time 0: truth (x, y, z) [m], the estimate\'s position (x, y, z) [m] '
                        'as the estimator held it then and the velocity estimate\'s error (vx, vy, vz) [m/s] '
                        '(estimate - truth) (``log_initial_state``); NaN for what the log does not give (garbage). '
                        'The heading is set at take-off (``initial_yaw``).')

Variant = collections.namedtuple('Variant', 'name label model_params controller_params schedule plan controllers')
Variant.__new__.__defaults__ = (None, None, None, None, None)
Variant.__doc__ = ('One configuration of the stand-in: name (short id), label (for tables), model_params (model '
                   'dict, None = anafi_model.yaml), controller_params ({"mpc": {...}, "pid": {...}} or None), '
                   'schedule (engine schedule overrides or None), plan (``replay_plan`` keyword arguments, e.g. '
                   'latency, or None), controllers (the controllers it applies to, None = all).')

Replay = collections.namedtuple('Replay', 'plan variant ok error standin cells histories info')
Replay.__doc__ = ('One replay: plan, variant, ok, error, standin (ReferenceLog on the log\'s grid or None), cells '
                  '({(source, stat): value}), histories ({name: rms}), info (the engine\'s run figures).')


# ---------------------------------------------------------------------------------------------- logs
def parse_name(name):
    """(scenario, controller) of a log name such as 'x_straight_3_mpc'; ValueError when it names none."""
    m = LOG_NAME.match(name)
    if not m:
        raise ValueError('reference log %r: the name must end in _pid or _mpc (the controller that flew it)' % name)
    return m.group('scenario'), m.group('controller')


def find_logs(directory):
    """Sorted paths of the reference-log CSVs in ``directory`` ([] when it does not exist)."""
    if not directory or not os.path.isdir(directory):
        return []
    return sorted(glob.glob(os.path.join(directory, '*.csv')))


def load_logs(directory):
    """The ``ReferenceLog`` of every CSV in ``directory`` whose name says pid or mpc, in name order."""
    logs = []
    for path in find_logs(directory):
        log = read_log(path)
        if LOG_NAME.match(log.name):
            logs.append(log)
    return logs


def _is_marker(row):
    return bool(np.all(row == 0.0))


def hover_point(log):
    """(x, y, z [m], yaw [deg]) of the logged estimate at the log's first sample (NaN-free fallback 0, 0, 1)."""
    p = [float(log.columns[c][0]) for c in ('x_anafi', 'y_anafi', 'z_anafi')]
    yaw = float(log.columns['yaw_anafi'][0])
    if not all(math.isfinite(v) and abs(v) < 1e3 for v in p):
        p = [0.0, 0.0, 1.0]
    return (p[0], p[1], p[2], math.degrees(yaw) if math.isfinite(yaw) else 0.0)


class ReplayTrajectory(object):
    """The logged waypoint stream as a trajectory: zero-order hold of one value per 10 Hz tick.

    ``values`` (K, 7): the waypoint of ticks 0..K-1 (x, y, z, vx, vy, vz, yaw [deg]; K >= 1); ``tick_tau``:
    trajectory time [s] of tick 0 (a multiple of 1/rate, >= 0). Before tick 0 (the lead-in) the first value
    extrapolated backwards at its own velocity, or, with ``period`` P ticks (a periodic stream, 0 < P <= K,
    ``stream_period``), the first period repeated backwards (tick -j is tick P - j mod P); after the last tick
    the last value. A trajectory time is mapped to the nearest tick (the generator ticks at multiples of 1/rate
    of trajectory time).
    """

    kind = 'replay'

    def __init__(self, values, tick_tau, rate=DEFAULT_RATE, period=None):
        self.values = np.asarray(values, dtype=np.float64).reshape(-1, 7)
        if not len(self.values):
            raise ValueError('a replay needs at least one waypoint')
        if period is not None and not 0 < int(period) <= len(self.values):
            raise ValueError('a replay period must be 1..%d ticks, got %r' % (len(self.values), period))
        self.rate = float(rate)
        self.tick0 = int(round(float(tick_tau) * self.rate))
        self.period_ticks = int(period) if period is not None else None

    def tick(self, t):
        """Tick index (relative to tick 0) of trajectory time ``t`` [s]."""
        return int(round(float(t) * self.rate)) - self.tick0

    def sample(self, t):
        """``WaypointSample`` at trajectory time ``t`` [s]."""
        j = self.tick(t)
        if j < 0 and self.period_ticks:
            j %= self.period_ticks
        if j < 0:
            v = self.values[0]
            dt = j / self.rate
            return WaypointSample(v[0] + v[3] * dt, v[1] + v[4] * dt, v[2] + v[5] * dt, v[3], v[4], v[5], v[6])
        v = self.values[min(j, len(self.values) - 1)]
        return WaypointSample(*[float(x) for x in v])

    __call__ = sample

    def period(self):
        """None: not periodic (the lead-in may repeat a period; the replay itself is the log's stream)."""
        return None


PERIOD_MIN = 2.0        # s, shortest period ``stream_period`` looks for
PERIOD_OVERLAP = 1.0    # s, at least this much of the stream must be seen twice to call it periodic
PERIOD_TOLERANCE = 0.02 # m, rms of (position one period later - position) below which a stream repeats


def stream_period(values, rate=DEFAULT_RATE, min_period=PERIOD_MIN, overlap=PERIOD_OVERLAP,
                  tolerance=PERIOD_TOLERANCE):
    """The period [ticks] of a waypoint tick stream ``values`` (K, 7) that repeats itself (a circle, a periodic
    vertical motion), or None: the smallest lag L >= ``min_period`` s, leaving at least ``overlap`` s seen
    twice, at which the rms of the position difference (values[i + L] - values[i], x y z) is below
    ``tolerance`` [m] (or 1 % of the motion's extent, the half-float step of the positions or half the motion
    of a tick, if larger) and no larger than at the lags beside it (the bottom of its dip: a circle's period is
    rarely a whole number of ticks). A straight line never repeats; a hover does at every lag (not moving:
    None)."""
    v = np.asarray(values, dtype=np.float64).reshape(-1, 7)[:, :3]
    k = len(v)
    first = int(math.ceil(min_period * rate - 1e-9))
    last = k - int(math.ceil(overlap * rate - 1e-9))
    spread = float(np.max(np.ptp(v, axis=0))) if k else 0.0
    if last <= first or spread <= tolerance:
        return None
    # a large motion or a half-float log far from the origin repeats only to within its own resolution, and a
    # period that is no whole number of ticks only to within half a tick of motion (plus the stream's jitter)
    step = float(np.median(np.sqrt(np.sum(np.diff(v, axis=0) ** 2, axis=1))))
    tolerance = max(tolerance, 0.01 * spread, float(np.spacing(np.float16(np.max(np.abs(v))))), 0.5 * step)
    rms = dict((lag, float(np.sqrt(np.mean(np.sum((v[lag:] - v[:-lag]) ** 2, axis=1)))))
               for lag in range(max(1, first - 1), min(k - 1, last + 1) + 1))
    for lag in range(first, last + 1):
        if rms[lag] < tolerance and rms[lag] <= rms.get(lag - 1, np.inf) and rms[lag] <= rms.get(lag + 1, np.inf):
            return lag
    return None


def log_initial_state(log, window=INITIAL_WINDOW, estimate_rate=20.0, at=-INITIAL_AHEAD, curved=False):
    """``InitialState`` of ``log`` at log time ``at`` [s] (default just before the first sample): per axis a
    line through the first ``window`` s (``reference_log.line_value``: the columns are float16) of the truth,
    of the estimate and of the velocity estimate's error (``curved``, a turning path such as a circle: a
    parabola through the positions, and the velocity error against the truth as old as the estimate's own lag,
    ``reference_log.velocity_lag``, which a line and a same-time difference would take for an offset and an
    error); the truth at ``at``, the estimate half an
    estimate period later (a held value is on average that old when logged: ``standin_log`` reads the
    stand-in's estimate the same way). An axis whose estimate column
    has garbage in the window is NaN (x_straight_2/3_pid: z wrapped, the truth sank under it)."""
    t = log.t
    first = t <= t[0] + float(window)
    garbage = detect_garbage(log)
    c = log.columns
    truth, estimate = [], []
    degree = 2 if curved else 1
    for axis in ('x', 'y', 'z'):
        bad = garbage.mask(axis + '_anafi', axis + '_sphinx')
        if np.any(bad & first):
            truth.append(float('nan'))
            estimate.append(float('nan'))
            continue
        ok = first & ~bad
        truth.append(line_value(t, c[axis + '_sphinx'], ok, t[0] + at, degree))
        estimate.append(line_value(t, c[axis + '_anafi'], ok, t[0] + at + 0.5 / float(estimate_rate), degree))
    lag = velocity_lag(log) if curved else 0.0
    velocity = tuple(initial_velocity_error(log, axis, window, at, lag) if axis in VELOCITY_ERROR_AXES
                     else float('nan') for axis in ('x', 'y', 'z'))
    return InitialState(tuple(truth), tuple(estimate), velocity)


STALL_SAMPLES = 3       # identical estimate rows in a row (while moving) that make a stall: 0.15 s at 20 Hz
STALL_SPEED = 0.5       # m/s, the truth's speed above which an unchanged estimate is a stall, not a hover
STALL_CAUGHT_UP = 0.5   # a row after a stall is fresh once the estimate moved this share of the truth's move


def log_stalls(log, samples=STALL_SAMPLES, speed=STALL_SPEED, caught_up=STALL_CAUGHT_UP):
    """((start, end), ...) log times [s] of the stalls of ``log``'s estimate stream: ``samples`` or more
    consecutive rows with every estimate column unchanged while the truth moves faster than ``speed`` (the
    published estimate held, then a jump to the current one; Sphinx's MPC lines at 2, 3 and 5 m/s show one
    each, and the MPC reacts to it). start: the first row of the run; end: the first row after it whose
    estimate has caught up, i.e. moved (horizontally, since the start) at least ``caught_up`` x the truth's
    move: a row that changed by a storage step only is still stale (x_straight_2_mpc: 4 unchanged rows, one
    0.06 m on, then the 0.5 m jump; x_straight_3_mpc: 0.13 m on after 0.6 m of truth, then the jump). The
    stale tail is looked for over at most as many rows as were held, and ends where the truth stops moving;
    a tail that does not catch up within it leaves the end at the first changed row. Stalls do not overlap."""
    est = np.column_stack([np.asarray(log.columns[n + '_anafi'], dtype=np.float64) for n in STATE_NAMES])
    same = np.all(est[1:] == est[:-1], axis=1)
    moving = np.hypot(log.columns['vx_sphinx'], log.columns['vy_sphinx']) > speed
    horizontal = {source: np.column_stack([np.asarray(log.columns['%s_%s' % (axis, source)], dtype=np.float64)
                                           for axis in ('x', 'y')]) for source in ('anafi', 'sphinx')}
    t = log.t
    out = []
    k = 0
    while k < len(same):
        if not same[k]:
            k += 1
            continue
        j = k
        while j < len(same) and same[j]:
            j += 1
        end = j + 1                       # the first changed row; stale while it has not caught up
        last = min(len(t) - 1, j + 1 + (j - k + 1))
        while end <= last and moving[end] and (
                np.hypot(*(horizontal['anafi'][end] - horizontal['anafi'][k]))
                < caught_up * np.hypot(*(horizontal['sphinx'][end] - horizontal['sphinx'][k]))):
            end += 1
        if end > last:                    # never caught up within the tail: the first changed row
            end = j + 1
        if j - k + 1 >= samples and np.all(moving[k:j + 1]) and end < len(t):
            out.append((float(t[k]), float(t[end])))
            k = max(j, end)
            continue
        k = j
    return tuple(out)


def stall_actions(plan):
    """Engine actions that hold the stand-in's published estimate over ``plan.stalls`` (from the sim time of
    each stall's first row to half an estimate period before its end: ``standin_log`` reads the estimate that
    far back)."""
    out = []
    for start, end in plan.stalls:
        def action(engine, end=end):
            rate = float(engine.model_params['estimate_rate'])
            engine.sim.estimate.stall(float(engine.started_at) + plan.scenario_offset + end - 0.5 / rate)
        out.append((plan.scenario_offset + start, action))
    return out


def initial_state_action(plan):
    """fn(engine) that puts the replay of ``plan`` in the log's initial state (``plan.initial_state``, run
    ``INITIAL_AHEAD`` before log time 0). With the position fusion: the drone (and its estimate's history)
    translated so that the truth is the log's, then the fused position moved to the log's estimate. Without
    it the position estimate holds no error of its own (it is the delayed truth), so the drone is translated
    so that the estimate, the controller's input, is the log's. Then, with the velocity error state, the
    velocity estimate's error is set to the log's. These are the estimate's errors of that moment (Sphinx's
    lines start with errors left by each run's approach), which then decay by the model's dynamics. An axis
    without a value (NaN) is left as it is."""
    state = plan.initial_state
    shift = (plan.shift[0], plan.shift[1], 0.0)

    def move_to(target, current):
        return [target[i] - (current[i] + shift[i]) if math.isfinite(target[i]) else 0.0 for i in range(3)]

    def action(engine):
        sim = engine.sim
        estimate = sim.estimate
        if estimate.fusion:
            m = sim.model
            sim.translate(*move_to(state.truth, (m.x, m.y, m.z)))
            estimate.add_position_error(*move_to(state.estimate, estimate.position_state))
        else:
            sim.translate(*move_to(state.estimate, estimate.position_state))
        now = estimate.velocity_error
        estimate.add_velocity_error(*[state.velocity_error[i] - now[i] if math.isfinite(state.velocity_error[i])
                                      else 0.0 for i in range(3)])
    return action


LEAD_ALTITUDES = (1.0, 40.0)     # m, the band a straight lead-in stays in (inside the controllers' 0.5-50 m)


def straight_lead_limit(first, band=LEAD_ALTITUDES):
    """The longest straight lead-in [s] behind the waypoint ``first`` (x, y, z, vx, vy, vz, ...) that stays in
    the altitude ``band`` [m] (inf when it does not climb or sink): a log that starts climbing (a vertical
    motion shorter than a period and a second) would otherwise be led in from under the ground, and its
    replay never start."""
    z, vz = float(first[2]), float(first[5])
    if vz > 0.0:
        return max(0.0, (z - band[0]) / vz)
    if vz < 0.0:
        return max(0.0, (band[1] - z) / -vz)
    return float('inf')


def waypoint_ticks(clean, t, rate, latency):
    """The waypoint stream of a log as generator ticks: (indices of the rows where the waypoint changes, the value
    of every tick from the one before the first change on, log time [s] of that first value, slips). ``clean``:
    the log's waypoint rows (markers replaced), ``t`` their log times [s]; consecutive changes are counted in
    whole periods of ``rate`` [Hz] (a change not a whole number of periods after the previous one is a slip of
    the logger's phase); a tick was published ``latency`` [s] before the logger first shows it."""
    n = len(clean)
    changes = [i for i in range(1, n) if np.any(clean[i] != clean[i - 1])]
    period = 1.0 / rate
    # tick -1: the value the log starts with; ticks 0..: the changes, counted in whole periods
    ticks = [0]
    slips = 0
    for a, b in zip(changes, changes[1:]):
        gap = (t[b] - t[a]) / period
        ticks.append(ticks[-1] + max(1, int(round(gap))))
        if abs(gap - round(gap)) > 0.25 or round(gap) < 1:
            slips += 1
    if not changes:
        return changes, [clean[0]], 0.0, slips
    t_change = np.array([t[i] for i in changes])
    tick_log_time = float(np.median(t_change - np.array(ticks) * period)) - latency
    values = [clean[changes[0] - 1]] + [None] * (ticks[-1] + 1)
    for k, i in zip(ticks, changes):
        values[k + 1] = clean[i]
    for k in range(1, len(values)):         # ticks between two changes hold the earlier one
        if values[k] is None:
            values[k] = values[k - 1]
    # the value of tick -1 becomes the first of the trajectory, one period before tick 0
    return changes, values, tick_log_time - period, slips


def replay_plan(log, rate=DEFAULT_RATE, lead=DEFAULT_LEAD, approach=None, latency=None, controller=None,
                initial_state=True, stalls=True, stored=True):
    """The ``ReplayPlan`` of ``log`` (see the module doc).

    rate [Hz]: the waypoint stream's; lead [s]: lead-in for a log that starts in motion; approach [s]: hover
    at the start first (default ``APPROACH_MOVING`` / ``APPROACH_STATIC``); latency [s]: how long before the
    logger's first sample of a new waypoint it was published (default half the log's sample period);
    controller: 'pid' | 'mpc' (default from the log's name); initial_state: put the replay in the log's state
    at log time 0 (``log_initial_state``, ``initial_state_action``); stalls: hold the stand-in's estimate where
    the log's estimate stream stalled (``log_stalls``, ``stall_actions``); stored: ``standin_log`` stores the
    stand-in's columns as the logger stored Sphinx's (``reference_log.as_logged``; False: unrounded).
    """
    if controller is None:
        controller = parse_name(log.name)[1]
    wp = log.waypoint()
    n = len(wp)
    if n < 2:
        raise ValueError('%s: too short to replay (%d samples)' % (log.name, n))
    if not np.all(np.isfinite(wp)):
        raise ValueError('%s: the waypoint columns have non-finite values' % log.name)
    t = log.t
    if latency is None:
        latency = 0.5 * float(np.median(np.diff(t)))
    hover = hover_point(log)
    markers = 0
    clean = wp.copy()
    for i in range(n):
        if _is_marker(wp[i]):
            clean[i] = (hover[0], hover[1], hover[2], 0.0, 0.0, 0.0, hover[3])
            markers += 1
    changes, values, tick_log_time, slips = waypoint_ticks(clean, t, rate, latency)
    period = 1.0 / rate
    moving = bool(np.any(clean[0, 3:6] != 0.0))
    if approach is None:
        approach = APPROACH_MOVING if moving else APPROACH_STATIC
    lead_in = float(lead) if moving else 0.0
    repeat = stream_period(np.array(values, dtype=np.float64), rate) if moving else None
    if repeat is None and moving:
        lead_in = min(lead_in, straight_lead_limit(values[0]))
    # trajectory time tau of log time 0 must be >= lead_in; ticks at multiples of the period of tau
    first_tick_tau = math.ceil((lead_in - tick_log_time) * rate - 1e-9) * period
    first_tick_tau = max(first_tick_tau, 0.0)
    tau_log0 = first_tick_tau - tick_log_time            # trajectory time of log time 0
    if tau_log0 < 0.0:                                   # the stream starts after the log: shift by whole ticks
        shift = math.ceil(-tau_log0 * rate - 1e-9) * period
        first_tick_tau += shift
        tau_log0 += shift
    # replay in a frame shifted horizontally so that the start (the lead-in's first point) is above the
    # take-off point: the dynamics do not depend on x, y, and the waypoint limits (geofence, jump from the
    # drone) hold for the logs far from the origin (x_straight_5: x = 153 .. 300 m)
    values = np.array(values, dtype=np.float64)
    start = ReplayTrajectory(values, first_tick_tau, rate, repeat).sample(0.0)
    shift = (float(start.x), float(start.y))
    values[:, 0] -= shift[0]
    values[:, 1] -= shift[1]
    trajectory = ReplayTrajectory(values, first_tick_tau, rate, repeat)
    duration = float(t[-1]) + TAIL
    phases = [Phase('approach', float(approach), True, False)]
    if tau_log0 > 1e-9:
        phases.append(Phase('lead', tau_log0, False, False))
    phases.append(Phase('replay', duration, False, True))
    scenario = Scenario('replay_%s' % log.name, trajectory, phases,
                        description='closed-loop replay of the reference log %s' % log.name)
    scenario_offset = float(approach) + tau_log0        # scenario time of log time 0
    return ReplayPlan(log, log.name, controller, scenario, tick_log_time, first_tick_tau, scenario_offset,
                      len(changes), slips, markers, moving, shift,
                      log_initial_state(log, curved=repeat is not None) if initial_state else None,
                      log_stalls(log) if stalls else (),
                      bool(stored), repeat)


# ---------------------------------------------------------------------------------------------- runs
def estimate_samples(t_publish, rows, rate):
    """The estimate's own sample stream from its published copies: the estimate changes at multiples of
    1/``rate`` [s] of simulation time (``anafi_sim.sim.state_estimate``) and is republished at the bridge's
    rate; each publish carries the value of the latest multiple at or before it. Returns (times [s] of the
    multiples, rows), one per multiple (the first publish of each)."""
    t_publish = np.asarray(t_publish, dtype=np.float64)
    rows = np.asarray(rows, dtype=np.float64).reshape(len(t_publish), -1)
    ticks = np.floor(t_publish * rate + 1e-6)
    keep = np.ones(len(ticks), dtype=bool)
    keep[1:] = ticks[1:] != ticks[:-1]
    return ticks[keep] / rate, rows[keep]


def standin_log(plan, engine):
    """The stand-in's run as a ``ReferenceLog`` on ``plan.log``'s sample times and waypoint columns.

    Ground truth: the 100 Hz samples interpolated (angles unwrapped). Estimate: as a 20 Hz logger whose
    phase drifts against the estimate's (Sphinx's estimate changes at 19.5 Hz, the logs sample at 20 Hz)
    sees it on average: the estimate's own samples (``estimate_samples``) interpolated half a sample period
    back (the mean of a zero-order hold over a uniform phase; a fixed phase would bias e by up to half a
    sample of motion, 0.025 m at 1 m/s). NaN where the run has no sample. With ``plan.stored`` (default) both
    are then stored as the logger stored Sphinx's values (``reference_log.as_logged``: the shortest repr of
    the half float, a 0.0625-0.125 m grid at 64-256 m), so the stand-in's e_max sees the same rounding as
    Sphinx's (x_straight_2_mpc's truth e_max is one sample stored 0.2 m ahead of the waypoint: "81.4" for the
    half float 81.375). ``engine``: an Engine after ``run()``."""
    log = plan.log
    if engine.started_at is None:
        raise ValueError('the replay of %s never started (the monitor\'s start rule did not pass)' % plan.name)
    t_sim = float(engine.started_at) + plan.scenario_offset + log.t           # sim time of each log sample
    est_rows, truth_rows = logged_states(engine, t_sim)
    columns = collections.OrderedDict()
    for rows in (truth_rows, est_rows):
        rows[:, 0] += plan.shift[0]
        rows[:, 1] += plan.shift[1]
    if plan.stored:                           # like for like: the logger stored Sphinx's values as half floats
        truth_rows = as_logged(truth_rows)
        est_rows = as_logged(est_rows)
    for j, name in enumerate(STATE_NAMES):
        columns['%s_sphinx' % name] = truth_rows[:, j]
    for j, name in enumerate(STATE_NAMES):
        columns['%s_anafi' % name] = est_rows[:, j]
    for name in WAYPOINT_COLUMNS:
        columns[name] = np.array(log.columns[name], dtype=np.float64)
    ordered = collections.OrderedDict((c, columns[c]) for c in COLUMNS[1:])
    return ReferenceLog(ordered, log.time_ns.copy(), path=log.path)


def logged_states(engine, t_sim):
    """(estimate, truth) (n, 9) rows of a finished engine run at sim times ``t_sim`` [s] as a 20 Hz logger sees
    them (``standin_log``): the estimate's own samples (``estimate_samples``) interpolated half an estimate
    period back (the mean of a zero-order hold over a drifting phase), the truth interpolated (angles
    unwrapped); NaN where the run has no sample."""
    streams = engine.evaluator.streams
    est = list(streams['estimate'])
    truth = list(streams['truth'])
    if est:
        rate = float(engine.model_params['estimate_rate'])
        t_est, rows = estimate_samples([s * 1e-9 for s, _ in est], [r for _, r in est], rate)
        est_rows = interpolate(t_est, rows, t_sim - 0.5 / rate, max_gap=0.5, angle_columns=(6, 7, 8))
    else:
        est_rows = np.full((len(t_sim), 9), np.nan)
    if truth:
        t_tr = np.array([s for s, _ in truth], dtype=np.float64) * 1e-9
        rows = np.array([r for _, r in truth], dtype=np.float64)
        truth_rows = interpolate(t_tr, rows, t_sim, max_gap=0.5, angle_columns=(6, 7, 8))
    else:
        truth_rows = np.full((len(t_sim), 9), np.nan)
    return est_rows, truth_rows


def run_log(engine, begin=None, end=None, rate=20.0, stored=True, name=None):
    """A finished engine run as a reference log, recorded the way the paper's logger recorded Sphinx: samples at
    ``rate`` [Hz] over [``begin``, ``end``] (sim time [s]; default the measured window), each with the latest
    waypoint received and the estimate and ground truth as ``logged_states`` reads them, stored as half floats
    (``reference_log.as_logged``; ``stored=False``: unrounded); ``ReferenceLog`` with time in ns of sim time,
    named ``name`` (e.g. 'circle_r2_v2_mpc': ``replay_plan`` takes the controller from it). E.g. to replay the
    stand-in's own runs."""
    ev = engine.evaluator
    begin = ev.t_begin * 1e-9 if begin is None and ev.t_begin is not None else begin
    end = ev.t_end * 1e-9 if end is None and ev.t_end is not None else end
    if begin is None or end is None or not end > begin:
        raise ValueError('run_log: no window to record (begin %r, end %r)' % (begin, end))
    streams = dict((k, list(ev.streams[k])) for k in ('estimate', 'truth', 'waypoint'))
    if not all(streams.values()):
        raise ValueError('run_log: the run has no %s samples' % ', '.join(k for k, v in streams.items() if not v))
    t_ns = np.round(np.arange(begin, end + 1e-9, 1.0 / rate) * 1e9).astype(np.int64)
    t = t_ns * 1e-9
    rows = {}
    index = latest_waypoint(waypoint_arrivals(engine), t_ns)    # the latest one received
    values = np.array([r for _, r in streams['waypoint']], dtype=np.float64)
    rows['waypoint'] = np.where((index >= 0)[:, None], values[np.clip(index, 0, None)], np.nan)
    rows['estimate'], rows['truth'] = logged_states(engine, t)
    if stored:
        rows = dict((k, as_logged(v)) for k, v in rows.items())
    columns = collections.OrderedDict()
    for j, state in enumerate(STATE_NAMES):
        columns['%s_sphinx' % state] = rows['truth'][:, j]
        columns['%s_anafi' % state] = rows['estimate'][:, j]
    for j, column in enumerate(WAYPOINT_COLUMNS):
        columns[column] = rows['waypoint'][:, j]
    ordered = collections.OrderedDict((c, columns[c]) for c in COLUMNS[1:])
    return ReferenceLog(ordered, t_ns, path=name + '.csv' if name else None)


def waypoint_arrivals(engine):
    """The arrival times [int ns of sim time] of a run's waypoint stream."""
    return np.array([x for x, _ in engine.evaluator.streams['waypoint']], dtype=np.int64)


def latest_waypoint(arrivals, t_ns):
    """Index into the waypoint stream (``waypoint_arrivals``) of the latest waypoint received at or before each
    time ``t_ns`` [int ns of sim time] (-1: none yet)."""
    return np.searchsorted(arrivals, np.asarray(t_ns, dtype=np.int64), side='right') - 1


def horizontal_sources(log):
    """The sources whose cells are horizontal in ``log``: both when no 3-D estimate sample is valid (the
    controller flew on a garbage altitude, e.g. x_straight_2/3_pid: z_anafi wrapped at 16 bit, and Sphinx's
    drone sank 128-277 m below the ground under it, so the vertical of the truth is no flight either), else
    those without a valid 3-D sample."""
    out = set()
    for source in SOURCES:
        if tracking_error(log, SOURCE_COLUMN[source], exclude_garbage=True).stats.n_valid == 0:
            out.add(source)
    if 'estimate' in out:
        out.add('truth')
    return out


def cells(log, horizontal=None):
    """{(source, stat): value [m]} of a log: e_mu and e_max against the estimate and ground truth
    (``reference_log.tracking_error``, garbage excluded), horizontal for the sources in ``horizontal``
    (default ``horizontal_sources(log)``; give the reference log's set when evaluating a replay of it).
    Also {'horizontal': that set}."""
    horizontal = horizontal_sources(log) if horizontal is None else set(horizontal)
    out = collections.OrderedDict()
    for source in SOURCES:
        te = tracking_error(log, SOURCE_COLUMN[source], exclude_garbage=True)
        stats = te.stats_h if source in horizontal else te.stats
        out[(source, 'e_mu')] = stats.mean
        out[(source, 'e_max')] = stats.max
    out['horizontal'] = horizontal
    return out


def history_rms(reference, standin, names=HISTORIES):
    """{name: rms difference} of the ground-truth histories (roll, pitch [rad], vz [m/s]) of ``standin`` vs
    ``reference`` on their common sample times (both ReferenceLogs on the same grid; NaN pairs skipped)."""
    out = collections.OrderedDict()
    for name in names:
        a = np.asarray(reference.columns['%s_sphinx' % name], dtype=np.float64)
        b = np.asarray(standin.columns['%s_sphinx' % name], dtype=np.float64)
        ok = np.isfinite(a) & np.isfinite(b) & (np.abs(a) < 100.0)
        out[name] = float(np.sqrt(np.mean((a[ok] - b[ok]) ** 2))) if ok.any() else float('nan')
    return out


def _controller_params(variant, controller):
    params = (variant.controller_params or {}).get(controller) if variant is not None else None
    return dict(params) if params else None


def initial_yaw(log, model_params):
    """Take-off heading [rad] of a replay: the one at which the stand-in's estimate shows the log's first
    estimated yaw (the logged estimate minus the model's ``estimate_yaw_bias``), so that the controller starts
    from the heading it saw in Sphinx. It matters for a 180 deg turn: its direction follows the sign of the
    yaw error (static_waypoint_yaw_180_pid: Sphinx's estimate -1.8 deg -> a clockwise turn; from 0 deg the
    replay turned the other way)."""
    yaw = float(log.columns['yaw_anafi'][0])
    if not math.isfinite(yaw):
        return 0.0
    return yaw - float(model_params.get('estimate_yaw_bias', 0.0))


def run_replay(plan, variant=None, seed=None, settings=None):
    """Replay ``plan`` on the engine with ``variant`` (None: the shipped defaults); ``Replay``. The simulated
    drone takes off at ``initial_yaw``; ``settings``: more simulator settings (e.g. a flight's wind)."""
    name = variant.name if variant is not None else 'default'
    try:
        model = variant.model_params if variant is not None and variant.model_params is not None \
            else load_model_params()
        engine = Engine(plan.scenario, plan.controller, seed=seed,
                        settings=dict(settings or {}, initial_yaw=initial_yaw(plan.log, model)),
                        controller_params=_controller_params(variant, plan.controller),
                        schedule=variant.schedule if variant is not None else None,
                        model_params=model,
                        name='%s_%s' % (plan.name, name),
                        max_sim_time=plan.scenario.duration + 60.0,
                        actions=([(plan.scenario_offset - INITIAL_AHEAD, initial_state_action(plan))]
                                 if plan.initial_state is not None else []) + stall_actions(plan))
        result = engine.run()
    except (ValueError, RuntimeError, KeyError) as error:
        return Replay(plan, variant, False, '%s: %s' % (type(error).__name__, error), None, {}, {}, {})
    if not result.ok:
        return Replay(plan, variant, False, result.error, None, {}, {}, result.info)
    standin = standin_log(plan, engine)
    return Replay(plan, variant, True, '', standin, cells(standin, horizontal_sources(plan.log)),
                  history_rms(plan.log, standin), result.info)


LATE = 1.0      # s, "after the first second": the part of a log the initial state does not set


def late_cells(log, horizontal):
    """``cells`` of ``log`` from log time ``LATE`` on (the initial state puts a replay where the log is at its
    start, so the first second matches partly by construction; what follows is the model's)."""
    return cells(log.select(log.t >= LATE), horizontal)


def reference_cells(log):
    """``cells`` of the Sphinx log itself (the reference values)."""
    return cells(log)


def compare(reference, replay_cells):
    """{(source, stat): (stand-in, Sphinx, ratio)} (ratio NaN when either is missing)."""
    out = collections.OrderedDict()
    for key in CELLS:
        ref = reference.get(key, float('nan'))
        val = replay_cells.get(key, float('nan'))
        ratio = val / ref if (math.isfinite(ref) and math.isfinite(val) and ref > 0) else float('nan')
        out[key] = (val, ref, ratio)
    return out


def within(ratio, band):
    """True when ``ratio`` is finite and |ratio - 1| <= band."""
    return math.isfinite(ratio) and abs(ratio - 1.0) <= band + 1e-12


def _run_one(args):
    """Worker: (log path, variant, seed) -> plain record (picklable)."""
    path, variant, seed = args
    log = read_log(path)
    plan = replay_plan(log, **((variant.plan if variant is not None else None) or {}))
    rep = run_replay(plan, variant, seed=seed)
    return replay_record(rep)


def replay_record(rep):
    """A plain dict of a ``Replay`` (for YAML and worker processes): name, controller, variant, ok, error,
    cells {source: {stat: value}}, reference cells, ratios, histories, horizontal sources, info figures,
    and the stand-in's columns needed for plots (t, truth/estimate x y z vz roll pitch)."""
    plan = rep.plan
    ref = reference_cells(plan.log)
    variant = rep.variant.name if rep.variant is not None else 'default'
    rec = collections.OrderedDict([('log', plan.name), ('controller', plan.controller), ('variant', variant),
                                   ('name', '%s [%s]' % (plan.name, variant)), ('ok', bool(rep.ok)),
                                   ('error', rep.error)])
    rec['reference'] = dict(('%s_%s' % k, _num(ref[k])) for k in CELLS)
    rec['standin'] = dict(('%s_%s' % k, _num(rep.cells.get(k, float('nan')))) for k in CELLS)
    rec['ratio'] = dict(('%s_%s' % k, _num(v[2])) for k, v in compare(ref, rep.cells).items())
    if rep.standin is not None:
        late = compare(late_cells(plan.log, ref['horizontal']), late_cells(rep.standin, ref['horizontal']))
        rec['ratio_late'] = dict(('%s_%s' % k, _num(v[2])) for k, v in late.items())
    rec['horizontal'] = sorted(ref['horizontal'] | set(rep.cells.get('horizontal', ())))
    rec['histories'] = dict((k, _num(v)) for k, v in rep.histories.items())
    info = rep.info or {}
    rec['hover_commands'] = info.get('hover_commands')
    rec['wall_s'] = info.get('wall_s')
    rec['info'] = dict(achieved_rtf=info.get('achieved_rtf'))
    rec['ticks'] = plan.ticks
    rec['markers'] = plan.markers
    if rep.standin is not None:
        rec['series'] = dict((c, rep.standin.columns[c].tolist()) for c in PLOT_COLUMNS)
    return rec


PLOT_COLUMNS = ('x_anafi', 'y_anafi', 'z_anafi', 'x_sphinx', 'y_sphinx', 'z_sphinx', 'vz_sphinx', 'roll_sphinx',
                'pitch_sphinx')


def _num(v):
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return round(v, 5) if math.isfinite(v) else None


def applies(variant, path_or_name):
    """True when ``variant`` is meant for the controller of that log (``Variant.controllers``)."""
    if variant is None or not variant.controllers:
        return True
    name = os.path.splitext(os.path.basename(str(path_or_name)))[0]
    return parse_name(name)[1] in variant.controllers


def replay_all(paths, variants, seed=None, workers=1, progress=None):
    """Replay every log (paths) with every variant that applies to its controller; {(log name, variant
    name): record}. Runs through ``anafi_lab.engine.runs.execute`` (``workers`` processes)."""
    from anafi_lab.engine import runs
    tasks = [(p, v, seed) for v in variants for p in paths if applies(v, p)]
    records = runs.execute(tasks, workers=workers, progress=progress, label='fidelity', function=_run_one)
    return collections.OrderedDict(((r['log'], r['variant']), r) for r in records)
