"""Stage: controllers -> piloting command. A tracking MPC with reference preview beyond the paper (pure core).

``PreviewMpc`` is a ``contract.Controller`` (the same gate, reason keys and failsafes as the paper's MPC and
PID). Where the paper's MPC (``anafi_control.mpc``) predicts a mass point with a constant-velocity target at
10 Hz, this one predicts what the Anafi does, from the calibration (``anafi_sim/config/anafi_model.yaml``
numbers, passed in by the node / engine through ``PredictionModel``), at 20-50 Hz:

* **Model** (per cycle, step ``dt`` [s], horizon ``N``), in the heading frame of the current yaw (x forward,
  y left; the tilt limits are per body axis there), z up::

      p' = v,  v' = a - drag_linear v + e,  a' = (u - a) / attitude_time_constant      (x and y)
      z' = v_z,  v_z' = (u_z - v_z) / vertical_speed_time_constant + e_z

  a = the horizontal acceleration the tilt produces (g tan(pitch), -g tan(roll) / cos(pitch)), u its
  command (-> roll/pitch), u_z the vertical-speed command (gaz). e = -drag_quadratic |v_ref| v_ref + d: the
  quadratic drag linearised along the reference plus the disturbance estimate d. Exact zero-order-hold
  discretisation (matrix exponential). The firmware applies a command ``attitude_delay`` after it was sent:
  the QP starts at t0 = t + ``command_latency`` + attitude_delay, from the state predicted to t0 by
  integrating the model with the commands already sent (a Smith predictor). While the drone yaws at r the
  firmware's roll/pitch loop loses authority, turns and slows its steps and precesses the tilt
  (``gyroscopic_coupling`` G, ``yaw_tilt_authority`` c, ``yaw_tilt_precession`` w, anafi_sim.sim.drone_model):
  the forward prediction does too, and while the QP asks for a large tilt change the yaw rate is held to where
  the coupling changes the tilt loop by little (``YAW_GOVERNOR_*``).
* **QP** in deviation variables from the reference trajectory (x - x_ref, u - u_ref; well scaled, the cost
  has no linear term): sum_k |dx_k|^2_Q + |du_k|^2_R, terminal Q * ``terminal_factor``; constraints: the
  dynamics, |u_x|, |u_y| <= g tan(max tilt) * ``tilt_margin`` (the bridge's max tilt, per body axis),
  |u_z| <= max vertical speed. x_ref / u_ref come from the reference: positions, velocities and
  accelerations (the acceleration feed-forward, incl. drag, tilt lag and the disturbance). OSQP set up once;
  per cycle only l and u change; warm-started; a fixed rho-update interval (deterministic).
* **Reference**: a preview (``on_reference``: the trajectory generator's upcoming samples) when one fresh
  (``preview_timeout`` [s]) and covering the horizon is held, else ``TargetEstimator`` (anafi_control.
  target_estimator) on the waypoint history (``use_preview`` False: always the estimator); holding
  (contract HOLD): the hold point.
* **Offset-free**: d (world frame, m/s^2) is estimated from every new state sample: the velocity change
  against the model's with the measured tilt, filtered with ``disturbance_time_constant`` [s]; a constant
  wind leaves no steady error.
* **Estimate lag**: the state sample is taken as the truth ``estimate_lag`` [s] before its sample time (the
  receipt time rounded down to the estimate's ``sample_period``), the position moved by the fused fix's
  lag (D = ``position_lag`` [s], gain k = ``position_fix_gain`` [1/s]: e' = k (v D - e); v D on a line, less
  on a turn) and predicted forward from there (``lag_compensation`` False: not).

Yaw: yaw rate = ``yaw_gain`` (yaw_ref - yaw) + the reference's yaw rate, within the bridge's max yaw rate
(and within ``PredictionModel.yaw_governor_cap`` while the tilt acceleration has to change by more than
``YAW_GOVERNOR_DEMAND``, and for ``YAW_GOVERNOR_HOLD`` s after: the governor does not flicker between cycles).
``cycle`` result: ``PreviewResult`` (the paper MPC's stats fields plus the predicted / reference paths,
the reference source and the disturbance). Solver failure or an exception -> solver_failed (silent: the
firmware's hover brake), as the paper's MPC.
"""
import collections
import math
import time

import numpy as np
import scipy.linalg
import scipy.sparse as sparse

import osqp

from anafi_control.contract import (LIMIT_DEFAULTS, OK, SOLVER_FAILED, TIMEOUT_DEFAULTS, Controller, CycleOutput,
                                    ReferenceSample, envelope_from_config, hover_output)
from anafi_control.frames import (quaternion_to_euler, stability_to_world, tilt_loop_step, world_to_stability,
                                  wrap_angle)
from anafi_control.target_estimator import DEFAULTS as ESTIMATOR_DEFAULTS, TargetEstimator

_OSQP_1X = tuple(int(x) for x in osqp.__version__.split('.')[:2] if x.isdigit()) >= (1, 0)

NX, NU = 8, 3
#: the yaw governor (the firmware's roll/pitch loop coupled to the yaw rate: ``gyroscopic_coupling`` G,
#: ``yaw_tilt_authority`` c, ``yaw_tilt_precession`` w; ``PredictionModel.yaw_governor_cap``): while the QP asks
#: the tilt acceleration to change by more than YAW_GOVERNOR_DEMAND [m/s^2] at t0, and YAW_GOVERNOR_HOLD [s]
#: after, the yaw rate is held to where the tilt steps are turned by at most atan(YAW_GOVERNOR_TURN) (|G r| <=
#: YAW_GOVERNOR_TURN), the loop keeps 1 - YAW_GOVERNOR_AUTHORITY of its rate (c tau |r| <= YAW_GOVERNOR_AUTHORITY)
#: and the tilt precesses by at most YAW_GOVERNOR_TURN rad per time constant (|w r| tau): ~21 deg/s with the shipped
#: model; a fast yaw turn during a large tilt change swings the tilt round or holds it (the 180 deg static step
#: overshot by 1.2 m without the governor, benchmarks/results/preview_mpc.md; a cap of 31-41 deg/s settles the
#: heading sooner but overshoots by 0.1-0.2 m with ground truth as state)
YAW_GOVERNOR_DEMAND = 0.5
YAW_GOVERNOR_TURN = 0.5
YAW_GOVERNOR_AUTHORITY = 0.2
YAW_GOVERNOR_HOLD = 0.3
#: state indices: x (forward) p, v, a; y (left) p, v, a; z p, v
PX, VX, AX, PY, VY, AY, PZ, VZ = range(NX)
POS, VEL = (PX, PY, PZ), (VX, VY, VZ)

