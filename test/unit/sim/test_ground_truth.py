"""GroundTruthInterface (decimation, staleness, restarts, health) and the pose conversions, hand-checked."""
import math

import numpy as np
import pytest

from anafi_control import frames
from anafi_sim.interface import ground_truth as gt
from anafi_sim.telemetry.protocol import FIELDS, PHYSICAL_BOUNDS, TelemetrySample
from hypothesis import given, strategies as st


def sample_at(ts, **values):
    fields = dict((f, 0.0) for f in FIELDS)
    fields['timestamp'] = ts
    fields.update(values)
    return TelemetrySample(**fields)


def run(core, rate_hz, duration, t0=0.0, wall0=100.0):
    """Feed samples at rate_hz for duration [s] (timestamps accumulated like a simulator would); return published."""
    out = []
    ts = t0
    n = int(round(duration * rate_hz))
    for _ in range(n):
        s = core.on_sample(sample_at(ts), wall0 + ts - t0)
        if s is not None:
            out.append(s)
        ts += 1.0 / rate_hz
    return out


def rotmat(q):
    """3x3 rotation matrix of a quaternion (x, y, z, w) (standard formula, independent of frames.py)."""
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


# --- decimation ------------------------------------------------------------------

def test_source_at_the_publish_rate_publishes_every_sample():
    core = gt.GroundTruthInterface(publish_rate=100.0)
    out = run(core, 100.0, 20.0)
    assert len(out) == 2000
    assert core.decimated == 0


@pytest.mark.parametrize('source_hz', [20.0, 50.0, 99.0])
def test_slower_source_publishes_every_sample(source_hz):
    core = gt.GroundTruthInterface(publish_rate=100.0)
    assert len(run(core, source_hz, 5.0)) == int(round(5.0 * source_hz))


@pytest.mark.parametrize('source_hz', [150.0, 200.0, 250.0, 400.0, 1000.0])
def test_faster_source_is_decimated_to_the_publish_rate(source_hz):
    core = gt.GroundTruthInterface(publish_rate=100.0)
    out = run(core, source_hz, 10.0)
    assert abs(len(out) - 1000) <= 1
    gaps = np.diff([s.timestamp for s in out])
    assert np.mean(gaps) == pytest.approx(0.01, rel=1e-3)   # the average rate is the publish rate
    assert gaps.max() <= 0.01 + 1.0 / source_hz + 1e-9     # no sample held back longer than one source period
    if source_hz % 100.0 == 0.0:                            # integer ratio: exactly every n-th sample
        np.testing.assert_allclose(gaps, 0.01, atol=1e-9)
    assert core.decimated + core.published == core.received


def test_publish_rate_parameter_is_used():
    core = gt.GroundTruthInterface(publish_rate=25.0)
    assert len(run(core, 100.0, 4.0)) == 100


def test_duplicate_timestamp_is_not_republished():
    core = gt.GroundTruthInterface()
    assert core.on_sample(sample_at(1.0), 0.0) is not None
    assert core.on_sample(sample_at(1.0), 0.01) is None
    assert core.duplicates == 1


@pytest.mark.parametrize('field', ['x', 'yaw', 'timestamp', 'gimbal_pitch', 'body_wz'])
@pytest.mark.parametrize('bad', [float('nan'), float('inf'), -float('inf')])
def test_nonfinite_sample_is_rejected_and_does_not_refresh(field, bad):
    core = gt.GroundTruthInterface(stale_timeout=0.5)
    assert core.on_sample(sample_at(1.0), 10.0) is not None
    values = {field: bad} if field != 'timestamp' else {}
    s = sample_at(bad if field == 'timestamp' else 1.01, **values)
    assert core.on_sample(s, 10.4) is None
    assert core.rejected_nonfinite == 1
    assert core.is_stale(10.6)  # the rejected sample did not count as fresh
    assert core.last_timestamp == 1.0


# --- staleness and restarts ------------------------------------------------------------

def test_stale_before_first_sample_and_after_timeout():
    core = gt.GroundTruthInterface(stale_timeout=0.5)
    assert core.is_stale(0.0)
    assert core.sample_age(0.0) is None
    core.on_sample(sample_at(3.0), 10.0)
    assert not core.is_stale(10.0)
    assert not core.is_stale(10.49)
    assert core.is_stale(10.51)
    assert core.sample_age(10.25) == pytest.approx(0.25)
    core.on_sample(sample_at(3.01), 10.6)
    assert not core.is_stale(10.7)


