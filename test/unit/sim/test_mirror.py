"""Mirror core: model states from ground truth (hand-checked), twist rotation, rejection, rate limit, spawns."""
import math

import numpy as np
import pytest
from conftest import ROTATION_TOLERANCE, quaternion_angle

from anafi_control import frames
from anafi_sim.interface import ground_truth
from anafi_sim.gazebo import mirror

Q_IDENTITY = (0.0, 0.0, 0.0, 1.0)


def q_yaw(yaw):
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def axis(q, i):
    """World direction of body axis i of quaternion q (hand-built rotation via Hamilton products)."""
    v = [0.0, 0.0, 0.0, 0.0]
    v[i] = 1.0
    conj = (-q[0], -q[1], -q[2], q[3])
    r = frames.quaternion_multiply(frames.quaternion_multiply(q, tuple(v)), conj)
    return np.array(r[:3])


def spawned_mirror(**kwargs):
    m = mirror.Mirror(**kwargs)
    m.spawn.on_world(True, 'rosrpc://w:1', 0.0)
    for action, name in m.spawn.due_actions(0.0):
        assert action == 'spawn'
        m.spawn.on_spawn_result(name, True, 'ok', 0.0)
    assert m.spawn.all_spawned
    return m


# --- names ----------------------------------------------------------------------------------

def test_model_names_derive_from_the_drone_name():
    assert mirror.model_names('anafi') == ('anafi', 'anafi_camera')
    assert mirror.model_names('/bebop2/') == ('bebop2', 'bebop2_camera')
    assert mirror.model_names('a', 'body', 'cam') == ('body', 'cam')
    with pytest.raises(ValueError):
        mirror.Mirror(drone_model_name='x', camera_model_name='x')


# --- twist rotation -------------------------------------------------------------------------

def test_twist_rotation_body_to_world():
    # yaw 90 deg: body forward = world +y, body left = world -x
    lin, ang = mirror.body_twist_to_world(q_yaw(math.pi / 2), (1.0, 2.0, 0.5), (0.1, 0.0, 0.3))
    assert lin == pytest.approx((-2.0, 1.0, 0.5))
    assert ang == pytest.approx((0.0, 0.1, 0.3))
    # roll 90 deg: body z (up) points to world -y, body y (left) points to world +z
    q_roll = frames.euler_to_quaternion(math.pi / 2, 0.0, 0.0)
    lin, ang = mirror.body_twist_to_world(q_roll, (0.0, 1.0, 1.0), (0.0, 0.0, 2.0))
    assert lin == pytest.approx((0.0, -1.0, 1.0), abs=1e-12)
    assert ang == pytest.approx((0.0, -2.0, 0.0), abs=1e-12)


# --- model states ---------------------------------------------------------------------------

def test_drone_state_is_the_ground_truth_pose_with_world_twist():
    s = mirror.drone_model_state('anafi', (1.0, 2.0, 3.0), q_yaw(math.pi), (1.0, 0.0, 0.0), (0.0, 0.0, 0.2))
    assert s.model_name == 'anafi' and s.reference_frame == 'world'
    assert s.position == (1.0, 2.0, 3.0)
    assert s.orientation == pytest.approx(q_yaw(math.pi))
    assert s.linear == pytest.approx((-1.0, 0.0, 0.0), abs=1e-12)
    assert s.angular == pytest.approx((0.0, 0.0, 0.2), abs=1e-12)


def test_drone_state_normalises_the_quaternion():
    s = mirror.drone_model_state('anafi', (0, 0, 0), (0.0, 0.0, 0.0, 2.0), (0, 0, 0), (0, 0, 0))
    assert s.orientation == pytest.approx(Q_IDENTITY)


