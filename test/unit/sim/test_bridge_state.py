"""anafi_sim.interface.bridge_state: the controllers' state from the real bridge's topics, driven by
recorded-like streams (the bridge's ~30 Hz with jitter and drops, a motion-capture pose at 100 Hz, a frozen
topic)."""
import math
import random

import pytest

from anafi_control import frames
from anafi_control.frames import enu_from_nwu_vector, nwu_from_enu_vector
from anafi_sim.interface.bridge_state import DEFAULTS, BridgeStateAssembler

R, V = 2.0, 1.0   # a circle of 2 m at 1 m/s


def truth(t):
    """Position, velocity (ENU) and yaw on the circle at t."""
    w = V / R
    pos = (R * math.cos(w * t), R * math.sin(w * t), 2.0)
    vel = (-V * math.sin(w * t), V * math.cos(w * t), 0.0)
    return pos, vel, w * t + math.pi / 2


def stream(rate, t_end, seed, drop=0.0, jitter=0.0, phase=0.0, freeze_at=None):
    """(stamp, arrival) of a topic at ``rate`` Hz: stamps on a jittered grid, arrival after 0-``jitter`` s,
    ``drop`` of the messages lost, nothing after ``freeze_at``."""
    rng = random.Random(seed)
    out = []
    k = 0
    while True:
        stamp = phase + k / rate + rng.uniform(-0.1, 0.1) / rate
        k += 1
        if stamp > t_end:
            return out
        if freeze_at is not None and stamp > freeze_at:
            continue
        if rng.random() < drop:
            continue
        out.append((stamp, stamp + rng.uniform(0.0, jitter)))


def play(assembler, events):
    """Feed (arrival, kind, stamp) in arrival order; return the states and the arrival of each."""
    states = []
    for now, kind, stamp in sorted(events, key=lambda e: (e[0], e[1])):
        pos, vel, yaw = truth(stamp)
        q = frames.euler_to_quaternion(0.0, 0.0, yaw)
        if kind == 'pose':
            got = assembler.on_pose(stamp, pos, q, now)
        elif kind == 'speed':
            got = assembler.on_speed(stamp, nwu_from_enu_vector(vel), now)
        else:
            got = assembler.on_state_enu(stamp, pos, q, vel, now)
        states.extend((now, s) for s in got)
    return states


def check_states(states):
    for _, s in states:
        pos, vel, yaw = truth(s.stamp)
        assert s.position == pytest.approx(pos, abs=1e-9)
        # the speed paired within max_skew: its velocity error is at most V * w * skew
        assert max(abs(a - b) for a, b in zip(s.velocity, vel)) < V * (V / R) * DEFAULTS['max_skew'] + 1e-9
        body = frames.world_to_body(0.0, 0.0, yaw, s.velocity)
        assert s.body_velocity == pytest.approx(body, abs=1e-9)


def test_nwu_vector_round_trip_and_meaning():
    assert enu_from_nwu_vector((1.0, 0.0, 0.0)) == (0.0, 1.0, 0.0)    # north is ENU +y
    assert enu_from_nwu_vector((0.0, 1.0, 0.0)) == (-1.0, 0.0, 0.0)   # west is ENU -x
    assert enu_from_nwu_vector(nwu_from_enu_vector((0.3, -0.2, 0.5))) == pytest.approx((0.3, -0.2, 0.5))


def test_state_enu_stream_with_jitter_and_drops():
    a = BridgeStateAssembler(source='state_enu')
    msgs = stream(30.0, 20.0, seed=1, drop=0.1, jitter=0.02)
    states = play(a, [(now, 'state', stamp) for stamp, now in msgs])
    assert len(states) == len(msgs) == a.counters['states']
    assert a.counters['refused'] == 0
    for _, s in states:
        pos, vel, _ = truth(s.stamp)
        assert s.velocity == pytest.approx(vel, abs=1e-9)


@pytest.mark.parametrize('seed', [2, 3, 4])
def test_pose_enu_and_speed_of_the_same_frames_pair_exactly(seed):
    """The fork's drone/pose_enu and drone/speed come from one video frame (same stamp), in either order."""
    a = BridgeStateAssembler(source='pose_speed')
    msgs = stream(30.0, 20.0, seed=seed, drop=0.05, jitter=0.0)
    rng = random.Random(seed)
    events = []
    for stamp, now in msgs:
        events.append((now + rng.uniform(0, 0.01), 'pose', stamp))
        events.append((now + rng.uniform(0, 0.01), 'speed', stamp))
    states = play(a, events)
    assert a.counters['refused'] == 0
    assert len(states) >= len(msgs) - 1          # the last pose may wait for its speed
    for _, s in states:
        assert s.velocity == pytest.approx(truth(s.stamp)[1], abs=1e-9)


