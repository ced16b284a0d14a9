"""anafi_control.contract: the controller contract, run against every implementation (MpcTracking, PidTracking),
and the one input gate (order of the reasons, timeouts, clock jumps, counters) that they and the distributed PID
framework's relative-state node share."""
import math

import pytest

from anafi_control import contract
from anafi_control.contract import HOVER, HOVER_KEYS, MESSAGES, Controller, InputGate, health
from anafi_control.frames import euler_to_quaternion
from anafi_control.mpc_tracking import MpcTracking
from anafi_control.pid_framework import PidTracking

NAN = float('nan')
LEVEL = (0.0, 0.0, 0.0, 1.0)
WP = (3.0, 2.0, 5.0, 0.0, 0.0, 0.0, 30.0)
POS, VEL = (0.0, 0.0, 1.0), (0.0, 0.0, 0.0)

IMPLEMENTATIONS = [MpcTracking, PidTracking]


@pytest.fixture(params=IMPLEMENTATIONS, ids=lambda cls: cls.NAME)
def ctl(request):
    return request.param(state_timeout=0.5, waypoint_timeout=1.0)


def feed(c, t, state=True, waypoint=True, pos=POS, wp=WP, q=LEVEL):
    if state:
        c.on_state(t, pos, q, VEL)
    if waypoint:
        c.on_waypoint(t, wp)


def assert_hover(out, key):
    assert out.command == HOVER and not out.ok and out.key == key, out
    assert out.reason.startswith(MESSAGES[key])


def assert_runs(out):
    assert out.ok and out.key == 'ok', out
    assert len(out.command) == 4 and all(isinstance(v, float) and math.isfinite(v) for v in out.command)


def warm(c, t0=0.0):
    """Good inputs and two cycles 1/30 s apart (a PID loop computes from its second update on)."""
    for k in range(2):
        t = t0 + k / 30.0
        feed(c, t)
        assert_runs(c.cycle(t))
    assert c.last.command != HOVER
    return t0 + 1 / 30.0


# -- the contract, every implementation -------------------------------------------------------
def test_implements_the_contract(ctl):
    assert isinstance(ctl, Controller) and ctl.NAME and ctl.RATE > 0
    assert ctl.COMMAND_RATE is None or 0 < ctl.COMMAND_RATE <= ctl.RATE
    assert_hover(ctl.last, 'no_state')


def test_no_state_then_no_waypoint_then_runs(ctl):
    assert_hover(ctl.cycle(0.0), 'no_state')
    feed(ctl, 0.0, waypoint=False)
    assert_hover(ctl.cycle(0.03), 'no_waypoint')
    feed(ctl, 0.05)
    assert_runs(ctl.cycle(0.06))


def test_waypoint_without_state_is_no_state(ctl):
    feed(ctl, 0.0, state=False)
    assert_hover(ctl.cycle(0.0), 'no_state')


@pytest.mark.parametrize('bad', [dict(pos=(0.0, NAN, 1.0)), dict(q=(0.0, 0.0, 0.0, 0.0)),
                                 dict(q=(0.0, 0.0, 0.0, float('inf')))], ids=['nan_position', 'zero_q', 'inf_q'])
def test_bad_state_hovers_then_recovers(ctl, bad):
    t = warm(ctl)
    assert not ctl.on_state(t + 0.03, bad.get('pos', POS), bad.get('q', LEVEL), VEL)
    assert_hover(ctl.cycle(t + 0.04), 'bad_state')
    assert ctl.counters['rejected_states'] == 1
    feed(ctl, t + 0.07, waypoint=False)              # the held waypoint is still good
    assert_runs(ctl.cycle(t + 0.08))


@pytest.mark.parametrize('bad', [WP[:6] + (NAN,), WP[:3], None, 'abcdefg'], ids=['nan', 'short', 'none', 'text'])
def test_bad_waypoint_hovers_then_recovers(ctl, bad):
    t = warm(ctl)
    assert not ctl.on_waypoint(t + 0.03, bad)
    feed(ctl, t + 0.03, waypoint=False)
    assert_hover(ctl.cycle(t + 0.04), 'bad_waypoint')
    assert ctl.counters['rejected_waypoints'] == 1
    feed(ctl, t + 0.07)
    assert_runs(ctl.cycle(t + 0.08))


def test_stale_state_hovers_then_recovers(ctl):
    t = warm(ctl)
    ctl.on_waypoint(t + 0.6, WP)
    assert_hover(ctl.cycle(t + 0.6), 'stale_state')
    assert 'stale state (0.60 s old > 0.50 s)' in ctl.last.reason
    feed(ctl, t + 0.65, waypoint=False)
    assert_runs(ctl.cycle(t + 0.66))


