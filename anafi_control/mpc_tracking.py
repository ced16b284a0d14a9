"""Stage: controllers -> piloting command. The paper's MPC as a ``contract.Controller`` (pure core, no ROS).

Wraps ``anafi_control.mpc.CumulativeErrorMpc`` (position/velocity, eqs. 1-15) and one
``anafi_control.pid.PidController`` for the yaw angle (the PID framework's yaw loop, Table 2, config
``anafi_control.pid_framework.DEFAULT_CONFIG['yaw']``) into the controller contract (``anafi_control.contract``:
``on_state``, ``on_waypoint``, ``cycle``, the one input gate and its reason keys):

* ``on_state``: besides storing the state (twist in the child frame, or world ENU with
  ``twist_in_child_frame=False``), the yaw PID is stepped here, once per state message, as the pid package's
  node computes once per state message (~30 Hz on drone/odom): setpoint = waypoint yaw [deg], state = drone
  yaw [deg], both absolute in the world frame (angle_error wraps the difference); only while the waypoint is
  usable and fresh.
* ``cycle(t)`` (10 Hz): after the gate, solves the MPC, maps u_0* to roll/pitch (eqs. 9-10 after the
  rotation into the stability axes), takes v_z of x_5* as gaz and the last yaw PID effort as yaw rate;
  ``result`` is the MpcResult. Besides the gate's keys: solver not solved (infeasible, max iterations, ...)
  -> solver_failed; a non-finite output -> bad_output.

``paper_timing`` (mpc.yaml; see mpc.CumulativeErrorMpc.solve): u_0* and v_z come from the state and
waypoint of the previous cycle, the rotation into the stability axes uses the newest heading (the authors'
node converts at publication time). The measured velocity is clipped into +-v_max for x_0. Counters besides
the contract's: solved_inaccurate (accepted OSQP 'solved inaccurate'), velocity_clipped, cold_resolves
(verify: warm-started solution re-solved cold), waypoint_jumps, reconfigurations.

A hover cycle resets the yaw PID, the held inputs of paper_timing (no stale integral/derivative history) and the carried cumulative errors.
With ``carry_cumulative_errors`` (off by default, see mpc.py) the carried cumulative errors are also reset
when the clock jumps back and when the waypoint jumps, i.e. when a new waypoint lies farther than
``cum_reset_distance`` [m] from where the previous one would be by now at its own velocity.
"""
import collections
import copy
import math

import numpy as np

from anafi_control.contract import (BAD_OUTPUT, LIMIT_DEFAULTS, OK, SOLVER_FAILED, TIMEOUT_DEFAULTS, Controller,
                                    CycleOutput, envelope_from_config, hover_output)
from anafi_control.mpc import DEFAULT_PARAMS as MPC_DEFAULTS
from anafi_control.mpc import DRONE_POS, REF_POS, CumulativeErrorMpc, attitude_from_acceleration
from anafi_control.pid import PidController
from anafi_control.pid_framework import DEFAULT_CONFIG as PID_FRAMEWORK_CONFIG

#: flat, reconfigurable parameter names (cfg/Mpc.cfg, anafi_sim/config/mpc.yaml) -> MPC core
RECONFIGURABLE = ('q_cum', 'q_cum_terminal', 'q_cum_vel', 'q_cum_vel_terminal', 'r',
                  'v_max_x', 'v_max_y', 'v_max_z', 'a_max', 'N', 'carry_cumulative_errors', 'max_iter')

#: counters of MpcTracking besides the contract's (contract.COUNTER_NAMES)
EXTRA_COUNTERS = ('waypoint_jumps', 'reconfigurations', 'solved_inaccurate', 'velocity_clipped', 'cold_resolves')

#: defaults of the tracking parameters (= anafi_sim/config/mpc.yaml, checked by test/unit/control/test_mpc_defaults.py)
DEFAULTS = {
    'rate': 10.0,                 # [Hz] cycle (solve) rate, = 1/dt
    'state_timeout': TIMEOUT_DEFAULTS['state_timeout'],        # [s] state older than this -> silent
    'waypoint_timeout': TIMEOUT_DEFAULTS['waypoint_timeout'],  # [s] waypoint older -> hold; 0 = never stale
    'twist_in_child_frame': True,  # nav_msgs/Odometry: twist in child_frame_id (body)
    'cum_reset_distance': 1.0,    # [m] waypoint jump that resets carried cumulative errors
}
DEFAULTS.update(LIMIT_DEFAULTS)   # the flight envelope (anafi_control.envelope: geofence, reach, speeds, tilt)

#: the MPC's flat parameter names in mpc.yaml (v_max split per axis, as the reconfigure server has them)
PARAM_NAMES = tuple(k for k in MPC_DEFAULTS if k != 'v_max') + ('v_max_x', 'v_max_y', 'v_max_z')
#: MpcTracking's own parameters in mpc.yaml (keyword arguments)
TRACKING_KEYS = ('state_timeout', 'waypoint_timeout', 'twist_in_child_frame', 'cum_reset_distance')

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


