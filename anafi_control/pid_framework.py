"""The paper's cascaded PID tracking framework (Sec. III-D, Tables 1-2) as a pure core.

Stage: controllers -> piloting command. Input: drone state estimate (position
[m] and velocity [m/s] in the ENU world frame, heading [rad]) and the paper's
waypoint (x, y, z [m], v_x, v_y, v_z [m/s], ENU world; yaw [deg], world).
Output: a ROS ``olympe_bridge/PilotingCommand`` tuple (roll [deg], pitch
[deg], yaw rate [deg/s], gaz [m/s]) with the anafi_ros signs: +roll = tilt
right (flies towards -y), +pitch = nose down (flies forward), +yaw rate =
counter-clockwise seen from above, +gaz = up (see ``anafi_sim/sim/bridge.py``).

How each loop is fed (one relative-state step, ~30 Hz, then every loop once):

* Relative state: the waypoint position relative to the drone, rotated by
  the drone heading into the stability axes (x forward in the horizontal
  plane, y left, z up); the drone's velocity rotated likewise. The drone's
  own position in these axes is the origin, so every position loop gets
  setpoint = relative waypoint position and state = 0. (Feeding both
  absolute positions rotated by the heading would give the pid package the
  very same error setpoint - state = R(yaw) (p_wp - p), so the numbers are
  identical; the relative form is what the reference's "relative positional
  information" node computed and stays well-conditioned far from the origin.)
* x outer: setpoint rel_x, state 0 -> v_x,ref [m/s] (+-10, windup 0.11).
  x inner: setpoint v_x,ref, state v_x (stability) -> pitch [deg] (+-30.64,
  windup 0, i.e. a pure P+D loop since Ki x integral is always 0).
* y outer: setpoint rel_y, state 0 -> v_y,ref [m/s] (+-10, windup 5).
  y inner: setpoint v_y,ref, state v_y -> roll [deg] (+-30.64, windup 10);
  its gains are negative because +roll moves the drone to -y.
* vertical: setpoint rel_z, state 0 -> gaz [m/s] (+-2, windup 0.5).
* yaw: setpoint waypoint yaw [deg], state drone yaw [deg] (both absolute,
  world, as the reference's angle_error = true / angle_wrap = 360 implies)
  -> yaw rate [deg/s] (+-180, windup 0.5). The pid wraps the error; on every
  cycle that needs a wrap (drone and target on both sides of +-180) it zeroes
  its derivative history and integral as the pid package does (see
  anafi_control/pid.py); the integral is worth at most 0.2 * 0.5 = 0.1
  deg/s anyway, below one PCMD percent (1.8 deg/s).
* No velocity feed-forward: Fig. 4 is p_ref -> outer -> v -> inner ->
  angle, a pid node has one setpoint input, and the reference straight-line
  logs show it (mean 0.875*(x_wp - x) ~= v_x + pitch/10, e.g. 1.32 m lag at
  1 m/s; a feed-forward of the waypoint velocity would remove that lag). The
  waypoint velocity is still rotated into stability axes and exposed in
  ``RelativeState`` for diagnostics and for the MPC.

Ordering: the outer loops run before the inner loops in the same cycle, so
an inner loop sees the fresh outer effort (the pid nodes see whichever
control_effort message arrived last; with messages arriving within one
spin this is the same). A loop that returns None (first cycle, dt == 0,
disabled) keeps its last published effort, as the command-assembly node
keeps the last message it received (0 before the first).

Safety: non-finite input -> the cycle is not fed to any loop, all loops are
reset (no garbage in filters/integrals; the next good cycle is a first
computation) and ``command()`` returns hover (0, 0, 0, 0) until a good cycle
produced new efforts. Before the first good cycle ``command()`` is hover.
Timeouts (stale state / waypoint) are the input gate's business:
``PidTracking`` is the framework behind the controller contract
(``anafi_control.contract``: the one input gate, ``cycle`` at 30 Hz, the
command sent at 10 Hz), as the single-process ``pid_framework`` node runs it.
"""
import collections
import copy
import math