def test_stale_waypoint_hovers_then_recovers(ctl):
    t = warm(ctl)
    feed(ctl, t + 1.2, waypoint=False)
    assert_hover(ctl.cycle(t + 1.2), 'stale_waypoint')
    feed(ctl, t + 1.25)
    assert_runs(ctl.cycle(t + 1.26))


def test_clock_jump_drops_the_inputs_until_both_arrive_again(ctl):
    warm(ctl, 100.0)
    feed(ctl, 3.0, waypoint=False)                    # simulation restarted: state first
    assert_hover(ctl.cycle(3.01), 'clock_jump')
    assert 'by 97.' in ctl.last.reason and ctl.counters['clock_jumps'] == 1
    feed(ctl, 3.04, state=False)
    assert_runs(ctl.cycle(3.05))


def test_clock_jump_seen_by_the_cycle(ctl):
    t = warm(ctl, 100.0)
    assert_hover(ctl.cycle(t - 0.6), 'clock_jump')
    assert_hover(ctl.cycle(t - 0.5), 'clock_jump')     # the held inputs are gone
    feed(ctl, t - 0.45)
    assert_runs(ctl.cycle(t - 0.44))


def test_input_stamped_just_after_the_cycle_time_is_fresh(ctl):
    # the node reads the clock, then a callback stamped a few ms later wins the lock first: no jump
    t = warm(ctl)
    feed(ctl, t + 0.04)
    assert_runs(ctl.cycle(t + 0.035))
    assert ctl.counters['clock_jumps'] == 0


def test_non_finite_cycle_time_hovers(ctl):
    t = warm(ctl)
    assert_hover(ctl.cycle(NAN), 'bad_state')
    feed(ctl, t + 0.03)
    assert_runs(ctl.cycle(t + 0.04))


def test_counters_add_up(ctl):
    ctl.cycle(0.0)
    t = warm(ctl, 1.0)
    ctl.cycle(t + 2.0)
    c = ctl.counters
    assert c['cycles'] == 4 and c['ok'] == 2 and c['hover'] == 2
    assert c['hover'] == sum(c[k] for k in HOVER_KEYS)
    assert c['no_state'] == 1 and c['stale_state'] == 1
    assert c['states'] == 2 and c['waypoints'] == 2


def test_commands_are_finite_along_a_moving_target(ctl):
    for k in range(60):
        t = k / 30.0
        yaw = math.radians(170.0 + 20.0 * math.sin(t))
        ctl.on_state(t, (0.1 * t, 0.0, 1.0), euler_to_quaternion(0.05, -0.02, yaw), (0.3, 0.1, 0.0))
        ctl.on_waypoint(t, (3.0 + t, 2.0, 5.0, 1.0, 0.0, 0.0, -175.0))
        out = ctl.cycle(t)
        assert_runs(out)
        assert ctl.last is out
    assert ctl.last.command != HOVER


# -- diagnostics ------------------------------------------------------------------------------
def test_health_levels():
    assert health('ok', 'ok') == (contract.LEVEL_OK, 'tracking', [])
    assert health('no_waypoint', MESSAGES['no_waypoint'])[:2] == (contract.LEVEL_OK,
                                                                  'hovering: no waypoint received yet')
    for key in ('no_state', 'bad_state', 'bad_waypoint', 'stale_state', 'stale_waypoint', 'clock_jump'):
        assert health(key, MESSAGES[key]).level == contract.LEVEL_WARN
    for key in ('solver_failed', 'bad_output'):
        assert health(key, MESSAGES[key]).level == contract.LEVEL_ERROR
    assert set(HOVER_KEYS) <= set(contract.COUNTER_NAMES)


def test_controller_health_reports_the_last_cycle_and_the_counters(ctl):
    ctl.cycle(0.0)
    h = ctl.health()
    assert h.level == contract.LEVEL_WARN and h.message == 'hovering: no state received yet'
    values = dict(h.values)
    assert values['last_reason'] == 'no state received yet' and values['cycles'] == 1 and values['no_state'] == 1
    warm(ctl, 1.0)
    assert ctl.health()[:2] == (contract.LEVEL_OK, 'tracking')


