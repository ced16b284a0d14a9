"""anafi_sim.sim.simulator: the simulated Anafi's step (inputs, decimated outputs, flight states) and health."""
import math

import pytest

from anafi_control import frames
from anafi_sim.mission import monitor
from anafi_sim.sim.bridge import BridgeEstimate, PilotingMapping, bridge_estimate
from anafi_sim.sim.clock import SimClock
from anafi_sim.sim.drone_model import FLYING, LANDED, TAKING_OFF, AnafiModel, load_model_params
from anafi_sim.sim.simulator import FOREIGN_CLOCK_MARGIN, SimulatedAnafi
from anafi_sim.sim.state_estimate import StateEstimate


class FakeServer(object):
    port = 9060
    client_count = 1
    clients_dropped_slow = 0
    clients_disconnected = 2

    def __init__(self):
        self.samples = []

    def publish(self, sample):
        self.samples.append(sample)


def simulator(auto_takeoff=True, server=None, rtf=1.0):
    mapping = PilotingMapping()
    model = AnafiModel(load_model_params(), mapping=mapping, seed=0)
    sim = SimulatedAnafi(model, StateEstimate(model.params),
                         SimClock(200.0, rtf, telemetry_rate=100.0, estimate_rate=30.0, publish_clock=True),
                         server=server, auto_takeoff=auto_takeoff)
    sim.start(0.0)
    return sim


def steps(sim, n):
    return [sim.step() for _ in range(n)]


def test_steps_take_off_and_decimate_the_outputs():
    server = FakeServer()
    sim = simulator(server=server)
    out = steps(sim, 400)                                      # 2 s
    assert out[-1].t == pytest.approx(2.0) and all(s.clock for s in out)
    assert out[0].state == TAKING_OFF and FLYING in [s.state for s in out if s.state]
    samples = [s.sample for s in out if s.sample is not None]
    assert len(samples) == 201 and server.samples == samples  # 100 Hz, also to the telemetry server
    assert samples[-1].timestamp == pytest.approx(2.0)
    estimates = [s.estimate for s in out if s.estimate is not None]
    assert 50 <= len(estimates) <= 61 and isinstance(estimates[-1], BridgeEstimate)


def test_commands_apply_at_the_next_step_and_non_finite_ones_are_refused():
    sim = simulator(auto_takeoff=False)
    sim.model.reset(0.0, 0.0, 5.0, 0.0, flying=True)
    assert sim.on_command(float('nan'), 0.0, 0.0, 0.0) is False
    assert sim.bad_commands == 1 and not sim.commands
    assert sim.on_command(0.0, 10.0, 0.0, 0.5) is True
    assert list(sim.commands) == [sim.model.mapping.to_pcmd(0.0, 10.0, 0.0, 0.5)]
    sim.step()
    assert not sim.commands and sim.model.last_pcmd == sim.model.mapping.to_pcmd(0.0, 10.0, 0.0, 0.5)
    assert sim.commands_received == 1 and sim.model.command_age(sim.clock.t) == pytest.approx(0.005)
    for _ in range(200):                                        # a command stream (the hover brake needs one)
        sim.on_command(0.0, 10.0, 0.0, 0.5)
        sim.step()
    assert sim.model.commanding and sim.model.vx > 0.1          # pitch down: flies forward


def test_take_off_and_landing_requests_are_applied_and_reported():
    sim = simulator(auto_takeoff=False)
    assert sim.step().state == LANDED
    sim.on_event('takeoff')
    step = sim.step()
    assert step.events == [('takeoff', True, TAKING_OFF)] and step.state == TAKING_OFF
    while sim.model.state != FLYING:
        sim.step()
    sim.on_event('takeoff')
    assert sim.step().events == [('takeoff', False, FLYING)]   # already flying: ignored
    with pytest.raises(ValueError):
        sim.on_event('flip')


