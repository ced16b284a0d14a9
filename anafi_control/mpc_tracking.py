"""Stage: controllers -> piloting command. One cycle of the ``mpc_controller`` node (pure core, no ROS).

Wraps ``anafi_control.mpc.CumulativeErrorMpc`` (position/velocity, eqs. 1-15) and one
``anafi_control.pid.PidController`` for the yaw angle (the PID framework's yaw loop, Table 2, config
``anafi_control.pid_framework.DEFAULT_CONFIG['yaw']``) into what the node does every cycle:

* ``on_state(t, position, orientation, twist_linear)``: a nav_msgs/Odometry sample received at time ``t``
  [s, caller's clock = ROS time in the node]. Position [m] world ENU, orientation quaternion (x, y, z, w),
  linear twist [m/s] in the child (body, FLU) frame as nav_msgs/Odometry defines it (rotated into the
  world with R(roll, pitch, yaw)); ``twist_in_child_frame=False`` takes it as already world ENU. The yaw
  PID is stepped here, once per state message, as the pid package's node computes once per state message
  (~30 Hz on drone/odom): setpoint = waypoint yaw [deg], state = drone yaw [deg], both absolute in the
  world frame (angle_error wraps the difference).
* ``on_waypoint(t, waypoint)``: the paper's waypoint (x, y, z [m], v_x, v_y, v_z [m/s] ENU, yaw [deg]).
* ``cycle(t)`` (10 Hz): checks the inputs, solves the MPC, maps u_0* to roll/pitch (eqs. 9-10 after the
  rotation into the stability axes), takes v_z of x_5* as gaz and the last yaw PID effort as yaw rate.
  Returns a ``CycleOutput`` whose ``command`` is (roll [deg], pitch [deg], yaw rate [deg/s], gaz [m/s]) in
  the olympe_bridge/PilotingCommand convention (+roll = right, +pitch = nose down, +yaw rate = CCW, +gaz =
  up).

Safety (a cycle never raises): no state / no waypoint yet, the last state or waypoint non-finite or
malformed, stale state (older than ``state_timeout``) or stale waypoint (older than ``waypoint_timeout``),
solver not solved (infeasible, max iterations, ...), or a non-finite output -> ``command`` = HOVER (all
zero, as the paper's code published), ``ok`` False, ``reason`` says why, ``counters[reason key]`` += 1,
and the yaw PID is reset (no stale integral/derivative history). The next good cycle produces a normal
command again: nothing latches.

With ``carry_cumulative_errors`` (off by default, see mpc.py) the carried cumulative errors are reset on
a hover cycle and when the waypoint jumps, i.e. when a new waypoint lies farther than
``cum_reset_distance`` [m] from where the previous one would be by now at its own velocity.
"""
import collections
import copy
import math

import numpy as np

from anafi_control.mpc import DEFAULT_PARAMS as MPC_DEFAULTS
from anafi_control.mpc import DRONE_POS, REF_POS, CumulativeErrorMpc, attitude_from_acceleration
from anafi_control.pid import PidController
from anafi_control.pid_framework import DEFAULT_CONFIG as PID_FRAMEWORK_CONFIG
from anafi_control.pid_wiring import odometry_state

HOVER = (0.0, 0.0, 0.0, 0.0)

#: flat, reconfigurable parameter names (cfg/Mpc.cfg, anafi_sim/config/mpc.yaml) -> MPC core
RECONFIGURABLE = ('q_cum', 'q_cum_terminal', 'q_cum_vel', 'q_cum_vel_terminal', 'r',
                  'v_max_x', 'v_max_y', 'v_max_z', 'a_max', 'N', 'carry_cumulative_errors')

#: counters kept by MpcTracking (reason keys of hover cycles, plus totals)
COUNTER_NAMES = ('cycles', 'ok', 'hover', 'no_state', 'no_waypoint', 'bad_state', 'bad_waypoint',
                 'stale_state', 'stale_waypoint', 'solver_failed', 'bad_output', 'states', 'waypoints',
                 'rejected_states', 'rejected_waypoints', 'waypoint_jumps', 'reconfigurations')

