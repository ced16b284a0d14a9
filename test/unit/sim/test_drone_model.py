"""anafi_sim.sim.drone_model: the simulated Anafi's dynamics, command mapping, hover brake and flight states."""
import math
import os

import pytest
import yaml

from anafi_sim.sim.bridge import MAX_TILT_DEG, PilotingMapping
from anafi_sim.sim.drone_model import (DEFAULT_MODEL_FILE, DEFAULT_SETTINGS, FLYING, LANDED, LANDING,
                                   MODEL_KEYS, TAKING_OFF, AnafiModel, load_model_params,
                                   validate_model_params)
from anafi_sim.telemetry.protocol import FIELDS, TelemetrySample

DT = 0.005
PARAMS = {
    'gravity': 9.81,
    'attitude_time_constant': 0.2,
    'attitude_delay': 0.0,
    'yaw_rate_time_constant': 0.1,
    'vertical_speed_time_constant': 0.3,
    'drag_linear': 0.14,
    'drag_quadratic': 0.035,
    'drag_vertical': 0.3,
    'estimate_delay': 0.2,
    'estimate_time_constant': 0.05,
    'estimate_rate': 20.0,
    'estimate_float16': True,
}


def params(**overrides):
    p = dict(PARAMS)
    p.update(overrides)
    return p


def flying_model(z=5.0, yaw=0.0, settings=None, seed=0, **overrides):
    model = AnafiModel(params(**overrides), settings=settings, seed=seed)
    model.reset(0.0, 0.0, z, yaw, flying=True)
    return model


def run(model, duration, pcmd=None, t0=None, command_period=0.1):
    """Step for ``duration`` s, streaming ``pcmd`` every ``command_period`` s if given; returns the end time."""
    t = model.time if t0 is None else t0
    n = int(round(duration / DT))
    every = max(1, int(round(command_period / DT)))
    for k in range(n):
        if pcmd is not None and k % every == 0:
            model.set_command(pcmd[0], pcmd[1], pcmd[2], pcmd[3], t)
        model.step(DT, t)
        t += DT
    return t


# ---------------------------------------------------------------- parameters
def test_parameter_validation():
    assert validate_model_params(PARAMS) == PARAMS
    missing = dict(PARAMS)
    del missing['drag_linear']
    with pytest.raises(ValueError, match='drag_linear'):
        AnafiModel(missing)
    with pytest.raises(ValueError, match='bogus'):
        AnafiModel(params(bogus=1.0))
    with pytest.raises(ValueError, match='attitude_time_constant'):
        AnafiModel(params(attitude_time_constant=float('nan')))
    with pytest.raises(ValueError, match='gravity'):
        AnafiModel(params(gravity=float('inf')))
    with pytest.raises(ValueError, match='drag_vertical'):
        AnafiModel(params(drag_vertical=-0.1))
    with pytest.raises(ValueError, match='estimate_float16'):
        AnafiModel(params(estimate_float16=1))
    with pytest.raises(ValueError, match='wind_q'):
        AnafiModel(PARAMS, settings={'wind_q': 1.0})
    with pytest.raises(ValueError, match='command_timeout'):
        AnafiModel(PARAMS, settings={'command_timeout': float('nan')})


def test_packaged_config_files_are_valid():
    loaded = load_model_params(DEFAULT_MODEL_FILE)
    assert sorted(loaded) == sorted(MODEL_KEYS)
    sim_file = os.path.join(os.path.dirname(DEFAULT_MODEL_FILE), 'sim.yaml')
    with open(sim_file) as stream:
        sim = yaml.safe_load(stream)
    settings = dict((k, sim[k]) for k in DEFAULT_SETTINGS)   # every model setting is in sim.yaml
    AnafiModel(loaded, settings=settings)
    assert sim['max_tilt_deg'] == pytest.approx(MAX_TILT_DEG, abs=0.005)
    assert sim['rate'] >= 200


# ------------------------------------------------------------------- hover
def test_hover_equilibrium_holds_with_zero_command():
    model = flying_model(z=5.0)
    run(model, 10.0, pcmd=(0, 0, 0, 0))
    assert model.position() == pytest.approx((0.0, 0.0, 5.0), abs=1e-9)
    assert model.velocity() == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
    assert model.thrust == pytest.approx(9.81)
    assert model.commanding


def test_one_percent_quantisation_keeps_the_drone_level():
    mapping = PilotingMapping()
    pcmd = mapping.to_pcmd(0.3, 0.3, 0.0, 0.0)          # 0.3 deg of 30.64 deg -> 0 %
    assert pcmd == (0, 0, 0, 0)
    model = flying_model()
    run(model, 2.0, pcmd=pcmd)
    assert model.attitude()[:2] == (0.0, 0.0)
    pcmd = mapping.to_pcmd(0.4, 0.0, 0.0, 0.0)          # 1.3 % -> 1 % = 0.3064 deg
    model.set_command(*(pcmd + (model.time,)))
    run(model, 3.0, pcmd=pcmd)
    assert math.degrees(model.roll) == pytest.approx(0.3064, rel=1e-3)


