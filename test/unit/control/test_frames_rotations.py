"""anafi_control.frames: quaternion_matrix and world_to_body, hand-checked and against rotation_matrix."""
import math

import numpy as np
import pytest

from anafi_control import frames

Q_IDENTITY = (0.0, 0.0, 0.0, 1.0)


def q_yaw(yaw):
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


@pytest.mark.parametrize('q, expected', [
    (Q_IDENTITY, np.eye(3)),
    (q_yaw(math.pi / 2), np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]])),
    (q_yaw(math.pi), np.array([[-1, 0, 0], [0, -1, 0], [0, 0, 1]])),
    ((math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4)), np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]])),
])
def test_quaternion_matrix_hand_checked(q, expected):
    assert np.allclose(frames.quaternion_matrix(q), expected, atol=1e-12)


@pytest.mark.parametrize('rpy', [(0.1, -0.2, 0.3), (-1.0, 0.5, 3.0), (0.0, 0.0, -2.5)])
def test_quaternion_matrix_equals_the_euler_matrix_and_ignores_scale(rpy):
    q = frames.euler_to_quaternion(*rpy)
    assert np.allclose(frames.quaternion_matrix(q), frames.rotation_matrix(*rpy), atol=1e-12)
    assert np.allclose(frames.quaternion_matrix(tuple(3.0 * v for v in q)), frames.rotation_matrix(*rpy), atol=1e-12)


def test_quaternion_matrix_refuses_the_zero_quaternion():
    with pytest.raises(ValueError):
        frames.quaternion_matrix((0.0, 0.0, 0.0, 0.0))


def test_world_to_body_hand_checked():
    # heading 90 deg: world +y is body forward, world +x is body right (-y)
    assert frames.world_to_body(0.0, 0.0, math.pi / 2, (1.0, 2.0, 3.0)) == pytest.approx((2.0, -1.0, 3.0))
    # nose down 90 deg (pitch +): world down is body forward
    assert frames.world_to_body(0.0, math.pi / 2, 0.0, (0.0, 0.0, -1.0)) == pytest.approx((1.0, 0.0, 0.0), abs=1e-12)


@pytest.mark.parametrize('rpy', [(0.1, -0.2, 0.3), (-1.0, 0.5, 3.0)])
def test_world_to_body_is_the_transposed_rotation(rpy):
    v = np.array([0.3, -1.2, 2.0])
    assert frames.world_to_body(*(rpy + (tuple(v),))) == pytest.approx(tuple(frames.rotation_matrix(*rpy).T.dot(v)))