# -- the input gate alone (as the relative-state node uses it) ---------------------------------
def test_gate_reasons_in_order_then_runs():
    gate = InputGate(state_timeout=0.5, waypoint_timeout=1.0)
    assert gate.check(0.0) == (None, 'no_state', 'no state received yet')
    gate.on_state(0.1, (1, 2, 3), LEVEL, (0, 0, 0))
    assert gate.check(0.2) == (None, 'no_waypoint', 'no waypoint received yet')
    gate.on_waypoint(0.2, WP)
    inputs, key, _ = gate.check(0.3)
    assert key == 'ok'
    assert inputs.pos == (1, 2, 3) and inputs.vel == (0, 0, 0) and inputs.yaw == 0.0 and inputs.waypoint == WP
    for k in ('no_state', 'no_waypoint', 'ok'):
        gate.count_cycle(k)
    assert gate.counters['cycles'] == 3 and gate.counters['hover'] == 2


def test_gate_timeout_boundaries():
    gate = InputGate(state_timeout=0.5, waypoint_timeout=1.0)
    gate.on_state(0.0, (0, 0, 0), LEVEL, (0, 0, 0))
    gate.on_waypoint(0.0, WP)
    assert gate.check(0.5)[1] == 'ok'                # exactly the timeout is still fresh
    assert gate.check(0.51)[1] == 'stale_state'
    gate.on_state(0.9, (0, 0, 0), LEVEL, (0, 0, 0))
    assert gate.check(1.0)[1] == 'ok'
    assert gate.check(1.01)[1] == 'stale_waypoint'
    assert gate.fresh_waypoint(1.01) is None and gate.fresh_waypoint(1.0) == WP


def test_gate_state_problems_come_before_waypoint_problems():
    gate = InputGate()
    gate.on_waypoint(0.0, WP[:3])
    gate.on_state(0.0, (NAN, 0, 0), LEVEL, (0, 0, 0))
    assert gate.check(0.0)[1] == 'bad_state'


def test_gate_waypoint_timeout_zero_holds_a_single_waypoint():
    gate = InputGate(state_timeout=0.5, waypoint_timeout=0.0)
    gate.on_waypoint(0.0, WP)
    gate.on_state(100.0, (0, 0, 0), LEVEL, (0, 0, 0))
    assert gate.check(100.1)[1] == 'ok'


def test_gate_twist_frame():
    q = euler_to_quaternion(0.0, 0.0, math.pi / 2)
    child, world = InputGate(), InputGate(twist_frame='world')
    for gate in (child, world):
        gate.on_state(0.0, (0, 0, 0), q, (1.0, 0.0, 0.0))
        gate.on_waypoint(0.0, WP)
    assert child.check(0.0)[0].vel == pytest.approx((0.0, 1.0, 0.0), abs=1e-12)
    assert world.check(0.0)[0].vel == (1.0, 0.0, 0.0)
    with pytest.raises(ValueError):
        InputGate(twist_frame='body')


def test_gate_refuses_a_non_finite_sample_time():
    gate = InputGate()
    assert not gate.on_state(NAN, (0, 0, 0), LEVEL, (0, 0, 0))
    assert not gate.on_waypoint(float('inf'), WP)
    assert gate.check(0.0)[1] == 'bad_state' and gate.counters['rejected_states'] == 1
    assert gate.counters['rejected_waypoints'] == 1


def test_gate_calls_back_on_a_clock_jump():
    jumps = []
    gate = InputGate(on_clock_jump=lambda: jumps.append(1))
    gate.on_state(10.0, (0, 0, 0), LEVEL, (0, 0, 0))
    gate.on_waypoint(10.0, WP)
    gate.on_waypoint(9.6, WP)                          # 0.4 s back: within the tolerance
    assert not jumps and gate.check(10.0)[1] == 'ok'
    gate.on_waypoint(1.0, WP)
    assert jumps == [1] and gate.check(1.0)[1] == 'clock_jump' and gate.counters['clock_jumps'] == 1


@pytest.mark.parametrize('value', [0.0, -1.0, NAN, float('inf'), True, '1'])
def test_bad_timeouts_are_refused(value):
    with pytest.raises(ValueError):
        InputGate(state_timeout=value)
    for cls in IMPLEMENTATIONS:
        with pytest.raises(ValueError):
            cls(state_timeout=value)


def test_waypoint_timeout_zero_allowed_only_where_it_means_never():
    assert contract.check_timeout('w', 0, allow_zero=True) == 0.0
    assert InputGate(waypoint_timeout=0.0).waypoint_timeout == 0.0
    with pytest.raises(ValueError):
        InputGate(waypoint_timeout=-0.1)