# -------------------------------------------------------------- step responses
def _fraction_at(model, getter, pcmd, setpoint, tau):
    start = getter(model)
    run(model, tau, pcmd=pcmd)
    return (getter(model) - start) / (setpoint - start)


def test_pitch_step_reaches_63_percent_at_tau():
    tau = PARAMS['attitude_time_constant']
    model = flying_model()
    setpoint = 0.5 * math.radians(MAX_TILT_DEG)
    frac = _fraction_at(model, lambda m: m.pitch, (0, 50, 0, 0), setpoint, tau)
    assert frac == pytest.approx(1.0 - math.exp(-1.0), abs=0.02)
    run(model, 5 * tau, pcmd=(0, 50, 0, 0))
    assert model.pitch == pytest.approx(setpoint, rel=0.01)


def test_roll_step_with_delay_starts_late_then_tracks():
    model = flying_model(attitude_delay=0.1, attitude_time_constant=0.25)
    run(model, 0.095, pcmd=(-40, 0, 0, 0))
    assert model.roll == 0.0                                # nothing before the delay
    setpoint = -0.4 * math.radians(MAX_TILT_DEG)
    run(model, 0.25, pcmd=(-40, 0, 0, 0))
    # 0.25 s after the delay has elapsed (+ up to one step of rounding)
    assert model.roll / setpoint == pytest.approx(1.0 - math.exp(-1.0), abs=0.03)


def test_yaw_rate_step_reaches_63_percent_at_tau():
    tau = PARAMS['yaw_rate_time_constant']
    model = flying_model()
    setpoint = math.radians(90.0)                   # PCMD yaw -50 = counter-clockwise 90 deg/s
    frac = _fraction_at(model, lambda m: m.yaw_rate, (0, 0, -50, 0), setpoint, tau)
    assert frac == pytest.approx(1.0 - math.exp(-1.0), abs=0.02)
    run(model, 1.0, pcmd=(0, 0, -50, 0))
    assert model.body_angular_velocity()[2] == pytest.approx(setpoint, rel=1e-3)


def test_vertical_speed_step_reaches_63_percent_at_tau():
    tau = PARAMS['vertical_speed_time_constant']
    model = flying_model()
    frac = _fraction_at(model, lambda m: m.vz, (0, 0, 0, 50), 1.0, tau)
    assert frac == pytest.approx(1.0 - math.exp(-1.0), abs=0.02)
    run(model, 3.0, pcmd=(0, 0, 0, 50))
    assert model.vz == pytest.approx(1.0, rel=1e-3)
    # physically realised: the thrust exceeds gravity while climbing faster
    model2 = flying_model()
    run(model2, 0.05, pcmd=(0, 0, 0, 100))
    assert model2.thrust > 9.81


def test_attitude_is_clamped_to_max_tilt():
    model = flying_model()
    run(model, 3.0, pcmd=(100, -100, 0, 0))
    tilt = math.radians(MAX_TILT_DEG)
    assert abs(model.roll) <= tilt + 1e-12 and abs(model.pitch) <= tilt + 1e-12
    assert model.roll == pytest.approx(tilt, rel=1e-3)


# ------------------------------------------------------------------- signs
def test_positive_pitch_accelerates_forward_along_x_at_yaw_0():
    model = flying_model()
    run(model, 1.0, pcmd=(0, 30, 0, 0))
    assert model.vx > 0.5 and abs(model.vy) < 1e-9
    ax, ay, az = model.body_linear_acceleration()
    assert ax > 0.5


def test_positive_roll_accelerates_towards_minus_y():
    model = flying_model()
    run(model, 1.0, pcmd=(30, 0, 0, 0))
    assert model.vy < -0.5 and abs(model.vx) < 1e-9


def test_positive_pitch_at_yaw_90_moves_along_plus_y():
    model = flying_model(yaw=math.pi / 2)
    run(model, 1.0, pcmd=(0, 30, 0, 0))
    assert model.vy > 0.5 and abs(model.vx) < 1e-6


def test_positive_ros_yaw_rate_increases_yaw():
    mapping = PilotingMapping()
    pcmd = mapping.to_pcmd(0.0, 0.0, 45.0, 0.0)
    model = flying_model()
    run(model, 1.0, pcmd=pcmd)
    assert model.yaw > math.radians(30.0)


