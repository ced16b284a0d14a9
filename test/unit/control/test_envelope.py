"""anafi_control.envelope: the flight envelope every controller shares (unit tests of the core), a property test
with the envelope as invariant (any waypoint stream through the admission and the gate, flown in closed loop
by the simulated Anafi: the target stays in the fence, the commanded tilt within its limit, the drone in the
fence), and the closed loop of a ``vx = 1e6`` stream: the drone stays in the fence, the health says
'limiting', and the legitimate stream, resumed, brings it back within the time the envelope's speed allows."""
import math

import pytest

from anafi_control import contract
from anafi_control.envelope import ENVELOPE_DEFAULTS, LIMITS, Envelope, reason
from anafi_control.frames import euler_to_quaternion, world_to_body
from anafi_control.mpc_tracking import MpcTracking
from anafi_control.pid_framework import PidTracking
from anafi_control.waypoint_admission import WaypointAdmission
from anafi_sim.sim.bridge import PilotingMapping
from anafi_sim.sim.drone_model import AnafiModel, load_model_params

CENTRE = (0.0, 0.0)
DRONE = (0.0, 0.0, 5.0)


def names(notes):
    return [n for n, _ in notes]


# -- the core ------------------------------------------------------------------------------------
def test_defaults_and_limits():
    env = Envelope()
    assert env.as_dict() == ENVELOPE_DEFAULTS
    assert env.target_radius == env.geofence_radius - env.geofence_margin
    assert set(LIMITS) == set(n[len('limited_'):] for n in contract.COUNTER_NAMES if n.startswith('limited_'))


def test_a_target_inside_the_envelope_is_untouched():
    env = Envelope()
    wp = (3.0, -2.0, 5.0, 4.9, -1.0, 1.5, 30.0)
    out, notes = env.limit_waypoint(wp, CENTRE, DRONE)
    assert out is wp and notes == []
    assert env.limit_command((30.64, -30.64, 100.0, 2.0)) == ((30.64, -30.64, 100.0, 2.0), [])
    assert env.limit_acceleration((3.0, 4.0, -5.0)) == ((3.0, 4.0, -5.0), [])


@pytest.mark.parametrize('v', [(1e6, 0.0), (3e5, -4e5), (1.7e308, 1.7e308), (-1e-300, 11.0)])
def test_the_reference_speed_is_scaled_down_keeping_its_direction(v):
    env = Envelope()
    out, notes = env.limit_waypoint((0.0, 0.0, 5.0) + v + (0.0, 0.0), CENTRE, DRONE)
    assert names(notes) == ['speed']
    assert math.hypot(out[3], out[4]) == pytest.approx(10.0)
    assert math.atan2(out[4], out[3]) == pytest.approx(math.atan2(v[1], v[0]))


def test_the_vertical_reference_speed_is_clipped():
    out, notes = Envelope().limit_waypoint((0.0, 0.0, 5.0, 0.0, 0.0, -1e300, 0.0), CENTRE, DRONE)
    assert names(notes) == ['vertical_speed'] and out[5] == -2.0


@pytest.mark.parametrize('position, expected', [
    ((300.0, 0.0, 5.0), (247.0, 0.0, 5.0)),            # beyond the radius: on the target's fence
    ((-1e300, 0.0, 5.0), (-247.0, 0.0, 5.0)),          # huge finite
    ((30.0, 40.0, 60.0), (30.0, 40.0, 50.0)),          # above the ceiling
    ((30.0, 40.0, -1e9), (30.0, 40.0, 0.5)),           # below the floor
])
def test_a_target_outside_the_fence_is_moved_into_it(position, expected):
    env = Envelope()
    out, notes = env.limit_waypoint(position + (0.0, 0.0, 0.0, 0.0), CENTRE, None)
    assert names(notes) == ['geofence']
    assert out[:3] == pytest.approx(expected)
    assert env.inside(out, CENTRE, margin=env.geofence_margin)


def test_the_fence_is_around_the_take_off_point():
    env = Envelope(geofence_radius=10.0, geofence_margin=0.0)
    out, notes = env.limit_waypoint((100.0, 50.0, 5.0, 0.0, 0.0, 0.0, 0.0), (100.0, 30.0), None)
    assert out[:2] == pytest.approx((100.0, 40.0)) and names(notes) == ['geofence']