@pytest.mark.parametrize('yaw, g_pitch, position, x_axis', [
    # level, gimbal straight ahead: 0.1 m in front, looking along +x
    (0.0, 0.0, (1.1, 2.0, 3.0), (1.0, 0.0, 0.0)),
    # yaw 180 deg: camera 0.1 m towards -x, looking along -x
    (math.pi, 0.0, (0.9, 2.0, 3.0), (-1.0, 0.0, 0.0)),
    # yaw 90 deg, gimbal pitched 90 deg down: 0.1 m towards +y, looking straight down
    (math.pi / 2, math.pi / 2, (1.0, 2.1, 3.0), (0.0, 0.0, -1.0)),
    # yaw 180 deg, gimbal 0.5 rad down: looking back and down
    (math.pi, 0.5, (0.9, 2.0, 3.0), (-math.cos(0.5), 0.0, -math.sin(0.5))),
])
def test_camera_state_hand_checked(yaw, g_pitch, position, x_axis):
    s = mirror.camera_model_state('anafi_camera', (1.0, 2.0, 3.0), q_yaw(yaw), (0, 0, 0), (0, 0, 0),
                                  0.0, g_pitch)
    assert s.model_name == 'anafi_camera'
    assert s.position == pytest.approx(position, abs=1e-12)
    assert axis(s.orientation, 0) == pytest.approx(np.array(x_axis), abs=1e-12)


def test_camera_state_uses_the_shared_camera_pose():
    q = frames.euler_to_quaternion(0.1, -0.2, 2.5)
    s = mirror.camera_model_state('c', (4.0, -1.0, 7.0), q, (0, 0, 0), (0, 0, 0), 0.05, 0.3, (0.1, 0.02, -0.03))
    pos, cq = ground_truth.camera_pose((4.0, -1.0, 7.0), 0.1, -0.2, 2.5, 0.05, 0.3, (0.1, 0.02, -0.03))
    assert s.position == pytest.approx(pos, abs=1e-12)
    assert quaternion_angle(s.orientation, cq) < ROTATION_TOLERANCE     # same rotation (q and -q alike)


def test_camera_gimbal_roll_rotates_about_the_viewing_axis():
    s = mirror.camera_model_state('c', (0, 0, 0), Q_IDENTITY, (0, 0, 0), (0, 0, 0), math.pi / 2, 0.0)
    assert axis(s.orientation, 0) == pytest.approx(np.array([1.0, 0.0, 0.0]), abs=1e-12)
    assert axis(s.orientation, 1) == pytest.approx(np.array([0.0, 0.0, 1.0]), abs=1e-12)


def test_camera_twist_includes_the_lever_arm():
    # drone at rest yawing at 1 rad/s, camera 0.1 m ahead: camera moves at 0.1 m/s to the left (+y)
    s = mirror.camera_model_state('c', (0, 0, 0), Q_IDENTITY, (0, 0, 0), (0, 0, 1.0), 0.0, 0.0)
    assert s.linear == pytest.approx((0.0, 0.1, 0.0), abs=1e-12)
    assert s.angular == pytest.approx((0.0, 0.0, 1.0), abs=1e-12)
    # yaw 180 deg, flying forward at 2 m/s (world -x) while yawing: lever arm points to -x
    s = mirror.camera_model_state('c', (0, 0, 0), q_yaw(math.pi), (2.0, 0, 0), (0, 0, 1.0), 0.0, 0.0)
    assert s.linear == pytest.approx((-2.0, -0.1, 0.0), abs=1e-12)


# --- the Mirror class -----------------------------------------------------------------------

def feed(m, t, now=None, position=(1.0, 2.0, 3.0), q=Q_IDENTITY, lin=(0.0, 0.0, 0.0), ang=(0.0, 0.0, 0.0)):
    return m.on_ground_truth(position, q, lin, ang, t, t if now is None else now)


def test_mirror_sends_drone_and_camera_with_latest_gimbal():
    m = spawned_mirror(drone_name='anafi')
    assert m.on_gimbal(0.0, math.pi / 2, 0.0, 0.0)
    states = feed(m, 1.0, q=q_yaw(math.pi))
    assert [s.model_name for s in states] == ['anafi', 'anafi_camera']
    assert states[0].position == (1.0, 2.0, 3.0)
    assert states[1].position == pytest.approx((0.9, 2.0, 3.0))
    assert axis(states[1].orientation, 0) == pytest.approx(np.array([0.0, 0.0, -1.0]), abs=1e-12)
    assert m.accepted == 1


def test_mirror_without_camera_sends_only_the_drone():
    m = spawned_mirror(spawn_camera=False)
    assert [s.model_name for s in feed(m, 1.0)] == ['anafi']
    assert m.spawn.names == ('anafi',)