def test_body_frame_outputs_and_gimbal():
    model = flying_model(yaw=math.pi / 2)
    run(model, 2.0, pcmd=(0, 30, 0, 0))
    bvx, bvy, bvz = model.body_velocity()
    speed = math.sqrt(model.vx ** 2 + model.vy ** 2 + model.vz ** 2)
    assert math.sqrt(bvx ** 2 + bvy ** 2 + bvz ** 2) == pytest.approx(speed)
    assert bvx > 0.9 * speed                          # flying forward
    g_roll, g_pitch = model.gimbal_angles()
    assert g_pitch == pytest.approx(-model.pitch) and g_roll == pytest.approx(-model.roll)
    model.set_gimbal_pitch(0.3)
    assert model.gimbal_angles()[1] == pytest.approx(-model.pitch + 0.3)
    sample = model.truth_sample(12.5)
    assert isinstance(sample, TelemetrySample) and sample.timestamp == 12.5
    assert all(math.isfinite(getattr(sample, f)) for f in FIELDS)
    assert (sample.x, sample.y, sample.z) == model.position()
    assert sample.body_vx == pytest.approx(bvx)


def test_angular_velocity_and_acceleration_during_pitch_step():
    model = flying_model()
    run(model, 0.1, pcmd=(0, 50, 0, 0))
    wx, wy, wz = model.body_angular_velocity()
    assert wy > 0.1 and abs(wx) < 1e-9                # nose going down = +pitch rate about +y
    alpha_y = model.body_angular_acceleration()[1]
    assert alpha_y < 0.0                              # the first-order response is slowing down


# -------------------------------------------------------------- drag steady state
def test_steady_state_speed_matches_tilt_and_drag():
    model = flying_model()
    run(model, 40.0, pcmd=(0, 20, 0, 0))
    theta = 0.2 * math.radians(MAX_TILT_DEG)
    # g tan(theta) = (c1 + c2 v) v
    c1, c2, g = PARAMS['drag_linear'], PARAMS['drag_quadratic'], PARAMS['gravity']
    a = g * math.tan(theta)
    v = (-c1 + math.sqrt(c1 * c1 + 4 * c2 * a)) / (2 * c2)
    assert model.vx == pytest.approx(v, rel=1e-3)
    assert model.body_linear_acceleration()[0] == pytest.approx(0.0, abs=1e-6)


def test_wind_changes_airspeed_drag():
    calm = flying_model()
    windy = flying_model(settings={'wind_x': 3.0})
    run(calm, 60.0, pcmd=(0, 0, 0, 0))
    run(windy, 60.0, pcmd=(0, 0, 0, 0))
    assert calm.vx == pytest.approx(0.0, abs=1e-9)
    assert windy.vx == pytest.approx(3.0, rel=1e-3)   # level attitude: drifts with the air


# ------------------------------------------------------------------- wind gusts
def test_gusts_are_deterministic_for_a_seed():
    settings = {'gust_std_horizontal': 1.0, 'gust_std_vertical': 0.3, 'gust_time_constant': 1.0}
    a = flying_model(settings=settings, seed=7)
    b = flying_model(settings=settings, seed=7)
    c = flying_model(settings=settings, seed=8)
    for m in (a, b, c):
        run(m, 5.0, pcmd=(0, 0, 0, 0))
    assert a.position() == b.position() and a.wind() == b.wind()
    assert a.position() != c.position()
    assert a.wind() != (0.0, 0.0, 0.0)
    a.reset(0, 0, 5, 0, flying=True)                  # reset replays the same gusts
    run(a, 5.0, pcmd=(0, 0, 0, 0), t0=0.0)
    assert a.position() == b.position()


def test_gust_statistics_match_the_intensity():
    settings = {'gust_std_horizontal': 0.8, 'gust_time_constant': 0.5}
    model = flying_model(settings=settings, seed=3)
    values = []
    t = 0.0
    for k in range(60000):                            # 300 s = 600 correlation times
        model.step(DT, t)
        t += DT
        if k % 20 == 0:
            values.append(model.gust[0])
    mean = sum(values) / len(values)
    std = math.sqrt(sum((v - mean) ** 2 for v in values) / len(values))
    assert std == pytest.approx(0.8, rel=0.15)
    assert model.gust[2] == 0.0


# -------------------------------------------------------------- command timeout
def test_hover_in_place_on_command_timeout():
    model = flying_model()
    t = run(model, 3.0, pcmd=(0, 40, 0, 20))
    assert model.vx > 2.0 and model.commanding
    t = run(model, 0.4)                                # shorter than the 0.5 s timeout: still commanded
    assert model.commanding and model.pitch > 0.1
    run(model, 8.0)
    assert not model.commanding
    stopped = model.position()
    run(model, 3.0)
    assert math.sqrt(model.vx ** 2 + model.vy ** 2 + model.vz ** 2) < 0.01
    moved = math.sqrt(sum((a - b) ** 2 for a, b in zip(model.position(), stopped)))
    assert moved < 0.01
    assert model.state == FLYING
    # a new command stream takes over again
    run(model, 1.0, pcmd=(0, -40, 0, 0))
    assert model.commanding and model.vx < -0.5


