"""Scripted path of the airship in the multi-robot scene (pure, no ROS).

Stage: scene actors (the second robot of the paper's airship demo, Sec. IV.C / V.A), moved in the world
through /gazebo/set_model_state; later the drone's tracking target.

``AirshipPath`` is a pure function of time t [s]: a slow horizontal figure-eight (lemniscate of Gerono)
or circle around ``center`` (x, y) [m] at ``altitude`` [m] with a gentle vertical oscillation, in the
world ENU frame. ``state(t)`` returns position [m], velocity [m/s] (world), heading yaw [rad] along the
velocity and yaw rate [rad/s], all analytic (no integration, no drift).
"""
import collections
import math

PathState = collections.namedtuple('PathState', 'position velocity yaw yaw_rate')
"""position (x, y, z) [m] and velocity (vx, vy, vz) [m/s] in the world ENU frame; yaw [rad] (nose along the
horizontal velocity), yaw_rate [rad/s]."""

SHAPES = ('figure_eight', 'circle')


class AirshipPath(object):
    """shape 'figure_eight' or 'circle'; size [m]: circle radius / half-width of the eight; period [s] of
    one lap; altitude [m] (8-12 m in the scene); z_amplitude [m] and z_period [s] of the vertical bob;
    center (x, y) [m]; phase [rad] of the lap at t = 0."""

    def __init__(self, shape='figure_eight', size=20.0, period=120.0, altitude=10.0, z_amplitude=1.0,
                 z_period=60.0, center=(0.0, 0.0), phase=0.0):
        if shape not in SHAPES:
            raise ValueError('shape must be one of %s, got %r' % (SHAPES, shape))
        for name, value in (('size', size), ('period', period), ('z_period', z_period)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError('%s must be a finite number > 0, got %r' % (name, value))
        if not (math.isfinite(altitude) and math.isfinite(z_amplitude) and abs(z_amplitude) < altitude):
            raise ValueError('need finite altitude > |z_amplitude|, got %r, %r' % (altitude, z_amplitude))
        self.shape = shape
        self.size = float(size)
        self.period = float(period)
        self.altitude = float(altitude)
        self.z_amplitude = float(z_amplitude)
        self.z_period = float(z_period)
        self.center = (float(center[0]), float(center[1]))
        self.phase = float(phase)

    def _horizontal(self, t):
        """(x, y, vx, vy, ax, ay) relative to the center."""
        w = 2.0 * math.pi / self.period
        s = w * t + self.phase
        a = self.size
        if self.shape == 'circle':
            return (a * math.cos(s), a * math.sin(s),
                    -a * w * math.sin(s), a * w * math.cos(s),
                    -a * w * w * math.cos(s), -a * w * w * math.sin(s))
        # lemniscate of Gerono: x = a sin(s), y = a sin(s) cos(s) = a/2 sin(2s)
        return (a * math.sin(s), 0.5 * a * math.sin(2.0 * s),
                a * w * math.cos(s), a * w * math.cos(2.0 * s),
                -a * w * w * math.sin(s), -2.0 * a * w * w * math.sin(2.0 * s))

    def state(self, t):
        """``PathState`` at time t [s]."""
        x, y, vx, vy, ax, ay = self._horizontal(t)
        wz = 2.0 * math.pi / self.z_period
        z = self.altitude + self.z_amplitude * math.sin(wz * t)
        vz = self.z_amplitude * wz * math.cos(wz * t)
        yaw = math.atan2(vy, vx)
        speed2 = vx * vx + vy * vy
        yaw_rate = (vx * ay - vy * ax) / speed2 if speed2 > 1e-12 else 0.0
        return PathState((self.center[0] + x, self.center[1] + y, z), (vx, vy, vz), yaw, yaw_rate)