#: tuning defaults (= anafi_sim/config/preview_mpc.yaml and cfg/PreviewMpc.cfg, test_preview_mpc checks)
DEFAULTS = collections.OrderedDict([
    ('rate', 20.0),                      # [Hz] cycle rate
    ('dt', 0.05),                        # [s] prediction step
    ('N', 30),                           # horizon [steps]
    ('q_pos', 40.0),                     # Q: horizontal position error [1/m^2]
    ('q_pos_z', 40.0),                   # Q: altitude error
    ('q_vel', 4.0),                      # Q: horizontal velocity error
    ('q_vel_z', 2.0),                    # Q: vertical velocity error
    ('q_acc', 0.05),                     # Q: tilt acceleration error
    ('r', 0.02),                         # R: tilt acceleration command
    ('r_z', 0.2),                        # R: vertical speed command
    ('terminal_factor', 5.0),            # Q_N = terminal_factor Q
    ('tilt_margin', 0.95),               # fraction of the bridge's max tilt the QP may command
    ('disturbance_time_constant', 1.0),  # [s] of the disturbance estimate (0 = no estimate)
    ('lag_compensation', True),          # predict the truth from the delayed estimate
    ('use_preview', True),               # track a received preview (False: always the target estimator)
    ('preview_timeout', 0.5),            # [s] a preview older than this is not used
    ('yaw_gain', 1.5),                   # [1/s] yaw rate per yaw error
    ('command_latency', 0.0),            # [s] from the cycle to the command reaching the bridge
    ('quantise', True),                  # whole bridge percents, rounding error carried to the next cycle
    ('estimator_window', ESTIMATOR_DEFAULTS['window']),      # [s] target estimator's waypoint history
    ('estimator_max_rate', ESTIMATOR_DEFAULTS['max_rate']),  # [rad/s] its largest turn rate
    ('state_timeout', TIMEOUT_DEFAULTS['state_timeout']),        # [s] contract: older state -> silent
    ('waypoint_timeout', TIMEOUT_DEFAULTS['waypoint_timeout']),  # [s] contract: older waypoint -> hold (0: never)
    ('twist_in_child_frame', True),      # nav_msgs/Odometry twist in the body frame
    ('eps_abs', 1e-4), ('eps_rel', 1e-4), ('max_iter', 4000),
    ('accept_inaccurate', True),         # OSQP 'solved inaccurate' is used (else solver_failed)
])
DEFAULTS.update(LIMIT_DEFAULTS)

#: parameters applied live (dynamic_reconfigure, cfg/PreviewMpc.cfg); N / dt rebuild the QP
RECONFIGURABLE = ('N', 'dt', 'q_pos', 'q_pos_z', 'q_vel', 'q_vel_z', 'q_acc', 'r', 'r_z', 'terminal_factor',
                  'tilt_margin', 'disturbance_time_constant', 'lag_compensation', 'use_preview', 'yaw_gain')
_WEIGHTS = ('q_pos', 'q_pos_z', 'q_vel', 'q_vel_z', 'q_acc', 'r', 'r_z', 'terminal_factor')

EXTRA_COUNTERS = ('previews', 'rejected_previews', 'preview_cycles', 'estimator_cycles', 'reconfigurations')

#: keys of the prediction model (``PredictionModel``), from anafi_model.yaml / sim.yaml (bridge limits)
MODEL_KEYS = ('gravity', 'attitude_time_constant', 'attitude_delay', 'vertical_speed_time_constant',
              'drag_linear', 'drag_quadratic', 'estimate_lag', 'position_lag', 'position_fix_gain',
              'sample_period', 'max_tilt_deg', 'max_vertical_speed', 'max_yaw_rate_deg',
              'tilt_attenuation', 'tilt_attenuation_speed', 'tilt_attenuation_speed_full',
              'vertical_acceleration_limit', 'tilt_rate_limit', 'gyroscopic_coupling', 'yaw_tilt_authority',
              'yaw_tilt_precession')
_SIGNED = ('gyroscopic_coupling', 'yaw_tilt_precession')