@pytest.mark.parametrize('field, value', [
    ('position', (float('nan'), 0.0, 0.0)), ('position', (0.0, float('inf'), 0.0)),
    ('q', (float('nan'), 0.0, 0.0, 1.0)), ('q', (0.0, 0.0, 0.0, 0.0)),
    ('lin', (0.0, 0.0, float('-inf'))), ('ang', (float('nan'),) * 3), ('position', (1.0, 2.0)),
])
def test_non_finite_or_malformed_input_is_never_forwarded(field, value):
    m = spawned_mirror()
    assert feed(m, 1.0, **{field: value}) == []
    assert m.rejected_nonfinite == 1
    assert m.last_states == []
    # a good sample afterwards goes through
    assert len(feed(m, 1.01)) == 2


def test_nan_stamp_is_rejected():
    m = spawned_mirror()
    assert m.on_ground_truth((0, 0, 0), Q_IDENTITY, (0, 0, 0), (0, 0, 0), float('nan'), 1.0) == []
    assert m.rejected_nonfinite == 1


def test_stale_and_future_samples_are_rejected():
    m = spawned_mirror(stale_timeout=0.2)
    assert feed(m, 1.0, now=1.25) == []
    assert m.rejected_stale == 1
    assert feed(m, 2.0, now=1.7) == []
    assert m.rejected_future == 1
    assert len(feed(m, 3.0, now=3.15)) == 2  # 150 ms old is still fresh
    health = m.health(3.15)
    assert dict(health.values)['rejected stale'] == '1'
    assert dict(health.values)['rejected future stamp'] == '1'
    assert health.level != ground_truth.OK


def test_nan_gimbal_is_rejected_and_the_last_good_one_kept():
    m = spawned_mirror()
    assert m.on_gimbal(0.0, 0.3, 0.0, 0.0)
    assert not m.on_gimbal(float('nan'), 0.1, 0.0, 0.0)
    assert m.gimbal == (0.0, 0.3) and m.gimbal_rejected == 1


def test_duplicate_stamps_are_dropped_and_a_stamp_reset_reanchors():
    m = spawned_mirror()
    assert feed(m, 5.0)
    assert feed(m, 5.0) == []
    assert m.duplicates == 1
    assert feed(m, 1.0)  # simulator restarted: time went back, still mirrored
    assert m.stamp_resets == 1
    assert feed(m, 1.01)


def count_sent(m, stamps):
    n = 0
    for t in stamps:
        if feed(m, t):
            n += 1
    return n


def test_rate_limit_decimates_a_faster_input_to_the_rate():
    m = spawned_mirror(rate=100.0)
    sent = count_sent(m, [1.0 + i * 0.005 for i in range(400)])  # 200 Hz for 2 s
    assert sent == pytest.approx(200 + mirror.BURST - 1, abs=2)  # the rate, and the first burst on top
    assert m.decimated == 400 - sent


def test_rate_limit_passes_a_jittery_input_at_the_rate():
    m = spawned_mirror(rate=100.0)
    rng = np.random.RandomState(3)
    stamps = [1.0 + i * 0.01 + rng.uniform(-0.002, 0.002) for i in range(300)]
    assert count_sent(m, stamps) == 300


def test_rate_limit_passes_a_slower_input_unchanged():
    m = spawned_mirror(rate=100.0)
    assert count_sent(m, [1.0 + i * 0.04 for i in range(50)]) == 50


def test_lag_statistics():
    m = spawned_mirror()
    for i in range(100):
        m.record_sent(10.0 + i * 0.01, 10.0 + i * 0.01 + 0.001 * (i + 1))
    lag = m.lag_stats()
    assert lag.count == 100
    assert lag.max == pytest.approx(0.1)
    assert lag.p50 == pytest.approx(0.0505)
    assert 0.099 <= lag.p99 <= 0.1
    # sent every 11 ms (stamps 10 ms apart, lag growing 1 ms per cycle): 1 / 0.011 = 90.9 Hz
    assert m.sent_rate(10.0 + 99 * 0.011 + 0.001) == pytest.approx(91.0, abs=1.0)