def test_outage_notices_once_then_every_repeat_and_once_when_flowing_again():
    core = gt.GroundTruthInterface(stale_timeout=0.5)
    assert core.outage_notice(0.0, repeat=10.0) == 'stale'         # nothing received yet
    assert [core.outage_notice(t, repeat=10.0) for t in (1.0, 9.9)] == [None, None]
    assert core.outage_notice(10.0, repeat=10.0) == 'stale'
    core.on_sample(sample_at(3.0), 11.0)
    assert core.outage_notice(11.1, repeat=10.0) == 'flowing'
    assert core.outage_notice(11.2, repeat=10.0) is None
    assert core.outage_notice(12.0, repeat=10.0) == 'stale'        # stale again: told at once


def test_decimated_samples_still_keep_it_fresh():
    core = gt.GroundTruthInterface(publish_rate=1.0, stale_timeout=0.5)
    run(core, 100.0, 3.0, wall0=0.0)
    assert 3 <= core.published <= 4
    assert not core.is_stale(2.99 + 0.4)


def test_simulator_restart_resets_decimation_and_is_reported():
    core = gt.GroundTruthInterface(publish_rate=100.0)
    run(core, 200.0, 5.0, t0=100.0)
    assert core.sim_restarts == 0
    first = core.on_sample(sample_at(0.0), 200.0)
    assert first is not None and first.timestamp == 0.0     # published at once, not held back by the old grid
    assert core.restarted and core.sim_restarts == 1
    assert core.on_sample(sample_at(0.005), 200.005) is None  # decimation restarts from the new timeline
    assert not core.restarted
    assert core.on_sample(sample_at(0.010), 200.01) is not None
    out = run(core, 200.0, 5.0, t0=0.015, wall0=200.015)
    assert abs(len(out) - 500) <= 1
    assert core.sim_restarts == 1


def test_small_step_back_is_a_restart_too():
    core = gt.GroundTruthInterface()
    core.on_sample(sample_at(5.0), 0.0)
    assert core.on_sample(sample_at(4.999), 0.01) is not None
    assert core.sim_restarts == 1


# --- health ------------------------------------------------------------------------------

def test_health_levels():
    core = gt.GroundTruthInterface(publish_rate=100.0, stale_timeout=0.5)
    h = core.health(0.0)
    assert h.level == gt.ERROR and 'no telemetry' in h.message
    run(core, 100.0, 2.0, wall0=0.0)
    proc = dict(running=True, restarts=0, starts=1)
    parse = dict(lines=100, malformed=0, nonfinite=0, partial_samples=0, unknown_key=3, blank=0)
    h = core.health(2.0, parse, proc)
    assert h.level == gt.OK, h
    values = dict(h.values)
    assert float(values['publish rate [Hz]']) == pytest.approx(100.0, abs=1.0)
    assert values['sim restarts'] == '0'
    assert values['process restarts'] == '0'
    assert values['parse unknown key'] == '3'
    # a process restart is a WARN once, and stays visible in the values
    proc = dict(running=True, restarts=1, starts=2)
    h = core.health(2.0, parse, proc)
    assert h.level == gt.WARN and 'process restarts' in h.message
    h = core.health(2.0, parse, proc)
    assert h.level == gt.OK and dict(h.values)['process restarts'] == '1'
    # stale -> ERROR
    h = core.health(2.0 + 0.6, parse, dict(running=False, restarts=1))
    assert h.level == gt.ERROR and 'stale' in h.message and 'not running' in h.message
    assert float(dict(h.values)['sample age [s]']) == pytest.approx(0.61, abs=0.01)


