"""Tracking-error evaluator core (pure Python, no ROS): the paper's e = |waypoint - drone position|.

Stage: (waypoint, drone estimate, ground truth) -> tracking-error summary.
Units and frames: positions [m], velocities [m/s] in the ENU world frame,
times [s] (ROS time), yaw of the waypoint [deg], attitude [rad].

Every input is turned into one representation, a ``reference_log.ReferenceLog``
(the column format of anafi_sim/data/reference_logs: one row per drone-estimate
sample with the ground truth and the waypoint of that instant), then
``evaluate_log`` computes, over the measured window:

- e = |wp - p_estimate| per sample (the paper's metric) and
  e = |wp - p_truth| (when ground truth is present), 3-D and horizontal;
- e_max, e_mu (mean), e_sigma (population standard deviation, ddof 0) over
  the valid samples, and the drift of e (least-squares slope [m/s], about 0
  once the controller has settled on a straight line);
- garbage samples (``reference_log.detect_garbage``: non-finite, 16-bit wrap
  such as z = 65280, absurd magnitudes, time not increasing) and samples
  below ground (z < ``min_altitude``, default -1 m; e.g. Sphinx's ground
  truth at z = -111 m in a glitched log) are EXCLUDED from the statistics and
  REPORTED (column, count, reason); a horizontal error is still given when
  only z is bad.

Entry points: ``evaluate_log`` (a ReferenceLog), ``evaluate_csv`` (a
reference-log CSV), ``evaluate_arrays`` (numpy arrays), ``evaluate_messages``
(iterables of (t, msg) pairs, e.g. from a rosbag: anafi_sim/Waypoint,
nav_msgs/Odometry, begin/end std_msgs/Header), and ``LiveEvaluator`` (for the
node: samples added one by one).

Time alignment: the rows are the drone-estimate samples (the controllers'
state, as in the paper's logs). The waypoint of a row is the latest waypoint
at or before the sample time (zero-order hold: what the controller was
tracking); estimate samples before the first waypoint are dropped (counted in
``Evaluation.dropped_before_waypoint``). Ground truth is linearly
interpolated at the sample time between its two neighbours (angles
unwrapped), NaN when no truth sample lies within ``max_truth_gap`` s (0.5)
on both sides; such samples are reported, not evaluated. Message times are
the header stamps (``use_header_stamp``; a zero stamp falls back to the
receive/bag time). The measured window is [last begin, first end after it]
when begin/end signals are given, else the whole log.
"""
import collections
import math

import numpy as np

from anafi_control.frames import odometry_to_world, odometry_twist_frame
from anafi_sim.mission import reference_log
from anafi_sim.mission.reference_log import (COLUMNS, STATE_NAMES, WAYPOINT_COLUMNS, GarbageReport, ReferenceLog,
                                     detect_garbage, error_stats, read_log)

DEFAULT_MIN_ALTITUDE = -1.0   # m: a position below this is not a flight sample (excluded, reported)
DEFAULT_MAX_TRUTH_GAP = 0.5   # s: ground truth is interpolated only between samples this close
TRUTH_COLUMNS = tuple('%s_sphinx' % n for n in STATE_NAMES)
ANGLE_NAMES = ('roll', 'pitch', 'yaw')


# ---------------------------------------------------------------- time and messages

def to_ns(t):
    """Time as int nanoseconds: a float/int in seconds, or a rospy/genpy Time/Duration (secs, nsecs)."""
    if hasattr(t, 'secs') and hasattr(t, 'nsecs'):
        return int(t.secs) * 1000000000 + int(t.nsecs)
    if hasattr(t, 'to_nsec'):
        return int(t.to_nsec())
    return int(round(float(t) * 1e9))


def stamp_ns(msg, t, use_header_stamp=True):
    """Time of a message [ns]: its header stamp (or a Time message's data) when non-zero, else ``t``."""
    if use_header_stamp and msg is not None:
        stamp = None
        header = getattr(msg, 'header', None)
        if header is not None:
            stamp = getattr(header, 'stamp', None)
        elif hasattr(msg, 'stamp'):
            stamp = msg.stamp                      # a std_msgs/Header itself
        elif hasattr(msg, 'data') and hasattr(msg.data, 'secs'):
            stamp = msg.data                       # std_msgs/Time
        if stamp is not None:
            ns = to_ns(stamp)
            if ns != 0:
                return ns
    return to_ns(t)


def waypoint_from_msg(msg):
    """(x, y, z [m], vx, vy, vz [m/s], yaw [deg]) of an anafi_sim/Waypoint."""
    return (float(msg.x), float(msg.y), float(msg.z), float(msg.vx), float(msg.vy), float(msg.vz),
            float(msg.yaw))


