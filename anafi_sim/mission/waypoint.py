"""The paper's waypoint as the mission's cores pass it around (pure Python, no ROS)."""
import collections

WaypointSample = collections.namedtuple('WaypointSample', 'x y z vx vy vz yaw')
WaypointSample.__doc__ = ('The paper\'s waypoint: position [m], velocity [m/s] (ENU world frame), '
                          'yaw [deg].')