def test_velocity_toward_the_fence_brakes_to_stop_on_it():
    env = Envelope()
    a = 0.5 * env.max_reference_acceleration
    # 7 m from the target's fence, flying out at 9 m/s and along it at 3 m/s: the outward part is cut
    out, notes = env.limit_waypoint((240.0, 0.0, 5.0, 9.0, 3.0, 0.0, 0.0), CENTRE, (235.0, 0.0, 5.0))
    assert names(notes) == ['fence_braking']
    assert out[3] == pytest.approx(math.sqrt(2.0 * a * 7.0)) and out[4] == 3.0
    # on the fence: nothing outward; inward is free
    out, _ = env.limit_waypoint((247.0, 0.0, 5.0, 10.0, 0.0, 0.0, 0.0), CENTRE, (240.0, 0.0, 5.0))
    assert out[3] == pytest.approx(0.0, abs=1e-9)
    wp = (247.0, 0.0, 5.0, -10.0, 0.0, 0.0, 0.0)
    assert env.limit_waypoint(wp, CENTRE, (240.0, 0.0, 5.0)) == (wp, [])
    # the ceiling and the floor
    out, notes = env.limit_waypoint((0.0, 0.0, 49.5, 0.0, 0.0, 2.0, 0.0), CENTRE, (0.0, 0.0, 48.0))
    assert names(notes) == ['fence_braking'] and out[5] == pytest.approx(math.sqrt(2.0 * a * 0.5))
    out, notes = env.limit_waypoint((0.0, 0.0, 0.5, 0.0, 0.0, -1.0, 0.0), CENTRE, DRONE)
    assert out[5] == 0.0


def test_a_target_trailing_the_drone_brakes_from_the_drone_s_distance():
    # waypoints at where the drone was (a late stream at the drone's own position): the drone nearer the fence
    env = Envelope()
    a = 0.5 * env.max_reference_acceleration
    out, notes = env.limit_waypoint((240.0, 0.0, 5.0, 10.0, 0.0, 0.0, 0.0), CENTRE, (246.5, 0.0, 5.0))
    assert names(notes) == ['fence_braking'] and out[3] == pytest.approx(math.sqrt(2.0 * a * 0.5))
    out, _ = env.limit_waypoint((240.0, 0.0, 5.0, 10.0, 0.0, 0.0, 0.0), CENTRE, (248.0, 0.0, 5.0))
    assert out[3] == pytest.approx(0.0, abs=1e-9)
    out, notes = env.limit_waypoint((0.0, 0.0, 48.0, 0.0, 0.0, 2.0, 0.0), CENTRE, (0.0, 0.0, 49.5))
    assert names(notes) == ['fence_braking'] and out[5] == pytest.approx(math.sqrt(2.0 * a * 0.5))
    # inward, or a drone farther inside than its target: untouched
    wp = (240.0, 0.0, 5.0, -10.0, 0.0, 0.0, 0.0)
    assert env.limit_waypoint(wp, CENTRE, (246.5, 0.0, 5.0)) == (wp, [])
    wp = (200.0, 0.0, 5.0, 10.0, 0.0, 0.0, 0.0)
    assert env.limit_waypoint(wp, CENTRE, (195.0, 0.0, 5.0)) == (wp, [])


def test_a_waypoint_beyond_reach_is_approached():
    env = Envelope()
    out, notes = env.limit_waypoint((0.0, 0.0, 5.0, 3.0, 0.0, 0.0, 45.0), CENTRE, (200.0, 0.0, 5.0))
    assert names(notes) == ['reach'] and '200.0 m > 50.0 m' in notes[0][1]
    assert out == pytest.approx((150.0, 0.0, 5.0, 0.0, 0.0, 0.0, 45.0))
    # a drone that overshot the fence: the approach point is back in the fence
    out, _ = env.limit_waypoint((0.0, 300.0, 5.0, 0.0, 0.0, 0.0, 0.0), CENTRE, (0.0, 1000.0, 5.0))
    assert env.inside(out, CENTRE, margin=env.geofence_margin)


