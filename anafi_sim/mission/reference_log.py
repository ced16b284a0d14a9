"""Reference flight logs (CSV) of the paper's Sphinx runs: read, write, check, evaluate (pure Python).

Stage: evaluation / calibration input. A reference log (format of
``anafi_sim/data/reference_logs/``) has one row per sample (~20 Hz) and the columns
``COLUMNS``: ``time`` [int ns, ROS time], ground truth ``*_sphinx`` and the
drone's own estimate ``*_anafi`` (x, y, z [m], vx, vy, vz [m/s] in the ENU
world frame; roll, pitch, yaw [rad], FLU Euler), and the waypoint ``wp_*``
(x, y, z [m], vx, vy, vz [m/s], ENU; ``wp_yaw`` [deg]).

``read_log`` gives a ``ReferenceLog`` with every column as a float64 numpy
array (``log.x_anafi``, ``log['x_anafi']``), ``log.time_ns`` (int64) and
``log.t`` (s since the first sample). ``detect_garbage`` flags samples that
cannot be measurements (non-finite, 16-bit wrap such as z_anafi = 65280,
absurd magnitudes, time not increasing) per column, with the reason, so an
evaluator reports them instead of averaging them in. ``tracking_error``
computes the paper's e = |wp - p| (3-D and horizontal) per sample.
"""
import collections
import csv
import math

import numpy as np

STATE_NAMES = ('x', 'y', 'z', 'vx', 'vy', 'vz', 'roll', 'pitch', 'yaw')
SOURCES = ('sphinx', 'anafi')
WAYPOINT_COLUMNS = ('wp_x', 'wp_y', 'wp_z', 'wp_vx', 'wp_vy', 'wp_vz', 'wp_yaw')
COLUMNS = (('time',) + tuple('%s_sphinx' % n for n in STATE_NAMES)
           + tuple('%s_anafi' % n for n in STATE_NAMES) + WAYPOINT_COLUMNS)

# Plausibility limits per kind of column: |value| above is "absurd" (not a measurement).
POSITION_LIMIT = 10000.0       # m   (a 10 km flight is already far beyond an Anafi test)
VELOCITY_LIMIT = 100.0         # m/s (the Anafi flies < 20 m/s)
ANGLE_LIMIT = 2.0 * math.pi    # rad (roll, pitch, yaw; yaw may come unwrapped by one turn)
YAW_DEG_LIMIT = 720.0          # deg (wp_yaw)
WRAP_16 = 65536.0              # 2**16: an unsigned 16-bit wrap of a negative value v shows as v + 65536


def column_limit(name):
    """Plausibility limit of column ``name`` (|value| above it is garbage), None for ``time``."""
    if name == 'time':
        return None
    if name == 'wp_yaw':
        return YAW_DEG_LIMIT
    base = name.split('_')[0]
    if base in ('x', 'y', 'z'):
        return POSITION_LIMIT
    if base in ('vx', 'vy', 'vz'):
        return VELOCITY_LIMIT
    if base in ('roll', 'pitch', 'yaw'):
        return ANGLE_LIMIT
    return POSITION_LIMIT