DEFAULTS = {
    'state_timeout': 0.5,         # [s] state older than this -> hover
    'waypoint_timeout': 1.0,      # [s] waypoint older than this -> hover
    'twist_in_child_frame': True,  # nav_msgs/Odometry: twist in child_frame_id (body)
    'cum_reset_distance': 1.0,    # [m] waypoint jump that resets carried cumulative errors
}

CycleOutput = collections.namedtuple('CycleOutput', ['command', 'ok', 'reason', 'key', 'result'])
CycleOutput.__doc__ = ('One cycle: command (roll deg, pitch deg, yaw rate deg/s, gaz m/s); ok False -> '
                       'command is HOVER and reason/key say why; result = MpcResult or None.')

DroneState = collections.namedtuple('DroneState', ['t', 'position', 'velocity', 'yaw'])
DroneState.__doc__ = 'Drone state at receipt time t [s]: position [m], velocity [m/s] world ENU, heading [rad].'


def mpc_params_from_flat(flat):
    """Flat parameters (``v_max_x/y/z``, scalar ``a_max``, the rest as mpc.DEFAULT_PARAMS) -> MPC params.

    Unknown keys raise ValueError (a typo in the YAML must not be silently ignored).
    """
    flat = dict(flat)
    params = {}
    vmax = list(MPC_DEFAULTS['v_max'])
    for i, axis in enumerate('xyz'):
        key = 'v_max_' + axis
        if key in flat:
            vmax[i] = flat.pop(key)
    params['v_max'] = tuple(vmax)
    for key, value in flat.items():
        if key not in MPC_DEFAULTS:
            raise ValueError('unknown MPC parameter %r' % (key,))
        params[key] = value
    return params


def odometry_to_world(position, orientation, twist_linear, twist_in_child_frame=True):
    """(position, world velocity, yaw [rad]) of an odometry sample as numpy 3-vectors, or None if unusable.

    The PID framework's ``pid_wiring.odometry_state`` (quaternion normalised, zero or non-finite refused,
    child-frame twist rotated into the world); ``twist_in_child_frame=False`` takes the twist as world ENU.
    """
    odo = odometry_state(position, orientation, twist_linear if twist_in_child_frame else (0.0, 0.0, 0.0))
    if odo is None:
        return None
    pos, vel, yaw = odo
    if not twist_in_child_frame:
        try:
            vel = tuple(float(v) for v in twist_linear)
        except (TypeError, ValueError):
            return None
        if len(vel) != 3 or not all(math.isfinite(v) for v in vel):
            return None
    return np.array(pos, dtype=float), np.array(vel, dtype=float), float(yaw)