class PredictionModel(collections.namedtuple('PredictionModel', MODEL_KEYS)):
    """The calibrated numbers the MPC predicts with (SI; angles in degrees where named so)."""
    __slots__ = ()

    @classmethod
    def from_params(cls, model, max_tilt_deg, max_vertical_speed, max_yaw_rate_deg):
        """From an anafi_model.yaml dict (anafi_sim.sim.drone_model's keys) and the bridge's limits.

        estimate_lag = estimate_delay + estimate_time_constant; position_lag, position_fix_gain = the
        position fix's delay D [s] and gain k [1/s] when the model fuses a delayed position fix, else 0;
        sample_period = 1 / estimate_rate; the firmware's tilt attenuation (anafi_sim.sim.drone_model: a
        fraction a of the commanded tilt, or with tilt_attenuation_speed v0 > 0 of its part that drives the
        drone along its velocity, ramped in from v0 to tilt_attenuation_speed_full) is commanded in advance;
        vertical_acceleration_limit [m/s^2] (0 = none) clips the vertical loop in the forward prediction and the
        disturbance estimate, tilt_rate_limit [rad/s] (0 = none) the tilt acceleration's rate (g x R) in the
        forward prediction (the QP's model stays linear: the limits bind only on large steps), the roll/pitch
        loop's coupling to the yaw rate r (gyroscopic_coupling G [s], yaw_tilt_authority c [1/rad],
        yaw_tilt_precession w [-]; 0 = none, G and w signed; ``anafi_control.frames.tilt_loop_step``) in the
        forward prediction (r: the last measured yaw rate, held; the body's own turn under the held commands is
        not predicted: the governor keeps it small) and in the yaw governor."""
        lag = float(model.get('estimate_delay', 0.0)) + float(model.get('estimate_time_constant', 0.0))
        fusion = bool(model.get('estimate_position_fusion', False))
        return cls(float(model['gravity']), float(model['attitude_time_constant']), float(model['attitude_delay']),
                   float(model['vertical_speed_time_constant']), float(model['drag_linear']),
                   float(model['drag_quadratic']), lag,
                   float(model.get('estimate_position_fix_delay', 0.0)) if fusion else 0.0,
                   float(model.get('estimate_position_fix_gain', 0.0)) if fusion else 0.0,
                   1.0 / float(model['estimate_rate']) if model.get('estimate_rate') else 0.0,
                   float(max_tilt_deg), float(max_vertical_speed), float(max_yaw_rate_deg),
                   float(model.get('tilt_attenuation', 0.0)), float(model.get('tilt_attenuation_speed', 0.0)),
                   float(model.get('tilt_attenuation_speed_full', 0.0)),
                   float(model.get('vertical_acceleration_limit', 0.0)),
                   float(model.get('tilt_rate_limit', 0.0)), float(model.get('gyroscopic_coupling', 0.0)),
                   float(model.get('yaw_tilt_authority', 0.0)), float(model.get('yaw_tilt_precession', 0.0)))

    def yaw_governor_cap(self):
        """The yaw rate [rad/s] the governor holds the drone to while a large tilt change is asked (module doc:
        YAW_GOVERNOR_*); inf when the model has no coupling to the yaw rate."""
        tau = self.attitude_time_constant
        caps = [YAW_GOVERNOR_TURN / abs(self.gyroscopic_coupling) if self.gyroscopic_coupling else math.inf,
                YAW_GOVERNOR_AUTHORITY / (self.yaw_tilt_authority * tau) if self.yaw_tilt_authority else math.inf,
                YAW_GOVERNOR_TURN / (abs(self.yaw_tilt_precession) * tau) if self.yaw_tilt_precession else math.inf]
        return min(caps)

    def vertical_acceleration(self, command, vz):
        """Vertical acceleration [m/s^2] of the firmware's vertical-speed loop at ``vz`` [m/s] under ``command``."""
        acc = (command - vz) / self.vertical_speed_time_constant
        limit = self.vertical_acceleration_limit
        return max(-limit, min(limit, acc)) if limit > 0.0 else acc

    def tilt_gain(self, speed):
        """Fraction of a commanded (driving) tilt the firmware delivers at horizontal ``speed`` [m/s]."""
        a, v0 = self.tilt_attenuation, self.tilt_attenuation_speed
        if a > 0.0 and v0 > 0.0:
            a *= min(1.0, max(0.0, (speed - v0) / max(self.tilt_attenuation_speed_full - v0, 1e-9)))
        return 1.0 - a

    def governed(self, acceleration, velocity, inverse):
        """Horizontal tilt acceleration (fwd, left) [m/s^2] the firmware delivers for a commanded one
        (``inverse`` False) or the one to command for a wanted one (True), at the horizontal ``velocity``
        (fwd, left) [m/s], both in the stability axes (linear in the tilt: small angles)."""
        speed = math.hypot(velocity[0], velocity[1])
        gain = self.tilt_gain(speed)
        if gain >= 1.0:
            return float(acceleration[0]), float(acceleration[1])
        if self.tilt_attenuation_speed <= 0.0:                  # constant: the whole tilt
            k = 1.0 / gain if inverse else gain
            return float(acceleration[0]) * k, float(acceleration[1]) * k
        u = (velocity[0] / speed, velocity[1] / speed)
        drive = acceleration[0] * u[0] + acceleration[1] * u[1]
        if drive <= 0.0:                                        # braking / sideways: delivered whole
            return float(acceleration[0]), float(acceleration[1])
        k = (1.0 - gain) / gain if inverse else -(1.0 - gain)
        return float(acceleration[0] + k * drive * u[0]), float(acceleration[1] + k * drive * u[1])

    def check(self):
        for key, value in zip(MODEL_KEYS, self):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or (value < 0.0 and key not in _SIGNED):
                raise ValueError('prediction model %s must be a finite number%s, got %r'
                                 % (key, '' if key in _SIGNED else ' >= 0', value))
        for key in ('gravity', 'attitude_time_constant', 'vertical_speed_time_constant', 'max_tilt_deg',
                    'max_vertical_speed', 'max_yaw_rate_deg'):
            if not getattr(self, key) > 0.0:
                raise ValueError('prediction model %s must be > 0' % key)
        if not self.tilt_attenuation < 1.0:           # as anafi_sim.sim.drone_model validates its model
            raise ValueError('prediction model tilt_attenuation must be < 1, got %r' % (self.tilt_attenuation,))
        if self.tilt_attenuation_speed > 0.0 and not self.tilt_attenuation_speed_full > self.tilt_attenuation_speed:
            raise ValueError('prediction model tilt_attenuation_speed_full must be > tilt_attenuation_speed')
        return self


def discretise(model, dt):
    """(Ad (8x8), Bd (8x3), Ed (8x3)) of the model at step ``dt`` [s] (zero-order hold on u and e)."""
    Ac = np.zeros((NX, NX))
    Bc = np.zeros((NX, NU))
    Ec = np.zeros((NX, 3))
    tau, k = model.attitude_time_constant, model.drag_linear
    for i, (p, v, a) in enumerate(((PX, VX, AX), (PY, VY, AY))):
        Ac[p, v] = 1.0
        Ac[v, v] = -k
        Ac[v, a] = 1.0
        Ac[a, a] = -1.0 / tau
        Bc[a, i] = 1.0 / tau
        Ec[v, i] = 1.0
    Ac[PZ, VZ] = 1.0
    Ac[VZ, VZ] = -1.0 / model.vertical_speed_time_constant
    Bc[VZ, 2] = 1.0 / model.vertical_speed_time_constant
    Ec[VZ, 2] = 1.0
    M = np.zeros((NX + 6, NX + 6))
    M[:NX, :NX] = Ac
    M[:NX, NX:NX + 3] = Bc
    M[:NX, NX + 3:] = Ec
    Md = scipy.linalg.expm(M * dt)
    return Md[:NX, :NX], Md[:NX, NX:NX + 3], Md[:NX, NX + 3:]