def test_hover_holds_against_wind():
    model = flying_model(settings={'wind_y': 4.0})
    run(model, 1.0, pcmd=(0, 0, 0, 0))
    run(model, 20.0)
    assert not model.commanding
    held = model.position()
    run(model, 5.0)
    drift = math.sqrt(sum((a - b) ** 2 for a, b in zip(model.position(), held)))
    assert drift < 0.02 and model.roll > 0.05         # leaning into the wind (+roll = towards -y)


# -------------------------------------------------------------- take-off / landing
def test_takeoff_and_landing():
    model = AnafiModel(PARAMS, settings={'takeoff_altitude': 2.0, 'initial_x': 1.0, 'initial_y': -2.0})
    assert model.state == LANDED and model.position() == (1.0, -2.0, 0.0)
    t = run(model, 1.0, pcmd=(0, 50, 0, 50))          # commands while landed do nothing
    assert model.position() == (1.0, -2.0, 0.0)
    assert not model.land(t)
    assert model.takeoff(t) and model.state == TAKING_OFF
    assert not model.takeoff(t)
    t = run(model, 1.0)
    assert model.state == TAKING_OFF and model.vz > 0.5
    t = run(model, 9.0)
    assert model.state == FLYING
    assert model.position() == pytest.approx((1.0, -2.0, 2.0), abs=0.02)
    assert model.land(t) and model.state == LANDING
    t = run(model, 10.0)
    assert model.state == LANDED
    assert model.position() == pytest.approx((1.0, -2.0, 0.0), abs=0.02)
    assert model.velocity() == (0.0, 0.0, 0.0)
    assert model.takeoff(t)


def test_ground_clamp_while_flying():
    model = flying_model(z=0.5)
    run(model, 3.0, pcmd=(0, 0, 0, -100))
    assert model.z == 0.0 and model.vz == 0.0


def test_bad_pcmd_and_dt_raise():
    model = flying_model()
    with pytest.raises(ValueError):
        model.set_command(0, 101, 0, 0, 0.0)
    with pytest.raises(ValueError):
        model.step(0.0, 0.0)
    assert math.isinf(model.command_age(1.0))           # the rejected PCMD was not recorded


# -------------------------------------------------------------- firmware without a command (anafi_ros.md)
def test_zero_pcmd_levels_out_and_drifts_with_momentum():
    """A streamed PCMD of zeros holds level attitude and 0 m/s climb: the drone does NOT stop."""
    model = flying_model()
    run(model, 4.0, pcmd=(0, 50, 0, 0))
    v0 = model.vx
    assert v0 > 3.0
    run(model, 3.0, pcmd=(0, 0, 0, 0))
    assert model.commanding
    assert abs(model.pitch) < 1e-3 and abs(model.roll) < 1e-9         # level
    assert abs(model.vz) < 1e-6 and model.z == pytest.approx(5.0, abs=0.05)
    # only drag slows it: after 3 s still most of the speed (drag_linear 0.14 1/s, quadratic 0.035 1/m)
    assert 0.4 * v0 < model.vx < v0
    x0 = model.x
    run(model, 1.0, pcmd=(0, 0, 0, 0))
    assert model.x - x0 > 0.4 * v0 * 1.0 * 0.5                     # still travelling


def test_zero_pcmd_drifts_with_the_wind_and_timeout_holds_against_it():
    model = flying_model(settings={'wind_x': 3.0})
    run(model, 30.0, pcmd=(0, 0, 0, 0))
    assert model.commanding and model.vx == pytest.approx(3.0, abs=0.05)   # carried along by the wind
    assert abs(model.pitch) < 1e-9
    run(model, 15.0)                                                        # stream stops: brake and hold
    assert not model.commanding
    held = model.position()
    run(model, 5.0)
    assert math.sqrt(sum((a - b) ** 2 for a, b in zip(model.position(), held))) < 0.02
    assert model.pitch < -0.05                                              # leaning into the wind (nose up)


# -------------------------------------------------------------- fidelity effects
EFFECT_SETTINGS = dict(PARAMS, tilt_attenuation=0.2, max_descent_speed=1.5)