def state_from_odometry(msg):
    """(x, y, z, vx, vy, vz, roll, pitch, yaw) of a nav_msgs/Odometry: ENU world, SI, rad.

    ``anafi_control.frames.odometry_to_world`` with the twist frame picked from the message's frame names
    (``odometry_twist_frame``: the twist is in ``child_frame_id`` unless that is empty or equals
    header.frame_id), keeping the values it cannot compute as NaN (reported per column as garbage).
    """
    p, q, v = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear
    parent = getattr(getattr(msg, 'header', None), 'frame_id', '') or ''
    twist_frame = odometry_twist_frame(parent, getattr(msg, 'child_frame_id', '') or '')
    pos, vel, rpy = odometry_to_world((p.x, p.y, p.z), (q.x, q.y, q.z, q.w), (v.x, v.y, v.z), twist_frame,
                                      partial=True)
    return pos + vel + rpy


# ---------------------------------------------------------------- alignment

def align_zoh(t_source, values, t_query):
    """Zero-order hold: for each query time the latest source row at or before it.

    ``t_source`` (N,) ascending, ``values`` (N, k), ``t_query`` (M,) -> ((M, k)
    array, (M,) bool mask), NaN rows and False where no source sample precedes.
    """
    t_source = np.asarray(t_source)
    values = np.asarray(values, dtype=np.float64).reshape(len(t_source), -1)
    t_query = np.asarray(t_query)
    idx = np.searchsorted(t_source, t_query, side='right') - 1
    valid = idx >= 0
    out = np.full((len(t_query), values.shape[1]), np.nan)
    out[valid] = values[idx[valid]]
    return out, valid


def interpolate(t_source, values, t_query, max_gap=None, angle_columns=()):
    """Linear interpolation of ``values`` (N, k) at ``t_query``; NaN outside the source range and
    where the neighbouring source samples are more than ``max_gap`` apart (same time unit).
    Columns in ``angle_columns`` (indices, rad) are unwrapped first and wrapped back to [-pi, pi)."""
    t_source = np.asarray(t_source, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64).reshape(len(t_source), -1)
    t_query = np.asarray(t_query, dtype=np.float64)
    out = np.full((len(t_query), values.shape[1]), np.nan)
    if len(t_source) == 0:
        return out
    inside = (t_query >= t_source[0]) & (t_query <= t_source[-1])
    if max_gap is not None and len(t_source) > 1:
        hi = np.clip(np.searchsorted(t_source, t_query, side='left'), 0, len(t_source) - 1)
        lo = np.clip(hi - 1, 0, len(t_source) - 1)
        exact = t_source[hi] == t_query
        gap = t_source[hi] - t_source[lo]
        inside &= exact | (gap <= max_gap)
    for j in range(values.shape[1]):
        col = values[:, j]
        ok = np.isfinite(col)
        if ok.sum() == 0:
            continue
        ts, vs = t_source[ok], col[ok]
        if j in angle_columns:
            vs = np.unwrap(vs)
        res = np.interp(t_query, ts, vs)
        if j in angle_columns:
            res = (res + math.pi) % (2.0 * math.pi) - math.pi
        # a non-finite source sample next to the query makes the result non-finite (reported, not hidden)
        near_bad = np.zeros(len(t_query), dtype=bool)
        if not ok.all():
            hi = np.clip(np.searchsorted(t_source, t_query, side='left'), 0, len(t_source) - 1)
            lo = np.clip(hi - 1, 0, len(t_source) - 1)
            near_bad = ~ok[hi] | ~ok[lo]
        out[:, j] = np.where(inside & ~near_bad, res, np.nan)
    return out


def _sorted(t_ns, rows, width):
    t_ns = np.asarray(t_ns, dtype=np.int64)
    rows = np.asarray(rows, dtype=np.float64).reshape(len(t_ns), width)
    order = np.argsort(t_ns, kind='stable')
    return t_ns[order], rows[order]