def tilt_acceleration(roll, pitch, g):
    """(a_forward, a_left) [m/s^2] the tilt (roll, pitch [rad], FLU Euler) produces at constant altitude."""
    cp = math.cos(pitch)
    return g * math.tan(pitch), -g * math.tan(roll) / cp


def attitude_for_acceleration(a_forward, a_left, g):
    """(roll_deg, pitch_deg) of the PilotingCommand that produces (a_forward, a_left) [m/s^2] (the inverse of
    ``tilt_acceleration``; + roll = right, + pitch = nose down)."""
    pitch = math.atan(a_forward / g)
    roll = math.atan(-a_left * math.cos(pitch) / g)
    return math.degrees(roll), math.degrees(pitch)


class PreviewResult(object):
    """One cycle's detail (MpcStats fields as MpcResult, plus paths, source and disturbance)."""

    def __init__(self, status, ok=False):
        self.ok = ok
        self.status = status
        self.iterations = 0
        self.solve_time = float('nan')     # [s] OSQP solve time
        self.setup_time = 0.0              # [s] OSQP setup in this cycle (0: set up once)
        self.run_time = 0.0                # [s] the whole cycle
        self.u0 = (0.0, 0.0, 0.0)          # commanded world acceleration (a_x, a_y) [m/s^2], 0
        self.vz_command = 0.0              # [m/s]
        self.predicted = None              # (N+1, 3) predicted positions [m] world ENU, from t0
        self.reference = None              # (N+1, 3) reference positions [m]
        self.t0 = None                     # [s] time of the first predicted point
        self.source = ''                   # 'preview', 'estimator' or 'hold'
        self.disturbance = (0.0, 0.0, 0.0)  # [m/s^2] world

    def __repr__(self):
        return 'PreviewResult(ok=%r, status=%r, source=%r, u0=%r, vz=%r)' % (
            self.ok, self.status, self.source, self.u0, self.vz_command)


