"""anafi_sim.ros.conversions: the message side of the one Odometry -> numbers conversion."""
import math

import pytest

pytest.importorskip('nav_msgs.msg')
from nav_msgs.msg import Odometry  # noqa: E402

from anafi_control.frames import euler_to_quaternion  # noqa: E402
from anafi_sim.msg import Waypoint  # noqa: E402
from anafi_sim.ros import conversions  # noqa: E402


def _odom(frame_id='world', child_frame_id='anafi/base_link', yaw=math.pi / 2, twist=(1.0, 0.0, 0.0)):
    m = Odometry()
    m.header.frame_id, m.child_frame_id = frame_id, child_frame_id
    m.pose.pose = conversions.pose((1.0, 2.0, 3.0), euler_to_quaternion(0.0, 0.0, yaw))
    m.twist.twist = conversions.twist(twist, (0.0, 0.0, 0.0))
    return m


def test_odometry_numbers_are_the_fields():
    pos, q, v = conversions.odometry_numbers(_odom())
    assert pos == (1.0, 2.0, 3.0) and v == (1.0, 0.0, 0.0)
    assert q == pytest.approx(euler_to_quaternion(0.0, 0.0, math.pi / 2))


@pytest.mark.parametrize('child,expected', [('anafi/base_link', (0.0, 1.0, 0.0)), ('', (1.0, 0.0, 0.0)),
                                            ('world', (1.0, 0.0, 0.0))])
def test_odometry_state_picks_the_twist_frame_from_the_frame_names(child, expected):
    pos, vel, rpy = conversions.odometry_state(_odom(child_frame_id=child))
    assert pos == (1.0, 2.0, 3.0) and vel == pytest.approx(expected, abs=1e-12)
    assert rpy[2] == pytest.approx(math.pi / 2)
    _, vel, _ = conversions.odometry_state(_odom(child_frame_id=child), twist_frame='world')
    assert vel == (1.0, 0.0, 0.0)


def test_odometry_state_refuses_a_zero_quaternion():
    m = _odom()
    m.pose.pose.orientation.w = m.pose.pose.orientation.z = 0.0
    assert conversions.odometry_state(m) is None


def test_waypoint_numbers():
    w = Waypoint(x=1.0, y=2.0, z=3.0, vx=0.1, vy=0.2, vz=0.3, yaw=45.0)
    assert conversions.waypoint_numbers(w) == (1.0, 2.0, 3.0, 0.1, 0.2, 0.3, 45.0)