def test_hold_state_once_when_input_goes_stale():
    m = spawned_mirror(stale_timeout=0.2)
    states = feed(m, 1.0, lin=(1.0, 0.0, 0.0), ang=(0.0, 0.0, 0.5))
    assert states[0].linear != (0.0, 0.0, 0.0)
    assert m.check_stale(1.1) == []
    held = m.check_stale(1.3)
    assert [s.model_name for s in held] == ['anafi', 'anafi_camera']
    assert all(s.linear == (0.0, 0.0, 0.0) and s.angular == (0.0, 0.0, 0.0) for s in held)
    assert held[0].position == states[0].position
    assert m.check_stale(1.5) == []
    assert m.holds == 1
    assert feed(m, 2.0)
    assert m.check_stale(2.5)  # a new stale episode holds again


# --- spawn bookkeeping (the tracker itself: test_spawn.py) -----------------------------------

def test_nothing_is_sent_or_spawned_while_there_is_no_world():
    m = mirror.Mirror()
    m.spawn.on_world(False, None, 0.0)
    assert m.spawn.due_actions(0.0) == []
    assert feed(m, 1.0) == []
    assert m.not_spawned == 1
    health = m.health(1.0)
    assert health.level == ground_truth.ERROR and 'Gazebo not available' in health.message


def test_world_restart_by_endpoint_change_triggers_respawn():
    m = spawned_mirror()
    assert feed(m, 1.0)
    m.spawn.on_world(True, 'rosrpc://w:1', 1.0)  # same world: nothing
    assert m.spawn.all_spawned
    m.spawn.on_world(True, 'rosrpc://w:2', 2.0)  # restarted in between two checks
    assert not m.spawn.is_spawned('anafi')
    assert feed(m, 2.0) == []  # nothing sent to models that are not there
    assert m.spawn.due_actions(2.0) == [('spawn', 'anafi'), ('spawn', 'anafi_camera')]
    for _, name in m.spawn.due_actions(2.0):
        m.spawn.on_spawn_result(name, True, '', 2.1)
    assert m.spawn.world_restarts == 1 and m.spawn.respawns == 2
    assert feed(m, 2.2)


def test_health_ok_when_mirroring_at_rate():
    m = spawned_mirror(rate=100.0)
    m.on_gimbal(0.0, 0.0, 0.0, 0.0)
    for i in range(150):
        t = 1.0 + i * 0.01
        if feed(m, t):
            m.record_sent(t, t + 0.001)
    health = m.health(2.5)
    assert health.level == ground_truth.OK, health.message
    assert dict(health.values)['lag p99 [ms]'] == '1.0'


@pytest.mark.parametrize('kwargs', [
    {'rate': 0.0}, {'rate': float('nan')}, {'stale_timeout': -1.0}, {'camera_offset': (0.1, 0.0)},
    {'camera_offset': (0.1, float('nan'), 0.0)}, {'rate_tolerance': 1.0}, {'retry_period': 0.0},
])
def test_bad_parameters_fail_at_construction(kwargs):
    with pytest.raises(ValueError):
        mirror.Mirror(**kwargs)


def test_frame_names_of_sensor_plugins_follow_the_drone_name():
    xml = '<frameName>anafi/camera_optical</frameName><cameraName>gazebo_camera</cameraName>'
    assert mirror.namespaced_model_xml(xml, '/anafi') == xml
    assert mirror.namespaced_model_xml(xml, 'drone2') == ('<frameName>drone2/camera_optical</frameName>'
                                                          '<cameraName>gazebo_camera</cameraName>')


def test_model_warnings_name_gravity_and_collision_links():
    from anafi_sim import paths
    with open(paths.data_path('urdf', 'anafi.urdf')) as f:
        assert mirror.model_warnings(f.read()) == []
    xml = ('<robot name="r"><link name="body"><inertial><mass value="0.3"/></inertial>'
           '<collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link></robot>')
    warnings = mirror.model_warnings(xml)
    assert len(warnings) == 2 and warnings[0].startswith('gravity ON for links body')
    assert warnings[1].startswith('collision geometry on links body')
    with pytest.raises(ValueError):
        mirror.model_warnings('<robot')