def test_health_is_error_while_the_process_is_down_or_restarting_until_samples_flow():
    core = gt.GroundTruthInterface(publish_rate=100.0, stale_timeout=0.5)
    core.on_process_start()
    run(core, 100.0, 2.0, wall0=0.0)
    proc = dict(running=True, restarts=0, starts=1)
    assert core.health(2.0, {}, proc).level == gt.OK
    # kill -9: the process is gone, samples are still fresh (< stale_timeout): ERROR, not OK
    h = core.health(2.05, {}, dict(running=False, restarts=0, starts=1))
    assert h.level == gt.ERROR and 'not running' in h.message
    # restarted: ERROR until a sample arrives, and the restart note is in the message
    core.on_process_start()
    h = core.health(2.1, {}, dict(running=True, restarts=1, starts=2))
    assert h.level == gt.ERROR and 'restarted, no sample since' in h.message and 'process restarts' in h.message
    assert core.health(2.2, {}, dict(running=True, restarts=1, starts=2)).level == gt.ERROR
    core.on_sample(sample_at(2.5), 2.5)
    assert core.health(2.5, {}, dict(running=True, restarts=1, starts=2)).level != gt.ERROR


def test_restart_note_is_kept_when_the_rate_warning_wins():
    core = gt.GroundTruthInterface(publish_rate=100.0)
    run(core, 50.0, 2.0, wall0=0.0)
    h = core.health(1.99, {}, dict(running=True, restarts=1, starts=2))
    assert h.level == gt.WARN and 'Hz' in h.message and 'process restarts' in h.message


def test_health_warns_on_low_rate_and_lost_samples():
    core = gt.GroundTruthInterface(publish_rate=100.0)
    run(core, 50.0, 2.0, wall0=0.0)
    h = core.health(1.99)
    assert h.level == gt.WARN and 'Hz' in h.message
    core = gt.GroundTruthInterface(publish_rate=100.0)
    run(core, 100.0, 2.0, wall0=0.0)
    assert core.health(1.99, dict(partial_samples=0)).level == gt.OK
    assert core.health(1.99, dict(partial_samples=2)).level == gt.WARN
    assert core.health(1.99, dict(partial_samples=2)).level == gt.OK
    assert core.health(1.99, dict(partial_samples=2, nonfinite=1)).level == gt.WARN
    # decoration lines (malformed / unknown keys) are shown but do not make the interface unhealthy
    h = core.health(1.99, dict(partial_samples=2, nonfinite=1, malformed=50, unknown_key=80))
    assert h.level == gt.OK and dict(h.values)['parse malformed'] == '50'


def test_bad_construction_parameters():
    for kwargs in (dict(publish_rate=0.0), dict(publish_rate=-1.0), dict(publish_rate=float('nan')),
                   dict(stale_timeout=0.0), dict(stale_timeout=float('inf')), dict(rate_tolerance=1.0)):
        with pytest.raises(ValueError):
            gt.GroundTruthInterface(**kwargs)


# --- conversions ----------------------------------------------------------------------------

def test_odometry_pose_and_body_twist():
    s = sample_at(1.0, x=1.0, y=-2.0, z=3.0, yaw=math.pi / 2, body_vx=0.5, body_vy=0.25, body_vz=-0.1,
                  vx=-0.25, vy=0.5, vz=-0.1, body_wx=0.01, body_wy=0.02, body_wz=0.3)
    odo = gt.odometry(s)
    assert odo.position == (1.0, -2.0, 3.0)
    np.testing.assert_allclose(odo.orientation, (0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)), atol=1e-12)
    assert odo.linear == (0.5, 0.25, -0.1)     # body frame, as the child frame of the Odometry
    assert odo.angular == (0.01, 0.02, 0.3)    # angular, not the linear velocity (the reference bug)
    # consistency: the body twist rotated by the orientation is the world velocity
    np.testing.assert_allclose(rotmat(odo.orientation).dot(odo.linear), (s.vx, s.vy, s.vz), atol=1e-12)


def test_stability_axes_keep_heading_only_and_compose_to_the_body():
    roll, pitch, yaw = 0.1, -0.2, 2.5
    t, q = gt.stability_axes_pose(1.0, 2.0, 3.0, yaw)
    assert t == (1.0, 2.0, 3.0)
    np.testing.assert_allclose(q, (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)), atol=1e-12)
    r = rotmat(q)
    np.testing.assert_allclose(r[2], (0.0, 0.0, 1.0), atol=1e-12)  # z up: horizontal x/y plane
    t2, q2 = gt.base_link_in_stability_axes(roll, pitch)
    assert t2 == (0.0, 0.0, 0.0)
    full = rotmat(q).dot(rotmat(q2))
    np.testing.assert_allclose(full, frames.rotation_matrix(roll, pitch, yaw), atol=1e-12)
    # base_link relative to the stability axes carries no heading
    assert frames.yaw_from_quaternion(*q2) == pytest.approx(0.0, abs=1e-12)


