"""Sphinx ground-truth telemetry: the keys and the text protocol of ``tlm-data-logger``.

Stage: telemetry (simulator side) -> interface. One line per value,
``KEY : NUMBER``; a sample is one value for each key. The drone's keys carry
a prefix (Sphinx names it ``omniscient_anafi.``), the gimbal keys do not.
See ``shared/interfaces/sphinx_telemetry.md``.

``TelemetrySample`` fields use SI units: positions [m] and velocities [m/s]
in the world ENU frame, attitude (roll, pitch, yaw) [rad], body-frame (FLU)
velocity, angular velocity [rad/s], acceleration [m/s^2] and angular
acceleration [rad/s^2], the simulation ``timestamp`` [s] and the gimbal
motor angles relative to the body [rad].
"""
import collections

DEFAULT_PREFIX = 'omniscient_anafi.'

# (key after the prefix, sample field); order = the order the stand-in prints.
DRONE_KEYS = (
    ('worldPosition.x', 'x'), ('worldPosition.y', 'y'), ('worldPosition.z', 'z'),
    ('worldLinearVelocity.x', 'vx'), ('worldLinearVelocity.y', 'vy'), ('worldLinearVelocity.z', 'vz'),
    ('worldAttitude.x', 'roll'), ('worldAttitude.y', 'pitch'), ('worldAttitude.z', 'yaw'),
    ('relativeLinearVelocity.x', 'body_vx'), ('relativeLinearVelocity.y', 'body_vy'),
    ('relativeLinearVelocity.z', 'body_vz'),
    ('relativeAngularVelocity.x', 'body_wx'), ('relativeAngularVelocity.y', 'body_wy'),
    ('relativeAngularVelocity.z', 'body_wz'),
    ('relativeLinearAcceleration.x', 'body_ax'), ('relativeLinearAcceleration.y', 'body_ay'),
    ('relativeLinearAcceleration.z', 'body_az'),
    ('relativeAngularAcceleration.x', 'body_alpha_x'), ('relativeAngularAcceleration.y', 'body_alpha_y'),
    ('relativeAngularAcceleration.z', 'body_alpha_z'),
    ('timestamp', 'timestamp'),
)
# Gimbal keys have no drone prefix.
GIMBAL_KEYS = (
    ('gimbal_roll_anafi.motor_angle', 'gimbal_roll'),
    ('gimbal_pitch_anafi.motor_angle', 'gimbal_pitch'),
)

FIELDS = tuple(f for _, f in DRONE_KEYS) + tuple(f for _, f in GIMBAL_KEYS)

TelemetrySample = collections.namedtuple('TelemetrySample', FIELDS)


def key_map(prefix=DEFAULT_PREFIX):
    """Ordered {full key: sample field} for a drone named by ``prefix``."""
    keys = collections.OrderedDict((prefix + k, f) for k, f in DRONE_KEYS)
    keys.update(GIMBAL_KEYS)
    return keys


def format_sample(sample, prefix=DEFAULT_PREFIX):
    """The lines ``tlm-data-logger`` prints for one sample, as one string (ends with a newline)."""
    return ''.join('%s : %.9g\n' % (key, getattr(sample, field))
                   for key, field in key_map(prefix).items())