def test_bridge_estimate_numbers():
    values = (1.0, 2.0, 3.0, 1.0, 0.0, 0.5, 0.1, -0.2, math.pi / 2)
    e = bridge_estimate(values, gimbal_pitch=-0.3)
    assert e.position == (1.0, 2.0, 3.0) and e.velocity == (1.0, 0.0, 0.5)
    assert e.orientation == frames.euler_to_quaternion(0.1, -0.2, math.pi / 2)
    assert e.body_velocity == pytest.approx(frames.world_to_body(0.1, -0.2, math.pi / 2, (1.0, 0.0, 0.5)))
    assert e.rpy_deg == pytest.approx((math.degrees(0.1), math.degrees(-0.2), 90.0))
    # camera/attitude as the real bridge publishes it: referenced to north-west-up (test_camera_attitude.py)
    camera = frames.euler_to_quaternion(0.0, -0.3, math.pi / 2)
    assert frames.enu_from_nwu(e.camera_orientation) == pytest.approx(camera)
    assert frames.enu_from_nwu(e.camera_base_orientation) == pytest.approx(frames.euler_to_quaternion(0, 0, math.pi / 2))
    # drone/speed and drone/attitude as the real bridge: north-west-up; flying east = north 0, west -1
    assert e.speed_nwu == (0.0, -1.0, 0.5)
    assert frames.enu_from_nwu(e.attitude_nwu) == pytest.approx(e.orientation)
    # heading north (ENU yaw 90 deg) is yaw 0 in NWU
    assert frames.yaw_from_quaternion(*e.attitude_nwu) == pytest.approx(0.0, abs=1e-12)


def test_health_values_and_warnings():
    server = FakeServer()
    sim = simulator(server=server)
    steps(sim, 200)
    health = sim.health(1.0)                                    # 200 steps in 1 s of wall: on rate
    values = dict(health.values)
    assert not health.warning
    assert values[monitor.SIM_RTF_KEY] == '1.000' and values[monitor.SIM_OVERRUNS_KEY] == '0'
    assert values['physics rate achieved [Hz wall]'] == '200.0' and values['flight state'] == sim.model.state
    assert values['telemetry clients'] == '1' and values['telemetry clients disconnected'] == '2'
    assert values['command age [s sim]'] == 'none'
    sim.on_command(float('inf'), 0.0, 0.0, 0.0)
    steps(sim, 100)
    health = sim.health(2.0)                                    # 100 steps in 1 s: half the rate
    assert health.warning
    assert health.message == 'physics 100 Hz of wall time, wanted 200; 1 non-finite commands ignored'
    steps(sim, 200)
    health = sim.health(3.0)
    assert not health.warning and health.message in (FLYING, 'flying, hovering (no piloting command)')
    assert 'telemetry port' not in dict(simulator().health(1.0).values)   # no server: no telemetry values


# ------------------------------------------------------------------ lockstep (~sync)
def lockstep_simulator(timeout=0.01):
    from anafi_sim.sim.clock import Lockstep
    mapping = PilotingMapping()
    model = AnafiModel(load_model_params(), mapping=mapping, seed=0)
    lock = Lockstep(0.1, 0.005, timeout=timeout, max_missed=100)
    sim = SimulatedAnafi(model, StateEstimate(model.params),
                         SimClock(200.0, 1.0, telemetry_rate=100.0, estimate_rate=30.0, publish_clock=True),
                         lockstep=lock)
    sim.start(0.0)
    return sim, lock


def test_without_lockstep_sync_never_waits():
    sim = simulator()
    step = sim.step()
    assert sim.sync(step.t) is None
    assert sim.on_command(1.0, 0.0, 0.0, 0.0, stamp=0.1)      # a stamp without lockstep is just ignored


def test_lockstep_waits_at_the_period_of_the_stamped_commands():
    sim, lock = lockstep_simulator()
    assert all(sim.sync(sim.step().t) is None for _ in range(40))   # not armed: no command yet
    sim.on_command(2.0, 0.0, 0.0, 0.0, stamp=0.2)            # the controller's cycle at 0.2 s
    waited = []
    for _ in range(20):                                      # 0.205 .. 0.3 s
        step = sim.step()
        waited.append((round(step.t, 3), sim.sync(step.t)))
    due = [(t, w) for t, w in waited if w is not None]
    assert due == [(0.3, False)]                             # due at 0.3 s, no command: timed out
    sim.on_command(2.0, 0.0, 0.0, 0.0, stamp=0.4)
    while sim.clock.t < 0.395:
        assert sim.sync(sim.step().t) is None
    step = sim.step()
    assert round(step.t, 3) == 0.4 and sim.sync(step.t) is True
    values = dict(sim.health(1.0).values)
    assert values['lockstep periods waited'] == '2'
    assert values['lockstep timeouts (period went on without a command)'] == '1'