class ReferenceLog(object):
    """Columns of one reference log as numpy arrays (see module doc).

    ``columns``: {name: float64 array}; ``time_ns``: int64 array; ``path``;
    ``parse_errors``: [(line number, reason)] of rows that could not be read
    (skipped, never silently: they are listed here).
    """

    def __init__(self, columns, time_ns, path=None, parse_errors=None, extra_columns=()):
        self.columns = columns
        self.time_ns = np.asarray(time_ns, dtype=np.int64)
        self.path = path
        self.parse_errors = list(parse_errors or [])
        self.extra_columns = tuple(extra_columns)
        n = len(self.time_ns)
        for name, values in columns.items():
            if len(values) != n:
                raise ValueError('column %s has %d samples, time has %d' % (name, len(values), n))
        self.time = self.time_ns.astype(np.float64) * 1e-9          # s, ROS time
        self.t = (self.time_ns - self.time_ns[0]).astype(np.float64) * 1e-9 if n else np.zeros(0)

    @property
    def name(self):
        """File name without directory and extension ('' when not read from a file)."""
        if not self.path:
            return ''
        base = str(self.path).replace('\\', '/').rsplit('/', 1)[-1]
        return base[:-4] if base.endswith('.csv') else base

    def __len__(self):
        return len(self.time_ns)

    def __getitem__(self, name):
        if name == 'time':
            return self.time_ns
        return self.columns[name]

    def __getattr__(self, name):
        columns = self.__dict__.get('columns')
        if columns is not None and name in columns:
            return columns[name]
        raise AttributeError(name)

    def state(self, source):
        """(N, 9) array x, y, z, vx, vy, vz, roll, pitch, yaw of ``source`` ('sphinx' or 'anafi')."""
        _check_source(source)
        return np.column_stack([self.columns['%s_%s' % (n, source)] for n in STATE_NAMES])

    def position(self, source):
        """(N, 3) position [m], ENU."""
        _check_source(source)
        return np.column_stack([self.columns['%s_%s' % (n, source)] for n in ('x', 'y', 'z')])

    def velocity(self, source):
        """(N, 3) velocity [m/s], ENU."""
        _check_source(source)
        return np.column_stack([self.columns['%s_%s' % (n, source)] for n in ('vx', 'vy', 'vz')])

    def attitude(self, source):
        """(N, 3) roll, pitch, yaw [rad]."""
        _check_source(source)
        return np.column_stack([self.columns['%s_%s' % (n, source)] for n in ('roll', 'pitch', 'yaw')])

    def waypoint(self):
        """(N, 7) waypoint x, y, z [m], vx, vy, vz [m/s], yaw [deg]."""
        return np.column_stack([self.columns[c] for c in WAYPOINT_COLUMNS])

    def select(self, mask):
        """A new ``ReferenceLog`` with only the samples where ``mask`` (bool array or index array) holds."""
        columns = collections.OrderedDict((k, v[mask]) for k, v in self.columns.items())
        return ReferenceLog(columns, self.time_ns[mask], path=self.path, parse_errors=self.parse_errors,
                            extra_columns=self.extra_columns)

    def as_dict(self):
        """{column: array} in ``COLUMNS`` order (time as int64 ns), e.g. for ``write_log``."""
        out = collections.OrderedDict()
        out['time'] = self.time_ns
        for name in COLUMNS[1:]:
            out[name] = self.columns[name]
        return out


def _check_source(source):
    if source not in SOURCES:
        raise ValueError("source must be one of %s, got %r" % (SOURCES, source))


def _parse_time(text):
    text = text.strip()
    try:
        return int(text)
    except ValueError:
        value = float(text)          # '1.7e18' style: accepted, but precision is that of a float
        if not math.isfinite(value):
            raise ValueError('non-finite time %r' % text)
        return int(round(value))


def read_log(path):
    """Read a reference-log CSV into a ``ReferenceLog``.

    The header must contain every name of ``COLUMNS`` (any order; extra
    columns are kept in ``columns`` too). Cells that are not numbers become
    NaN (``detect_garbage`` reports them); rows with the wrong number of
    fields or an unreadable time are skipped and listed in ``parse_errors``.
    Raises ValueError for a missing/incomplete header.
    """
    with open(path, newline='') as stream:
        reader = csv.reader(stream)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise ValueError('%s: empty file, expected a header with %s' % (path, ', '.join(COLUMNS)))
        missing = [c for c in COLUMNS if c not in header]
        if missing:
            raise ValueError('%s: header lacks columns %s' % (path, ', '.join(missing)))
        if len(set(header)) != len(header):
            raise ValueError('%s: duplicate column names in header' % path)
        index = dict((name, i) for i, name in enumerate(header))
        time_i = index['time']
        value_names = [h for h in header if h != 'time']
        times = []
        rows = []
        errors = []
        for line_no, row in enumerate(reader, start=2):
            if not row or all(not cell.strip() for cell in row):
                errors.append((line_no, 'blank line'))
                continue
            if len(row) != len(header):
                errors.append((line_no, '%d fields, expected %d' % (len(row), len(header))))
                continue
            try:
                t_ns = _parse_time(row[time_i])
            except ValueError:
                errors.append((line_no, 'unreadable time %r' % row[time_i]))
                continue
            values = []
            for name in value_names:
                cell = row[index[name]]
                try:
                    values.append(float(cell))
                except ValueError:
                    values.append(float('nan'))
            times.append(t_ns)
            rows.append(values)
    data = np.array(rows, dtype=np.float64).reshape(len(rows), len(value_names))
    columns = collections.OrderedDict()
    for j, name in enumerate(value_names):
        columns[name] = data[:, j].copy()
    extra = [h for h in header if h not in COLUMNS]
    return ReferenceLog(columns, np.array(times, dtype=np.int64), path=path, parse_errors=errors,
                        extra_columns=extra)