def test_reference_acceleration_and_command_tilt():
    env = Envelope()
    a, notes = env.limit_acceleration((30.0, 40.0, -1e300))
    assert names(notes) == ['acceleration'] and a == pytest.approx((3.0, 4.0, -5.0))
    cmd, notes = env.limit_command((45.0, -1e300, 20.0, 1.0))
    assert names(notes) == ['tilt'] and cmd == (30.65, -30.65, 20.0, 1.0)
    assert env.limit_command(None) == (None, [])
    assert reason([('speed', 'a'), ('geofence', 'b'), ('speed', 'c')]) == 'a; b'


# -- closed loop: the simulated Anafi flown by a contract controller -------------------------------
RATE = 200.0         # physics [Hz]


class Flight(object):
    """The simulated Anafi (model + firmware) at ``start`` flown by ``controller``; ``targets`` and ``tilts`` keep
    every target the controller computed for and every command it gave."""

    def __init__(self, controller, start=(0.0, 0.0, 3.0)):
        self.model = AnafiModel(load_model_params(), mapping=PilotingMapping(), seed=0)
        self.model.reset(start[0], start[1], start[2], 0.0, flying=True)
        self.ctl = controller
        self.admission = WaypointAdmission()
        self.t = 0.0
        self.k = 0
        self.targets, self.commands, self.keys = [], [], []
        self.farthest = 0.0
        compute = controller._compute

        def recorded(t, inputs):
            self.targets.append(inputs.waypoint)
            return compute(t, inputs)
        controller._compute = recorded

    def fly(self, seconds, waypoint):
        """Fly ``seconds``; ``waypoint(t, drone) -> (stamp, waypoint 7-tuple)`` at 10 Hz through the admission."""
        m, ctl = self.model, self.ctl
        cycle_every = int(round(RATE / ctl.RATE))
        command_every = cycle_every if ctl.COMMAND_RATE is None else int(round(RATE / ctl.COMMAND_RATE))
        for _ in range(int(round(seconds * RATE))):
            t, k = self.k / RATE, self.k
            if k % int(RATE / 30) == 0:
                ctl.on_state(t, (m.x, m.y, m.z), euler_to_quaternion(0.0, 0.0, m.yaw),
                             world_to_body(0.0, 0.0, m.yaw, (m.vx, m.vy, m.vz)))
            if k % int(RATE / 10) == 0:
                stamp, wp = waypoint(t, (m.x, m.y, m.z))
                if self.admission.admit(t, stamp, 'world')[0]:
                    ctl.on_waypoint(t, wp)
            if k % cycle_every == 0:
                out = ctl.cycle(t)
                self.keys.append(out.key)
                if out.command is not None:
                    self.commands.append(out.command)
            if k % command_every == 0 and ctl.last.command is not None:
                m.set_command(*(m.mapping.to_pcmd(*ctl.last.command) + (t,)))
            m.step(1.0 / RATE, t)
            self.farthest = max(self.farthest, math.hypot(m.x, m.y))
            self.k += 1
        self.t = self.k / RATE


def check_invariants(flight, env):
    for target in flight.targets:
        assert env.inside(target, (0.0, 0.0), tolerance=1e-6, margin=env.geofence_margin), target
        assert math.hypot(target[3], target[4]) <= env.max_reference_speed * (1 + 1e-12)
        assert abs(target[5]) <= env.max_reference_vertical_speed
    for command in flight.commands:
        assert all(math.isfinite(v) for v in command)
        assert abs(command[0]) <= env.max_command_tilt_deg and abs(command[1]) <= env.max_command_tilt_deg


hypothesis = pytest.importorskip('hypothesis')
from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402

huge = st.one_of(st.floats(-1e3, 1e3), st.floats(allow_nan=False, allow_infinity=False),
                 st.sampled_from([1e6, -1e6, 1e300, -1.7e308]))
#: one waypoint of a stream: relative to the drone or absolute, any finite velocity, a stamp offset from the
#: receipt time (0 = unstamped)
waypoint_event = st.tuples(st.booleans(), huge, huge, st.floats(-100.0, 100.0), huge, huge, huge,
                           st.one_of(st.just(None), st.floats(-2.0, 2.0)))


