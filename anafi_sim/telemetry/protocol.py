"""Sphinx ground-truth telemetry: the keys and the text protocol of ``tlm-data-logger``.

Stage: telemetry (simulator side) -> interface. One line per value,
``KEY : NUMBER``; a sample is one value for each key. The drone's keys carry
a prefix (Sphinx names it ``omniscient_anafi.``), the gimbal keys do not.
See ``shared/interfaces/sphinx_telemetry.md``.

``TelemetrySample`` fields use SI units: positions [m] and velocities [m/s]
in the world ENU frame, attitude (roll, pitch, yaw) [rad], body-frame (FLU)
velocity, angular velocity [rad/s], acceleration [m/s^2] and angular
acceleration [rad/s^2], the simulation ``timestamp`` [s] and the gimbal
motor angles relative to the body [rad].

Stream identity: our simulator starts every sample with one extra line
``<prefix>streamId : N`` (``STREAM_ID_KEY``; N an integer that identifies the
simulator instance, see ``new_stream_id``), so an interface can refuse another
drone's stream. The real ``tlm-data-logger`` prints no such key: a stream
without it is read as before (``TelemetryParser.stream_id`` stays None).
"""
import collections
import os

DEFAULT_PREFIX = 'omniscient_anafi.'

# (key after the prefix, sample field); order = the order the stand-in prints.
DRONE_KEYS = (
    ('worldPosition.x', 'x'), ('worldPosition.y', 'y'), ('worldPosition.z', 'z'),
    ('worldLinearVelocity.x', 'vx'), ('worldLinearVelocity.y', 'vy'), ('worldLinearVelocity.z', 'vz'),
    ('worldAttitude.x', 'roll'), ('worldAttitude.y', 'pitch'), ('worldAttitude.z', 'yaw'),
    ('relativeLinearVelocity.x', 'body_vx'), ('relativeLinearVelocity.y', 'body_vy'),
    ('relativeLinearVelocity.z', 'body_vz'),
    ('relativeAngularVelocity.x', 'body_wx'), ('relativeAngularVelocity.y', 'body_wy'),
    ('relativeAngularVelocity.z', 'body_wz'),
    ('relativeLinearAcceleration.x', 'body_ax'), ('relativeLinearAcceleration.y', 'body_ay'),
    ('relativeLinearAcceleration.z', 'body_az'),
    ('relativeAngularAcceleration.x', 'body_alpha_x'), ('relativeAngularAcceleration.y', 'body_alpha_y'),
    ('relativeAngularAcceleration.z', 'body_alpha_z'),
    ('timestamp', 'timestamp'),
)
# Gimbal keys have no drone prefix.
GIMBAL_KEYS = (
    ('gimbal_roll_anafi.motor_angle', 'gimbal_roll'),
    ('gimbal_pitch_anafi.motor_angle', 'gimbal_pitch'),
)

#: key (after the prefix) of the stand-in's stream identity line, printed first in every sample
STREAM_ID_KEY = 'streamId'
#: stream ids are integers in [1, STREAM_ID_MAX] (exact in the float a reader parses)
STREAM_ID_MAX = 2 ** 31 - 1

FIELDS = tuple(f for _, f in DRONE_KEYS) + tuple(f for _, f in GIMBAL_KEYS)

TelemetrySample = collections.namedtuple('TelemetrySample', FIELDS)

#: field -> largest magnitude a real (or simulated) Anafi can show: a sample beyond it is malformed input,
#: never ground truth (positions [m] 100 km, speeds [m/s], angles [rad] (unwrapped yaw allowed), rates
#: [rad/s], accelerations [m/s^2, rad/s^2], timestamp [s] of simulation time, >= 0)
PHYSICAL_BOUNDS = dict(
    [(f, 1e5) for f in ('x', 'y', 'z')]
    + [(f, 1e3) for f in ('vx', 'vy', 'vz', 'body_vx', 'body_vy', 'body_vz')]
    + [(f, 1e4) for f in ('roll', 'pitch', 'yaw', 'gimbal_roll', 'gimbal_pitch')]
    + [(f, 1e3) for f in ('body_wx', 'body_wy', 'body_wz')]
    + [(f, 1e5) for f in ('body_ax', 'body_ay', 'body_az', 'body_alpha_x', 'body_alpha_y', 'body_alpha_z')]
    + [('timestamp', 1e10)])
_BOUNDS = tuple((field, PHYSICAL_BOUNDS[field]) for field in FIELDS)   # in the sample's order


def beyond_bounds(sample):
    """The first field of ``sample`` beyond ``PHYSICAL_BOUNDS`` (or a negative timestamp), None when none."""
    for (field, bound), value in zip(_BOUNDS, sample):
        if abs(value) > bound:
            return field
    return 'timestamp' if sample.timestamp < 0.0 else None


def key_map(prefix=DEFAULT_PREFIX):
    """Ordered {full key: sample field} for a drone named by ``prefix``."""
    keys = collections.OrderedDict((prefix + k, f) for k, f in DRONE_KEYS)
    keys.update(GIMBAL_KEYS)
    return keys


def new_stream_id(random_bytes=os.urandom):
    """A fresh stream id: a random integer in [1, STREAM_ID_MAX]."""
    return int.from_bytes(random_bytes(4), 'big') % STREAM_ID_MAX + 1


_TEMPLATES = {}