def test_camera_pose_level_drone_no_gimbal():
    pos, q = gt.camera_pose((1.0, 2.0, 3.0), 0.0, 0.0, 0.0, 0.0, 0.0)
    np.testing.assert_allclose(pos, (1.1, 2.0, 3.0), atol=1e-12)
    np.testing.assert_allclose(q, (0.0, 0.0, 0.0, 1.0), atol=1e-12)


def test_camera_pose_yaw_180():
    pos, q = gt.camera_pose((1.0, 2.0, 3.0), 0.0, 0.0, math.pi, 0.0, 0.0)
    np.testing.assert_allclose(pos, (0.9, 2.0, 3.0), atol=1e-12)   # 0.1 m ahead = towards -x
    np.testing.assert_allclose(rotmat(q).dot((1, 0, 0)), (-1.0, 0.0, 0.0), atol=1e-12)


def test_camera_pose_yaw_180_gimbal_pitch_down():
    pos, q = gt.camera_pose((1.0, 2.0, 3.0), 0.0, 0.0, math.pi, 0.0, 0.5)
    np.testing.assert_allclose(pos, (0.9, 2.0, 3.0), atol=1e-12)   # gimbal turns, does not move, the camera
    view = rotmat(q).dot((1, 0, 0))
    np.testing.assert_allclose(view, (-math.cos(0.5), 0.0, -math.sin(0.5)), atol=1e-12)  # backwards and down
    np.testing.assert_allclose(rotmat(q).dot((0, 1, 0)), (0.0, -1.0, 0.0), atol=1e-12)


def test_camera_pose_body_pitch_moves_the_offset_and_gimbal_compensates():
    pos, q = gt.camera_pose((0.0, 0.0, 1.0), 0.0, 0.3, 0.0, 0.0, -0.3)
    np.testing.assert_allclose(pos, (0.1 * math.cos(0.3), 0.0, 1.0 - 0.1 * math.sin(0.3)), atol=1e-12)
    np.testing.assert_allclose(q, (0.0, 0.0, 0.0, 1.0), atol=1e-12)  # camera level again


def test_camera_pose_gimbal_roll_with_yaw_90_and_custom_offset():
    pos, q = gt.camera_pose((0.0, 0.0, 0.0), 0.0, 0.0, math.pi / 2, 0.2, 0.0, offset=(0.1, 0.05, -0.02))
    np.testing.assert_allclose(pos, (-0.05, 0.1, -0.02), atol=1e-12)
    np.testing.assert_allclose(rotmat(q).dot((0, 1, 0)), (-math.cos(0.2), 0.0, math.sin(0.2)), atol=1e-12)
    np.testing.assert_allclose(rotmat(q).dot((1, 0, 0)), (0.0, 1.0, 0.0), atol=1e-12)


def test_camera_pose_equals_the_tf_chain():
    roll, pitch, yaw, groll, gpitch = 0.05, -0.1, -2.0, 0.1, 0.7
    p = (3.0, -1.0, 2.0)
    pos, q = gt.camera_pose(p, roll, pitch, yaw, groll, gpitch)
    t1, q1 = gt.stability_axes_pose(p[0], p[1], p[2], yaw)
    _, q2 = gt.base_link_in_stability_axes(roll, pitch)
    t3, q3 = gt.camera_in_base_link(groll, gpitch)
    r12 = rotmat(q1).dot(rotmat(q2))
    np.testing.assert_allclose(pos, np.add(t1, r12.dot(t3)), atol=1e-12)
    np.testing.assert_allclose(rotmat(q), r12.dot(rotmat(q3)), atol=1e-12)
    assert sum(v * v for v in q) == pytest.approx(1.0)


