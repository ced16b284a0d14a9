"""anafi_sim.sim.step_schedule: piecewise-constant command schedule."""
import pytest

from anafi_sim.sim.step_schedule import Segment, StepSchedule


def test_segments_in_order_and_end():
    s = StepSchedule((Segment(1.0, 'a', 0, 0, 0, 0), Segment(2.0, 'b', 1, 2, 3, 4)))
    assert s.duration == 3.0
    assert s.command(0.5) == (0, 0, 0, 0)
    assert s.command(1.0) == (1, 2, 3, 4)
    assert s.command(2.99) == (1, 2, 3, 4)
    assert s.command(3.0) is None
    assert s.command(-0.1) is None
    assert s.segment(1.5)[0] == 1


def test_bad_segments_refused():
    with pytest.raises(ValueError):
        StepSchedule(())
    with pytest.raises(ValueError):
        StepSchedule((Segment(0.0, 'x', 0, 0, 0, 0),))