def test_tilt_attenuation_delivers_the_fraction_of_the_commanded_tilt():
    commanded = math.radians(MAX_TILT_DEG) * 0.4                     # PCMD pitch 40 %
    for a in (0.0, 0.2, 0.5):
        model = flying_model(tilt_attenuation=a)
        run(model, 3.0, pcmd=(0, 40, 0, 0))                           # >> attitude time constant
        assert model.pitch == pytest.approx((1.0 - a) * commanded, rel=1e-3)
    model = flying_model(tilt_attenuation=0.3)
    run(model, 3.0, pcmd=(-30, 0, 0, 0))
    assert model.roll == pytest.approx(-0.7 * math.radians(MAX_TILT_DEG) * 0.3, rel=1e-3)


def test_speed_gated_tilt_attenuation_acts_only_above_its_speed():
    """tilt_attenuation_speed v0 / tilt_attenuation_speed_full v1: the whole command below v0, (1 - a) of it from
    v1 on, linear in between (the horizontal speed when the PCMD arrives)."""
    gates = dict(tilt_attenuation=0.2, tilt_attenuation_speed=4.0, tilt_attenuation_speed_full=5.0)
    model = flying_model(**gates)
    for speed, gain in ((0.0, 1.0), (3.9, 1.0), (4.5, 0.9), (5.0, 0.8), (7.0, 0.8)):
        model.vx, model.vy = 0.6 * speed, -0.8 * speed
        assert model.tilt_gain() == pytest.approx(gain, abs=1e-12), speed
    # in flight: a slow cruise gets its whole pitch, a fast one (terminal speed ~6 m/s) 0.8 of it
    slow, fast = flying_model(**gates), flying_model(**gates)
    run(slow, 40.0, pcmd=(0, 10, 0, 0))
    run(fast, 40.0, pcmd=(0, 50, 0, 0))
    assert slow.vx < 3.0 and slow.pitch == pytest.approx(math.radians(MAX_TILT_DEG) * 0.1, rel=1e-3)
    assert fast.vx > 5.5 and fast.pitch == pytest.approx(0.8 * math.radians(MAX_TILT_DEG) * 0.5, rel=1e-3)
    constant = flying_model(tilt_attenuation=0.2)                      # v0 = 0: at any speed, as before
    assert constant.tilt_gain() == pytest.approx(0.8)
    assert constant.delivered_tilt(0.1, -0.2) == pytest.approx((0.08, -0.16))


def test_speed_governor_takes_only_the_driving_part_of_the_tilt():
    """Above its speed the gate cuts the tilt that pushes the drone along its velocity; braking and sideways
    tilt are delivered whole (the hover-brake and failsafe distances do not grow)."""
    model = flying_model(yaw=math.pi / 2, tilt_attenuation=0.2, tilt_attenuation_speed=4.0,
                         tilt_attenuation_speed_full=5.0)
    model.vx, model.vy = 0.0, 6.0                                       # flying nose first (heading +y)
    assert model.delivered_tilt(0.0, 0.2) == pytest.approx((0.0, 0.16))        # driving: 0.8 of it
    assert model.delivered_tilt(0.0, -0.2) == pytest.approx((0.0, -0.2))       # braking: whole
    assert model.delivered_tilt(0.1, 0.0) == pytest.approx((0.1, 0.0))        # sideways: whole
    model.vx, model.vy = 6.0, 0.0                                       # now flying to the right of the nose
    assert model.delivered_tilt(0.1, 0.05) == pytest.approx((0.08, 0.05))      # roll right drives: 0.8 of it
    assert model.delivered_tilt(-0.1, 0.05) == pytest.approx((-0.1, 0.05))


def test_tilt_attenuation_does_not_weaken_the_hover_brake():
    model = flying_model(tilt_attenuation=0.5, settings={'wind_y': 4.0})
    run(model, 1.0, pcmd=(0, 0, 0, 0))
    run(model, 20.0)
    held = model.position()
    run(model, 5.0)
    assert math.sqrt(sum((a - b) ** 2 for a, b in zip(model.position(), held))) < 0.02


def test_max_descent_speed_limits_descent_not_climb():
    model = flying_model(z=50.0, max_descent_speed=1.5)
    run(model, 3.0, pcmd=(0, 0, 0, -100))                              # -2 m/s commanded
    assert model.vz == pytest.approx(-1.5, abs=1e-3)
    run(model, 3.0, pcmd=(0, 0, 0, -50))                               # -1 m/s: below the limit
    assert model.vz == pytest.approx(-1.0, abs=1e-3)
    run(model, 3.0, pcmd=(0, 0, 0, 100))                               # climbs are not limited
    assert model.vz == pytest.approx(2.0, abs=1e-3)
    unlimited = flying_model(z=50.0)
    run(unlimited, 3.0, pcmd=(0, 0, 0, -100))
    assert unlimited.vz == pytest.approx(-2.0, abs=1e-3)