def test_camera_optical_frame_looks_along_the_camera_x_axis():
    R = frames.rotation_matrix(*frames.quaternion_to_euler(*gt.CAMERA_OPTICAL_ROTATION))
    # optical z (view) = camera x, optical x (image right) = camera -y, optical y (image down) = camera -z
    assert np.allclose(R[:, 2], [1, 0, 0]) and np.allclose(R[:, 0], [0, -1, 0]) and np.allclose(R[:, 1], [0, 0, -1])


# --- shared pieces (also the mirror's) ---------------------------------------------------------

def test_stamp_decimator_grid_jitter_and_reanchor():
    d = gt.StampDecimator(0.01)
    passed = [k for k in range(40) if d.accept(k * 0.004)]           # 250 Hz -> 100 Hz on the grid
    assert len(passed) == 16 and passed[:4] == [0, 3, 5, 8]                    # 0.16 s: 16 grid points
    d = gt.StampDecimator(0.01)
    assert d.accept(0.0) and not d.accept(0.0089) and d.accept(0.0091, early=0.001)   # jitter tolerance
    assert d.accept(0.5) and not d.accept(0.505) and d.accept(0.51)              # slower source: re-anchored
    d.reset()
    assert d.accept(0.2)


def test_rate_limiter_passes_a_jittered_source_at_the_rate_and_thins_a_faster_one():
    def passed(limiter, stamps, early=0.003):
        return [t for t in stamps if limiter.accept(t, early=early)]
    # 100 Hz receipt times with jitter: late, early, a delayed pair -- every sample passes
    jittered = [0.0, 0.014, 0.0141, 0.026, 0.041, 0.047, 0.06, 0.07, 0.0801, 0.09]
    assert passed(gt.RateLimiter(0.01), jittered) == jittered
    # the grid decimator thins the same stream (its grid drifts from the source's phase)
    assert len(passed(gt.StampDecimator(0.01), jittered)) < len(jittered)
    # a faster source: 250 Hz in -> 100 Hz out (the 3 of the first burst on top)
    fast = [k * 0.004 for k in range(250)]
    assert abs(len(passed(gt.RateLimiter(0.01), fast, early=0.0)) - 100) <= 3
    # one burst of 10 at once passes 3; reset: a full bucket again
    limiter = gt.RateLimiter(0.01)
    assert len(passed(limiter, [1.0] * 10, early=0.0)) == 3
    limiter.reset()
    assert limiter.accept(0.5)
    with pytest.raises(ValueError):
        gt.RateLimiter(0.0)


def test_rate_window_and_new_counts():
    w = gt.RateWindow(1.0)
    for i in range(50):
        w.add(10.0 + i * 0.02)
    assert w.rate(10.99) == 50.0 and w.rate(11.5) == 25.0 and w.rate(20.0) == 0.0
    n = gt.NewCounts()
    assert n.news({'stale samples': 0, 'restarts': 2}) == ['2 new restarts']
    assert n.news({'stale samples': 3, 'restarts': 2}) == ['3 new stale samples']
    assert n.news({'stale samples': 3, 'restarts': 2}) == []


@pytest.mark.parametrize('field, bad', [('x', 1e308), ('z', -2e5), ('vx', 5e3), ('body_wz', 1e6), ('timestamp', -1.0)])
def test_a_sample_beyond_physical_bounds_is_malformed_not_ground_truth(field, bad):
    core = gt.GroundTruthInterface(stale_timeout=0.5)
    assert core.on_sample(sample_at(1.0), 10.0) is not None
    s = sample_at(bad if field == 'timestamp' else 1.01, **({field: bad} if field != 'timestamp' else {}))
    assert core.on_sample(s, 10.4) is None
    assert core.rejected_beyond_bounds == 1 and core.last_timestamp == 1.0
    values = dict(core.health(10.45).values)
    assert values['rejected samples beyond physical bounds'] == '1 (last: %s)' % field


@given(st.sampled_from(FIELDS), st.floats(allow_nan=False, allow_infinity=False))
def test_published_ground_truth_stays_within_physical_bounds(field, value):
    core = gt.GroundTruthInterface()
    out = core.on_sample(sample_at(1.0, **({field: value} if field != 'timestamp' else {})) if field != 'timestamp'
                         else sample_at(value), 10.0)
    if out is not None:
        assert all(abs(v) <= PHYSICAL_BOUNDS[f] for f, v in zip(FIELDS, out)) and out.timestamp >= 0.0