@settings(max_examples=8, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from([MpcTracking, PidTracking]), st.lists(waypoint_event, min_size=1, max_size=8))
def test_under_any_waypoint_stream_the_target_stays_in_the_fence_and_the_tilt_in_its_limit(cls, events):
    env = Envelope(geofence_radius=15.0, max_altitude=12.0)
    flight = Flight(cls(limits=env))

    def waypoint(t, drone):
        relative, x, y, z, vx, vy, vz, stamp = events[int(t * 10) % len(events)]
        position = (drone[0] + x, drone[1] + y, drone[2] + z) if relative and abs(x) < 1e6 and abs(y) < 1e6 \
            else (x, y, z)
        return (0.0 if stamp is None else t + stamp), position + (vx, vy, vz, 0.0)
    flight.fly(8.0, waypoint)
    check_invariants(flight, env)
    assert flight.farthest <= env.geofence_radius


@pytest.mark.parametrize('cls', [MpcTracking, PidTracking], ids=lambda c: c.NAME)
def test_a_vx_1e6_stream_is_limited_and_the_legitimate_stream_brings_the_drone_back(cls):
    env = Envelope(geofence_radius=60.0)
    flight = Flight(cls(limits=env))
    home = (0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0)
    flight.fly(3.0, lambda t, drone: (t, home))                               # the legitimate mission
    assert flight.ctl.health().message == 'tracking'
    # the fault: waypoints at the drone's own position with vx = 1e6 (finite), stamped, at 10 Hz
    flight.fly(20.0, lambda t, drone: (t, drone + (1e6, 0.0, 0.0, 0.0)))
    h = flight.ctl.health()
    assert h.level == contract.LEVEL_WARN and h.message.startswith('limiting: ') and 'reference speed' in h.message
    assert 'tracking' not in flight.keys[-150:] and contract.OK not in flight.keys[-150:]
    assert flight.farthest <= env.geofence_radius                             # stayed in the fence
    check_invariants(flight, env)
    # the legitimate stream, resumed: back home within the time the envelope's speed allows
    away = math.hypot(flight.model.x, flight.model.y)
    allowed = away / env.max_reference_speed + 10.0                           # + accelerating and settling
    flight.fly(allowed, lambda t, drone: (t, home))
    m = flight.model
    assert math.hypot(m.x, m.y) < 0.5 and abs(m.z - 3.0) < 0.5, (away, m.x, m.y, m.z)
    assert flight.ctl.health().message == 'tracking'
    check_invariants(flight, env)


sample = st.tuples(*([st.one_of(st.floats(-300.0, 300.0), st.sampled_from([0.0, 1e9, -1e9, 149.0, 150.0]))] * 9))


@settings(max_examples=300, deadline=None, database=None)
@given(st.lists(sample, min_size=1, max_size=6), st.one_of(st.none(), st.just(CENTRE), st.just((5.0, -3.0))),
       st.one_of(st.none(), st.just(DRONE), st.just((10.0, 0.0, 2.0))))
def test_inert_holds_only_where_no_limit_acts_on_any_sample(samples, centre, drone):
    """``inert`` (the whole-reference check the preview MPC takes before limiting each sample) is True only when
    ``limit_target`` and ``limit_acceleration`` would leave every sample as it is."""
    import numpy as np
    env = Envelope(geofence_radius=150.0, max_altitude=120.0)
    arr = np.array(samples, dtype=float)
    P, V, A = arr[:, 0:3], arr[:, 3:6], arr[:, 6:9]
    if env.inert(P, V, A, centre, drone):
        for i in range(len(arr)):
            assert env.limit_target(tuple(P[i]), tuple(V[i]), centre, drone)[2] == []
            assert env.limit_acceleration(tuple(A[i]))[1] == []


def test_inert_on_a_reference_inside_and_one_sample_out():
    import numpy as np
    env = Envelope()
    P = np.array([[1.0, 2.0, 5.0], [1.5, 2.0, 5.0]])
    V = np.array([[1.0, 0.0, 0.5], [1.0, 0.0, 0.5]])
    A = np.zeros((2, 3))
    assert env.inert(P, V, A, CENTRE, DRONE)
    V[1, 0] = 1e6                                  # one sample too fast: the per-sample limits must act
    assert not env.inert(P, V, A, CENTRE, DRONE)
    V[1, 0] = float('nan')
    assert not env.inert(P, V, A, CENTRE, DRONE)