def test_a_refused_command_still_answers_the_lockstep_period():
    sim, lock = lockstep_simulator()
    sim.on_command(0.0, 0.0, 0.0, 0.0, stamp=0.5)
    assert not sim.on_command(float('nan'), 0.0, 0.0, 0.0, stamp=0.6)
    assert lock.newest == pytest.approx(0.6) and sim.bad_commands == 1


def test_lockstep_timeouts_are_a_warning_and_the_wanted_rate_is_not():
    sim, lock = lockstep_simulator()
    sim.on_command(0.0, 0.0, 0.0, 0.0, stamp=0.005)
    steps(sim, 40)
    assert not sim.health(1.0).warning                        # slow on the wall clock: the controller's pace
    t = sim.step().t
    while sim.sync(t) is None:
        t = sim.step().t
    health = sim.health(2.0)
    assert health.warning and 'lockstep timeouts' in health.message
    assert not sim.health(3.0).warning                        # reported once


def test_unstamped_commands_count_at_their_arrival_time_and_say_so():
    """The reference implementation's controllers leave header.stamp at 0: the lockstep takes the
    simulation time of arrival instead (before, such commands never armed it: the world ran free)."""
    sim, lock = lockstep_simulator()
    sim.on_command(1.0, 0.0, 0.0, 0.0, stamp=0.0)            # at time 0 (start hold): counted, not armed
    assert not lock.armed and sim.unstamped_commands == 1
    steps(sim, 40)                                           # 0.2 s
    sim.on_command(1.0, 0.0, 0.0, 0.0, stamp=0.0)            # arrives at 0.2 s: arms, stamped 0.2
    assert lock.armed and lock.last == pytest.approx(0.2)
    t = sim.step().t
    while not lock.due(t):
        assert sim.sync(t) is None
        t = sim.step().t
    assert t == pytest.approx(0.3)                           # due one period after the arrival
    sim.on_command(1.0, 0.0, 0.0, 0.0, stamp=None)           # arrives while the clock waits at 0.3 s
    assert sim.sync(t) is True and lock.last == pytest.approx(0.3)
    health = sim.health(1.0)
    assert not health.warning and 'unstamped commands, taken at their arrival time (3)' in health.message
    assert dict(health.values)['lockstep unstamped commands (taken at arrival)'] == '3'


def test_a_command_stamped_on_the_wall_clock_counts_at_its_arrival_and_warns_once():
    """A node on the wall clock (no /use_sim_time) stamps its commands ~1.7e9 s: the lockstep cannot pace it;
    taken at its arrival (a wall stamp would hold the lockstep's period end out of reach), WARN once."""
    sim, lock = lockstep_simulator()
    steps(sim, 40)                                           # 0.2 s
    sim.on_command(1.0, 0.0, 0.0, 0.0, stamp=1.7e9)
    assert lock.armed and lock.last == pytest.approx(0.2)
    assert sim.foreign_clock_commands == 1 and sim.unstamped_commands == 0
    health = sim.health(1.0)
    assert health.warning and 'cannot pace a node on another clock' in health.message and '1 commands' in health.message
    assert dict(health.values)['lockstep commands on another clock (taken at arrival)'] == '1'
    assert not sim.health(2.0).warning                       # reported once
    sim.on_command(1.0, 0.0, 0.0, 0.0, stamp=0.2 + FOREIGN_CLOCK_MARGIN)   # within the margin: its own stamp
    assert sim.foreign_clock_commands == 1 and lock.newest == pytest.approx(0.2 + FOREIGN_CLOCK_MARGIN)


def test_stamped_commands_are_not_counted_as_unstamped():
    sim, lock = lockstep_simulator()
    sim.on_command(1.0, 0.0, 0.0, 0.0, stamp=0.1)
    assert sim.unstamped_commands == 0 and 'unstamped' not in sim.health(1.0).message