def build_log(t_estimate_ns, estimate_states, t_waypoint_ns, waypoints, t_truth_ns=None, truth_states=None,
              name='', max_truth_gap=DEFAULT_MAX_TRUTH_GAP):
    """A ``ReferenceLog`` (one row per estimate sample) from sample streams; see the module doc.

    ``estimate_states`` / ``truth_states``: (N, 9) x, y, z, vx, vy, vz, roll,
    pitch, yaw; ``waypoints``: (M, 7) x, y, z, vx, vy, vz, yaw [deg]; times
    int ns. Returns (log, info) with info = {'absent': columns not supplied,
    'dropped_before_waypoint': int, 'truth_uncovered': int}.
    """
    t_est, est = _sorted(t_estimate_ns, estimate_states, 9)
    t_wp, wps = _sorted(t_waypoint_ns, waypoints, 7)
    wp_rows, has_wp = align_zoh(t_wp, wps, t_est)
    dropped = int((~has_wp).sum())
    t_est, est, wp_rows = t_est[has_wp], est[has_wp], wp_rows[has_wp]
    columns = collections.OrderedDict()
    for j, n in enumerate(STATE_NAMES):
        columns['%s_anafi' % n] = est[:, j]
    absent = []
    uncovered = 0
    if t_truth_ns is not None and len(t_truth_ns):
        t_tr, tr = _sorted(t_truth_ns, truth_states, 9)
        if len(t_est):
            base = t_est[0]
            truth = interpolate((t_tr - base) * 1e-9, tr, (t_est - base) * 1e-9, max_gap=max_truth_gap,
                                angle_columns=(6, 7, 8))
        else:
            truth = np.zeros((0, 9))
        uncovered = int(np.isnan(truth[:, 0]).sum())
    else:
        truth = np.full((len(t_est), 9), np.nan)
        absent = list(TRUTH_COLUMNS)
    for j, n in enumerate(STATE_NAMES):
        columns['%s_sphinx' % n] = truth[:, j]
    for j, c in enumerate(WAYPOINT_COLUMNS):
        columns[c] = wp_rows[:, j]
    ordered = collections.OrderedDict((c, columns[c]) for c in COLUMNS[1:])
    log = ReferenceLog(ordered, t_est, path=None)
    log.label = name
    return log, {'absent': absent, 'dropped_before_waypoint': dropped, 'truth_uncovered': uncovered}


def slice_log(log, mask):
    """A new ``ReferenceLog`` with the rows where ``mask`` is True."""
    mask = np.asarray(mask, dtype=bool)
    columns = collections.OrderedDict((k, np.asarray(v)[mask]) for k, v in log.columns.items())
    out = ReferenceLog(columns, log.time_ns[mask], path=log.path, parse_errors=log.parse_errors,
                       extra_columns=log.extra_columns)
    if hasattr(log, 'label'):
        out.label = log.label
    return out


# ---------------------------------------------------------------- results

class SourceResult(object):
    """Tracking error against one source ('estimate' = the drone's estimate, 'truth' = ground truth).

    ``stats`` / ``stats_h``: ``reference_log.ErrorStats`` (mean, max, std,
    n_valid, n_excluded) of the 3-D / horizontal error [m]; ``e`` / ``e_h`` per
    sample (NaN = excluded); ``drift``: slope of e over time [m/s] (NaN when
    fewer than 2 valid samples); ``excluded``: {reason: count} for the 3-D e.
    """

    def __init__(self, source, e, e_h, t, excluded):
        self.source = source
        self.e = e
        self.e_h = e_h
        self.stats = error_stats(e)
        self.stats_h = error_stats(e_h)
        self.excluded = excluded
        ok = np.isfinite(e)
        if ok.sum() >= 2 and np.ptp(t[ok]) > 0:
            self.drift = float(np.polyfit(t[ok], e[ok], 1)[0])
        else:
            self.drift = float('nan')

    @property
    def e_max(self):
        return self.stats.max

    @property
    def e_mu(self):
        return self.stats.mean

    @property
    def e_sigma(self):
        return self.stats.std

    def as_dict(self):
        def f(v):
            return None if not math.isfinite(v) else round(float(v), 4)
        return dict([
            ('e_max', f(self.stats.max)), ('e_mu', f(self.stats.mean)), ('e_sigma', f(self.stats.std)),
            ('n_valid', self.stats.n_valid), ('n_excluded', self.stats.n_excluded),
            ('e_max_horizontal', f(self.stats_h.max)), ('e_mu_horizontal', f(self.stats_h.mean)),
            ('e_sigma_horizontal', f(self.stats_h.std)), ('n_valid_horizontal', self.stats_h.n_valid),
            ('drift', f(self.drift)),
            ('excluded', dict(self.excluded)),
        ])