def as_logged(values):
    """``values`` as the reference logs store them: the shortest decimal repr of their IEEE half float, read
    back as a float (float64 array of the same shape; non-finite values kept). The logs' columns are all on
    this grid, which is coarse far from the origin: at 64-128 m a 0.0625 m float16 step, whose shortest repr
    moves it by up to another 0.025 m (81.375 is stored as "81.4"); at 128-256 m 0.125 m. Beyond the half
    float's range (65504) a value becomes inf, as a half float does. Independent of numpy's print options."""
    out = np.array(values, dtype=np.float64)
    flat = out.reshape(-1)
    with np.errstate(over='ignore'):
        for i in np.flatnonzero(np.isfinite(flat)):
            flat[i] = float(np.format_float_positional(np.float16(flat[i]), unique=True))
    return out


def _format_value(value, float16):
    value = float(value)
    if float16:
        return str(float(as_logged(value)))         # shortest repr of the half float, as the reference logs
    return repr(value)


def write_log(path, columns, float16=False):
    """Write ``columns`` ({name: sequence} or a ``ReferenceLog``) as a reference-log CSV.

    Header and column order are ``COLUMNS``; ``time`` is written as integer
    nanoseconds. Values are written exactly (shortest float repr) or, with
    ``float16=True``, as the shortest repr of their IEEE half float, which is
    how the paper's reference logs store every column. Raises ValueError when
    a column is missing or the lengths differ.
    """
    if isinstance(columns, ReferenceLog):
        columns = columns.as_dict()
    missing = [c for c in COLUMNS if c not in columns]
    if missing:
        raise ValueError('cannot write a reference log without columns %s' % ', '.join(missing))
    lengths = set(len(columns[c]) for c in COLUMNS)
    if len(lengths) != 1:
        raise ValueError('columns have different lengths: %s' % sorted(lengths))
    times = [int(t) for t in np.asarray(columns['time']).tolist()]
    value_columns = [np.asarray(columns[c], dtype=np.float64) for c in COLUMNS[1:]]
    with open(path, 'w', newline='') as stream:
        writer = csv.writer(stream, lineterminator='\n')
        writer.writerow(COLUMNS)
        for i, t_ns in enumerate(times):
            writer.writerow([str(t_ns)] + [_format_value(col[i], float16) for col in value_columns])


ColumnGarbage = collections.namedtuple('ColumnGarbage', ['column', 'count', 'reasons', 'mask'])
ColumnGarbage.__doc__ = ('Garbage in one column: number of bad samples, {reason: count}, '
                         'boolean mask (True = garbage).')


class GarbageReport(object):
    """Per-column garbage of one log (only columns with garbage appear in ``columns``)."""

    def __init__(self, n_samples, columns, name=''):
        self.n_samples = n_samples
        self.columns = columns           # OrderedDict column -> ColumnGarbage
        self.name = name

    def __bool__(self):
        return bool(self.columns)

    __nonzero__ = __bool__

    def mask(self, *names):
        """Boolean mask of samples that are garbage in any of ``names`` (all columns when none given)."""
        names = names or tuple(self.columns)
        out = np.zeros(self.n_samples, dtype=bool)
        for name in names:
            if name in self.columns:
                out |= self.columns[name].mask
        return out

    @property
    def n_bad(self):
        """Samples with garbage in any column."""
        return int(self.mask().sum())

    def summary(self):
        """Human-readable lines (empty list when clean): one per set of bad samples, the columns that are bad at
        exactly those samples for the same reasons named together (one NaN sample is one line, not one per
        column)."""
        groups = collections.OrderedDict()
        for name, info in self.columns.items():
            key = (np.asarray(info.mask, dtype=bool).tobytes(), tuple(info.reasons.items()))
            groups.setdefault(key, []).append(name)
        lines = []
        for names in groups.values():
            info = self.columns[names[0]]
            why = ', '.join('%s: %d' % (r, c) for r, c in info.reasons.items())
            lines.append('%s%s: %d of %d samples (%s)' % ((self.name + ' ') if self.name else '', ', '.join(names),
                                                         info.count, self.n_samples, why))
        return lines

    def without(self, rows, columns):
        """This report with the samples where ``rows`` (boolean mask) is True no longer garbage in ``columns``
        (they are reported elsewhere, e.g. ground truth missing); a column left without garbage is dropped.
        Only non-finite values are taken out (the reason of a missing value)."""
        rows = np.asarray(rows, dtype=bool)
        out = collections.OrderedDict()
        for name, info in self.columns.items():
            if name in columns and rows.any():
                mask = np.asarray(info.mask, dtype=bool) & ~rows
                removed = info.count - int(mask.sum())
                reasons = collections.OrderedDict(info.reasons)
                if removed:
                    reasons['non-finite'] = reasons.get('non-finite', 0) - removed
                    if reasons['non-finite'] <= 0:
                        del reasons['non-finite']
                if not mask.any():
                    continue
                info = ColumnGarbage(name, int(mask.sum()), reasons, mask)
            out[name] = info
        return GarbageReport(self.n_samples, out, name=self.name)


