"""Whether a running fleet keeps real time: the rule a fleet host reports on /diagnostics (pure, no ROS).

A fleet host (scripts/fleet_host.py) samples counters of its instances every diagnostics period: each
simulator's simulation time [s] and each ground-truth interface's samples published. ``RateWindow`` turns the
samples into rates over the last ``WINDOW`` s of wall time (a simulator's RTF = simulation time advanced / wall
time; the ground truth's rate in Hz), and ``real_time_status`` says whether the drones keep real time: a drone
is behind when its RTF is below ``MIN_RTF`` or its ground truth below ``MIN_RATE_FRACTION`` of the interface's
publish rate (the thresholds of benchmarks/fleet_report.HOLD: RTF >= 0.98, ground truth >= 97 of 100 Hz).
A counter is judged only once it advanced before the window began (a drone whose telemetry has not started yet
is not behind), and a counter that goes back (an instance rebuilt by a respawned host) starts a new window.
"""
import collections

#: a drone keeps real time while its simulator's RTF is at least this
MIN_RTF = 0.98
#: ... and its ground truth's rate at least this fraction of the interface's publish rate
MIN_RATE_FRACTION = 0.97
#: [s] of wall time the rates are measured over
WINDOW = 5.0


class RateWindow(object):
    """Counter samples (wall time [s], value) per key, kept over the last ``window`` s: the rate of each key over
    them. A key is rated once its samples span at least ``min_span`` x ``window`` and its value had advanced
    before the first of them."""

    def __init__(self, window=WINDOW, min_span=0.8):
        if not window > 0 or not 0 < min_span <= 1:
            raise ValueError('window must be > 0 and min_span in (0, 1], got %r, %r' % (window, min_span))
        self.window = float(window)
        self.min_span = float(min_span)
        self._samples = collections.defaultdict(collections.deque)
        self._started = {}     # key -> the value when it was first seen (or reset)

    def add(self, key, now, value):
        samples = self._samples[key]
        if samples and (value < samples[-1][1] or now <= samples[-1][0]):
            if value < samples[-1][1]:      # the counter went back: a new instance
                samples.clear()
                self._started.pop(key, None)
            else:
                return
        self._started.setdefault(key, value)
        samples.append((now, value))
        while len(samples) > 2 and now - samples[1][0] >= self.window:
            samples.popleft()

    def forget(self, key):
        self._samples.pop(key, None)
        self._started.pop(key, None)

    def rate(self, key):
        """Value per second over the window, None while not rated (too short, or not advancing before it)."""
        samples = self._samples.get(key)
        if not samples or len(samples) < 2:
            return None
        (t0, v0), (t1, v1) = samples[0], samples[-1]
        if t1 - t0 < self.min_span * self.window or v0 <= self._started.get(key, v0):
            return None
        return (v1 - v0) / (t1 - t0)


Status = collections.namedtuple('Status', 'behind message values')
Status.__doc__ = 'behind: True when a drone is behind real time; message: one line; values: (key, text) pairs.'


def real_time_status(rtf, truth_hz, expected_hz, min_rtf=MIN_RTF, min_fraction=MIN_RATE_FRACTION):
    """``rtf``: {drone: RTF}, ``truth_hz``: {drone: ground truth Hz}, ``expected_hz``: {drone: the interface's
    publish rate} (None values: not rated yet) -> Status. Behind: 'behind real time: RTF 0.93 (anafi3) / ground
    truth 89 Hz (anafi7); 2 of 20 drones', naming the worst drone of each figure."""
    rtf = dict((d, v) for d, v in rtf.items() if v is not None)
    truth = dict((d, v) for d, v in truth_hz.items() if v is not None and expected_hz.get(d))
    slow_rtf = sorted(d for d, v in rtf.items() if v < min_rtf)
    slow_truth = sorted(d for d, v in truth.items() if v < min_fraction * expected_hz[d])
    worst_rtf = min(rtf, key=lambda d: rtf[d]) if rtf else None
    worst_truth = min(truth, key=lambda d: truth[d] / expected_hz[d]) if truth else None
    drones = set(rtf) | set(truth)
    behind = sorted(set(slow_rtf) | set(slow_truth))
    values = [('drones rated', str(len(drones))), ('drones behind', str(len(behind))),
              ('behind', ', '.join(behind) if behind else 'none'),
              ('RTF min', '-' if worst_rtf is None else '%.3f (%s)' % (rtf[worst_rtf], worst_rtf)),
              ('ground truth min [Hz]',
               '-' if worst_truth is None else '%.1f (%s)' % (truth[worst_truth], worst_truth)),
              ('thresholds', 'RTF >= %g, ground truth >= %g x its rate, over %g s' % (min_rtf, min_fraction, WINDOW))]
    if behind:
        parts = []
        if slow_rtf:
            parts.append('RTF %.2f (%s)' % (rtf[worst_rtf], worst_rtf))
        if slow_truth:
            parts.append('ground truth %.0f Hz (%s)' % (truth[worst_truth], worst_truth))
        return Status(True, 'behind real time: %s; %d of %d drones' % (' / '.join(parts), len(behind), len(drones)),
                      values)
    if not drones:
        return Status(False, 'real time: not rated yet', values)
    figures = []
    if worst_rtf is not None:
        figures.append('RTF min %.2f' % rtf[worst_rtf])
    if worst_truth is not None:
        figures.append('ground truth min %.0f Hz' % truth[worst_truth])
    return Status(False, 'real time: %s (%d drones)' % (', '.join(figures), len(drones)), values)