def test_vertical_acceleration_limit_ramps_a_large_step_and_leaves_a_small_one():
    """tau 0.3 s, A 2 m/s^2: a 2 m/s step (first-order start 6.7 m/s^2) ramps at A up and down until (c - v) / tau
    < A; a 0.5 m/s step (1.7 m/s^2) never reaches the limit and is the first order bit for bit."""
    for pcmd, sign in (((0, 0, 0, 100), 1.0), ((0, 0, 0, -100), -1.0)):
        model = flying_model(z=50.0, vertical_acceleration_limit=2.0)
        previous, t = model.vz, model.time
        for _ in range(10):
            t = run(model, 0.05, pcmd=pcmd, t0=t, command_period=0.05)
            assert abs(model.vz - previous) <= 2.0 * 0.05 + 1e-9               # never faster than A
            previous = model.vz
        assert model.vz == pytest.approx(sign * 1.0, abs=0.01)                  # 0.5 s at 2 m/s^2
        run(model, 3.0, pcmd=pcmd)
        assert model.vz == pytest.approx(sign * 2.0, abs=1e-3)                  # the command is reached
    unlimited = flying_model(z=50.0)
    run(unlimited, 0.5, pcmd=(0, 0, 0, 100))
    assert unlimited.vz > 1.5                                                   # the first order alone
    small, plain = flying_model(vertical_acceleration_limit=2.0), flying_model()
    for model in (small, plain):
        run(model, 2.0, pcmd=(0, 0, 0, 25))
    assert small.truth_sample() == plain.truth_sample()


def test_tilt_rate_limit_ramps_a_large_tilt_step_and_leaves_a_small_one():
    """tau 0.2 s, R 1 rad/s: a full-tilt roll+pitch step (first-order start ~3.8 rad/s) turns the tilt vector at
    R exactly, in the commanded direction; a 2 % step (~0.05 rad/s) is the first order bit for bit."""
    model = flying_model(tilt_rate_limit=1.0)
    previous, t = (model.roll, model.pitch), model.time
    for _ in range(6):
        t = run(model, 0.05, pcmd=(60, 80, 0, 0), t0=t, command_period=0.05)
        step = math.hypot(model.roll - previous[0], model.pitch - previous[1])
        assert step == pytest.approx(1.0 * 0.05, rel=1e-6)                       # at R, not faster
        previous = (model.roll, model.pitch)
    assert model.roll / model.pitch == pytest.approx(60.0 / 80.0, rel=1e-6)      # along the command
    unlimited = flying_model()
    run(unlimited, 0.3, pcmd=(60, 80, 0, 0))
    assert math.hypot(unlimited.roll, unlimited.pitch) > 1.3 * math.hypot(model.roll, model.pitch)   # 0.42 vs 0.30
    small, plain = flying_model(tilt_rate_limit=1.0), flying_model()
    for m in (small, plain):
        run(m, 2.0, pcmd=(2, -2, 0, 0))
    assert small.truth_sample() == plain.truth_sample()


def test_gyroscopic_coupling_turns_and_slows_the_tilt_step_only_while_yawing():
    """G = -1 s: without a yaw rate the model is the first order bit for bit; while yawing at r each roll/pitch
    step is the first-order step multiplied by (I - G r J)^-1 in the (forward, left) plane: turned by atan(G r)
    and shortened by 1 / sqrt(1 + (G r)^2)."""
    calm, plain = flying_model(gyroscopic_coupling=-1.0), flying_model()
    for m in (calm, plain):
        run(m, 1.0, pcmd=(40, 60, 0, 0))
    assert calm.truth_sample() == plain.truth_sample()
    model = flying_model(gyroscopic_coupling=-1.0)
    t = run(model, 2.0, pcmd=(0, 0, -100, 0))      # PCMD yaw + = clockwise: yawing counter-clockwise, level
    r = model.yaw_rate
    assert r > 1.0                                                  # rad/s (counter-clockwise)
    roll0, pitch0 = model.roll, model.pitch
    model.set_command(0, 40, -100, 0, t)
    expected = None
    for k in range(int(round((PARAMS['attitude_delay'] + 0.05) / DT))):   # the step arrives after the delay
        before = (model.roll, model.pitch, model.yaw_rate)
        model.step(DT, t + k * DT)
        if expected is None and (model.roll, model.pitch) != before[:2]:
            c = 1.0 - math.exp(-DT / PARAMS['attitude_time_constant'])
            d_pitch, d_roll = c * (math.radians(40 * model.mapping.max_tilt_deg / 100.0) - before[1]), \
                c * (0.0 - before[0])
            a = -1.0 * before[2]
            forward, left = d_pitch, -d_roll                       # (forward, left) = (pitch, -roll)
            turned = ((forward - a * left) / (1 + a * a), (left + a * forward) / (1 + a * a))
            expected = (before[0] - turned[1], before[1] + turned[0])
            assert (model.roll, model.pitch) == pytest.approx(expected, abs=1e-12)
            step = math.hypot(model.roll - before[0], model.pitch - before[1])
            assert step == pytest.approx(math.hypot(d_roll, d_pitch) / math.sqrt(1 + a * a), rel=1e-9)
            # G < 0, r > 0: the step toward +pitch (forward) is turned clockwise, i.e. to the right: + roll
            assert model.roll - before[0] > 0.0
    assert expected is not None and (roll0, pitch0) == (0.0, 0.0)


