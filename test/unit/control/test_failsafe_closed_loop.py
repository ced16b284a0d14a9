"""Failsafe in closed loop (pure Python): the simulated Anafi (anafi_sim.sim: model + firmware hover brake) flown
by each contract controller (MpcTracking, PidTracking) along a straight line at ~8 m/s, then a fault.

The bound of docs/reliability.md: after a bad waypoint (the controller holds with its own loop) or a bad
state (the controller sends nothing, the firmware brakes), the drone stops no farther from where the fault began
than the firmware's own brake does from the same flight (the controller killed at the same moment) + 20 %, and
stays there. A stale state is only known as such after ~state_timeout (0.5 s), so its bound adds the distance
flown meanwhile: 1.2 x (brake distance + speed x state_timeout). The old behaviour (an all-zero command = level attitude) coasts several times farther; the
test checks that too, so the bound is not vacuous.
"""
import math

import pytest

from anafi_control.contract import HOLD, SILENT
from anafi_control.frames import euler_to_quaternion, world_to_body
from anafi_control.mpc_tracking import MpcTracking
from anafi_control.pid_framework import PidTracking
from anafi_sim.sim.bridge import PilotingMapping
from anafi_sim.sim.drone_model import AnafiModel, load_model_params

RATE = 200.0            # physics [Hz]
SPEED = 8.0             # [m/s] along +x
ALT = 10.0              # [m]
T_FAULT = 14.0          # [s] long enough to settle on the line at SPEED
T_END = T_FAULT + 20.0
NAN = float('nan')


def fly(controller_class, fault):
    """Fly the line, inject ``fault`` at T_FAULT; returns (speed at the fault, farthest horizontal distance from
    the fault position afterwards, final position (x, y), final speed, the controller)."""
    model = AnafiModel(load_model_params(), mapping=PilotingMapping(), seed=0)
    model.reset(0.0, 0.0, ALT, 0.0, flying=True)
    ctl = controller_class()
    mapping = model.mapping
    dt = 1.0 / RATE
    state_every, wp_every = int(RATE / 30), int(RATE / 10)
    cycle_every = int(round(RATE / ctl.RATE))
    command_every = cycle_every if ctl.COMMAND_RATE is None else int(round(RATE / ctl.COMMAND_RATE))
    start = fault_pos = speed_at_fault = None
    farthest = 0.0
    for k in range(int(T_END * RATE)):
        t = k * dt
        after = t >= T_FAULT
        if after and fault_pos is None:
            fault_pos = (model.x, model.y)
            speed_at_fault = math.hypot(model.vx, model.vy)
        if k % state_every == 0 and not (after and fault == 'stale_state'):
            pos = (model.x, model.y, model.z)
            if after and fault == 'nan_state':
                pos = (NAN, model.y, model.z)
            twist = world_to_body(0.0, 0.0, model.yaw, (model.vx, model.vy, model.vz))
            ctl.on_state(t, pos, euler_to_quaternion(0.0, 0.0, model.yaw), twist)
        if k % wp_every == 0 and not (after and fault == 'stale_waypoint'):
            if start is None:
                start = t
            x = SPEED * (t - 3.0) if t > 3.0 else 0.0       # hold 3 s, then the line
            wp = (x, 0.0, ALT, SPEED if t > 3.0 else 0.0, 0.0, 0.0, 0.0)
            if after and fault == 'nan_waypoint':
                wp = (NAN,) + wp[1:]
            ctl.on_waypoint(t, wp)
        if k % cycle_every == 0:
            ctl.cycle(t)
        if k % command_every == 0 and not (after and fault == 'killed'):
            cmd = ctl.last.command
            if after and fault == 'zeros':                  # the old "hover": an all-zero command
                cmd = (0.0, 0.0, 0.0, 0.0)
            if cmd is not None:
                model.set_command(*(mapping.to_pcmd(*cmd) + (t,)))
        model.step(dt, t)
        if fault_pos is not None:
            farthest = max(farthest, math.hypot(model.x - fault_pos[0], model.y - fault_pos[1]))
    return speed_at_fault, farthest, (model.x, model.y), math.hypot(model.vx, model.vy), ctl


def distance(a, b):
    return math.hypot(a[0] - b[0], a[1] - b[1])


CONTROLLERS = [MpcTracking, PidTracking]
_BRAKE = {}


def firmware_brake(controller_class):
    """The reference: the same flight, the controller killed at T_FAULT (no command: the firmware brakes)."""
    if controller_class not in _BRAKE:
        _BRAKE[controller_class] = fly(controller_class, 'killed')
    return _BRAKE[controller_class]


@pytest.mark.parametrize('cls', CONTROLLERS, ids=lambda c: c.NAME)
@pytest.mark.parametrize('fault, failsafe', [('nan_waypoint', HOLD), ('stale_waypoint', HOLD), ('nan_state', SILENT),
                                             ('stale_state', SILENT)])
def test_a_fault_at_8_m_s_stops_the_drone_within_the_firmware_brake_distance(cls, fault, failsafe):
    speed, brake_distance, _, brake_speed, _ = firmware_brake(cls)
    assert speed > 7.5, 'the drone did not reach ~8 m/s (%.2f m/s)' % speed
    assert brake_speed < 0.2                                              # the firmware stops the drone
    speed, farthest, final, final_speed, ctl = fly(cls, fault)
    assert speed > 7.5
    bound = 1.2 * brake_distance
    if fault == 'stale_state':          # known only after the timeout: the distance flown meanwhile is added
        bound = 1.2 * (brake_distance + speed * ctl.gate.state_timeout)
    if fault == 'stale_waypoint':       # the same for a waypoint (meanwhile the controller closes on the last one)
        bound = 1.2 * (brake_distance + speed * ctl.gate.waypoint_timeout)
    assert farthest <= bound, '%s: %.1f m > bound %.1f m (firmware brake %.1f m)' % (
        fault, farthest, bound, brake_distance)
    assert final_speed < 0.2                                              # stopped, and stays there
    assert ctl.counters[failsafe] > 0 and ctl.last.ok is False
    if failsafe == HOLD:
        assert ctl.counters['holds'] == 1 and ctl.last.command is not None
        assert distance(final, ctl.gate.hold) < 0.5                       # at the hold point
    else:
        assert ctl.last.command is None


@pytest.mark.parametrize('cls', CONTROLLERS, ids=lambda c: c.NAME)
def test_the_old_all_zero_hover_command_coasts_far_beyond_the_bound(cls):
    _, brake_distance, _, _, _ = firmware_brake(cls)
    _, farthest, _, _, _ = fly(cls, 'zeros')
    assert farthest > 2.0 * brake_distance
