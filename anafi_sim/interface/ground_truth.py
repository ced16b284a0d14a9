"""Ground-truth interface core: telemetry samples -> what the interface publishes (pure, no ROS).

Stage: telemetry -> **interface** -> (mirror | controllers).

``GroundTruthInterface`` decides which parsed ``TelemetrySample`` s are
published (decimation to ``publish_rate`` on the samples' simulation
timestamps, rejection of non-finite samples and duplicates, detection of a
simulator restart), tracks staleness on the receipt (wall) clock and sums the
health up for ``/diagnostics``. Its pieces, shared with the Gazebo mirror:
``StampDecimator`` (at most one sample per period of stamp time),
``RateWindow`` (events per second over a window) and ``NewCounts`` (which
counters grew since the previous health report).

The conversion helpers turn a sample into poses, all in SI units:
positions [m] in the world ENU frame, quaternions (x, y, z, w), angles [rad]
with R = Rz(yaw) Ry(pitch) Rx(roll) (see ``anafi_control.frames``), body
frame FLU. The ground truth's frames (drone ``anafi``; the estimate's REP-105 frames are the
simulator's, ``anafi_sim.names``): ``world`` ->
``anafi/stability_axes`` (drone position, heading only) ->
``anafi/base_link_gt`` (roll and pitch only) -> ``anafi/camera`` (fixed offset,
then the gimbal roll and pitch motor angles, which are relative to the body;
camera x axis = viewing direction, FLU like the body, positive gimbal pitch
looks down).
"""
import collections
import math


from anafi_control import frames
from anafi_sim.telemetry.protocol import beyond_bounds

OK, WARN, ERROR = 0, 1, 2  # same values as diagnostic_msgs/DiagnosticStatus levels

DEFAULT_CAMERA_OFFSET = (0.1, 0.0, 0.0)
# <drone>/camera (FLU: x along the view) -> <drone>/camera_optical (REP-103 optical: z along the view,
# x right, y down), the frame the Gazebo camera plugin stamps its images with: rpy (-pi/2, 0, -pi/2).
CAMERA_OPTICAL_ROTATION = (-0.5, 0.5, -0.5, 0.5)

Health = collections.namedtuple('Health', 'level message values')
"""level: OK/WARN/ERROR; message: one line; values: list of (key, value string)."""

Odometry = collections.namedtuple('Odometry', 'position orientation linear angular')
"""position (x, y, z) world [m]; orientation quaternion world->body; linear [m/s] and angular [rad/s]
velocity in the body frame (FLU), as nav_msgs/Odometry carries them (twist in child_frame_id)."""


def _finite_sample(sample):
    for v in sample:
        if v - v != 0.0:
            return False
    return True


class StampDecimator(object):
    """At most one sample per ``period`` [s] of its stamps, on a grid kept from the first accepted stamp; a
    sample up to ``early`` s before the grid point passes (jitter). A source slower than the period passes
    every sample (the grid re-anchors on it)."""

    def __init__(self, period):
        self.period = float(period)
        self._next_due = None

    def reset(self):
        """Forget the grid (the next sample passes and anchors it)."""
        self._next_due = None

    def accept(self, stamp, early=0.0):
        """True when the sample stamped ``stamp`` passes (then the grid moves one period)."""
        due = self._next_due
        if due is not None and stamp < due - early:
            return False
        due = stamp + self.period if due is None else due + self.period
        if due <= stamp:  # the source is slower than the period: re-anchor on it
            due = stamp + self.period
        self._next_due = due
        return True


class RateLimiter(object):
    """At most one sample per ``period`` [s] of its stamps on average, up to ``burst`` samples at once (a token
    bucket refilled at 1 / ``period`` per second of stamp time): samples around the rate pass whatever their
    jitter (receipt-time stamps of a busy process come late, early and in pairs); a faster source is thinned
    to the rate. The first sample (and the first after ``reset``) passes with a full bucket."""

    def __init__(self, period, burst=3.0):
        if not period > 0 or not burst >= 1:
            raise ValueError('period must be > 0 and burst >= 1, got %r, %r' % (period, burst))
        self.period = float(period)
        self.burst = float(burst)
        self._tokens = None
        self._last = None

    def reset(self):
        """Forget the history (the next sample passes with a full bucket)."""
        self._tokens = None

    def accept(self, stamp, early=0.0):
        """True when the sample stamped ``stamp`` passes; ``early`` [s]: a sample that far short of a whole
        token passes too (jitter)."""
        if self._tokens is None:
            self._tokens, self._last = self.burst, stamp
        else:
            self._tokens = min(self.burst, self._tokens + max(0.0, stamp - self._last) / self.period)
            self._last = max(self._last, stamp)
        if self._tokens >= 1.0 - early / self.period:
            self._tokens -= 1.0
            return True
        return False


