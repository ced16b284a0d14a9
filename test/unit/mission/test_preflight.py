"""anafi_sim.mission.preflight: go only with a fresh state, a flying drone and the first waypoint in reach."""
import pytest

from anafi_sim.mission.preflight import PreflightCheck


def test_waits_for_each_condition_and_says_which():
    c = PreflightCheck((2.0, 0.0, 5.0), max_reach=5.0, state_timeout=0.5)
    ready, waiting = c.check(0.0)
    assert not ready and len(waiting) == 3
    assert waiting[0] == 'a state on drone/odom (none yet)' and waiting[1] == 'drone/state flying (now not heard)'
    c.on_state(1.0, (0.0, 0.0, 1.0))
    c.on_drone_state('landed')
    assert c.check(1.1) == (False, ['drone/state flying (now landed)'])
    c.on_drone_state('flying')
    assert c.check(1.1) == (True, [])
    assert c.check(1.6)[1] == ['a fresh state on drone/odom (last 0.6 s ago)']


def test_first_waypoint_out_of_reach():
    c = PreflightCheck((20.0, 0.0, 5.0), max_reach=5.0)
    c.on_drone_state('flying')
    c.on_state(0.0, (0.0, 0.0, 5.0))
    ready, waiting = c.check(0.1)
    assert not ready and waiting == ['the first waypoint (20.00, 0.00, 5.00) within 5.0 m (now 20.0 m away)']
    c.on_state(0.2, (16.0, 0.0, 5.0))
    assert c.check(0.3) == (True, [])


@pytest.mark.parametrize('bad', [(float('nan'), 0, 0), (0, 0), 'xyz', None])
def test_bad_states_are_counted(bad):
    c = PreflightCheck((0.0, 0.0, 1.0))
    assert not c.on_state(0.0, bad)
    assert c.bad_states == 1 and c.position is None


@pytest.mark.parametrize('kwargs', [dict(max_reach=0.0), dict(state_timeout=float('inf')),
                                    dict(first_waypoint=(0, 0)), dict(first_waypoint=(0, float('nan'), 0))])
def test_settings_are_checked(kwargs):
    args = dict(first_waypoint=(0.0, 0.0, 1.0))
    args.update(kwargs)
    with pytest.raises(ValueError):
        PreflightCheck(**args)


def test_the_waiting_line_names_the_state_source():
    c = PreflightCheck((0.0, 0.0, 1.0), state_from='/anafi/position_control/state_enu (bridge_state.py)')
    assert c.check(0.0)[1][0] == 'a state on drone/odom (none yet; from /anafi/position_control/state_enu ' \
                                 '(bridge_state.py))'
