"""KinematicWorld against a recorded run: the same inputs give the same poses, twists, contacts and counters.

``replay`` drives a world through a seeded sequence (spawns in the world and in a model's frame, set_state
in the world and in moving models' frames, zero and non-zero twists, gravity-on, static and colliding
models, invalid inputs, deletes, advances with substeps, get_state in model frames) and returns everything
the world answered. The recording (data/kinematic_world_replay.json) was made with the world core as it
was before its per-message and per-cycle paths were rewritten in plain Python; it is compared to 1e-12
(relative and m / rad / s), the floating-point noise of a different BLAS, libm or machine.

Record anew after an intended change of behaviour: python test/unit/sim/test_kinematic_world_replay.py --record
"""
import json
import math
import os
import random
import sys

import pytest

from anafi_sim.gazebo.kinematic_world import KinematicWorld

HERE = os.path.dirname(os.path.abspath(__file__))
RECORDING = os.path.join(HERE, 'data', 'kinematic_world_replay.json')
URDF_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(HERE))), 'anafi_sim', 'urdf')


def _box(name, gravity, static=False, size='0.3 0.3 0.3'):
    gz = '<gazebo reference="base_link"><gravity>%d</gravity></gazebo>' % gravity
    if static:
        gz += '<gazebo><static>true</static></gazebo>'
    return ('<robot name="%s"><link name="base_link"><inertial><mass value="0.3"/></inertial>'
            '<collision><origin xyz="0.05 0 0.1" rpy="0.1 0.2 0.3"/><geometry><box size="%s"/></geometry>'
            '</collision></link>%s</robot>' % (name, size, gz))


BALL_SDF = ('<sdf version="1.6"><model name="ball"><link name="l"><pose>0 0 0.1 0 0 0.4</pose>'
            '<inertial><mass>1</mass></inertial><collision name="c"><geometry><sphere><radius>0.2</radius>'
            '</sphere></geometry></collision><collision name="m"><pose>0.1 0 0 0 0 0</pose><geometry><mesh>'
            '<scale>1 2 1</scale></mesh></geometry></collision></link></model></sdf>')


def _numbers(values):
    return [v + 0.0 if isinstance(v, float) else v for v in values]   # -0.0 and 0.0 alike


def _state(result_state):
    result, state = result_state
    out = [result.success, result.status_message]
    if state is not None:
        out += _numbers(state.position + state.orientation + state.linear + state.angular)
    return out


def replay(seed=11, iterations=120, record_every=4):
    """Everything a world answers to a seeded sequence of calls, as JSON-able lists."""
    rng = random.Random(seed)
    with open(os.path.join(URDF_DIR, 'anafi.urdf')) as f:
        drone = f.read()
    with open(os.path.join(URDF_DIR, 'anafi_camera.urdf')) as f:
        camera = f.read()
    world = KinematicWorld(gravity=9.81, ground_plane=True)
    out = []

    def result(r):
        out.append([r.success, r.status_message])

    result(world.spawn('anafi', drone, (0.0, 0.0, 1.0), (0.0, 0.0, 0.3, 0.95)))
    result(world.spawn('anafi_camera', camera, (0.1, 0.0, 0.95), (0.0, 0.0, 0.0, 1.0), 'world'))
    result(world.spawn('fall', _box('fall', 1), (0.5, 0.0, 0.6)))
    result(world.spawn('float', _box('float', 0), (0.2, 0.1, 0.4)))
    result(world.spawn('wall', _box('wall', 1, static=True, size='0.2 2 1'), (1.0, 0.0, 0.5)))
    result(world.spawn('ball', BALL_SDF, (0.0, 0.5, 0.3), (0.1, 0.0, 0.0, 1.0)))
    result(world.spawn('rider', _box('rider', 0), (0.2, 0.0, 0.1), (0.0, 0.1, 0.0, 1.0), 'anafi'))
    result(world.spawn('nowhere', _box('nowhere', 0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), 'no_such_frame'))
    movable = ['anafi', 'anafi_camera', 'fall', 'float', 'wall', 'ball', 'rider']
    for k in range(iterations):
        for _ in range(rng.randint(0, 4)):
            name = rng.choice(movable)
            frame = rng.choice(['', 'world', 'world', '', 'anafi', 'fall', 'ball'])
            position = tuple(rng.uniform(-1.0, 1.0) for _ in range(2)) + (rng.uniform(-0.1, 1.2),)
            orientation = tuple(rng.uniform(-1.0, 1.0) for _ in range(4))
            linear = tuple(rng.uniform(-2.0, 2.0) for _ in range(3))
            angular = tuple(rng.uniform(-3.0, 3.0) for _ in range(3)) if rng.random() < 0.6 else (0.0, 0.0, 0.0)
            choice = rng.random()
            if choice < 0.05:
                position = (float('nan'), 0.0, 0.0)
            elif choice < 0.08:
                orientation = (0.0, 0.0, 0.0, 0.0)
            elif choice < 0.1:
                name = 'ghost'
            result(world.set_state(name, position, orientation, linear, angular, frame))
        if k == 40:
            result(world.delete('float'))
            movable.remove('float')
        if k == 60:
            result(world.spawn('float', _box('float', 0), (0.0, 0.0, 0.5), (0.0, 0.0, 1.0, 0.0), 'ball'))
            movable.append('float')
        events = world.advance(rng.choice([0.004, 0.01, 0.013, 0.025]), 0.01)
        out.append([list(e[:2]) + list(e[2:6]) + _numbers([e.depth]) for e in events])
        if k % record_every == 0:
            out.append(_numbers([world.time]))
            out.append([[name] + _numbers(s.position + s.orientation + s.linear + s.angular)
                        for name, s in world.states()])
            out.append([[c.model_a, c.model_b, c.geom_a, c.geom_b] + _numbers([c.depth])
                        for c in world.contacts()])
            out.append(_state(world.get_state(rng.choice(movable), rng.choice(['', 'anafi', 'ball', 'nope']))))
            out.append([[name, report['state_updates']] + _numbers([report['sag'], report['max_sag']])
                        for name, report in ((n, world.report(n)) for n in world.names())])
    out.append(list(world.counters.items()))
    return out


def _compare(expected, actual, where='replay'):
    if isinstance(expected, list):
        assert isinstance(actual, (list, tuple)) and len(actual) == len(expected), where
        for i, (e, a) in enumerate(zip(expected, actual)):
            _compare(e, a, '%s[%d]' % (where, i))
    elif isinstance(expected, float):
        assert isinstance(actual, float), where
        assert math.isclose(actual, expected, rel_tol=1e-12, abs_tol=1e-12), '%s: %r != %r' % (where, actual,
                                                                                          expected)
    else:
        assert actual == expected, '%s: %r != %r' % (where, actual, expected)


def test_a_replayed_sequence_gives_the_recorded_answers():
    with open(RECORDING) as f:
        recorded = json.load(f)
    _compare(recorded, json.loads(json.dumps(replay())))


def test_the_comparison_sees_a_changed_pose():
    with open(RECORDING) as f:
        recorded = json.load(f)
    changed = json.loads(json.dumps(recorded))
    states = next(item for item in changed if item and isinstance(item[0], list) and item[0][:1] == ['ground_plane'])
    states[1][1] += 1e-9
    with pytest.raises(AssertionError):
        _compare(recorded, changed)


if __name__ == '__main__' and sys.argv[1:] == ['--record']:
    with open(RECORDING, 'w') as f:
        json.dump(replay(), f, separators=(',', ':'))
    print('wrote %s' % RECORDING)