def _number(name, value, minimum=0.0, strict=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or value < minimum or (strict and value == minimum):
        raise ValueError('%s must be a finite number %s %g, got %r' % (name, '>' if strict else '>=', minimum,
                                                                       value))
    return float(value)


def check_params(params):
    """DEFAULTS updated with ``params`` (unknown keys / bad values: ValueError)."""
    p = collections.OrderedDict(DEFAULTS)
    unknown = sorted(k for k in dict(params or {}) if k not in DEFAULTS)
    if unknown:
        raise ValueError('unknown preview_mpc parameter(s): %s' % ', '.join(unknown))
    p.update(params or {})
    for key in ('rate', 'dt', 'preview_timeout', 'estimator_window', 'estimator_max_rate', 'state_timeout',
                'tilt_margin', 'eps_abs', 'eps_rel'):
        p[key] = _number(key, p[key], strict=key not in ('eps_abs', 'eps_rel'))
    for key in _WEIGHTS + ('disturbance_time_constant', 'yaw_gain', 'command_latency', 'waypoint_timeout'):
        p[key] = _number(key, p[key])
    if p['tilt_margin'] > 1.0:
        raise ValueError('tilt_margin must be <= 1, got %r' % p['tilt_margin'])
    for key in ('N', 'max_iter'):
        if isinstance(p[key], bool) or int(p[key]) != p[key] or p[key] < 2:
            raise ValueError('%s must be an integer >= 2, got %r' % (key, p[key]))
        p[key] = int(p[key])
    for key in ('lag_compensation', 'use_preview', 'twist_in_child_frame', 'accept_inaccurate', 'quantise'):
        if not isinstance(p[key], bool):
            raise ValueError('%s must be true or false, got %r' % (key, p[key]))
    return p


class PreviewMpc(Controller):
    """The preview MPC (see the module doc). ``model``: a ``PredictionModel``; ``params``: DEFAULTS keys
    (flat, as anafi_sim/config/preview_mpc.yaml); ``limits``: the flight envelope (envelope.Envelope).
    ValueError on bad parameters."""
    NAME = 'preview_mpc'
    RATE = DEFAULTS['rate']
    COUNTERS = EXTRA_COUNTERS
    PREVIEW = True
    CONFIG_KEYS = tuple(DEFAULTS) + tuple(k for k in LIMIT_DEFAULTS if k not in DEFAULTS)

    @classmethod
    def from_config(cls, config, limits=None, model=None):
        """From preview_mpc.yaml's keys (``DEFAULTS``, the flight envelope; see
        ``contract.Controller.from_config``) and the prediction ``model`` (a ``PredictionModel``: the node's
        ~model_file, the engine's model, with the bridge's limits)."""
        params = dict((k, v) for k, v in config.items() if k in DEFAULTS and k not in LIMIT_DEFAULTS)
        return cls(model, params, limits=envelope_from_config(config) if limits is None else limits)

    def __init__(self, model, params=None, limits=None):
        if not isinstance(model, PredictionModel):
            raise ValueError('model must be a PredictionModel, got %r' % (model,))
        self.model = model.check()
        self._yaw_cap = self.model.yaw_governor_cap()  # [rad/s] the yaw governor's limit (inf: no coupling)
        self.params = check_params(params)
        p = self.params
        Controller.__init__(self, p['state_timeout'], p['waypoint_timeout'],
                            'child' if p['twist_in_child_frame'] else 'world', limits)
        self.RATE = p['rate']
        self.estimator = TargetEstimator(p['estimator_window'], p['estimator_max_rate'])
        self.preview = None          # (receipt time, times (n,), P, V, A (n, 3), yaw_deg (n,))
        self.sample = None           # newest distinct state sample (see _state_received)
        self.lag_offset = None       # truth - estimate position [m] of the fused fix (see _state_received)
        self.disturbance = np.zeros(3)
        self.commands = collections.deque()   # (t_apply, u_x, u_y (world m/s^2), u_z (m/s))
        self.carry = [0.0, 0.0, 0.0, 0.0]     # quantisation error carried (roll, pitch, yaw rate, gaz)
        self._yaw_governed_until = -math.inf  # [s] the yaw governor holds the yaw rate until then
        self._build()

    # ----------------------------------------------------------------- QP
    def _build(self):
        p, m = self.params, self.model
        self.N, self.dt = p['N'], p['dt']
        self.Ad, self.Bd, self.Ed = discretise(m, self.dt)
        N = self.N
        self.n_x = NX * (N + 1)
        self.n_var = self.n_x + NU * N
        P = sparse.diags(self._cost_diagonal(), format='csc')
        Ax = sparse.kron(sparse.eye(N + 1), -sparse.eye(NX)) + sparse.kron(sparse.eye(N + 1, k=-1),
                                                                           sparse.csc_matrix(self.Ad))
        Bu = sparse.kron(sparse.vstack([sparse.csc_matrix((1, N)), sparse.eye(N)]), sparse.csc_matrix(self.Bd))
        A_eq = sparse.hstack([Ax, Bu])
        A_in = sparse.hstack([sparse.csc_matrix((NU * N, self.n_x)), sparse.eye(NU * N)])
        A = sparse.vstack([A_eq, A_in], format='csc')
        self.l = np.zeros(A.shape[0])
        self.u = np.zeros(A.shape[0])
        self.u_max = np.array([m.gravity * math.tan(math.radians(m.max_tilt_deg)) * p['tilt_margin']] * 2
                              + [m.max_vertical_speed])
        settings = dict(eps_abs=p['eps_abs'], eps_rel=p['eps_rel'], max_iter=p['max_iter'], verbose=False,
                        adaptive_rho_interval=25, check_termination=5)
        settings['warm_starting' if _OSQP_1X else 'warm_start'] = True
        settings['polishing' if _OSQP_1X else 'polish'] = False
        self.solver = osqp.OSQP()
        self.solver.setup(P, np.zeros(self.n_var), A, self.l, self.u, **settings)

    def _cost_diagonal(self):
        p, N = self.params, self.N
        q = np.zeros(NX)
        q[[PX, PY]] = p['q_pos']
        q[PZ] = p['q_pos_z']
        q[[VX, VY]] = p['q_vel']
        q[VZ] = p['q_vel_z']
        q[[AX, AY]] = p['q_acc']
        r = np.array([p['r'], p['r'], p['r_z']])
        return np.concatenate([np.zeros(NX)] + [q] * (N - 1) + [q * p['terminal_factor']] + [r] * N)

    # ----------------------------------------------------------------- inputs
    def on_state(self, t, position, orientation, twist_linear):
        """Store an odometry sample (see contract); the tilt comes from its orientation."""
        try:
            self._last_orientation = tuple(float(v) for v in orientation)
        except (TypeError, ValueError):
            self._last_orientation = None
        return Controller.on_state(self, t, position, orientation, twist_linear)

    def _lag_offset(self, ts, vel):
        """truth - estimate of the position [m] (world) at sample time ``ts``: the estimate's fix trails by D
        and is pulled in with gain k, e' = k (chord - e), the chord of the last D s ~ v D (on a line e -> v D,
        on a turn the filter attenuates it); the estimator's own filter run on the estimated velocity."""
        m = self.model
        chord = np.array(vel, dtype=float) * m.position_lag
        prev = self.sample
        if self.lag_offset is None or prev is None or m.position_lag <= 0.0:
            self.lag_offset = chord
        else:
            h = ts - prev['t']
            if 0.0 < h < 0.5:
                c = 1.0 - math.exp(-m.position_fix_gain * h)
                self.lag_offset = self.lag_offset + c * (chord - self.lag_offset)
        return self.lag_offset

    def _state_received(self, t):
        """A new state sample: keep it when its values changed (the estimate holds values between its
        samples), update the disturbance estimate."""
        pos, vel, yaw = self.gate.state.value
        q = self._orientation
        roll, pitch, _ = quaternion_to_euler(*q) if q is not None and len(q) == 4 else (0.0, 0.0, yaw)
        if self.sample is not None and self.sample['pos'] == pos and self.sample['vel'] == vel:
            return
        m = self.model
        ts = t
        if m.sample_period > 0.0:
            ts = math.floor(t / m.sample_period + 1e-6) * m.sample_period
        if self.params['lag_compensation']:
            ts -= m.estimate_lag
            pos = tuple(pi + oi for pi, oi in zip(pos, self._lag_offset(ts, vel)))
        fwd, left = tilt_acceleration(roll, pitch, m.gravity)
        ax, ay = stability_to_world(fwd, left, yaw)
        new = {'t': ts, 'pos': self.gate.state.value[0], 'vel': vel, 'p': np.array(pos), 'v': np.array(vel),
               'a': np.array([ax, ay]), 'yaw': yaw}
        prev = self.sample
        self.sample = new
        new['yaw_rate'] = 0.0
        h = ts - prev['t'] if prev is not None else 0.0
        if prev is not None and 0.0 < h < 0.5:
            new['yaw_rate'] = wrap_angle(yaw - prev['yaw']) / h     # [rad/s] measured
        tc = self.params['disturbance_time_constant']
        if prev is None or tc <= 0.0 or not 0.0 < h < 0.5:
            return
        vm = 0.5 * (prev['v'] + new['v'])
        speed = math.hypot(vm[0], vm[1])
        k = m.drag_linear + m.drag_quadratic * speed
        acc_h = 0.5 * (prev['a'] + new['a']) - k * vm[:2]
        uz = self._command_at(ts - 0.5 * h)
        acc_z = m.vertical_acceleration(uz[3] if uz is not None else vm[2], vm[2])
        residual = (new['v'] - prev['v']) / h - np.array([acc_h[0], acc_h[1], acc_z])
        d = self.disturbance + (h / max(tc, h)) * (residual - self.disturbance)
        limit = self.u_max[0]
        self.disturbance = np.minimum(np.maximum(d, -limit), limit)     # clip

    @property
    def _orientation(self):
        return getattr(self, '_last_orientation', None)

    def on_reference(self, t, samples):
        """A preview (``contract.ReferenceSample``s, increasing times) received at ``t`` [s]; False if refused
        (fewer than 2 samples, not increasing, not finite)."""
        try:
            rows = [(float(s[0]),) + tuple(map(float, s[1])) + tuple(map(float, s[2])) + tuple(map(float, s[3]))
                    + (float(s[4]),) for s in samples]
            arr = np.array(rows, dtype=float).reshape(-1, 11)
        except (TypeError, ValueError, IndexError):
            arr = None
        if arr is None or len(arr) < 2 or not np.all(np.isfinite(arr)) or not np.all(np.diff(arr[:, 0]) > 0) \
                or not math.isfinite(t):
            self.counters['rejected_previews'] += 1
            return False
        self.counters['previews'] += 1
        self.preview = (float(t), arr[:, 0], arr[:, 1:4], arr[:, 4:7], arr[:, 7:10], arr[:, 10])
        return True

    def on_waypoint(self, t, waypoint):
        """Store a waypoint (contract) and feed the target estimator."""
        if not Controller.on_waypoint(self, t, waypoint):
            return False
        wp = self.gate.waypoint.value
        self.estimator.add(t, wp[:3], wp[3:6])
        return True

    # ----------------------------------------------------------------- reference
    def _reference(self, t, times, inputs):
        """(P, V, A (n, 3) world, yaw_deg (n,), source) at ``times``."""
        n = len(times)
        wp = inputs.waypoint
        if self.gate.hold is not None:
            P = np.tile(np.asarray(wp[:3], dtype=float), (n, 1))
            Z = np.zeros((n, 3))
            return P, Z, Z.copy(), np.full(n, wp[6]), 'hold'
        pv = self.preview
        if pv is not None and self.params['use_preview'] and t - pv[0] <= self.params['preview_timeout'] \
                and pv[1][0] <= times[0] + 1e-6 and pv[1][-1] >= times[-1] - 1e-6:
            P, V, A, yaw = _interpolate(pv, times)
            return self._enveloped(P, V, A) + (yaw, 'preview')
        P, V, A = self.estimator.predict(times)
        return self._enveloped(P, V, A) + (np.full(n, wp[6]), 'estimator')

    def _enveloped(self, P, V, A):
        """(P, V, A) of the reference with every sample limited by the flight envelope (the gate's: fence,
        reach, speeds, acceleration; noted for the cycle's 'limiting'); the arrays untouched when none acts."""
        gate = self.gate
        env, drone, notes = gate.envelope, gate.state.value[0], []
        if env.inert(P, V, A, gate.centre, drone):     # no limit can act: the arrays as they are
            gate.note(notes)
            return P, V, A
        out = None
        for i in range(len(P)):
            p, v, n = env.limit_target(tuple(P[i]), tuple(V[i]), gate.centre, drone)
            a, m = env.limit_acceleration(tuple(A[i]))
            if n or m:
                if out is None:
                    out = [np.array(P, dtype=float), np.array(V, dtype=float), np.array(A, dtype=float)]
                out[0][i], out[1][i], out[2][i] = p, v, a
                notes += n + m
        gate.note(notes)
        return (P, V, A) if out is None else tuple(out)

    # ----------------------------------------------------------------- prediction
    def _command_at(self, s):
        """The command active at time ``s`` (the newest with t_apply <= s), or None."""
        active = None
        for c in self.commands:
            if c[0] <= s + 1e-9:
                active = c
            else:
                break
        return active

    def _propagate(self, t0):
        """The state (p (3,), v (3,), a (2,)) world at ``t0`` predicted from the newest sample with the
        commands already sent (their effect begins at t_apply)."""
        m, smp = self.model, self.sample
        p = [float(x) for x in smp['p']]
        v = [float(x) for x in smp['v']]
        a = [float(x) for x in smp['a']]
        d = self.disturbance
        s = smp['t']
        span = t0 - s
        if span <= 0.0:
            return np.array(p), np.array(v), np.array(a)
        steps = int(math.ceil(span / 0.01))
        h = span / steps
        ca = 1.0 - math.exp(-h / m.attitude_time_constant)
        cz = 1.0 - math.exp(-h / m.vertical_speed_time_constant)
        kl, kq = m.drag_linear, m.drag_quadratic
        r = smp.get('yaw_rate', 0.0)                 # the firmware's tilt loop is coupled to the yaw rate
        rate_cap = m.gravity * m.tilt_rate_limit     # the tilt-rate limit R as a rate of the tilt acceleration
        cmds = list(self.commands)
        i, active = 0, None
        for _ in range(steps):
            while i < len(cmds) and cmds[i][0] <= s + 1e-9:
                active = cmds[i]
                i += 1
            ux, uy, uz = (a[0], a[1], v[2]) if active is None else active[1:]
            a[0], a[1] = tilt_loop_step(a[0], a[1], ux, uy, ca, h, r, m.attitude_time_constant,
                                        m.gyroscopic_coupling, m.yaw_tilt_authority, m.yaw_tilt_precession, rate_cap)
            k = kl + kq * math.hypot(v[0], v[1])
            v[0] += h * (a[0] - k * v[0] + d[0])
            v[1] += h * (a[1] - k * v[1] + d[1])
            dvz = cz * (uz - v[2])
            if m.vertical_acceleration_limit > 0.0:
                cap = m.vertical_acceleration_limit * h
                dvz = max(-cap, min(cap, dvz))
            v[2] += dvz + h * d[2]
            p[0] += h * v[0]
            p[1] += h * v[1]
            p[2] += h * v[2]
            s += h
        return np.array(p), np.array(v), np.array(a)

    # ----------------------------------------------------------------- cycle
    def _compute(self, t, inputs):
        t_start = time.perf_counter()
        try:
            out = self._solve(t, inputs)
        except Exception as exc:     # a cycle never raises: silent, the firmware's hover brake acts
            out = hover_output(SOLVER_FAILED, ': %s: %s' % (type(exc).__name__, exc), PreviewResult(str(exc)))
        if out.result is not None:
            out.result.run_time = time.perf_counter() - t_start
        return out

    def _solve(self, t, inputs):
        p, m = self.params, self.model
        if self.sample is None:
            raise ValueError('no state sample')
        N, dt = self.N, self.dt
        t0 = t + p['command_latency'] + m.attitude_delay
        times = t0 + dt * np.arange(N + 2)
        P, V, A, yaw_ref, source = self._reference(t, times, inputs)
        result = PreviewResult('', False)
        result.source = source
        result.t0 = t0
        self.counters['preview_cycles' if source == 'preview' else 'estimator_cycles'] += source != 'hold'
        # state at t0 (world), then everything in the heading frame of the current yaw
        if p['lag_compensation']:
            p0, v0, a0 = self._propagate(t0)
        else:
            p0, v0, a0 = self.sample['p'], self.sample['v'], self.sample['a']
        # heading while u_0 acts: the measured yaw moved on at the measured yaw rate (a turning drone)
        yaw = inputs.yaw
        yaw = wrap_angle(yaw + self.sample.get('yaw_rate', 0.0) * max(0.0, t0 + 0.5 * dt - self.sample['t']))
        origin = P[0].copy()
        c, sn = math.cos(yaw), math.sin(yaw)
        R = np.array([[c, sn], [-sn, c]])            # world -> heading (stability axes)
        ref, u_ref, e = self._heading_reference(P - origin, V, A, R)
        # initial deviation
        ph, vh, ah0 = R.dot((p0 - origin)[:2]), R.dot(v0[:2]), R.dot(a0)
        x0 = np.array([ph[0], vh[0], ah0[0], ph[1], vh[1], ah0[1], p0[2] - origin[2], v0[2]])
        sol = self._solve_deviation(x0 - ref[0], ref, u_ref, e, result)
        if sol is None:
            self._reset_warm_start()
            return hover_output(SOLVER_FAILED, ': %s' % result.status, result)
        dx = sol[:self.n_x].reshape(N + 1, NX)
        du = sol[self.n_x:].reshape(N, NU)
        u0 = np.minimum(np.maximum(u_ref[0] + du[0], -self.u_max), self.u_max)     # clip
        if self._yaw_cap < math.inf and math.hypot(u0[0] - ah0[0], u0[1] - ah0[1]) > YAW_GOVERNOR_DEMAND:
            self._yaw_governed_until = t + YAW_GOVERNOR_HOLD       # a large tilt change ahead: no fast yaw
        x_pred = ref[:N + 1] + dx
        result.predicted = self._to_world(x_pred, yaw, origin)
        result.reference = P[:N + 1].copy()
        ax, ay = stability_to_world(u0[0], u0[1], yaw)
        result.u0 = (float(ax), float(ay), 0.0)
        result.vz_command = float(u0[2])
        result.disturbance = tuple(float(x) for x in self.disturbance)
        # velocity at t0 in the stability axes for the governor (the stand-in's firmware gates on its velocity when
        # the PCMD arrives, attitude_delay before t0: they differ by the acceleration x ~0.12 s)
        command = self._command(t, t0, u0, R.dot(v0[:2]), yaw, yaw_ref)
        result.ok = True
        return CycleOutput(tuple(command), True, OK, OK, result)

    def _heading_reference(self, Pr, V, A, R):
        """(reference states, reference inputs, known accelerations: drag along the reference and the disturbance)
        in the heading frame ``R`` from the world reference positions (relative to its first point) ``Pr``,
        velocities ``V`` and accelerations ``A``, N+2 points each."""
        m, N, dt, d_w = self.model, self.N, self.dt, self.disturbance
        Ph, Vh, Ah = Pr[:, :2].dot(R.T), V[:, :2].dot(R.T), A[:, :2].dot(R.T)
        dh = R.dot(d_w[:2])
        kl, kq = m.drag_linear, m.drag_quadratic
        speed = np.hypot(Vh[:, 0], Vh[:, 1])[:, None]
        eh = -kq * speed * Vh + dh                   # quadratic drag along the reference + disturbance
        e = np.column_stack([eh, np.full(N + 2, d_w[2])])
        ah = Ah + kl * Vh - eh                       # the tilt acceleration the reference needs
        ref = np.column_stack([Ph[:, 0], Vh[:, 0], ah[:, 0], Ph[:, 1], Vh[:, 1], ah[:, 1], Pr[:, 2], V[:, 2]])
        tau, tz = m.attitude_time_constant, m.vertical_speed_time_constant
        u_ref = np.zeros((N + 1, NU))
        u_ref[:, 0] = ref[:N + 1, AX] + tau * (ref[1:, AX] - ref[:-1, AX]) / dt
        u_ref[:, 1] = ref[:N + 1, AY] + tau * (ref[1:, AY] - ref[:-1, AY]) / dt
        u_ref[:, 2] = ref[:N + 1, VZ] + tz * (A[:N + 1, 2] - d_w[2])
        return ref, np.minimum(np.maximum(u_ref, -self.u_max), self.u_max), e     # clip

    def _solve_deviation(self, dx0, ref, u_ref, e, result):
        """The QP's solution (deviations from the reference) for the initial deviation ``dx0``, or None when
        OSQP gives none that is accepted and finite; fills ``result``'s status, iterations and solve time."""
        N = self.N
        # residuals of the reference in the model: dx_{k+1} = Ad dx_k + Bd du_k + r_k
        r = (ref[:N].dot(self.Ad.T) + u_ref[:N].dot(self.Bd.T) + e[:N].dot(self.Ed.T) - ref[1:N + 1])
        n_eq = self.n_x
        self.l[:NX] = self.u[:NX] = -dx0
        self.l[NX:n_eq] = self.u[NX:n_eq] = -r.reshape(-1)
        self.l[n_eq:] = (-self.u_max - u_ref[:N]).reshape(-1)
        self.u[n_eq:] = (self.u_max - u_ref[:N]).reshape(-1)
        self.solver.update(l=self.l, u=self.u)
        res = self.solver.solve(raise_error=False) if _OSQP_1X else self.solver.solve()
        info = res.info
        result.status = str(info.status)
        result.iterations = int(getattr(info, 'iter', 0))
        result.solve_time = float(getattr(info, 'solve_time', float('nan')))
        accepted = ('solved', 'solved inaccurate') if self.params['accept_inaccurate'] else ('solved',)
        sol = None if res.x is None else np.array(res.x, dtype=float)
        if result.status.lower() not in accepted or sol is None or sol.shape != (self.n_var,) \
                or not np.all(np.isfinite(sol)):
            return None
        return sol

    def _command(self, t, t0, u0, vh0, yaw, yaw_ref):
        """The piloting command [roll deg, pitch deg, yaw rate deg/s, vz m/s] for the first input ``u0`` (heading
        frame), the velocity ``vh0`` at t0 in the stability axes and the yaw reference; the command buffer of the
        Smith predictor gets what the firmware will apply."""
        p, m, dt = self.params, self.model, self.dt
        u_cmd = m.governed(u0[:2], vh0, inverse=True)
        roll, pitch = attitude_for_acceleration(u_cmd[0], u_cmd[1], m.gravity)
        # yaw: P on the error at t0 plus the reference's yaw rate
        yaw_err = math.degrees(wrap_angle(math.radians(yaw_ref[0]) - yaw))
        yaw_rate_ref = (yaw_ref[1] - yaw_ref[0]) / dt
        yaw_rate = max(-m.max_yaw_rate_deg, min(m.max_yaw_rate_deg, p['yaw_gain'] * yaw_err + yaw_rate_ref))
        if t < self._yaw_governed_until:
            cap = math.degrees(self._yaw_cap)
            yaw_rate = max(-cap, min(cap, yaw_rate))
        command = [roll, pitch, yaw_rate, float(u0[2])]
        realised = list(command)
        ax, ay = stability_to_world(u0[0], u0[1], yaw)
        if p['quantise']:
            quanta = (m.max_tilt_deg / 100.0, m.max_tilt_deg / 100.0, m.max_yaw_rate_deg / 100.0,
                      m.max_vertical_speed / 100.0)
            for i, q in enumerate(quanta):
                command[i], realised[i] = self._quantise(i, command[i], q)
            fwd, left = tilt_acceleration(math.radians(realised[0]), math.radians(realised[1]), m.gravity)
            fwd, left = m.governed((fwd, left), vh0, inverse=False)
            ax, ay = stability_to_world(fwd, left, yaw)
        # the command buffer of the Smith predictor: what the firmware will apply
        self.commands.append((t0, float(ax), float(ay), float(realised[3])))
        horizon = self.sample['t'] - 1.0
        while len(self.commands) > 1 and self.commands[1][0] <= horizon:
            self.commands.popleft()
        return command

    def _quantise(self, i, value, quantum):
        """(value to send, value the bridge realises) for whole percents of ``quantum`` (the bridge truncates
        toward zero: the sent value lies mid-way in the level's interval); the rounding error is carried to
        the next cycle (error feedback: the mean command is the one asked for)."""
        target = value + self.carry[i]
        n = max(-100, min(100, int(round(target / quantum))))
        self.carry[i] = max(-quantum, min(quantum, target - n * quantum))
        sent = 0.0 if n == 0 else (n + (0.5 if n > 0 else -0.5)) * quantum
        return sent, n * quantum

    @staticmethod
    def _to_world(x, yaw, origin):
        """Heading-frame states (n, NX) relative to ``origin`` -> world positions (n, 3)."""
        c, sn = math.cos(yaw), math.sin(yaw)
        out = np.column_stack([c * x[:, PX] - sn * x[:, PY], sn * x[:, PX] + c * x[:, PY], x[:, PZ]])
        return out + origin

    def _reset_warm_start(self):
        try:
            self.solver.warm_start(x=np.zeros(self.n_var), y=np.zeros(len(self.l)))
        except Exception:  # pragma: no cover
            pass

    def _hover(self, out):
        self.commands.clear()
        self._yaw_governed_until = -math.inf
        self.carry = [0.0, 0.0, 0.0, 0.0]
        self.disturbance = np.zeros(3)
        self._reset_warm_start()

    def _clock_jumped(self):
        self.commands.clear()
        self._yaw_governed_until = -math.inf
        self.sample = None
        self.lag_offset = None
        self.preview = None
        self.estimator.reset()
        self.disturbance = np.zeros(3)

    # ----------------------------------------------------------------- configuration
    def config(self):
        """The RECONFIGURABLE parameters now (flat dict)."""
        return dict((k, self.params[k]) for k in RECONFIGURABLE)

    def reconfigure(self, new):
        """Apply the RECONFIGURABLE entries of ``new`` (others ignored); returns the config now. A bad value
        raises ValueError and changes nothing. Any weight, N or dt change rebuilds the QP."""
        old = self.config()
        want = dict(old)
        want.update((k, v) for k, v in dict(new).items() if k in RECONFIGURABLE)
        if want == old:
            return old
        params = dict(self.params)
        params.update(want)
        self.params = check_params(params)
        self._build()
        self.counters['reconfigurations'] += 1
        return self.config()


def _interpolate(preview, times):
    """Preview (receipt, T, P, V, A, yaw) at ``times``: cubic Hermite positions, linear V, A and yaw."""
    _, T, P, V, A, Y = preview
    idx = np.minimum(np.maximum(np.searchsorted(T, times, side='right') - 1, 0), len(T) - 2)     # clip
    t0, t1 = T[idx], T[idx + 1]
    h = (t1 - t0)[:, None]
    s = ((np.asarray(times) - t0)[:, None] / h).clip(0.0, 1.0)
    s2, s3 = s ** 2, s ** 3
    h00 = 2 * s3 - 3 * s2 + 1
    h10 = s3 - 2 * s2 + s
    h01 = -2 * s3 + 3 * s2
    h11 = s3 - s2
    pos = h00 * P[idx] + h10 * h * V[idx] + h01 * P[idx + 1] + h11 * h * V[idx + 1]
    vel = (1 - s) * V[idx] + s * V[idx + 1]
    acc = (1 - s) * A[idx] + s * A[idx + 1]
    yaw = (1 - s[:, 0]) * Y[idx] + s[:, 0] * Y[idx + 1]
    return pos, vel, acc, yaw


def reference_samples(times, positions, velocities, accelerations, yaws):
    """``ReferenceSample``s from arrays (a helper for tests and callers)."""
    return [ReferenceSample(float(t), tuple(map(float, p)), tuple(map(float, v)), tuple(map(float, a)), float(y))
            for t, p, v, a, y in zip(times, positions, velocities, accelerations, yaws)]
