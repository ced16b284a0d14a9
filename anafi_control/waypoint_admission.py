"""Which received waypoints reach a controller: header stamp and frame checks (pure, no ROS).

Stage: waypoint -> **controller input** (before ``contract.InputGate``). A waypoint message carries a
header (``anafi_sim/Waypoint``: stamp, frame_id); ``WaypointAdmission.admit`` drops, and counts:

- ``stale``: stamped more than ``max_age`` s before the receipt time (e.g. a second, delayed stream);
- ``future``: stamped more than ``max_age`` s after the receipt time (a publisher on another clock);
- ``out_of_order``: stamped before the newest admitted waypoint (two streams interleaved, a replay);
- ``foreign_frame``: ``frame_id`` other than ``frame`` (the world frame the controllers work in, default
  ``world``; ``/world`` is the same). Such a waypoint is refused, not transformed: a publisher in another
  frame converts it to ``world`` (tf2 ``doTransform``) before publishing.

- ``other_source``: from another publisher than the waypoint source. With ``source`` given to ``admit`` (the
  glue passes the XML-RPC URI of the publisher the message's connection was made to, from the master's
  publisher list, never the header), the first publisher heard becomes the drone's one waypoint source;
  the others are refused and counted. Hand-over: ``release_source`` (the glue calls it when the source's
  publisher has left the topic: it unregistered or its connection closed), then the next publisher heard
  is the source; and a source silent for more than ``SOURCE_SILENCE`` s hands over to the next publisher heard
  (e.g. the experiment monitor's hold of the start, then the trajectory generator: a live 10 Hz stream is
  never displaced);
- ``unstamped``: a stamp of 0 from a source whose stream was stamped from the start.

A stamp of 0 (a publisher that does not stamp, such as the paper's own nodes) skips the time checks (only
from a source whose first waypoint was unstamped too, when sources are known) and an
empty ``frame_id`` is read as ``frame``. Dropped waypoints never reach the controller, so a stream of only
dropped waypoints ends in the input gate's stale-waypoint HOLD after ``waypoint_timeout``. The receipt
clock going back (a simulator restart under /use_sim_time) by more than ``max_age`` forgets the newest
stamp.
"""
import collections
import math

REASONS = ('stale', 'future', 'out_of_order', 'foreign_frame', 'other_source', 'unstamped')
TEXT = {'stale': 'stale stamp', 'future': 'stamp in the future', 'out_of_order': 'out of order',
        'foreign_frame': 'foreign frame', 'other_source': 'another publisher than the waypoint source',
        'unstamped': 'unstamped in a stamped stream'}
#: [s] a waypoint source silent for longer hands over to the next publisher heard (3 periods of a 10 Hz stream)
SOURCE_SILENCE = 0.3
DEFAULTS = {'waypoint_max_age': 1.0, 'waypoint_frame': 'world'}


class WaypointAdmission(object):
    """Stamp / frame checks of received waypoints (see the module doc). ``max_age`` [s] > 0."""

    def __init__(self, max_age=DEFAULTS['waypoint_max_age'], frame=DEFAULTS['waypoint_frame']):
        if isinstance(max_age, bool) or not isinstance(max_age, (int, float)) or not math.isfinite(max_age) \
                or max_age <= 0:
            raise ValueError('waypoint_max_age must be a finite number > 0 [s], got %r' % (max_age,))
        frame = str(frame).strip('/')
        if not frame:
            raise ValueError('waypoint_frame must name a frame, got %r' % (frame,))
        self.max_age = float(max_age)
        self.frame = frame
        self.newest = None           # stamp of the newest admitted waypoint [s]
        self.source = None           # the waypoint source (a publisher's URI), None until one is heard
        self.source_unstamped = None  # the source's first waypoint had stamp 0
        self.sources = 0             # sources taken (1 + hand-overs)
        self.source_heard = None     # receipt time of the source's newest admitted waypoint [s]
        self.last_receipt = None
        self.counters = collections.OrderedDict((r, 0) for r in REASONS)
        self.last_drop = ''          # text of the last drop
        self._reported = dict(self.counters)

    @property
    def dropped(self):
        return sum(self.counters.values())

    def release_source(self):
        """Forget the waypoint source (its publisher left the topic): the next publisher heard is the source."""
        if self.source is not None:
            self.source = None
            self.source_unstamped = None
            self.source_heard = None
            self.newest = None

    def admit(self, receipt, stamp, frame_id, source=None):
        """(True, '') when the waypoint received at ``receipt`` [s] with header ``stamp`` [s] and ``frame_id``
        from publisher ``source`` (None: not known, no source check) may go to the controller, else (False,
        reason text); drops are counted."""
        if self.last_receipt is not None and receipt < self.last_receipt - self.max_age:
            self.newest = None                    # the receipt clock jumped back: a new time line
        self.last_receipt = receipt
        frame = (frame_id or '').strip('/')
        if frame and frame != self.frame:
            return self._drop('foreign_frame', 'frame %r, not %r' % (frame_id, self.frame))
        if stamp and math.isfinite(stamp):
            age = receipt - stamp
            if age > self.max_age:
                return self._drop('stale', 'stamped %.2f s before its receipt (> %.2f s)' % (age, self.max_age))
            if -age > self.max_age:
                return self._drop('future', 'stamped %.2f s after its receipt (> %.2f s)' % (-age, self.max_age))
            if self.newest is not None and stamp < self.newest:
                return self._drop('out_of_order', 'stamped %.3f s before the newest waypoint' % (self.newest - stamp))
        stamped = bool(stamp) and math.isfinite(stamp)
        if source is not None:
            if self.source is None:
                self.source, self.source_unstamped = source, not stamped
                self.sources += 1
            elif source != self.source and self.source_heard is not None \
                    and receipt - self.source_heard > SOURCE_SILENCE:
                self.source, self.source_unstamped = source, not stamped     # the source fell silent: hand-over
                self.sources += 1
            elif source != self.source:
                return self._drop('other_source', '%s, the source is %s' % (str(source)[:120], self.source))
            if not stamped and not self.source_unstamped:
                return self._drop('unstamped', 'stamp 0 from %s, whose stream is stamped' % str(source)[:120])
        if stamped:
            self.newest = stamp
        if source is not None:
            self.source_heard = receipt
        return True, ''

    def _drop(self, reason, detail):
        self.counters[reason] += 1
        self.last_drop = '%s (%s)' % (TEXT[reason], detail)
        return False, self.last_drop

    def values(self):
        """Diagnostic values: the drop counters."""
        return [('dropped waypoints: %s' % TEXT[r], self.counters[r]) for r in REASONS] + [
            ('waypoint source', self.source or 'none yet'), ('waypoint sources taken', self.sources)]

    def news(self):
        """Text of the drops since the previous call ('' when none): for a WARN diagnostic."""
        new = dict((r, self.counters[r] - self._reported[r]) for r in REASONS)
        self._reported = dict(self.counters)
        parts = ['%d %s' % (n, TEXT[r]) for r, n in new.items() if n > 0]
        return ('dropped waypoints: %s; last: %s' % (', '.join(parts), self.last_drop)) if parts else ''