class Evaluation(object):
    """Result of one evaluation: per-source results, garbage and warnings (see ``as_dict``/``lines``).

    ``estimate``: ``SourceResult`` against the drone's estimate (the paper's
    metric); ``truth``: against ground truth, or None when absent;
    ``garbage``: ``GarbageReport`` over the window (absent columns omitted);
    ``window``: (t0, t1) [s since the log's first sample]; ``log``: the
    windowed ``ReferenceLog``; ``full_log``: the whole log (e.g. for CSV export).
    """

    def __init__(self, name, log, full_log, window, estimate, truth, garbage, warnings, dropped_before_waypoint=0,
                 truth_missing=0):
        self.name = name
        self.log = log
        self.full_log = full_log
        self.window = window
        self.estimate = estimate
        self.truth = truth
        self.garbage = garbage
        self.warnings = list(warnings)
        self.dropped_before_waypoint = dropped_before_waypoint
        self.truth_missing = int(truth_missing)     # samples without ground truth (interpolation gap)

    @property
    def n_samples(self):
        return len(self.log)

    @property
    def has_garbage(self):
        return bool(self.garbage)

    def as_dict(self):
        """Plain dict (insertion-ordered, YAML/JSON ready): name, samples, window, duration, estimate,
        truth (None when absent), garbage (lines), garbage_samples (samples with garbage in some column),
        truth_missing (samples without ground truth), warnings."""
        return dict([
            ('name', self.name),
            ('samples', self.n_samples),
            ('window', [round(self.window[0], 3), round(self.window[1], 3)]),
            ('duration', round(float(self.log.t[-1]) if len(self.log) else 0.0, 3)),
            ('estimate', self.estimate.as_dict()),
            ('truth', self.truth.as_dict() if self.truth is not None else None),
            ('garbage', self.garbage.summary()),
            ('garbage_samples', self.garbage.n_bad),
            ('truth_missing', self.truth_missing),
            ('warnings', list(self.warnings)),
        ])

    def lines(self):
        """Human-readable summary lines."""
        out = ['%s: %d samples, window %.2f .. %.2f s' % (self.name or '(unnamed)', self.n_samples,
                                                          self.window[0], self.window[1])]
        for label, res in (('estimate', self.estimate), ('ground truth', self.truth)):
            if res is None:
                out.append('  vs %-12s  (absent%s)' % (label, ': no ground truth' if res is self.truth else ''))
                continue
            s, h = res.stats, res.stats_h
            text = '  vs %-12s  e_max %s  e_mu %s  e_sigma %s  [m]  (%d valid, %d excluded)' % (
                label, _fmt(s.max), _fmt(s.mean), _fmt(s.std), s.n_valid, s.n_excluded)
            if s.n_excluded:
                text += '  horizontal: e_max %s  e_mu %s  e_sigma %s (%d valid)' % (
                    _fmt(h.max), _fmt(h.mean), _fmt(h.std), h.n_valid)
            out.append(text)
        for line in self.garbage.summary():
            out.append('  GARBAGE %s (excluded)' % line)
        for w in self.warnings:
            out.append('  WARNING %s' % w)
        return out


def _fmt(v):
    return '%6.3f' % v if math.isfinite(v) else '   n/a'


# ---------------------------------------------------------------- evaluation

def _filter_report(report, absent):
    cols = collections.OrderedDict((k, v) for k, v in report.columns.items() if k not in absent)
    return GarbageReport(report.n_samples, cols, name='')


def _truth_absent(log, absent):
    if all(c in absent for c in ('x_sphinx', 'y_sphinx', 'z_sphinx')):
        return True
    pos = np.column_stack([log.columns[c] for c in ('x_sphinx', 'y_sphinx', 'z_sphinx')])
    if len(pos) == 0:
        return False
    finite = np.isfinite(pos)
    # a real-flight CSV has the truth columns but fills them with zeros (no simulator): no ground truth
    return not finite.any() or bool(np.all(pos[finite] == 0.0))


def _source_result(log, source, min_altitude, result_name):
    te = reference_log.tracking_error(log, source, exclude_garbage=True)
    e, e_h = te.e.copy(), te.e_h.copy()
    excluded = collections.OrderedDict()
    garbage_cols = ('wp_x', 'wp_y', 'wp_z', 'x_' + source, 'y_' + source, 'z_' + source)
    n_garbage = int(te.garbage.mask(*garbage_cols).sum())
    if n_garbage:
        excluded['garbage'] = n_garbage
    if min_altitude is not None:
        z = log.columns['z_' + source]
        with np.errstate(invalid='ignore'):
            below = np.isfinite(z) & (z < min_altitude) & np.isfinite(e)
        if below.any():
            excluded['below ground'] = int(below.sum())
            e[below] = np.nan
    return SourceResult(result_name, e, e_h, log.t, excluded)