from anafi_control.contract import (BAD_OUTPUT, BAD_STATE, HOVER, LIMIT_DEFAULTS, OK, TIMEOUT_DEFAULTS, Controller,
                                    CycleOutput, envelope_from_config, hover_output)
from anafi_control.frames import is_finite, world_to_stability
from anafi_control.pid import PidController

LOOP_NAMES = ('x_outer', 'x_inner', 'y_outer', 'y_inner', 'vertical', 'yaw')

PID_PARAM_NAMES = ('Kp', 'Ki', 'Kd', 'upper_limit', 'lower_limit', 'windup_limit',
                   'cutoff_frequency', 'angle_error', 'angle_wrap')

# Table 2 gains, Table 1 limits, reference windup limits (shared/interfaces/pid_package.md).
DEFAULT_CONFIG = {
    'x_outer': {'Kp': 0.875, 'Ki': 0.0001, 'Kd': 0.0, 'upper_limit': 10.0, 'lower_limit': -10.0,
                'windup_limit': 0.11, 'cutoff_frequency': -1.0, 'angle_error': False,
                'angle_wrap': 2.0 * math.pi},
    'x_inner': {'Kp': 10.0, 'Ki': 1.0, 'Kd': 0.0, 'upper_limit': 30.64, 'lower_limit': -30.64,
                'windup_limit': 0.0, 'cutoff_frequency': -1.0, 'angle_error': False,
                'angle_wrap': 2.0 * math.pi},
    'y_outer': {'Kp': 0.875, 'Ki': 0.001, 'Kd': 0.0, 'upper_limit': 10.0, 'lower_limit': -10.0,
                'windup_limit': 5.0, 'cutoff_frequency': -1.0, 'angle_error': False,
                'angle_wrap': 2.0 * math.pi},
    'y_inner': {'Kp': -10.0, 'Ki': -1.0, 'Kd': 0.0, 'upper_limit': 30.64, 'lower_limit': -30.64,
                'windup_limit': 10.0, 'cutoff_frequency': -1.0, 'angle_error': False,
                'angle_wrap': 2.0 * math.pi},
    'vertical': {'Kp': 1.0, 'Ki': 0.0, 'Kd': 0.001, 'upper_limit': 2.0, 'lower_limit': -2.0,
                 'windup_limit': 0.5, 'cutoff_frequency': -1.0, 'angle_error': False,
                 'angle_wrap': 2.0 * math.pi},
    'yaw': {'Kp': 0.6, 'Ki': 0.2, 'Kd': 0.003, 'upper_limit': 180.0, 'lower_limit': -180.0,
            'windup_limit': 0.5, 'cutoff_frequency': -1.0, 'angle_error': True,
            'angle_wrap': 360.0},
}

RelativeState = collections.namedtuple('RelativeState', [
    'wp_x', 'wp_y', 'wp_z',          # waypoint relative to the drone, stability axes [m]
    'wp_vx', 'wp_vy', 'wp_vz',       # waypoint velocity, stability axes [m/s]
    'vx', 'vy', 'vz',                # drone velocity, stability axes [m/s]
    'yaw_deg', 'wp_yaw_deg',         # drone heading and waypoint yaw, world [deg]
])
RelativeState.__doc__ = ('Waypoint and drone in the drone\'s stability axes (drone at the origin); '
                         'yaw angles absolute in the world frame, degrees.')