def test_yaw_holds_the_tilt_and_turns_it_with_the_body():
    """yaw_tilt_authority c, yaw_tilt_precession w (with G = 0): without a yaw rate nothing changes, bit for bit;
    yawing at |r| > 1 / (c tau) the roll/pitch loop has no authority left: a tilt held before the yaw does not
    follow the new (level) setpoint, it keeps its magnitude and turns in the (roll, pitch) plane by w r dt per
    step (counter-clockwise with a counter-clockwise yaw for w > 0); with less yaw the loop's rate is reduced."""
    calm, plain = flying_model(yaw_tilt_authority=3.0, yaw_tilt_precession=1.2), flying_model()
    for m in (calm, plain):
        run(m, 1.0, pcmd=(40, 60, 0, 0))
    assert calm.truth_sample() == plain.truth_sample()
    tau = PARAMS['attitude_time_constant']
    model = flying_model(yaw_tilt_authority=3.0, yaw_tilt_precession=1.2)
    t = run(model, 1.0, pcmd=(0, 80, 0, 0))          # tilted forward (24.5 deg)
    t = run(model, 1.0, t0=t, pcmd=(0, 80, -100, 0))  # then yawing counter-clockwise at the max rate
    r = model.yaw_rate
    assert r > 1.0 / (3.0 * tau)                                    # beyond the authority: the tilt is held
    model.set_command(0, 0, -100, 0, t)                             # level setpoint, still yawing
    t = run(model, PARAMS['attitude_delay'] + 0.05, t0=t, pcmd=None)
    before = (model.roll, model.pitch, model.yaw_rate)
    model.step(DT, t)
    a = 1.2 * before[2] * DT
    expected = (math.cos(a) * before[0] - math.sin(a) * before[1], math.sin(a) * before[0] + math.cos(a) * before[1])
    assert (model.roll, model.pitch) == pytest.approx(expected, abs=1e-12)
    assert math.hypot(model.roll, model.pitch) == pytest.approx(math.hypot(before[0], before[1]), rel=1e-12)
    assert math.hypot(before[0], before[1]) > math.radians(15.0)   # held through the level setpoint
    # the loop's rate reduced by c |r| below that: the same step without the precession
    slow = flying_model(yaw_tilt_authority=3.0)
    t = run(slow, 2.0, pcmd=(0, 40, -20, 0))                        # a slow yaw
    r = slow.yaw_rate
    assert 0.0 < 3.0 * abs(r) < 1.0 / tau
    slow.set_command(0, 0, -20, 0, t)
    t = run(slow, PARAMS['attitude_delay'] + 0.05, t0=t, pcmd=None)
    before = (slow.roll, slow.pitch, slow.yaw_rate)
    slow.step(DT, t)
    lag = 1.0 - math.exp(-(1.0 / tau - 3.0 * abs(before[2])) * DT)
    assert (slow.roll, slow.pitch) == pytest.approx(((1 - lag) * before[0], (1 - lag) * before[1]), abs=1e-12)


def test_every_effect_off_is_bit_for_bit_the_model_without_them():
    from anafi_sim.sim.drone_model import EFFECTS_OFF
    plain = flying_model(settings={'wind_x': 1.0, 'gust_std_horizontal': 0.5}, seed=3)
    off = flying_model(settings={'wind_x': 1.0, 'gust_std_horizontal': 0.5}, seed=3, **EFFECTS_OFF)
    for model in (plain, off):
        for pcmd in ((10, 40, 20, -100), (-30, 0, -50, 60), (0, 0, 0, 0)):
            run(model, 2.0, pcmd=pcmd)
        run(model, 2.0)                                               # timeout: brake
    assert plain.truth_sample() == off.truth_sample()
    assert set(validate_model_params(dict(PARAMS, **EFFECTS_OFF))) == set(MODEL_KEYS)


