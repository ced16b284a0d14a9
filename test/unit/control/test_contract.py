"""anafi_control.contract: the controller contract, run against every implementation (MpcTracking, PidTracking),
and the one input gate (order of the reasons, timeouts, clock jumps, counters) that they and the distributed PID
framework's relative-state node share."""
import math

import pytest

from anafi_control import contract
from anafi_control.contract import (HOLD, HOLD_KEYS, HOVER, HOVER_KEYS, MESSAGES, SILENT, Controller, Envelope,
                                    InputGate, failsafe, health)
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


def assert_finite_command(command):
    assert len(command) == 4 and all(isinstance(v, float) and math.isfinite(v) for v in command), command


def assert_hover(out, key, warming=False):
    """A cycle that does not track, with its failsafe: SILENT = no command; HOLD = a finite command of the
    controller's own loop (None allowed on the first cycle of a hold: a PID loop warms up)."""
    assert not out.ok and out.key == key, out
    assert out.reason.startswith(MESSAGES[key])
    if failsafe(key) == SILENT:
        assert out.command is None, out
    elif not (warming and out.command is None):
        assert_finite_command(out.command)


def assert_runs(out, warming=False):
    assert out.ok and out.key == 'ok', out
    if not (warming and out.command is None):
        assert_finite_command(out.command)


def warm(c, t0=0.0):
    """Good inputs and two cycles 1/30 s apart (a PID loop computes from its second update on)."""
    for k in range(2):
        t = t0 + k / 30.0
        feed(c, t)
        assert_runs(c.cycle(t), warming=(k == 0))
    assert c.last.command is not None
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
    assert_runs(ctl.cycle(0.06), warming=True)


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
    assert_runs(ctl.cycle(t + 0.08), warming=True)


@pytest.mark.parametrize('bad', [WP[:6] + (NAN,), WP[:3], None, 'abcdefg'], ids=['nan', 'short', 'none', 'text'])
def test_bad_waypoint_hovers_then_recovers(ctl, bad):
    t = warm(ctl)
    assert not ctl.on_waypoint(t + 0.03, bad)
    feed(ctl, t + 0.03, waypoint=False)
    assert_hover(ctl.cycle(t + 0.04), 'bad_waypoint', warming=True)
    assert ctl.counters['rejected_waypoints'] == 1
    feed(ctl, t + 0.07, waypoint=False)
    assert_hover(ctl.cycle(t + 0.08), 'bad_waypoint')     # holding: the own loop's command
    feed(ctl, t + 0.1)
    assert_runs(ctl.cycle(t + 0.11), warming=True)


def test_stale_state_hovers_then_recovers(ctl):
    t = warm(ctl)
    ctl.on_waypoint(t + 0.6, WP)
    assert_hover(ctl.cycle(t + 0.6), 'stale_state')
    assert 'stale state (0.60 s old > 0.50 s)' in ctl.last.reason
    feed(ctl, t + 0.65, waypoint=False)
    assert_runs(ctl.cycle(t + 0.66), warming=True)


def test_stale_waypoint_hovers_then_recovers(ctl):
    t = warm(ctl)
    feed(ctl, t + 1.2, waypoint=False)
    assert_hover(ctl.cycle(t + 1.2), 'stale_waypoint', warming=True)
    feed(ctl, t + 1.25)
    assert_runs(ctl.cycle(t + 1.26), warming=True)


def test_clock_jump_drops_the_inputs_until_both_arrive_again(ctl):
    warm(ctl, 100.0)
    feed(ctl, 3.0, waypoint=False)                    # simulation restarted: state first
    assert_hover(ctl.cycle(3.01), 'clock_jump')
    assert 'by 97.' in ctl.last.reason and ctl.counters['clock_jumps'] == 1
    feed(ctl, 3.04, state=False)
    assert_runs(ctl.cycle(3.05), warming=True)


def test_clock_jump_seen_by_the_cycle(ctl):
    t = warm(ctl, 100.0)
    assert_hover(ctl.cycle(t - 0.6), 'clock_jump')
    assert_hover(ctl.cycle(t - 0.5), 'clock_jump')     # the held inputs are gone
    feed(ctl, t - 0.45)
    assert_runs(ctl.cycle(t - 0.44), warming=True)


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
    assert_runs(ctl.cycle(t + 0.04), warming=True)


def test_counters_add_up(ctl):
    ctl.cycle(0.0)
    t = warm(ctl, 1.0)
    ctl.cycle(t + 2.0)
    c = ctl.counters
    assert c['cycles'] == 4 and c['ok'] == 2 and c['hover'] == 2
    assert c['hover'] == sum(c[k] for k in HOVER_KEYS) == c['hold'] + c['silent']
    assert c['no_state'] == 1 and c['stale_state'] == 1 and c['silent'] == 2
    assert c['states'] == 2 and c['waypoints'] == 2