def relative_state(drone_pos, drone_vel_world, drone_yaw_rad, waypoint):
    """The relative-state step: RelativeState, or None when any input is missing or non-finite.

    drone_pos (x, y, z) [m] and drone_vel_world (vx, vy, vz) [m/s] in ENU;
    drone_yaw_rad heading [rad]; waypoint (x, y, z, vx, vy, vz, yaw_deg).
    """
    try:
        px, py, pz = drone_pos
        vx, vy, vz = drone_vel_world
        wx, wy, wz, wvx, wvy, wvz, wyaw = waypoint
    except (TypeError, ValueError):
        return None
    if not is_finite(px, py, pz, vx, vy, vz, drone_yaw_rad, wx, wy, wz, wvx, wvy, wvz, wyaw):
        return None
    rx, ry = world_to_stability(wx - px, wy - py, drone_yaw_rad)
    wsx, wsy = world_to_stability(wvx, wvy, drone_yaw_rad)
    dsx, dsy = world_to_stability(vx, vy, drone_yaw_rad)
    return RelativeState(rx, ry, float(wz - pz), wsx, wsy, float(wvz), dsx, dsy, float(vz),
                         math.degrees(drone_yaw_rad), float(wyaw))


def make_config(overrides=None):
    """DEFAULT_CONFIG updated with ``overrides`` ({loop: {param: value}}); unknown names -> ValueError."""
    config = copy.deepcopy(DEFAULT_CONFIG)
    if overrides is None:
        return config
    if not isinstance(overrides, dict):
        raise ValueError('PID framework config must be a mapping of loops, got %r' % (overrides,))
    for loop, params in overrides.items():
        if loop not in config:
            raise ValueError('unknown PID loop %r (expected one of %s)' % (loop, ', '.join(LOOP_NAMES)))
        if not isinstance(params, dict):
            raise ValueError('parameters of loop %r must be a mapping, got %r' % (loop, params))
        for name, value in params.items():
            if name not in PID_PARAM_NAMES:
                raise ValueError('unknown parameter %r in loop %r (expected one of %s)'
                                 % (name, loop, ', '.join(PID_PARAM_NAMES)))
            config[loop][name] = value
    return config


class PidFramework(object):
    """Six pid-package loops wired as in the paper; ``update`` per ~30 Hz cycle, ``command`` at 10 Hz.

    ``config``: {loop: {pid param: value}} overriding DEFAULT_CONFIG (partial
    is fine). Bad values raise ValueError at construction.
    """

    def __init__(self, config=None):
        self.config = make_config(config)
        self.loops = {}
        for name in LOOP_NAMES:
            try:
                self.loops[name] = PidController(**self.config[name])
            except ValueError as err:
                raise ValueError('PID loop %r: %s' % (name, err))
        self.efforts = dict((name, 0.0) for name in LOOP_NAMES)
        self.state = None          # last RelativeState fed to the loops
        self.valid = False         # True once a good cycle produced efforts and no bad input since
        self.rejected_inputs = 0   # cycles refused for missing / non-finite input
        self.enabled = True

    def hover(self):
        """Forget efforts and loop state; command() is hover until the loops produce again."""
        for loop in self.loops.values():
            loop.reset()
        self.efforts = dict((name, 0.0) for name in LOOP_NAMES)
        self.valid = False

    def update(self, t, drone_pos, drone_vel_world, drone_yaw_rad, waypoint):
        """One relative-state cycle at time t [s]; steps every loop once. Returns False on bad input."""
        rel = relative_state(drone_pos, drone_vel_world, drone_yaw_rad, waypoint)
        if rel is None or not is_finite(t):
            self.rejected_inputs += 1
            self.state = None
            self.hover()
            return False
        self.state = rel
        self._step('x_outer', rel.wp_x, 0.0, t)
        self._step('y_outer', rel.wp_y, 0.0, t)
        self._step('x_inner', self.efforts['x_outer'], rel.vx, t)
        self._step('y_inner', self.efforts['y_outer'], rel.vy, t)
        self._step('vertical', rel.wp_z, 0.0, t)
        produced = self._step('yaw', rel.wp_yaw_deg, rel.yaw_deg, t)
        if produced:
            self.valid = True
        return True

    def _step(self, name, setpoint, state, t):
        effort = self.loops[name].update(setpoint, state, t)
        if effort is None:
            return False
        self.efforts[name] = effort
        return True

    def command(self):
        """(roll_deg, pitch_deg, yaw_rate_deg_s, gaz_m_s) in the PilotingCommand convention, or HOVER."""
        if not (self.valid and self.enabled):
            return HOVER
        cmd = (self.efforts['y_inner'], self.efforts['x_inner'],
               self.efforts['yaw'], self.efforts['vertical'])
        if not is_finite(*cmd):
            return HOVER
        return cmd

    def set_enabled(self, enabled):
        """pid_enable for all six loops; while disabled command() is HOVER (integrals held at 0)."""
        self.enabled = bool(enabled)
        for loop in self.loops.values():
            loop.set_enabled(enabled)