def evaluate_log(log, window=None, relative=True, min_altitude=DEFAULT_MIN_ALTITUDE, absent=(), name=None,
                 dropped_before_waypoint=0):
    """``Evaluation`` of a ``ReferenceLog`` over ``window`` = (t0, t1) [s] (None: the whole log).

    ``relative``: window times are seconds since the log's first sample
    (else absolute ROS time). ``absent``: columns that were not recorded
    (not reported as garbage); ground truth counts as absent when its
    position columns are absent or entirely non-finite.
    ``min_altitude`` [m] (None disables): positions below it are excluded
    from the 3-D error and reported.
    """
    name = name if name is not None else (getattr(log, 'label', '') or log.name)
    absent = set(absent)
    warnings = []
    n = len(log)
    if window is None or n == 0:
        mask = np.ones(n, dtype=bool)
    else:
        t0, t1 = float(window[0]), float(window[1])
        if not t1 >= t0:
            raise ValueError('window end %r before its start %r' % (t1, t0))
        times = log.t if relative else log.time
        mask = (times >= t0) & (times <= t1)
    t_first = float(log.time[0]) if n else 0.0
    sub = slice_log(log, mask)
    if n and window is not None:
        w = (float(window[0]), float(window[1])) if relative else (window[0] - t_first, window[1] - t_first)
    else:
        w = (0.0, float(log.t[-1]) if n else 0.0)
    if len(sub) == 0:
        warnings.append('no samples in the window %.2f .. %.2f s' % w)
    if log.parse_errors:
        warnings.append('%d unreadable CSV rows skipped (first: line %d, %s)' % (
            len(log.parse_errors), log.parse_errors[0][0], log.parse_errors[0][1]))
    if dropped_before_waypoint and window is None:
        warnings.append('%d estimate samples before the first waypoint not evaluated' % dropped_before_waypoint)
    truth_absent = _truth_absent(sub, absent)
    if truth_absent:
        absent |= set(TRUTH_COLUMNS)
    garbage = _filter_report(detect_garbage(sub), absent)
    truth_missing = 0
    if not truth_absent and len(sub):
        # a sample without any ground truth (no truth sample within the interpolation gap) is missing, counted
        # once in the warning below, not garbage in each of the truth columns
        present = [c for c in TRUTH_COLUMNS if c in sub.columns]
        missing = np.all(np.column_stack([np.isnan(np.asarray(sub.columns[c], dtype=np.float64))
                                          for c in present]), axis=1)
        truth_missing = int(missing.sum())
        garbage = garbage.without(missing, set(present))
    estimate = _source_result(sub, 'anafi', min_altitude, 'estimate')
    truth = None if truth_absent else _source_result(sub, 'sphinx', min_altitude, 'truth')
    for res, label in ((estimate, 'estimate'), (truth, 'ground truth')):
        if res is not None and res.excluded.get('below ground'):
            warnings.append('%s below ground (z < %g m) at %d samples: excluded from the 3-D error'
                            % (label, min_altitude, res.excluded['below ground']))
        if res is not None and len(sub) and res.stats.n_valid == 0:
            warnings.append('no valid 3-D %s samples; horizontal e_mu = %s m' % (label, _fmt(res.stats_h.mean).strip()))
    if truth is not None and truth_missing:
        warnings.append('ground truth missing (no sample within the interpolation gap) at %d samples'
                        % truth_missing)
    return Evaluation(name, sub, log, w, estimate, truth, garbage, warnings, dropped_before_waypoint,
                      truth_missing=truth_missing)


def evaluate_csv(path, window=None, min_altitude=DEFAULT_MIN_ALTITUDE):
    """``Evaluation`` of a reference-log CSV file (window: seconds since its first sample)."""
    return evaluate_log(read_log(path), window=window, min_altitude=min_altitude)


