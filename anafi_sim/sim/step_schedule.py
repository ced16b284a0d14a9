"""A scripted piloting-command schedule (used by the foundation demo).

Stage: (demo) -> piloting command. ``StepSchedule`` maps time since start [s]
to a PilotingCommand tuple (roll [deg, + = right], pitch [deg, + = forward],
yaw rate [deg/s, + = counter-clockwise], gaz [m/s, + = up]).
"""
import collections

Segment = collections.namedtuple('Segment', 'duration label roll pitch yaw_rate gaz')

DEFAULT_SEGMENTS = (
    Segment(3.0, 'hover', 0.0, 0.0, 0.0, 0.0),
    Segment(2.0, 'pitch step 10 deg (forward)', 0.0, 10.0, 0.0, 0.0),
    Segment(3.0, 'hover', 0.0, 0.0, 0.0, 0.0),
    Segment(2.0, 'roll step -10 deg (left)', -10.0, 0.0, 0.0, 0.0),
    Segment(3.0, 'hover', 0.0, 0.0, 0.0, 0.0),
    Segment(2.0, 'climb 1 m/s', 0.0, 0.0, 0.0, 1.0),
    Segment(2.0, 'yaw rate 45 deg/s (counter-clockwise)', 0.0, 0.0, 45.0, 0.0),
    Segment(2.0, 'hover', 0.0, 0.0, 0.0, 0.0),
)


class StepSchedule(object):
    """Piecewise-constant command schedule; ``command(t)`` is None after the end."""

    def __init__(self, segments=DEFAULT_SEGMENTS):
        if not segments or any(s.duration <= 0 for s in segments):
            raise ValueError('segments must be non-empty with positive durations')
        self.segments = tuple(segments)
        self.duration = sum(s.duration for s in self.segments)

    def segment(self, t):
        """(index, Segment) active at time ``t`` [s], or (None, None) outside the schedule."""
        if t < 0.0:
            return None, None
        end = 0.0
        for i, s in enumerate(self.segments):
            end += s.duration
            if t < end:
                return i, s
        return None, None

    def command(self, t):
        _, s = self.segment(t)
        if s is None:
            return None
        return (s.roll, s.pitch, s.yaw_rate, s.gaz)