#: defaults of the single-process framework node (pid.launch sets the same values)
DEFAULTS = {
    'rate': 30.0,               # [Hz] relative-state cycle (every loop stepped once)
    'command_rate': 10.0,       # [Hz] PilotingCommand output
    'state_timeout': TIMEOUT_DEFAULTS['state_timeout'],        # [s] state older than this -> silent
    'waypoint_timeout': TIMEOUT_DEFAULTS['waypoint_timeout'],  # [s] waypoint older -> hold; 0 = never stale
}


class PidTracking(Controller):
    """The paper's PID framework behind the controller contract (the single-process ``pid_framework`` node).

    ``cycle(t)`` at ``RATE`` (30 Hz) is one relative-state cycle: the input gate, then every loop once
    (``PidFramework.update``); its command is ``PidFramework.command()`` (hover until the loops produced
    efforts, e.g. on the first cycle after a reset: command None, nothing sent); the node sends ``last.command``
    at ``COMMAND_RATE`` (10 Hz). A change of mode or a silent cycle resets the loops (``PidFramework.hover``);
    holding runs the same loops towards the hold point (``anafi_control.contract``). ``result`` is the RelativeState.
    ``config``: {loop: {pid param: value}} overriding DEFAULT_CONFIG; bad values raise ValueError.
    """
    NAME = 'pid'
    RATE = DEFAULTS['rate']
    COMMAND_RATE = DEFAULTS['command_rate']
    CONFIG_KEYS = LOOP_NAMES + tuple(TIMEOUT_DEFAULTS) + tuple(LIMIT_DEFAULTS)

    @classmethod
    def from_config(cls, config, limits=None):
        """From pid.yaml's keys: {loop: {pid param: value}} for the ``LOOP_NAMES``, the timeouts, the flight
        envelope (see ``contract.Controller.from_config``)."""
        loops = dict((k, v) for k, v in config.items() if k in LOOP_NAMES)
        return cls(loops, config.get('state_timeout', DEFAULTS['state_timeout']),
                   config.get('waypoint_timeout', DEFAULTS['waypoint_timeout']),
                   limits=envelope_from_config(config) if limits is None else limits)

    def __init__(self, config=None, state_timeout=DEFAULTS['state_timeout'],
                 waypoint_timeout=DEFAULTS['waypoint_timeout'], limits=None):
        self.framework = PidFramework(config)
        Controller.__init__(self, state_timeout, waypoint_timeout, 'child', limits)

    def _compute(self, t, inputs):
        fw = self.framework
        if not fw.update(t, inputs.pos, inputs.vel, inputs.yaw, inputs.waypoint):
            return hover_output(BAD_STATE, ' (refused by the framework)')     # not after the gate's checks
        if not fw.valid:         # warming up (a loop's first computation): nothing to send yet
            return CycleOutput(None, True, OK, OK, fw.state)
        cmd = (fw.efforts['y_inner'], fw.efforts['x_inner'], fw.efforts['yaw'], fw.efforts['vertical'])
        if not is_finite(*cmd):
            return hover_output(BAD_OUTPUT, result=fw.state)
        return CycleOutput(cmd, True, OK, OK, fw.state)

    def _hover(self, out):
        self.framework.hover()