def evaluate_arrays(t, waypoint, position, truth=None, t_waypoint=None, t_truth=None, window=None,
                    name='', min_altitude=DEFAULT_MIN_ALTITUDE):
    """``Evaluation`` from arrays: drone-estimate times ``t`` [s] (N,) and ``position`` (N, 3) [m];
    ``waypoint`` (M, 3) or (M, 7) [m, m/s, deg], sampled at ``t_waypoint`` (zero-order hold) or,
    when None, one per estimate sample; ``truth`` (K, 3) at ``t_truth`` (default ``t``), linearly
    interpolated. ``window`` in seconds since the first estimate sample. Velocities and
    attitude not given are zero (they do not enter the error)."""
    t = np.asarray(t, dtype=np.float64)
    position = np.asarray(position, dtype=np.float64).reshape(len(t), 3)
    waypoint = np.asarray(waypoint, dtype=np.float64)
    waypoint = waypoint.reshape(len(waypoint), -1)
    if waypoint.shape[1] == 3:
        waypoint = np.hstack([waypoint, np.zeros((len(waypoint), 4))])
    if waypoint.shape[1] != 7:
        raise ValueError('waypoint must be (M, 3) or (M, 7), got %s' % (waypoint.shape,))
    if t_waypoint is None:
        if len(waypoint) != len(t):
            raise ValueError('waypoint has %d rows, t has %d: give t_waypoint' % (len(waypoint), len(t)))
        t_waypoint = t
    t_ns = np.round(t * 1e9).astype(np.int64)
    est = np.hstack([position, np.zeros((len(t), 6))])
    truth_states = truth_ns = None
    if truth is not None:
        truth = np.asarray(truth, dtype=np.float64)
        truth = truth.reshape(len(truth), 3)
        t_truth = t if t_truth is None else np.asarray(t_truth, dtype=np.float64)
        truth_ns = np.round(t_truth * 1e9).astype(np.int64)
        truth_states = np.hstack([truth, np.zeros((len(truth), 6))])
    log, info = build_log(t_ns, est, np.round(np.asarray(t_waypoint, dtype=np.float64) * 1e9).astype(np.int64),
                          waypoint, truth_ns, truth_states, name=name, max_truth_gap=math.inf)
    return evaluate_log(log, window=window, min_altitude=min_altitude, absent=info['absent'], name=name,
                        dropped_before_waypoint=info['dropped_before_waypoint'])


def measured_window(begins_ns, ends_ns):
    """(t0, t1) [ns] of the measured segment: the last begin and the first end after it.

    None when there is no begin; t1 is None when no end follows the last begin.
    """
    begins = sorted(begins_ns)
    if not begins:
        return None
    t0 = begins[-1]
    after = sorted(e for e in ends_ns if e >= t0)
    return (t0, after[0] if after else None)


def evaluate_messages(waypoints, estimates, truths=(), begins=(), ends=(), name='', use_header_stamp=True,
                      window=None, min_altitude=DEFAULT_MIN_ALTITUDE, max_truth_gap=DEFAULT_MAX_TRUTH_GAP):
    """``Evaluation`` from iterables of (t, msg) pairs (t: receive/bag time, s or rospy Time).

    ``waypoints``: anafi_sim/Waypoint; ``estimates`` / ``truths``:
    nav_msgs/Odometry (the drone's estimate / ground truth); ``begins`` /
    ``ends``: std_msgs/Header (or Time, or None: the pair's t) marking the
    measured segment. ``window`` (s since the first evaluated sample)
    overrides the begin/end signals. Malformed messages are skipped and
    counted in a warning.
    """
    skipped = collections.Counter()

    def collect(pairs, convert, label):
        ts, rows = [], []
        for t, msg in pairs:
            try:
                row = convert(msg)
                ts.append(stamp_ns(msg, t, use_header_stamp))
            except (AttributeError, TypeError, ValueError):
                skipped[label] += 1
                continue
            rows.append(row)
        return ts, rows

    t_wp, wps = collect(waypoints, waypoint_from_msg, 'waypoint')
    t_est, est = collect(estimates, state_from_odometry, 'estimate')
    t_tr, tr = collect(truths, state_from_odometry, 'truth')
    b = [stamp_ns(m, t, use_header_stamp) for t, m in begins]
    e = [stamp_ns(m, t, use_header_stamp) for t, m in ends]
    if not t_wp or not t_est:
        raise ValueError('%s: need waypoint and drone-estimate messages (got %d waypoints, %d estimates)'
                         % (name or 'messages', len(t_wp), len(t_est)))
    log, info = build_log(t_est, est, t_wp, wps, t_tr if t_tr else None, tr if tr else None, name=name,
                          max_truth_gap=max_truth_gap)
    extra = []
    if window is None and len(log):
        span = measured_window(b, e)
        if span is not None:
            t1 = span[1]
            if t1 is None:
                extra.append('measured segment began but did not end: evaluated to the last sample')
                t1 = int(log.time_ns[-1])
            first = int(log.time_ns[0])
            window = ((span[0] - first) * 1e-9, (t1 - first) * 1e-9)   # same arithmetic as log.t
        elif b or e:
            extra.append('end signal without a begin: whole log evaluated')
    result = evaluate_log(log, window=window, min_altitude=min_altitude, absent=info['absent'], name=name,
                          dropped_before_waypoint=info['dropped_before_waypoint'])
    for label, count in sorted(skipped.items()):
        extra.append('%d malformed %s messages skipped' % (count, label))
    result.warnings.extend(extra)
    return result