def test_commands_are_finite_along_a_moving_target(ctl):
    for k in range(60):
        t = k / 30.0
        yaw = math.radians(170.0 + 20.0 * math.sin(t))
        ctl.on_state(t, (0.1 * t, 0.0, 1.0), euler_to_quaternion(0.05, -0.02, yaw), (0.3, 0.1, 0.0))
        ctl.on_waypoint(t, (3.0 + t, 2.0, 5.0, 1.0, 0.0, 0.0, -175.0))
        out = ctl.cycle(t)
        # (the MPC's world-axis acceleration limit may ask more than the tilt limit on a body axis: 'limiting')
        assert out.ok and out.key in contract.TRACKING, out
        if out.command is not None:
            assert_finite_command(out.command)
            assert max(abs(out.command[0]), abs(out.command[1])) <= ctl.gate.envelope.max_command_tilt_deg
        assert ctl.last is out
    assert ctl.last.command is not None


# -- diagnostics ------------------------------------------------------------------------------
def test_health_levels():
    assert health('ok', 'ok') == (contract.LEVEL_OK, 'tracking', [])
    assert health('no_waypoint', MESSAGES['no_waypoint'])[:2] == (
        contract.LEVEL_OK, 'no command, firmware hover brake: no waypoint received yet')
    for key in ('no_state', 'bad_state', 'bad_waypoint', 'stale_state', 'stale_waypoint', 'clock_jump'):
        assert health(key, MESSAGES[key]).level == contract.LEVEL_WARN
    assert health('bad_waypoint', 'x').message == 'holding position: x'
    assert health('stale_state', 'y').message == 'no command, firmware hover brake: y'
    assert health('limiting', 'z')[:2] == (contract.LEVEL_WARN, 'limiting: z')
    for key in ('solver_failed', 'bad_output'):
        assert health(key, MESSAGES[key]).level == contract.LEVEL_ERROR
    assert set(HOVER_KEYS) <= set(contract.COUNTER_NAMES)


def test_controller_health_reports_the_last_cycle_and_the_counters(ctl):
    ctl.cycle(0.0)
    h = ctl.health()
    assert h.level == contract.LEVEL_WARN and h.message == 'no command, firmware hover brake: no state received yet'
    values = dict(h.values)
    assert values['last_reason'] == 'no state received yet' and values['cycles'] == 1 and values['no_state'] == 1
    warm(ctl, 1.0)
    assert ctl.health()[:2] == (contract.LEVEL_OK, 'tracking')


# -- the input gate alone (as the relative-state node uses it) ---------------------------------
def test_gate_reasons_in_order_then_runs():
    gate = InputGate(state_timeout=0.5, waypoint_timeout=1.0)
    assert gate.check(0.0) == (None, 'no_state', 'no state received yet')
    gate.on_state(0.1, (1, 2, 3), LEVEL, (0, 0, 0))
    assert gate.check(0.2) == (None, 'no_waypoint', 'no waypoint received yet')       # silent: not engaged yet
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


# -- failsafes: hold the position (waypoint faults), silent (state faults) ------------------------
def test_failsafe_of_every_key():
    assert failsafe('ok') is None and failsafe('limiting') is None
    assert set(HOLD_KEYS) == {'bad_waypoint', 'stale_waypoint'}
    for key in HOVER_KEYS:
        assert failsafe(key) == (HOLD if key in HOLD_KEYS else SILENT)
    assert failsafe('no_waypoint') == SILENT          # not engaged yet: the firmware hovers by itself


def hold_cycles(ctl, t, n=3, key='bad_waypoint'):
    outs = []
    for k in range(n):
        feed(ctl, t + k / 30.0, waypoint=False)
        outs.append(ctl.cycle(t + k / 30.0))
        assert_hover(outs[-1], key, warming=(k == 0))
    return outs


def test_a_bad_waypoint_holds_the_position_where_the_hold_began(ctl):
    t = warm(ctl)
    ctl.on_waypoint(t + 0.03, WP[:6] + (NAN,))
    outs = hold_cycles(ctl, t + 0.04)
    assert ctl.gate.hold == (POS[0], POS[1], POS[2], 0.0, 0.0, 0.0, 0.0)     # drone at POS, heading 0 deg
    assert ctl.counters['holds'] == 1 and ctl.counters['hold'] == 3
    # at the hold point, at rest, level: the hold command is (close to) nothing to do -- not towards WP
    roll, pitch, _, gaz = outs[-1].command
    assert abs(roll) < 1.0 and abs(pitch) < 1.0 and abs(gaz) < 0.2
    assert ctl.health().message.startswith('holding position: non-finite waypoint')