def _template(prefix, stream_id):
    """The ``%`` format string of one sample's lines, with the keys in, and the sample field of each ``%.9g``."""
    entry = _TEMPLATES.get((prefix, stream_id))
    if entry is None:
        keys = key_map(prefix)
        head = '' if stream_id is None else '%s%s : %d\n' % (prefix, STREAM_ID_KEY, stream_id)
        text = head.replace('%', '%%') + ''.join(key.replace('%', '%%') + ' : %.9g\n' for key in keys)
        index = dict((f, i) for i, f in enumerate(FIELDS))
        entry = (text, tuple(index[field] for field in keys.values()))
        if len(_TEMPLATES) < 1024:     # one per simulator; bounded whatever callers pass
            _TEMPLATES[(prefix, stream_id)] = entry
    return entry


def format_sample(sample, prefix=DEFAULT_PREFIX, stream_id=None):
    """The lines ``tlm-data-logger`` prints for one sample, as one string (ends with a newline); with
    ``stream_id`` the sample starts with the stand-in's ``<prefix>streamId : N`` line."""
    text, order = _template(prefix, stream_id)
    return text % tuple([sample[i] for i in order])


# --- Parsing (interface side) ------------------------------------------------

COUNTER_NAMES = ('lines', 'samples', 'blank', 'malformed', 'nonfinite', 'unknown_key', 'partial_samples')


class TelemetryParser(object):
    """Turns ``tlm-data-logger`` output, one line at a time, into ``TelemetrySample`` s.

    A line is read as ``KEY<ws>:<ws>NUMBER``: the value is what follows the
    last colon, the key is the last whitespace-separated word before it (so a
    decoration in front of the key is tolerated). Every other line is counted
    and ignored. A sample completes -- and is returned at once -- when every
    required field has received a fresh finite value since the last completed
    sample. A required key that repeats before completion means a sample was
    cut short: it is counted in ``partial_samples``, dropped, and a new sample
    starts with that key. Known keys outside ``required_fields`` only update
    their last value (0.0 until first seen) and never complete a sample.

    A ``<prefix>streamId : N`` line (the stand-in's stream identity) sets
    ``stream_id`` (an int, None until seen): the id of the samples that follow.

    Counters (``counters`` property, a dict): lines, samples, blank,
    malformed (no colon, value not a number, line cut short),
    nonfinite (NaN/inf: value ignored), unknown_key, partial_samples.
    """

    def __init__(self, prefix=DEFAULT_PREFIX, required_fields=FIELDS):
        required = set(required_fields)
        unknown = required.difference(FIELDS)
        if unknown:
            raise ValueError('unknown telemetry fields: %s' % ', '.join(sorted(unknown)))
        if not required:
            raise ValueError('required_fields must name at least one field')
        index = dict((f, i) for i, f in enumerate(FIELDS))
        # full key -> (field index, required?)
        self._keys = dict((key, (index[field], field in required))
                          for key, field in key_map(prefix).items())
        self._stream_id_key = prefix + STREAM_ID_KEY
        self.stream_id = None               # the stream's identity (stand-in only), None until seen
        self._n_required = len(required)
        self._last = [0.0] * len(FIELDS)   # last values (seeds optional fields)
        self._pending = {}                  # field index -> value of the sample being assembled
        self.prefix = prefix
        self.required_fields = tuple(f for f in FIELDS if f in required)
        self.lines = 0
        self.samples = 0
        self.blank = 0
        self.malformed = 0
        self.nonfinite = 0
        self.unknown_key = 0
        self.partial_samples = 0

    @property
    def counters(self):
        """Snapshot of the counters as a dict (names in ``COUNTER_NAMES``)."""
        return dict((name, getattr(self, name)) for name in COUNTER_NAMES)

    @property
    def errors(self):
        """Lines or samples lost to bad input: malformed + nonfinite + partial_samples."""
        return self.malformed + self.nonfinite + self.partial_samples

    def reset(self):
        """Forget the sample being assembled (e.g. the telemetry process restarted); counts it if non-empty."""
        if self._pending:
            self.partial_samples += 1
            self._pending = {}

    def feed_line(self, line, complete=True):
        """Parse one line (trailing newline optional); return a completed ``TelemetrySample`` or None.

        ``complete=False`` marks a line known to be cut short (e.g. the last
        bytes before the process died, without newline): counted as malformed.
        """
        self.lines += 1
        head, sep, value_text = line.rpartition(':')
        if not sep:
            if line.strip():
                self.malformed += 1
            else:
                self.blank += 1
            return None
        if not complete:
            self.malformed += 1
            return None
        key = head.strip()
        entry = self._keys.get(key)
        if entry is None and key.split()[-1:] == [self._stream_id_key]:
            try:
                value = float(value_text)
            except ValueError:
                value = float('nan')
            if not (value == value and 0 < value <= STREAM_ID_MAX and value == int(value)):
                self.malformed += 1
                return None
            self.stream_id = int(value)
            return None
        if entry is None:
            words = key.split()
            entry = self._keys.get(words[-1]) if words else None
            if entry is None:
                self.unknown_key += 1
                return None
        try:
            value = float(value_text)
        except ValueError:
            self.malformed += 1
            return None
        if '_' in value_text or not value_text.isascii():   # float() also takes 1_000 and non-ASCII digits
            self.malformed += 1
            return None
        if value - value != 0.0:  # NaN or +-inf
            self.nonfinite += 1
            return None
        idx, required = entry
        if not required:
            self._last[idx] = value
            return None
        pending = self._pending
        if idx in pending:
            self.partial_samples += 1
            pending = self._pending = {}
        pending[idx] = value
        if len(pending) < self._n_required:
            return None
        values = list(self._last)
        for i, v in pending.items():
            values[i] = v
        self._pending = {}
        self.samples += 1
        return TelemetrySample._make(values)