# ---------------------------------------------------------------- live

class LiveEvaluator(object):
    """Collects samples as they arrive (node side) and evaluates the measured window on demand.

    Times are seconds (float) or rospy Time. ``begin(t)`` starts a new
    measured window (a later begin replaces it), ``end(t)`` closes it.
    ``evaluate(now)`` evaluates [begin, end] (or [begin, now] while running;
    the whole record when no begin was received). ``complete()`` is True
    once the window has ended and an estimate sample at or after its end
    has arrived (so the last samples are in). At most ``max_samples`` per
    stream are kept (oldest dropped, counted in ``dropped``).
    """

    def __init__(self, name='', min_altitude=DEFAULT_MIN_ALTITUDE, max_truth_gap=DEFAULT_MAX_TRUTH_GAP,
                 max_samples=500000):
        self.name = name
        self.min_altitude = min_altitude
        self.max_truth_gap = max_truth_gap
        self.max_samples = int(max_samples)
        self.streams = dict((k, collections.deque(maxlen=self.max_samples))
                            for k in ('waypoint', 'estimate', 'truth'))
        self.dropped = collections.Counter()
        self.rejected = collections.Counter()
        self.t_begin = None
        self.t_end = None

    def _add(self, stream, t, row):
        q = self.streams[stream]
        if len(q) == q.maxlen:
            self.dropped[stream] += 1
        q.append((to_ns(t), row))

    def add_waypoint(self, t, waypoint):
        """Waypoint (x, y, z, vx, vy, vz, yaw_deg) or an anafi_sim/Waypoint message at time t."""
        row = waypoint if isinstance(waypoint, (tuple, list)) else waypoint_from_msg(waypoint)
        if len(row) != 7:
            self.rejected['waypoint'] += 1
            return False
        self._add('waypoint', t, tuple(float(v) for v in row))
        return True

    def add_estimate(self, t, state):
        """Drone estimate: 9-tuple state (see ``state_from_odometry``) or a nav_msgs/Odometry."""
        return self._add_state('estimate', t, state)

    def add_truth(self, t, state):
        """Ground truth: 9-tuple state or a nav_msgs/Odometry."""
        return self._add_state('truth', t, state)

    def _add_state(self, stream, t, state):
        row = state if isinstance(state, (tuple, list)) else state_from_odometry(state)
        if len(row) != 9:
            self.rejected[stream] += 1
            return False
        self._add(stream, t, tuple(float(v) for v in row))
        return True

    def begin(self, t):
        self.t_begin = to_ns(t)
        self.t_end = None

    def end(self, t):
        ns = to_ns(t)
        if self.t_begin is not None and ns >= self.t_begin:
            self.t_end = ns

    @property
    def state(self):
        """'waiting' (no begin), 'measuring' or 'ended'."""
        if self.t_begin is None:
            return 'waiting'
        return 'measuring' if self.t_end is None else 'ended'

    def complete(self):
        est = self.streams['estimate']
        return self.t_end is not None and bool(est) and est[-1][0] >= self.t_end

    def counts(self):
        return dict((k, len(v)) for k, v in self.streams.items())

    def build_log(self):
        """(ReferenceLog of everything received, info) — see ``build_log``."""
        wp, est, tr = (list(self.streams[k]) for k in ('waypoint', 'estimate', 'truth'))
        if not wp or not est:
            return None, None
        return build_log([t for t, _ in est], [r for _, r in est], [t for t, _ in wp], [r for _, r in wp],
                         [t for t, _ in tr] if tr else None, [r for _, r in tr] if tr else None,
                         name=self.name, max_truth_gap=self.max_truth_gap)

    def evaluate(self, now=None):
        """``Evaluation`` of the measured window so far (None when no waypoint or estimate yet)."""
        log, info = self.build_log()
        if log is None or not len(log):
            return None
        window = None
        if self.t_begin is not None:
            t1 = self.t_end if self.t_end is not None else (to_ns(now) if now is not None else int(log.time_ns[-1]))
            t1 = max(t1, self.t_begin)
            first = int(log.time_ns[0])
            window = ((self.t_begin - first) * 1e-9, (t1 - first) * 1e-9)
        result = evaluate_log(log, window=window, min_altitude=self.min_altitude, absent=info['absent'],
                              name=self.name, dropped_before_waypoint=info['dropped_before_waypoint'])
        for stream, count in sorted(self.dropped.items()):
            result.warnings.append('%d oldest %s samples dropped (max_samples %d)' % (count, stream,
                                                                                      self.max_samples))
        for stream, count in sorted(self.rejected.items()):
            result.warnings.append('%d malformed %s samples rejected' % (count, stream))
        return result