@pytest.mark.parametrize('key, value', [
    ('tilt_attenuation', 1.0), ('tilt_attenuation', -0.1), ('tilt_attenuation', float('nan')),
    ('tilt_attenuation_speed', -1.0), ('tilt_attenuation_speed_full', 'fast'),
    ('max_descent_speed', -1.0), ('max_descent_speed', 'fast'), ('max_descent_speed', True),
    ('vertical_acceleration_limit', -1.0), ('vertical_acceleration_limit', float('nan')),
    ('tilt_rate_limit', -0.5), ('tilt_rate_limit', 'fast'),
    ('gyroscopic_coupling', float('nan')), ('gyroscopic_coupling', 'strong'), ('gyroscopic_coupling', True),
    ('yaw_tilt_authority', -1.0), ('yaw_tilt_authority', float('inf')), ('yaw_tilt_precession', float('nan')),
    ('yaw_tilt_precession', 'fast'),
    ('estimate_position_fusion', 'yes'), ('estimate_position_fix_gain', -0.2), ('estimate_quantum_x', float('inf'))])
def test_bad_effect_values_raise_value_error(key, value):
    with pytest.raises(ValueError, match=key):
        AnafiModel(params(**{key: value}))


def test_speed_gate_needs_a_full_speed_above_its_start():
    with pytest.raises(ValueError, match='tilt_attenuation_speed_full'):
        AnafiModel(params(tilt_attenuation=0.2, tilt_attenuation_speed=4.0, tilt_attenuation_speed_full=4.0))


def test_fitted_config_file_is_valid_and_has_every_effect_on():
    from anafi_sim import paths
    from anafi_sim.sim.drone_model import EFFECTS_OFF
    fitted = load_model_params(paths.config_path('anafi_model_fitted.yaml'))
    assert list(fitted) == list(MODEL_KEYS)
    assert fitted['estimate_position_fusion'] is True
    assert fitted['tilt_attenuation'] > 0.0 and fitted['max_descent_speed'] > 0.0
    assert fitted['vertical_acceleration_limit'] > 0.0 and fitted['tilt_rate_limit'] > 0.0
    assert fitted['gyroscopic_coupling'] < 0.0 and fitted['yaw_tilt_authority'] > 0.0
    assert fitted['yaw_tilt_precession'] > 0.0
    shipped = load_model_params(DEFAULT_MODEL_FILE)
    from anafi_sim.sim.drone_model import EFFECT_GROUPS
    refitted = set(k for keys in EFFECT_GROUPS.values() for k in keys)     # an effect's keys, refits included
    for key in MODEL_KEYS:                                             # the same fit, only the effects differ
        if key not in EFFECTS_OFF and key not in refitted:
            assert fitted[key] == shipped[key], key
    AnafiModel(fitted)


def test_unreadable_model_file_is_a_value_error(tmp_path):
    with pytest.raises(ValueError, match='cannot be read'):
        load_model_params(str(tmp_path / 'missing.yaml'))
    bad = tmp_path / 'bad.yaml'
    bad.write_text('gravity: [1, 2\n')
    with pytest.raises(ValueError, match='not valid YAML at line'):
        load_model_params(str(bad))
    wrong = tmp_path / 'wrong.yaml'
    wrong.write_text(yaml.safe_dump(dict(PARAMS, tilt_attenuation=1.5)))
    with pytest.raises(ValueError, match='tilt_attenuation'):
        load_model_params(str(wrong))


def test_translate_moves_the_drone_and_nothing_else():
    """A translation of the world: a moved copy flies the same commands to the same positions + d."""
    a, b = flying_model(z=5.0), flying_model(z=5.0)
    for m in (a, b):
        run(m, 2.0, pcmd=(5, 10, 0, 20))
    b.translate(1.0, -2.0, 0.5)
    assert b.position() == pytest.approx((a.position()[0] + 1.0, a.position()[1] - 2.0, a.position()[2] + 0.5))
    assert b.velocity() == pytest.approx(a.velocity())
    for m in (a, b):                 # no command: the firmware brakes and holds a point that moved along
        run(m, 8.0, pcmd=None, t0=2.0)
    assert b.position() == pytest.approx((a.position()[0] + 1.0, a.position()[1] - 2.0, a.position()[2] + 0.5),
                                         abs=1e-9)
    with pytest.raises(ValueError):
        b.translate(float('nan'), 0.0)


def test_translate_moves_the_hold_point_of_a_hovering_drone():
    model = flying_model(z=5.0)                       # hovering: the firmware holds (0, 0, 5)
    run(model, 1.0)
    model.translate(2.0, -1.0, 1.0)
    run(model, 10.0, t0=1.0)
    assert model.position() == pytest.approx((2.0, -1.0, 6.0), abs=1e-6)
    model.translate(0.0, 0.0, -10.0)                  # never below the ground, the hold with it
    assert model.position()[2] == 0.0