class MpcTracking(Controller):
    """The mpc_controller's per-cycle logic. ``mpc_params``: flat dict (see ``mpc_params_from_flat``).

    ``yaw_config``: overrides of the yaw PidController parameters (default: the PID framework's yaw loop).
    Bad parameters raise ValueError.
    """
    NAME = 'mpc'
    RATE = DEFAULTS['rate']
    COUNTERS = EXTRA_COUNTERS
    CONFIG_KEYS = PARAM_NAMES + TRACKING_KEYS + ('rate', 'yaw') + tuple(LIMIT_DEFAULTS)

    @classmethod
    def from_config(cls, config, limits=None):
        """From mpc.yaml's keys (``PARAM_NAMES``, ``TRACKING_KEYS``, ``yaw``: the yaw loop's overrides, the
        flight envelope; see ``contract.Controller.from_config``)."""
        return cls(dict((k, config[k]) for k in PARAM_NAMES if k in config), config.get('yaw'),
                   limits=envelope_from_config(config) if limits is None else limits,
                   **dict((k, config.get(k, DEFAULTS[k])) for k in TRACKING_KEYS))

    def __init__(self, mpc_params=None, yaw_config=None, state_timeout=DEFAULTS['state_timeout'],
                 waypoint_timeout=DEFAULTS['waypoint_timeout'],
                 twist_in_child_frame=DEFAULTS['twist_in_child_frame'],
                 cum_reset_distance=DEFAULTS['cum_reset_distance'], limits=None):
        self.mpc = CumulativeErrorMpc(mpc_params_from_flat(mpc_params or {}))
        cfg = copy.deepcopy(PID_FRAMEWORK_CONFIG['yaw'])
        if yaw_config:
            unknown = sorted(set(yaw_config) - set(cfg))
            if unknown:
                raise ValueError('unknown yaw PID parameter(s): %s' % ', '.join(unknown))
            cfg.update(yaw_config)
        self.yaw_config = cfg
        self.yaw_pid = PidController(**cfg)
        value = cum_reset_distance          # the timeouts: the input gate's rule (contract.check_timeout)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                math.isfinite(value) and value > 0.0):
            raise ValueError('cum_reset_distance must be a positive number, got %r' % (value,))
        self.cum_reset_distance = float(cum_reset_distance)
        self.twist_in_child_frame = bool(twist_in_child_frame)
        Controller.__init__(self, state_timeout, waypoint_timeout,
                            'child' if self.twist_in_child_frame else 'world', limits)
        self.state = None          # last good DroneState
        self.yaw_rate = 0.0        # [deg/s] last yaw PID effort

    # ----------------------------------------------------------------- inputs

    def _state_received(self, t):
        """Keep the state as numpy vectors and step the yaw PID towards a usable, fresh waypoint."""
        pos, vel, yaw = self.gate.state.value
        self.state = DroneState(t, np.array(pos, dtype=float), np.array(vel, dtype=float), float(yaw))
        wp = self.gate.fresh_waypoint(t)
        if wp is not None:
            effort = self.yaw_pid.update(wp[6], math.degrees(yaw), t)
            if effort is not None:
                self.yaw_rate = effort

    def on_waypoint(self, t, waypoint):
        """Store a waypoint (x, y, z, vx, vy, vz, yaw_deg) received at ``t`` [s]; False if rejected.

        A waypoint jump (see the module doc) resets the carried cumulative errors."""
        held = self.gate.waypoint
        previous = (held.time, held.value) if held.missing is None else None
        if not Controller.on_waypoint(self, t, waypoint):
            return False
        if previous is not None and self.gate.waypoint.missing is None:
            t0, w0 = previous
            new = np.asarray(self.gate.waypoint.value[:3], dtype=float)
            with np.errstate(over='ignore', invalid='ignore'):    # huge finite waypoints: inf / nan, a jump
                expected = np.asarray(w0[:3], dtype=float) + np.asarray(w0[3:6], dtype=float) * max(
                    0.0, float(t) - t0)
                distance = float(np.linalg.norm(new - expected))
            if not distance <= self.cum_reset_distance:
                self.counters['waypoint_jumps'] += 1
                self.mpc.reset_cumulative_errors()
        return True

    # ----------------------------------------------------------------- cycle

    def _compute(self, t, inputs):
        s = self.state
        wp = np.asarray(inputs.waypoint, dtype=float)
        result = self.mpc.solve(s.position, s.velocity, wp[:3], wp[3:6])
        for flag, counter in (('inaccurate', 'solved_inaccurate'), ('velocity_clipped', 'velocity_clipped'),
                              ('resolved', 'cold_resolves')):
            if getattr(result, flag):
                self.counters[counter] += 1
        if not result.ok:
            return hover_output(SOLVER_FAILED, ': %s' % (result.status,), result)
        try:
            roll, pitch = attitude_from_acceleration(result.u0[0], result.u0[1], s.yaw, self.mpc.gravity)
        except ValueError:
            return hover_output(BAD_OUTPUT, result=result)
        return CycleOutput((roll, pitch, self.yaw_rate, result.vz_command), True, OK, OK, result)

    def _hover(self, out):
        self.yaw_pid.reset()
        self.yaw_rate = 0.0
        self.mpc.reset_cumulative_errors()
        self.mpc.reset_timing()

    def _clock_jumped(self):
        self.mpc.reset_cumulative_errors()
        self.mpc.reset_timing()

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
            'max_iter': int(p['max_iter']),
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
            self.mpc.set_horizon(_integer(want['N'], 'N'))
        if want['max_iter'] != old['max_iter']:
            self.mpc.set_max_iter(_integer(want['max_iter'], 'max_iter'))
        if bool(want['carry_cumulative_errors']) != old['carry_cumulative_errors']:
            self.mpc.carry_cumulative_errors = bool(want['carry_cumulative_errors'])
            self.mpc.reset_cumulative_errors()


def _integer(value, name):
    """``value`` as an int; ValueError when it is a bool or not a whole number."""
    if isinstance(value, bool) or int(value) != value:
        raise ValueError('%s must be an integer, got %r' % (name, value))
    return int(value)


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


def _scalar(value):
    """A weight/limit given as 3 equal values -> that float; else the first value (flat configs are scalar)."""
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    return float(arr[0])