def test_hold_brakes_a_moving_drone_and_pulls_it_back(ctl):
    t = warm(ctl)
    ctl.on_waypoint(t + 0.03, (NAN,) * 7)
    for k in range(3):                 # flying +x at 5 m/s, 2 m past the hold point (captured at x = 0)
        tk = t + 0.04 + k / 30.0
        ctl.on_state(tk, (0.0 if k == 0 else 2.0, 0.0, 1.0), LEVEL, (5.0, 0.0, 0.0))
        out = ctl.cycle(tk)
    pitch = out.command[1]
    assert pitch < -5.0, out            # nose up: braking against +x


def test_state_faults_are_silent_no_command(ctl):
    t = warm(ctl)
    assert not ctl.on_state(t + 0.03, (NAN, 0.0, 1.0), LEVEL, VEL)
    out = ctl.cycle(t + 0.04)
    assert out.command is None and ctl.counters['silent'] == 1
    assert ctl.health().message.startswith('no command, firmware hover brake: non-finite state')


def test_hold_recaptures_after_tracking_again(ctl):
    t = warm(ctl)
    ctl.on_waypoint(t + 0.03, (NAN,) * 7)
    hold_cycles(ctl, t + 0.04)
    t2 = t + 0.2
    feed(ctl, t2, pos=(1.0, 1.0, 2.0))
    ctl.cycle(t2)
    assert ctl.gate.hold is None and ctl.mode == 'ok'
    ctl.on_waypoint(t2 + 0.03, (NAN,) * 7)
    ctl.on_state(t2 + 0.04, (1.0, 1.0, 2.0), LEVEL, VEL)
    ctl.cycle(t2 + 0.04)
    assert ctl.gate.hold[:3] == (1.0, 1.0, 2.0) and ctl.counters['holds'] == 2


# -- the flight envelope: geofence, reach, speeds (anafi_control.envelope) ------------------------
_K = 50.0 / math.hypot(247.0, 4.0)      # the target's fence: 250 m less the 3 m margin


@pytest.mark.parametrize('wp, limit, target', [
    ((300.0, 0.0, 5.0, 0, 0, 0, 0), 'geofence',                              # 300 m from the start: on the fence,
     (247.0 * _K, 0.0, 1.0 + 4.0 * _K)),                                    # then 50 m from the drone toward it
    ((3.0, 2.0, 60.0, 0, 0, 0, 0), 'geofence', (3.0, 2.0, 50.0)),          # above the altitude band: on the ceiling
    ((3.0, 2.0, 0.1, 0, 0, 0, 0), 'geofence', (3.0, 2.0, 0.5)),            # below it: on the floor
    ((60.0, 0.0, 1.0, 0, 0, 0, 0), 'reach', (50.0, 0.0, 1.0)),             # 60 m from the drone: 50 m toward it
    ((3.0, 2.0, 5.0, 1e6, 0, 0, 0), 'speed', (3.0, 2.0, 5.0)),             # the reference speed
    ((3.0, 2.0, 5.0, 0, 0, -1e300, 0), 'vertical_speed', (3.0, 2.0, 5.0)),
])
def test_waypoints_beyond_the_envelope_are_limited_and_flown(ctl, wp, limit, target):
    t = warm(ctl)
    assert ctl.on_waypoint(t + 0.03, wp)
    ctl.on_state(t + 0.04, POS, LEVEL, VEL)
    out = ctl.cycle(t + 0.04)
    assert out.ok and out.key == 'limiting' and ctl.mode == 'ok', out
    assert_finite_command(out.command)
    assert ctl.counters['limited_%s' % limit] == 1 and ctl.counters['limiting'] == 1
    assert ctl.counters['ok'] == 3 and ctl.counters['hover'] == 0 and ctl.counters['rejected_waypoints'] == 0
    inputs = ctl.gate.check(t + 0.05)[0]
    assert inputs.waypoint[:3] == pytest.approx(target)
    assert abs(inputs.waypoint[3]) <= 10.0 and abs(inputs.waypoint[5]) <= 2.0
    h = ctl.health()
    assert h.level == contract.LEVEL_WARN and h.message.startswith('limiting: ') and 'tracking' not in h.message
    feed(ctl, t + 0.1)                  # a waypoint inside the envelope again: tracking
    assert_runs(ctl.cycle(t + 0.1))
    assert ctl.health().message == 'tracking'


def test_geofence_centre_is_the_first_state_and_the_envelope_is_configurable():
    envelope = Envelope(geofence_radius=10.0, geofence_margin=0.0, min_altitude=1.0, max_altitude=20.0,
                        max_waypoint_jump=100.0)
    gate = InputGate(limits=envelope)
    gate.on_state(0.0, (50.0, 50.0, 5.0), LEVEL, (0, 0, 0))
    gate.on_state(0.1, (50.0, 50.0, 5.0), LEVEL, (0, 0, 0))
    assert gate.centre == (50.0, 50.0)
    assert gate.on_waypoint(0.1, (55.0, 55.0, 5.0, 0, 0, 0, 0))
    assert gate.check(0.1)[1] == 'ok'
    assert gate.on_waypoint(0.2, (0.0, 50.0, 5.0, 0, 0, 0, 0))
    inputs, key, reason = gate.check(0.2)
    assert key == 'limiting' and 'geofence' in reason and inputs.waypoint[:3] == (40.0, 50.0, 5.0)
    assert gate.counters['limited_geofence'] == 1