# ---------------------------------------------------------------- bags

BAG_STREAMS = collections.OrderedDict([
    ('waypoint', ('anafi_sim/Waypoint', 'position_control/waypoint')),
    ('estimate', ('nav_msgs/Odometry', 'drone/odom')),
    ('truth', ('nav_msgs/Odometry', 'ground_truth/odom')),
    ('begin', (None, 'trajectory/begin')),
    ('end', (None, 'trajectory/end')),
])


def select_bag_topics(topic_types, drone=None):
    """{stream: topic or None} for a bag's {topic: message type}.

    A stream's topic is the one ending in its suffix (``BAG_STREAMS``, e.g.
    /anafi/drone/odom) with the right type; ``drone`` restricts to
    /<drone>/<suffix>. Raises ValueError when several drones match (give
    ``drone``) or when waypoint or estimate is missing.
    """
    chosen = collections.OrderedDict()
    for stream, (msg_type, suffix) in BAG_STREAMS.items():
        if drone:
            wanted = '/%s/%s' % (drone.strip('/'), suffix)
            cands = [t for t in topic_types if t == wanted or t.lstrip('/') == wanted.lstrip('/')]
        else:
            cands = [t for t in topic_types if t == suffix or t.endswith('/' + suffix)]
        if msg_type:
            cands = [t for t in cands if topic_types[t] == msg_type]
        if len(cands) > 1:
            raise ValueError('several %s topics (%s): choose the drone' % (stream, ', '.join(sorted(cands))))
        chosen[stream] = cands[0] if cands else None
    missing = [s for s in ('waypoint', 'estimate') if chosen[s] is None]
    if missing:
        raise ValueError('bag has no %s topic (topics: %s)' % (' or '.join(missing), ', '.join(sorted(topic_types))))
    return chosen


def evaluate_bag(bag, drone=None, name='', window=None, use_header_stamp=True,
                 min_altitude=DEFAULT_MIN_ALTITUDE, max_truth_gap=DEFAULT_MAX_TRUTH_GAP):
    """``Evaluation`` of an open rosbag.Bag (duck-typed: get_type_and_topic_info(), read_messages()).

    Topics are found by ``select_bag_topics``; the messages go through
    ``evaluate_messages`` with the bag time as fallback stamp.
    """
    info = bag.get_type_and_topic_info()
    topic_types = dict((t, v.msg_type) for t, v in info.topics.items())
    topics = select_bag_topics(topic_types, drone)
    streams = dict((s, []) for s in topics)
    by_topic = dict((t, s) for s, t in topics.items() if t)
    for topic, msg, t in bag.read_messages(topics=list(by_topic)):
        streams[by_topic[topic]].append((t, msg))
    result = evaluate_messages(streams['waypoint'], streams['estimate'], streams['truth'], streams['begin'],
                               streams['end'], name=name, use_header_stamp=use_header_stamp, window=window,
                               min_altitude=min_altitude, max_truth_gap=max_truth_gap)
    result.topics = topics
    if topics['truth'] is None:
        result.warnings.append('no ground-truth topic in the bag')
    return result


def summary_markdown(summary):
    """Markdown text of a summary dict (Evaluation.as_dict() plus 'state')."""
    lines = ['# Tracking error: %s' % (summary.get('name') or '(unnamed)'), '',
             '%s samples, window %s s, state %s.' % (summary.get('samples'), summary.get('window'),
                                                      summary.get('state', '')), '',
             '| against | e_max [m] | e_mu [m] | e_sigma [m] | valid | excluded | e_mu horizontal [m] |',
             '|---|---|---|---|---|---|---|']
    for key, label in (('estimate', 'drone estimate'), ('truth', 'ground truth')):
        r = summary.get(key)
        if r is None:
            lines.append('| %s | absent | | | | | |' % label)
            continue
        lines.append('| %s | %s | %s | %s | %s | %s | %s |' % (
            label, r['e_max'], r['e_mu'], r['e_sigma'], r['n_valid'], r['n_excluded'], r['e_mu_horizontal']))
    for g in summary.get('garbage') or []:
        lines.append('- GARBAGE (excluded): %s' % g)
    for w in summary.get('warnings') or []:
        lines.append('- WARNING: %s' % w)
    return '\n'.join(lines) + '\n'
