"""The anafi_ros (olympe_bridge) piloting-command mapping, as the bridge does it.

Stage: piloting command -> drone. A ROS ``PilotingCommand`` (roll, pitch in
degrees, yaw *rate* in deg/s, gaz = vertical speed in m/s) becomes one Olympe
PCMD of whole percents of the firmware maxima; the firmware then tracks the
angle / rate / speed the percents stand for. See ``shared/interfaces/anafi_ros.md``.

Signs: PCMD roll +100 = tilt right (the drone flies right, -y in FLU/ENU),
pitch +100 = nose down (flies forward), yaw + = clockwise from above (the
bridge negates the ROS yaw rate, so a positive ROS yaw rate turns
counter-clockwise), gaz + = climb.

``bridge_estimate``: the numbers of the bridge's estimate topics (drone/odom, drone/rpy, camera/attitude,
...) from the drone's own estimate. drone/speed and drone/attitude as the real bridge has them (both bridges,
from the video metadata's NED values): frame_id "/world", referenced to north-west-up: the speed is
(north, -east, -down), the attitude (x, -y, -z, w) of the NED quaternion; drone/pose_enu and
position_control/state_enu (the authors' fork) are ENU.

Camera attitude (camera/attitude, camera/base/attitude; README, "The camera attitude"): anafi_ros builds it
from the video metadata's frame view quaternion (Olympe's camera.quat; camera.base_quat without the user's
tilt), which Parrot's metadata format defines in the local north-east-down frame, like the drone's own
quaternion: the camera's attitude in the world, heading included (the Anafi's gimbal has no yaw axis).
The bridge publishes it as (x, -y, -z, w), which turns that NED/FRD rotation into a north-west-up / FLU
one, with frame_id "/body" although nothing in it is relative to the body. ``camera_attitude`` gives
exactly that quaternion for a camera attitude in our ENU world (north = +y);
``anafi_control.frames.enu_from_nwu`` undoes it (the mirror's ``camera_attitude_source: bridge``).
"""
import collections
import math

from anafi_control import frames

BridgeEstimate = collections.namedtuple('BridgeEstimate', 'position orientation body_velocity velocity rpy_deg '
                                                         'camera_orientation camera_base_orientation '
                                                         'speed_nwu attitude_nwu')
"""What the bridge publishes of the drone's estimate: position (x, y, z) [m] and velocity [m/s] world ENU,
orientation quaternion (x, y, z, w), body_velocity [m/s] FLU (drone/odom's twist), rpy_deg (roll, pitch,
yaw) [deg] (drone/rpy), camera_orientation: the camera's attitude (gimbal pitch command, the drone's
yaw) as the real bridge publishes it on camera/attitude (``camera_attitude``: north-west-up referenced),
camera_base_orientation: the same without the gimbal's tilt (camera/base/attitude), speed_nwu: the velocity
(north, west, up) [m/s] (drone/speed), attitude_nwu: the orientation referenced to north-west-up
(drone/attitude)."""

CAMERA_FRAME_ID = '/body'
"""header.frame_id of the real bridge's camera/attitude and camera/base/attitude (a misnomer, see above)."""

WORLD_FRAME_ID = '/world'
"""header.frame_id of the real bridge's drone/speed, drone/attitude, drone/pose_enu and state_enu."""

# Firmware settings used by the paper (Table 1).
MAX_TILT_DEG = math.degrees(math.asin(5.0 / 9.81))   # 30.64 deg
MAX_VERTICAL_SPEED = 2.0                              # m/s
MAX_YAW_RATE_DEG = 180.0                              # deg/s


def _percent(value, maximum):
    """int(clamp(value / maximum * 100, -100, 100)) as the bridge computes it (truncation toward 0)."""
    if not math.isfinite(value):
        return 0
    return int(max(-100.0, min(100.0, value / maximum * 100.0)))


class PilotingMapping(object):
    """PilotingCommand (ROS units) <-> PCMD percents <-> firmware setpoints (SI, FLU).

    ``max_tilt_deg``, ``max_vertical_speed`` [m/s] and ``max_yaw_rate_deg``
    [deg/s] are the firmware settings the bridge scales with.
    """

    def __init__(self, max_tilt_deg=MAX_TILT_DEG, max_vertical_speed=MAX_VERTICAL_SPEED,
                 max_yaw_rate_deg=MAX_YAW_RATE_DEG):
        for name, value in (('max_tilt_deg', max_tilt_deg),
                            ('max_vertical_speed', max_vertical_speed),
                            ('max_yaw_rate_deg', max_yaw_rate_deg)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError('%s must be a positive finite number, got %r' % (name, value))
        self.max_tilt_deg = float(max_tilt_deg)
        self.max_vertical_speed = float(max_vertical_speed)
        self.max_yaw_rate_deg = float(max_yaw_rate_deg)

    def to_pcmd(self, roll_deg, pitch_deg, yaw_rate_deg, gaz):
        """ROS command -> PCMD (roll, pitch, yaw, gaz) integer percents, exactly as the bridge."""
        return (_percent(roll_deg, self.max_tilt_deg),
                _percent(pitch_deg, self.max_tilt_deg),
                _percent(-yaw_rate_deg, self.max_yaw_rate_deg),
                _percent(gaz, self.max_vertical_speed))

    def pcmd_to_setpoints(self, roll_pct, pitch_pct, yaw_pct, gaz_pct):
        """PCMD percents -> firmware setpoints in SI units, FLU/ENU signs.

        Returns (roll [rad, + = right wing down], pitch [rad, + = nose down],
        yaw_rate [rad/s, + = counter-clockwise], vertical_speed [m/s, + = up]).
        """
        tilt = math.radians(self.max_tilt_deg)
        return (roll_pct / 100.0 * tilt,
                pitch_pct / 100.0 * tilt,
                -yaw_pct / 100.0 * math.radians(self.max_yaw_rate_deg),
                gaz_pct / 100.0 * self.max_vertical_speed)

    def command_to_setpoints(self, roll_deg, pitch_deg, yaw_rate_deg, gaz):
        """ROS command -> quantised firmware setpoints (the composition of the two steps)."""
        return self.pcmd_to_setpoints(*self.to_pcmd(roll_deg, pitch_deg, yaw_rate_deg, gaz))


def camera_attitude(roll, pitch, yaw):
    """The real bridge's camera/attitude quaternion (x, y, z, w) of a camera at ``roll``, ``pitch`` (+ = looking
    down), ``yaw`` [rad] in the ENU world (FLU camera axes, x along the view): the metadata's NED/FRD
    quaternion after the bridge's (x, -y, -z, w), i.e. the attitude referenced to north-west-up."""
    return frames.nwu_from_enu(frames.euler_to_quaternion(roll, pitch, yaw))


def bridge_estimate(values, gimbal_pitch):
    """BridgeEstimate of the estimate's ``values`` (x, y, z, vx, vy, vz, roll, pitch, yaw) and the gimbal
    pitch command [rad]."""
    x, y, z, vx, vy, vz, roll, pitch, yaw = values
    orientation = frames.euler_to_quaternion(roll, pitch, yaw)
    return BridgeEstimate((x, y, z), orientation,
                          frames.world_to_body(roll, pitch, yaw, (vx, vy, vz)), (vx, vy, vz),
                          (math.degrees(roll), math.degrees(pitch), math.degrees(yaw)),
                          camera_attitude(0.0, gimbal_pitch, yaw), camera_attitude(0.0, 0.0, yaw),
                          frames.nwu_from_enu_vector((vx, vy, vz)), frames.nwu_from_enu(orientation))