def test_the_hold_point_is_moved_into_the_fence():
    gate = InputGate(limits=Envelope(geofence_radius=10.0, max_waypoint_jump=100.0))
    gate.on_state(0.0, (0.0, 0.0, 5.0), LEVEL, (0, 0, 0))
    gate.on_state(0.1, (30.0, 0.0, 5.0), LEVEL, (0, 0, 0))      # the drone overshot the fence
    gate.on_waypoint(0.1, (NAN,) * 7)
    inputs, key, _ = gate.check(0.1)
    assert key == 'bad_waypoint' and inputs.waypoint[:3] == (7.0, 0.0, 5.0)      # 10 m less the margin


def test_no_reach_without_a_state_but_the_altitude_band_applies():
    gate = InputGate()
    assert gate.on_waypoint(0.0, (100.0, 0.0, 5.0, 0, 0, 0, 0))
    assert gate.on_waypoint(0.0, (0.0, 0.0, -1.0, 0, 0, 0, 0))
    assert gate.envelope.limit_waypoint((100.0, 0.0, 5.0, 0, 0, 0, 0), None, None)[1] == []
    assert gate.envelope.limit_waypoint((0.0, 0.0, -1.0, 0, 0, 0, 0), None, None)[0][2] == 0.5


@pytest.mark.parametrize('kw', [dict(geofence_radius=0.0), dict(max_waypoint_jump=-1.0), dict(min_altitude=NAN),
                                dict(min_altitude=10.0, max_altitude=5.0), dict(max_altitude=True),
                                dict(geofence_radius='1'), dict(max_reference_speed=0.0),
                                dict(max_command_tilt_deg=90.0), dict(geofence_margin=-1.0),
                                dict(geofence_margin=300.0), dict(unknown=1.0)])
def test_bad_envelopes_are_refused(kw):
    with pytest.raises(ValueError):
        Envelope(**kw)
    with pytest.raises(ValueError):
        InputGate(limits='x')


def _controllers(state_timeout=None, waypoint_timeout=None):
    """The three controllers built with the given timeouts (None = their defaults)."""
    from anafi_control.preview_mpc import PreviewMpc
    kw = dict((k, v) for k, v in (('state_timeout', state_timeout), ('waypoint_timeout', waypoint_timeout))
              if v is not None)
    return (MpcTracking(**kw), PidTracking(**kw), PreviewMpc(_prediction_model(), kw))


def _prediction_model():
    from anafi_control.preview_mpc import PredictionModel
    return PredictionModel(9.81, 0.18, 0.12, 0.16, 0.2, 0.02, 0.02, 0.2, 0.26, 0.05, 30.64, 2.0, 180.0,
                           0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def test_every_controller_has_the_contract_timeouts_and_rule():
    """One rule (contract.check_timeout) and one set of defaults (contract.TIMEOUT_DEFAULTS) for all: the
    waypoint timeout may be 0 (a waypoint never goes stale), the state timeout may not."""
    for ctl in _controllers():
        assert (ctl.gate.state_timeout, ctl.gate.waypoint_timeout) == tuple(contract.TIMEOUT_DEFAULTS.values())
    for ctl in _controllers(waypoint_timeout=0.0):
        assert ctl.gate.waypoint_timeout == 0.0
    for bad in (dict(waypoint_timeout=-1.0), dict(state_timeout=0.0), dict(waypoint_timeout=float('nan'))):
        from anafi_control.preview_mpc import PreviewMpc
        for build in (lambda: MpcTracking(**bad), lambda: PidTracking(**bad),
                      lambda: PreviewMpc(_prediction_model(), bad)):
            with pytest.raises(ValueError, match='timeout'):
                build()


def test_stalled_when_the_cycles_stop():
    h = health('ok', 'ok', [('cycles', 3)])
    assert contract.stalled(h, None) is h and contract.stalled(h, contract.STALL_TIMEOUT) is h
    s = contract.stalled(h, 12.34)
    assert s.level == contract.LEVEL_WARN and s.values == h.values
    assert s.message == 'stalled: no controller cycle for 12.3 s of wall time (ROS time stopped?); last: tracking'
    err = health('solver_failed', 'solver')
    assert contract.stalled(err, 5.0, timeout=1.0).level == contract.LEVEL_ERROR