def detect_garbage(log):
    """``GarbageReport`` of ``log``: samples per column that cannot be measurements, and why.

    Reasons: 'non-finite' (NaN/inf or unreadable cell), '16-bit wrap' (a
    value >= 2**15 that becomes plausible after subtracting 2**16, e.g.
    z_anafi = 65280 = -256 + 65536), 'absurd magnitude' (beyond
    ``column_limit``), and for ``time`` 'time not increasing'.
    """
    found = collections.OrderedDict()
    n = len(log)
    t = log.time_ns
    if n > 1:
        bad = np.zeros(n, dtype=bool)
        bad[1:] = np.diff(t) <= 0
        if bad.any():
            found['time'] = ColumnGarbage('time', int(bad.sum()), {'time not increasing': int(bad.sum())}, bad)
    for name in COLUMNS[1:]:
        values = log.columns[name]
        limit = column_limit(name)
        finite = np.isfinite(values)
        reasons = collections.OrderedDict()
        mask = ~finite
        if mask.any():
            reasons['non-finite'] = int(mask.sum())
        with np.errstate(invalid='ignore'):
            big = finite & (np.abs(values) > limit)
            wrapped = finite & (values >= WRAP_16 / 2.0) & (np.abs(values - WRAP_16) <= limit)
        if wrapped.any():
            reasons['16-bit wrap'] = int(wrapped.sum())
        absurd = big & ~wrapped
        if absurd.any():
            reasons['absurd magnitude'] = int(absurd.sum())
        mask = mask | big | wrapped
        if mask.any():
            found[name] = ColumnGarbage(name, int(mask.sum()), reasons, mask)
    return GarbageReport(n, found, name=log.name)


ErrorStats = collections.namedtuple('ErrorStats', ['mean', 'max', 'std', 'n_valid', 'n_excluded'])
ErrorStats.__doc__ = 'mean, max, std [m] of an error series over its valid samples, and sample counts.'