class MpcTracking(object):
    """The mpc_controller's per-cycle logic. ``mpc_params``: flat dict (see ``mpc_params_from_flat``).

    ``yaw_config``: overrides of the yaw PidController parameters (default: the PID framework's yaw loop).
    Bad parameters raise ValueError.
    """

    def __init__(self, mpc_params=None, yaw_config=None, state_timeout=DEFAULTS['state_timeout'],
                 waypoint_timeout=DEFAULTS['waypoint_timeout'],
                 twist_in_child_frame=DEFAULTS['twist_in_child_frame'],
                 cum_reset_distance=DEFAULTS['cum_reset_distance']):
        self.mpc = CumulativeErrorMpc(mpc_params_from_flat(mpc_params or {}))
        cfg = copy.deepcopy(PID_FRAMEWORK_CONFIG['yaw'])
        if yaw_config:
            unknown = sorted(set(yaw_config) - set(cfg))
            if unknown:
                raise ValueError('unknown yaw PID parameter(s): %s' % ', '.join(unknown))
            cfg.update(yaw_config)
        self.yaw_config = cfg
        self.yaw_pid = PidController(**cfg)
        for name, value in (('state_timeout', state_timeout), ('waypoint_timeout', waypoint_timeout),
                            ('cum_reset_distance', cum_reset_distance)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                    math.isfinite(value) and value > 0.0):
                raise ValueError('%s must be a positive number, got %r' % (name, value))
        self.state_timeout = float(state_timeout)
        self.waypoint_timeout = float(waypoint_timeout)
        self.cum_reset_distance = float(cum_reset_distance)
        self.twist_in_child_frame = bool(twist_in_child_frame)
        self.counters = dict((name, 0) for name in COUNTER_NAMES)
        self.state = None          # last good DroneState
        self.state_bad = False     # the last state message was unusable
        self.waypoint = None       # (t, position array, velocity array, yaw_deg)
        self.waypoint_bad = False
        self.yaw_rate = 0.0        # [deg/s] last yaw PID effort
        self.last = CycleOutput(HOVER, False, 'no cycle yet', 'no_state', None)

    # ----------------------------------------------------------------- inputs

    def on_state(self, t, position, orientation, twist_linear):
        """Store an odometry sample received at ``t`` [s] and step the yaw PID. Returns False if rejected."""
        self.counters['states'] += 1
        odo = odometry_to_world(position, orientation, twist_linear, self.twist_in_child_frame)
        if odo is None or not _finite(t):
            self.counters['rejected_states'] += 1
            self.state_bad = True
            return False
        p, v, yaw = odo
        self.state = DroneState(float(t), p, v, yaw)
        self.state_bad = False
        if self.waypoint is not None and not self.waypoint_bad and \
                self._age(t, self.waypoint[0], self.waypoint_timeout) <= self.waypoint_timeout:
            effort = self.yaw_pid.update(self.waypoint[3], math.degrees(yaw), float(t))
            if effort is not None:
                self.yaw_rate = effort
        return True

    def on_waypoint(self, t, waypoint):
        """Store a waypoint (x, y, z, vx, vy, vz, yaw_deg) received at ``t`` [s]. Returns False if rejected."""
        self.counters['waypoints'] += 1
        try:
            w = np.asarray(waypoint, dtype=float).reshape(7)
        except (TypeError, ValueError):
            w = None
        if w is None or not np.all(np.isfinite(w)) or not _finite(t):
            self.counters['rejected_waypoints'] += 1
            self.waypoint_bad = True
            return False
        new = (float(t), w[:3].copy(), w[3:6].copy(), float(w[6]))
        if self.waypoint is not None and not self.waypoint_bad:
            t0, p0, v0, _ = self.waypoint
            expected = p0 + v0 * max(0.0, new[0] - t0)
            if float(np.linalg.norm(new[1] - expected)) > self.cum_reset_distance:
                self.counters['waypoint_jumps'] += 1
                self.mpc.reset_cumulative_errors()
        self.waypoint = new
        self.waypoint_bad = False
        return True

    # ----------------------------------------------------------------- cycle

    def cycle(self, t):
        """One 10 Hz cycle at time ``t`` [s]: CycleOutput (never raises)."""
        self.counters['cycles'] += 1
        out = self._cycle(t)
        if out.ok:
            self.counters['ok'] += 1
        else:
            self.counters['hover'] += 1
            self.counters[out.key] += 1
            self.yaw_pid.reset()
            self.yaw_rate = 0.0
            self.mpc.reset_cumulative_errors()
        self.last = out
        return out

    def _cycle(self, t):
        if not _finite(t):
            return CycleOutput(HOVER, False, 'non-finite time', 'bad_state', None)
        if self.state_bad:
            return CycleOutput(HOVER, False, 'last state message unusable (non-finite or malformed)',
                               'bad_state', None)
        if self.state is None:
            return CycleOutput(HOVER, False, 'no state received yet', 'no_state', None)
        age = self._age(t, self.state.t, self.state_timeout)
        if age > self.state_timeout:
            return CycleOutput(HOVER, False, 'stale state (%.2f s old > %.2f s)' % (age, self.state_timeout),
                               'stale_state', None)
        if self.waypoint_bad:
            return CycleOutput(HOVER, False, 'last waypoint unusable (non-finite or malformed)',
                               'bad_waypoint', None)
        if self.waypoint is None:
            return CycleOutput(HOVER, False, 'no waypoint received yet', 'no_waypoint', None)
        age = self._age(t, self.waypoint[0], self.waypoint_timeout)
        if age > self.waypoint_timeout:
            return CycleOutput(HOVER, False, 'stale waypoint (%.2f s old > %.2f s)'
                               % (age, self.waypoint_timeout), 'stale_waypoint', None)
        s = self.state
        result = self.mpc.solve(s.position, s.velocity, self.waypoint[1], self.waypoint[2])
        if not result.ok:
            return CycleOutput(HOVER, False, 'solver: %s' % (result.status,), 'solver_failed', result)
        try:
            roll, pitch = attitude_from_acceleration(result.u0[0], result.u0[1], s.yaw, self.mpc.gravity)
        except ValueError:
            return CycleOutput(HOVER, False, 'non-finite output', 'bad_output', result)
        command = (roll, pitch, self.yaw_rate, result.vz_command)
        if not all(_finite(c) for c in command):
            return CycleOutput(HOVER, False, 'non-finite output', 'bad_output', result)
        return CycleOutput(command, True, 'ok', 'ok', result)

    @staticmethod
    def _age(t, stamp, timeout):
        """Age [s] of a sample received at ``stamp``, 0 if it arrived just after ``t`` (threads race); a
        clock that went back by more than ``timeout`` (simulation restarted) makes it infinitely old."""
        age = float(t) - stamp
        if age < -timeout:
            return float('inf')
        return max(0.0, age)

    # ----------------------------------------------------------------- configuration

    def config(self):
        """Current reconfigurable parameters as a flat dict (RECONFIGURABLE keys)."""
        p = self.mpc.params
        a_max = p['a_max']
        return {
            'q_cum': _scalar(p['q_cum']), 'q_cum_terminal': _scalar(p['q_cum_terminal']),
            'q_cum_vel': _scalar(p['q_cum_vel']), 'q_cum_vel_terminal': _scalar(p['q_cum_vel_terminal']),
            'r': _scalar(p['r']),
            'v_max_x': float(p['v_max'][0]), 'v_max_y': float(p['v_max'][1]), 'v_max_z': float(p['v_max'][2]),
            'a_max': _scalar(a_max), 'N': int(p['N']),
            'carry_cumulative_errors': bool(self.mpc.carry_cumulative_errors),
        }

    def reconfigure(self, new):
        """Apply the changed RECONFIGURABLE entries of ``new`` (other keys ignored). Returns the config now.

        Weights update P in place, limits l/u, the horizon rebuilds the solver. An invalid value raises
        ValueError and leaves the controller unchanged (the old configuration is restored).
        """
        old = self.config()
        want = dict(old)
        want.update((k, v) for k, v in dict(new).items() if k in RECONFIGURABLE)
        if want == old:
            return old
        try:
            self._apply(old, want)
        except ValueError:
            self._apply(self.config(), old)
            raise
        self.counters['reconfigurations'] += 1
        return self.config()

    def _apply(self, old, want):
        weights = ('q_cum', 'q_cum_terminal', 'q_cum_vel', 'q_cum_vel_terminal', 'r')
        if any(want[k] != old[k] for k in weights):
            self.mpc.set_weights(**dict((k, float(want[k])) for k in weights))
        limits = ('v_max_x', 'v_max_y', 'v_max_z', 'a_max')
        if any(want[k] != old[k] for k in limits):
            self.mpc.set_limits(v_max=(float(want['v_max_x']), float(want['v_max_y']),
                                       float(want['v_max_z'])), a_max=float(want['a_max']))
        if want['N'] != old['N']:
            n = want['N']
            if isinstance(n, bool) or int(n) != n:
                raise ValueError('N must be an integer, got %r' % (n,))
            self.mpc.set_horizon(int(n))
        if bool(want['carry_cumulative_errors']) != old['carry_cumulative_errors']:
            self.mpc.carry_cumulative_errors = bool(want['carry_cumulative_errors'])
            self.mpc.reset_cumulative_errors()


def predicted_positions(result):
    """Drone positions x_0*..x_N* [m] world ENU, shape (N+1, 3), of an MpcResult (None if absent)."""
    if result is None or result.x_pred is None:
        return None
    return result.x_pred[:, list(DRONE_POS)]


def reference_positions(result):
    """Waypoint positions z_0..z_N [m] world ENU (constant-velocity model, eq. 8), shape (N+1, 3)."""
    if result is None or result.z_ref is None:
        return None
    return result.z_ref[:, list(REF_POS)]


def _finite(x):
    try:
        return math.isfinite(x)
    except TypeError:
        return False


def _scalar(value):
    """A weight/limit given as 3 equal values -> that float; else the first value (flat configs are scalar)."""
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    return float(arr[0])