class RateWindow(object):
    """Events per second over the last ``window`` seconds (event and query times on one clock)."""

    def __init__(self, window):
        self.window = float(window)
        self._times = collections.deque()

    def _trim(self, now):
        times = self._times
        while times and times[0] < now - self.window:
            times.popleft()

    def add(self, t):
        """An event at ``t`` [s]."""
        self._times.append(t)
        self._trim(t)

    def rate(self, now):
        """Events per second in (now - window, now]."""
        self._trim(now)
        return len(self._times) / self.window


class NewCounts(object):
    """Which counters grew since the previous call: for health messages ('3 new stale samples')."""

    def __init__(self):
        self._seen = {}

    def news(self, current):
        """['N new NAME', ...] of the counters in ``current`` ({name: count}) that grew since the previous call."""
        seen = self._seen
        self._seen = dict(current)
        return ['%d new %s' % (count - seen.get(name, 0), name) for name, count in current.items()
                if count > seen.get(name, 0)]


class GroundTruthInterface(object):
    """Accepts telemetry samples with their receipt time and returns the ones to publish.

    publish_rate [Hz]: at most this rate of simulation time is published; a
    source at or below it publishes every sample (``rate_tolerance`` is the
    fraction of a period a sample may come early and still be published, capped
    at half the source's sample interval). A faster source is decimated on a
    grid of ``1/publish_rate`` in simulation time, so the average rate is
    ``publish_rate`` even when it is not an integer fraction of the source rate.
    stale_timeout [s]: no accepted sample for longer (receipt clock) = stale.
    rate_window [s]: window of the published rate in ``health``.
    expected_stream_id: None (any stream, e.g. the real ``tlm-data-logger``, which prints no id) or the
    stream id of our simulator (``protocol.STREAM_ID_KEY``): a sample of a stream with another id, or
    with none, is refused (counted in ``foreign_samples``; health ERROR naming both ids).
    """

    def __init__(self, publish_rate=100.0, stale_timeout=0.5, rate_window=1.0, rate_tolerance=0.1,
                 low_rate_fraction=0.9):
        for name, value in (('publish_rate', publish_rate), ('stale_timeout', stale_timeout),
                            ('rate_window', rate_window)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError('%s must be a finite number > 0, got %r' % (name, value))
        if not 0.0 <= rate_tolerance < 1.0:
            raise ValueError('rate_tolerance must be in [0, 1), got %r' % (rate_tolerance,))
        self.publish_rate = float(publish_rate)
        self.period = 1.0 / self.publish_rate
        self.stale_timeout = float(stale_timeout)
        self.rate_window = float(rate_window)
        self._early = rate_tolerance * self.period
        self.low_rate_fraction = low_rate_fraction
        self.received = 0          # samples given to on_sample
        self.published = 0         # samples returned for publishing
        self.decimated = 0         # finite, in-order samples skipped by the rate limit
        self.rejected_nonfinite = 0
        self.rejected_beyond_bounds = 0
        self.last_beyond_bounds = ''
        self.duplicates = 0        # same timestamp as the previous sample
        self.sim_restarts = 0      # timestamp jumped back
        self.restarted = False     # the last on_sample call detected a simulator restart
        self.last_timestamp = None     # sim time of the last accepted sample [s]
        self.last_receipt = None       # receipt time of the last accepted sample [s]
        self._decimator = StampDecimator(self.period)
        self._published = RateWindow(self.rate_window)
        self._new = NewCounts()   # counters that grew since the previous health() call
        self._outage_noticed = None  # receipt-clock time the current outage was last reported
        self.process_starts = 0      # on_process_start calls
        self.awaiting_samples = False  # the telemetry process (re)started and no valid sample came since
        self.expected_stream_id = None  # set by the node from the simulator's parameter
        self.foreign_samples = 0       # samples refused: another stream id than expected (or none)
        self.last_foreign_id = None    # stream id of the last refused sample (None: the stream had none)
        self._last_foreign_receipt = None

    def reset(self):
        """Forget decimation state and the last timestamp (counters are kept)."""
        self.last_timestamp = None
        self._decimator.reset()

    def on_process_start(self):
        """The telemetry process was (re)started: after a restart, health is ERROR until a valid sample."""
        self.process_starts += 1
        if self.process_starts > 1:
            self.awaiting_samples = True

    def on_sample(self, sample, receipt_wall_time, stream_id=None):
        """Return ``sample`` if it is to be published now, else None. ``receipt_wall_time`` [s];
        ``stream_id``: the id the stream carried (``TelemetryParser.stream_id``), None if none."""
        self.received += 1
        self.restarted = False
        expected = self.expected_stream_id
        if expected is not None and stream_id != expected:
            self.foreign_samples += 1
            self.last_foreign_id = stream_id
            self._last_foreign_receipt = receipt_wall_time
            return None
        if not _finite_sample(sample):
            self.rejected_nonfinite += 1
            return None
        if beyond_bounds(sample) is not None:     # malformed input (a position of 1e308 m), never ground truth
            self.rejected_beyond_bounds += 1
            self.last_beyond_bounds = beyond_bounds(sample)
            return None
        self.awaiting_samples = False
        ts = sample.timestamp
        last = self.last_timestamp
        if last is not None:
            if ts < last:
                self.sim_restarts += 1
                self.restarted = True
                self._decimator.reset()
            elif ts == last:
                self.duplicates += 1
                return None
        self.last_timestamp = ts
        self.last_receipt = receipt_wall_time
        # a sample may be early by the tolerance, but by less than half a source period
        early = self._early if last is None or ts <= last else min(self._early, 0.5 * (ts - last))
        if not self._decimator.accept(ts, early):
            self.decimated += 1
            return None
        self.published += 1
        self._published.add(receipt_wall_time)
        return sample

    def sample_age(self, now_wall):
        """Seconds since the last accepted sample was received, or None if none yet."""
        if self.last_receipt is None:
            return None
        return now_wall - self.last_receipt

    def is_stale(self, now_wall):
        """True when no sample was accepted within ``stale_timeout`` (or none ever)."""
        age = self.sample_age(now_wall)
        return age is None or age > self.stale_timeout

    def outage_notice(self, now_wall, repeat=10.0):
        """What to tell the operator at ``now_wall`` about an outage: 'stale' when the input went stale (and
        again every ``repeat`` s while it stays stale), 'flowing' once when it flows again, else None."""
        if self.is_stale(now_wall):
            last = self._outage_noticed
            if last is None or not 0.0 <= now_wall - last < repeat:
                self._outage_noticed = now_wall
                return 'stale'
            return None
        if self._outage_noticed is not None:
            self._outage_noticed = None
            return 'flowing'
        return None

    def published_rate(self, now_wall):
        """Published samples per second over the last ``rate_window`` seconds of receipt time."""
        return self._published.rate(now_wall)

    def health(self, now_wall, parser_counters=None, process=None):
        """Diagnostics summary (``Health``) at ``now_wall``.

        parser_counters: dict of ``TelemetryParser.counters``; process: dict of
        ``ProcessSupervisor.snapshot()``. ERROR when stale, while the telemetry
        process is not running (dead, restarting) and after a restart until a
        valid sample arrives (``on_process_start``); WARN when the rate
        is below ``low_rate_fraction`` of ``publish_rate``, or since the previous
        call the process or the simulator restarted or samples were lost
        (partial samples, non-finite values); OK otherwise. Malformed, blank and
        unknown-key lines only show in the values (a decorated stream has them
        all the time). Remembers the counters between calls.
        """
        parser_counters = parser_counters or {}
        process = process or {}
        rate = self.published_rate(now_wall)
        age = self.sample_age(now_wall)
        values = [
            ('publish rate [Hz]', '%.1f' % rate),
            ('target rate [Hz]', '%.1f' % self.publish_rate),
            ('sample age [s]', 'none yet' if age is None else '%.3f' % age),
            ('last sim timestamp [s]', 'none yet' if self.last_timestamp is None else '%.3f' % self.last_timestamp),
            ('samples received', str(self.received)),
            ('samples published', str(self.published)),
            ('samples decimated', str(self.decimated)),
            ('rejected non-finite samples', str(self.rejected_nonfinite)),
            ('rejected samples beyond physical bounds', '%d%s' % (
                self.rejected_beyond_bounds, ' (last: %s)' % self.last_beyond_bounds if self.last_beyond_bounds else '')),
            ('duplicate samples', str(self.duplicates)),
            ('sim restarts', str(self.sim_restarts)),
            ('expected stream id', 'any' if self.expected_stream_id is None else str(self.expected_stream_id)),
            ('refused samples of another stream', str(self.foreign_samples)),
        ]
        for name in ('lines', 'blank', 'malformed', 'nonfinite', 'unknown_key', 'partial_samples'):
            if name in parser_counters:
                values.append(('parse ' + name.replace('_', ' '), str(parser_counters[name])))
        for name in ('running', 'pid', 'starts', 'restarts', 'exits', 'hangs', 'starved', 'spawn_failures',
                     'oversize_lines', 'stderr_bytes', 'stderr_oversize_lines', 'last_exit_code', 'last_stderr'):
            if name in process:
                values.append(('process ' + name.replace('_', ' '), str(process[name])))

        news = self._new.news(collections.OrderedDict([
            ('sim restarts', self.sim_restarts),
            ('process restarts', process.get('restarts', 0)),
            ('partial samples', parser_counters.get('partial_samples', 0)),
            ('non-finite values', parser_counters.get('nonfinite', 0) + self.rejected_nonfinite),
            ('samples beyond physical bounds', self.rejected_beyond_bounds),
        ]))

        down = bool(process) and not process.get('running', True)
        foreign_recent = self._last_foreign_receipt is not None and (
            self.last_receipt is None or self._last_foreign_receipt > self.last_receipt) and \
            now_wall - self._last_foreign_receipt <= max(self.stale_timeout, self.rate_window)
        if foreign_recent and (age is None or age > self.stale_timeout):
            level, message = ERROR, 'refusing the telemetry of another drone (%s, expected stream id %d; %d ' \
                'samples refused): nothing published' % (
                    'a stream without id' if self.last_foreign_id is None else 'stream id %d' % self.last_foreign_id,
                    self.expected_stream_id if self.expected_stream_id is not None else 0, self.foreign_samples)
        elif age is None:
            level, message = ERROR, 'no telemetry received yet'
        elif age > self.stale_timeout:
            level, message = ERROR, 'stale: no telemetry for %.1f s' % age
        elif down:
            level, message = ERROR, 'telemetry process not running (restarting)'
        elif self.awaiting_samples:
            level, message = ERROR, 'telemetry process restarted, no sample since'
        elif rate < self.low_rate_fraction * self.publish_rate:
            level, message = WARN, 'publishing %.1f Hz < %.1f Hz' % (rate, self.publish_rate)
        elif news:
            level, message = WARN, 'ok but ' + ', '.join(news)
        else:
            level, message = OK, 'publishing %.1f Hz' % rate
        if news and not message.startswith('ok but'):     # the restart note is never dropped
            message += ' (' + ', '.join(news) + ')'
        if down and 'not running' not in message:
            message += '; telemetry process not running'
        return Health(level, message, values)


# --- conversions (numbers in, numbers out) -------------------------------------

def odometry(sample):
    """``Odometry`` of a sample: world pose of the body and its body-frame (FLU) twist."""
    return Odometry(
        (sample.x, sample.y, sample.z),
        frames.euler_to_quaternion(sample.roll, sample.pitch, sample.yaw),
        (sample.body_vx, sample.body_vy, sample.body_vz),
        (sample.body_wx, sample.body_wy, sample.body_wz))


def stability_axes_pose(x, y, z, yaw):
    """world -> stability axes: translation (x, y, z) [m] and the heading-only quaternion."""
    return (x, y, z), frames.euler_to_quaternion(0.0, 0.0, yaw)


def base_link_in_stability_axes(roll, pitch):
    """stability axes -> base_link: zero translation and the roll/pitch-only quaternion."""
    return (0.0, 0.0, 0.0), frames.euler_to_quaternion(roll, pitch, 0.0)


def camera_in_base_link(gimbal_roll, gimbal_pitch, offset=DEFAULT_CAMERA_OFFSET):
    """base_link -> camera: translation ``offset`` (body frame [m]) and the gimbal rotation R(roll, pitch, 0)."""
    return (float(offset[0]), float(offset[1]), float(offset[2])), \
        frames.euler_to_quaternion(gimbal_roll, gimbal_pitch, 0.0)


def camera_pose(drone_position, roll, pitch, yaw, gimbal_roll, gimbal_pitch, offset=DEFAULT_CAMERA_OFFSET):
    """World pose of the camera: (position (x, y, z) [m], quaternion (x, y, z, w)).

    camera = base_link * translate(offset) * R(gimbal_roll, gimbal_pitch, 0);
    the gimbal angles [rad] are relative to the body, ``offset`` is in the body frame.
    """
    cr, sr = math.cos(roll), math.sin(roll)       # R = Rz(yaw) Ry(pitch) Rx(roll) (frames.rotation_matrix),
    cp, sp = math.cos(pitch), math.sin(pitch)     # in plain floats: 100 Hz per drone, numpy costs more here
    cy, sy = math.cos(yaw), math.sin(yaw)
    ox, oy, oz = (float(v) for v in offset)
    x, y, z = (float(v) for v in drone_position)
    position = (x + cy * cp * ox + (cy * sp * sr - sy * cr) * oy + (cy * sp * cr + sy * sr) * oz,
                y + sy * cp * ox + (sy * sp * sr + cy * cr) * oy + (sy * sp * cr - cy * sr) * oz,
                z - sp * ox + cp * sr * oy + cp * cr * oz)
    q_body = frames.euler_to_quaternion(roll, pitch, yaw)
    q = frames.quaternion_multiply(q_body, frames.euler_to_quaternion(gimbal_roll, gimbal_pitch, 0.0))
    return position, q