def line_value(t, values, ok, at, degree=1):
    """A logged quantity at time ``at`` [s] from a least-squares line through (t, values)[ok]: the columns
    are stored as float16 (x of x_straight_5 is on a 0.125-0.25 m grid), a line through a second of samples
    recovers the value below that step. ``degree`` 2: a parabola instead (a curved path, e.g. a second of a
    circle, which a line cuts by up to r (1 - cos(w / 2))). NaN with fewer than ``degree + 1`` samples."""
    t = np.asarray(t, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    ok = np.asarray(ok, dtype=bool) & np.isfinite(values)
    if np.count_nonzero(ok) < int(degree) + 1:
        return float('nan')
    tt, vv = t[ok], values[ok]
    if np.ptp(tt) <= 0.0:
        return float(np.mean(vv))
    return float(np.polyval(np.polyfit(tt - tt[0], vv, int(degree)), at - tt[0]))


INITIAL_WINDOW = 1.0
"""s, the first part of a log through which a line gives its initial values (``line_value``: float16 steps)."""

VELOCITY_ERROR_AXES = ('x', 'y')
"""The axes of the velocity estimate's initial error that is fitted and replayed (the straight flights are
level: z shows none to fit)."""


def velocity_error(log, axis, lag=0.0):
    """(b, ok): the velocity estimate's error v_anafi - v_sphinx [m/s] on ``axis`` ('x', 'y', 'z') per
    sample, and where it is valid (finite, no garbage in either column). ``lag`` [s]: against the truth that
    long before (the estimate's own lag: on a turning path the velocity changes direction within it, which
    is no error of the estimate; NaN where the log does not reach back)."""
    garbage = detect_garbage(log)
    truth = np.asarray(log.columns['v%s_sphinx' % axis], dtype=np.float64)
    if lag:
        t = log.t
        # garbage of the truth as NaN first: the value between two samples is only as good as both
        truth = np.where(garbage.mask('v%s_sphinx' % axis), np.nan, truth)
        truth = np.where(t - lag >= t[0] - 1e-9, np.interp(t - lag, t, truth), np.nan)
    b = np.asarray(log.columns['v%s_anafi' % axis], dtype=np.float64) - truth
    return b, np.isfinite(b) & ~garbage.mask('v%s_anafi' % axis, 'v%s_sphinx' % axis)


VELOCITY_LAGS = tuple(np.round(np.arange(0.0, 0.2001, 0.005), 3))
"""s, the lags ``velocity_lag`` tries."""


def velocity_lag(log, axes=('x', 'y'), lags=VELOCITY_LAGS):
    """The lag [s] of the velocity estimate behind the truth over the whole log: the one of ``lags`` with the
    least mean square of ``velocity_error`` on ``axes`` (identified where the velocity turns: a circle; on a
    straight line every lag fits alike and the smallest wins)."""
    best = None
    for lag in lags:
        ms = []
        for axis in axes:
            b, ok = velocity_error(log, axis, lag)
            if np.any(ok):
                ms.append(float(np.mean(b[ok] ** 2)))
        if ms and (best is None or np.mean(ms) < best[0] - 1e-12):
            best = (float(np.mean(ms)), float(lag))
    return best[1] if best else 0.0


def initial_velocity_error(log, axis, window=INITIAL_WINDOW, at=0.0, lag=0.0):
    """``velocity_error`` (against the truth ``lag`` s before) on ``axis`` at log time t0 + ``at`` [s]:
    ``line_value`` through its first ``window`` s of valid samples (NaN when fewer than two). The
    straight-line logs start with such an error, which decays (docs/calibration.md)."""
    b, ok = velocity_error(log, axis, lag)
    t = log.t
    return line_value(t, b, ok & (t <= t[0] + float(window)), t[0] + float(at))


class TrackingError(object):
    """Per-sample tracking error of a log: ``e`` (3-D) and ``e_h`` (horizontal) [m].

    Samples excluded for garbage are NaN in ``e`` / ``e_h``; ``stats`` and
    ``stats_h`` summarise the valid ones (mean is the paper's Table-3 value).
    ``garbage`` is the log's ``GarbageReport`` (None when not checked).
    """

    def __init__(self, e, e_h, garbage, source):
        self.e = e
        self.e_h = e_h
        self.garbage = garbage
        self.source = source
        self.stats = error_stats(e)
        self.stats_h = error_stats(e_h)


def error_stats(e):
    """``ErrorStats`` of an error array (NaN = excluded sample); mean/max/std are NaN when nothing is valid."""
    e = np.asarray(e, dtype=np.float64)
    valid = np.isfinite(e)
    n_valid = int(valid.sum())
    if n_valid == 0:
        return ErrorStats(float('nan'), float('nan'), float('nan'), 0, int(e.size))
    v = e[valid]
    return ErrorStats(float(v.mean()), float(v.max()), float(v.std()), n_valid, int(e.size - n_valid))


def tracking_error(log, source='anafi', exclude_garbage=True):
    """The paper's tracking error e = |wp - p_source| per sample (3-D and horizontal), as ``TrackingError``.

    ``source`` 'anafi' (the estimate, as the paper measures) or 'sphinx'
    (ground truth). With ``exclude_garbage`` a sample is NaN in ``e`` when
    any of wp_x/y/z, x/y/z_source is garbage there, and NaN in ``e_h`` when
    any of the x/y columns is; otherwise every sample counts as it is.
    """
    _check_source(source)
    dx = log.columns['wp_x'] - log.columns['x_' + source]
    dy = log.columns['wp_y'] - log.columns['y_' + source]
    dz = log.columns['wp_z'] - log.columns['z_' + source]
    with np.errstate(over='ignore', invalid='ignore'):
        e_h = np.hypot(dx, dy)
        e = np.sqrt(dx * dx + dy * dy + dz * dz)
    garbage = None
    if exclude_garbage:
        garbage = detect_garbage(log)
        horizontal = ('wp_x', 'wp_y', 'x_' + source, 'y_' + source)
        bad_h = garbage.mask(*horizontal) | ~np.isfinite(e_h)
        bad = garbage.mask(*(horizontal + ('wp_z', 'z_' + source))) | ~np.isfinite(e)
        e = np.where(bad, np.nan, e)
        e_h = np.where(bad_h, np.nan, e_h)
    return TrackingError(e, e_h, garbage, source)


def horizontal_tracking_error(log, source='anafi', exclude_garbage=True):
    """Horizontal e_h = |wp_xy - p_xy| per sample [m] (NaN where excluded)."""
    return tracking_error(log, source, exclude_garbage).e_h