@pytest.mark.parametrize('seed', [5, 6])
def test_motion_capture_pose_at_100hz_with_bridge_speed_at_30hz(seed):
    a = BridgeStateAssembler(source='pose_speed')
    poses = stream(100.0, 20.0, seed=seed, drop=0.02, jitter=0.005)
    speeds = stream(30.0, 20.0, seed=seed + 100, drop=0.1, jitter=0.03, phase=0.004)
    states = play(a, [(now, 'pose', st) for st, now in poses] + [(now, 'speed', st) for st, now in speeds])
    check_states(states)
    assert len(states) > 0.95 * len(poses)
    assert a.counters['skew'] <= 0.01 * len(poses)   # before the first speed, and the longest drop gaps
    # latency: a state is out at most one pose period (+ jitter) after its pose arrived
    arrivals = dict((st, now) for st, now in poses)
    assert max(now - arrivals[s.stamp] for now, s in states) < 0.05


def test_a_frozen_speed_stops_the_states_and_is_counted():
    a = BridgeStateAssembler(source='pose_speed')
    poses = stream(100.0, 10.0, seed=7, jitter=0.005)
    speeds = stream(30.0, 10.0, seed=8, jitter=0.02, freeze_at=5.0)
    states = play(a, [(now, 'pose', st) for st, now in poses] + [(now, 'speed', st) for st, now in speeds])
    check_states(states)
    last = max(s.stamp for _, s in states)
    assert 5.0 < last <= 5.0 + DEFAULTS['max_skew'] + 0.01
    assert a.counters['skew'] > 400                 # every pose after the freeze
    fresh, stale = a.health(10.0)
    assert not fresh and stale[0].startswith('speed silent for')


def test_a_frozen_pose_stops_the_states():
    a = BridgeStateAssembler(source='pose_speed')
    poses = stream(30.0, 10.0, seed=9, freeze_at=4.0)
    speeds = stream(30.0, 10.0, seed=10)
    states = play(a, [(now, 'pose', st) for st, now in poses] + [(now, 'speed', st) for st, now in speeds])
    assert max(s.stamp for _, s in states) <= 4.0
    assert a.health(10.0)[1] == ['pose silent for %.2f s' % (10.0 - poses[-1][1])]


def test_a_republished_or_late_message_is_refused():
    a = BridgeStateAssembler(source='state_enu')
    q = (0.0, 0.0, 0.0, 1.0)
    assert len(a.on_state_enu(1.0, (0, 0, 1), q, (0, 0, 0), 1.0)) == 1
    assert a.on_state_enu(1.0, (0, 0, 1), q, (0, 0, 0), 1.03) == []          # frozen: the same stamp again
    assert a.on_state_enu(0.9, (0, 0, 1), q, (0, 0, 0), 1.05) == []          # older
    assert a.on_state_enu(1.1, (0, 0, 1), q, (0, 0, 0), 1.1 + 0.31) == []    # arrived too late
    assert a.counters['repeated'] == 2 and a.counters['stale'] == 1
    assert a.health(1.2) == (True, [])
    assert a.health(1.31)[0] is False


@pytest.mark.parametrize('bad', [
    dict(position=(float('nan'), 0, 0)), dict(orientation=(0, 0, 0, 0)), dict(orientation=(0, 0, 1)),
    dict(velocity=(0, float('inf'), 0)), dict(position='abc'), dict(stamp=float('nan'))])
def test_bad_messages_are_counted_never_raise(bad):
    a = BridgeStateAssembler(source='state_enu')
    msg = dict(stamp=1.0, position=(0, 0, 1), orientation=(0, 0, 0, 1), velocity=(0, 0, 0))
    msg.update(bad)
    assert a.on_state_enu(msg['stamp'], msg['position'], msg['orientation'], msg['velocity'], 1.0) == []
    assert a.counters['bad'] == 1


def test_world_yaw_rotates_the_speed_into_the_pose_frame():
    a = BridgeStateAssembler(source='pose_speed', world_yaw=math.pi / 2)   # pose x axis points north
    a.on_speed(1.0, (1.0, 0.0, 0.0), 1.0)                                   # flying north
    (s,) = a.on_pose(1.0, (0, 0, 1), (0, 0, 0, 1), 1.0)
    assert s.velocity == pytest.approx((1.0, 0.0, 0.0), abs=1e-12)


def test_settings_are_checked():
    with pytest.raises(ValueError):
        BridgeStateAssembler(source='odom')
    with pytest.raises(ValueError):
        BridgeStateAssembler(max_skew=0.0)
    with pytest.raises(ValueError):
        BridgeStateAssembler(world_yaw=float('nan'))
    with pytest.raises(ValueError):
        BridgeStateAssembler(source='state_enu').on_pose(1.0, (0, 0, 0), (0, 0, 0, 1), 1.0)


def test_topic_names_as_the_real_bridges_have_them():
    from anafi_sim import names
    assert (names.STATE_ENU, names.POSE_ENU, names.SPEED) == (
        'position_control/state_enu', 'drone/pose_enu', 'drone/speed')
    assert names.CAMERA_BASE_ATTITUDE == 'camera/base/attitude'
