"""geometry_msgs builders shared by the nodes (ROS glue)."""
from geometry_msgs.msg import Pose, Twist


def pose(position, orientation):
    """Pose from (x, y, z) [m] and a quaternion (x, y, z, w)."""
    p = Pose()
    p.position.x, p.position.y, p.position.z = position
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = orientation
    return p


def twist(linear, angular):
    """Twist from linear (x, y, z) [m/s] and angular (x, y, z) [rad/s] vectors."""
    t = Twist()
    t.linear.x, t.linear.y, t.linear.z = linear
    t.angular.x, t.angular.y, t.angular.z = angular
    return t
