"""Stage: controllers. The paper's quadratic MPC with cumulative error states (Sec. III.E, eqs. 1-15, Table 1).

Pure core (no ROS). Units SI; positions, velocities and accelerations in the ENU world frame.
``CumulativeErrorMpc.solve(drone_pos, drone_vel, wp_pos, wp_vel)`` returns the optimal world accelerations
u_0* = (a_x, a_y, a_z) [m/s^2], the predicted states x_0*..x_N* and the vertical-speed command v_z of x_5*;
``attitude_from_acceleration`` turns (a_x, a_y) into PilotingCommand roll/pitch [deg] (eqs. 9-10).

State vector (eq. 4), 18 entries, reference/drone pairs interleaved::

    0 x_ref   1 x    2 y_ref   3 y    4 z_ref   5 z
    6 vx_ref  7 vx   8 vy_ref  9 vy  10 vz_ref 11 vz
    12 x_cum 13 y_cum 14 z_cum 15 vx_cum 16 vy_cum 17 vz_cum

Readings of the paper that needed a decision (all tested in test/unit/test_mpc.py):

* A (eq. 5): the upper 12x12 block is the mass-point model [[I6, dt I6], [0, I6]], so both the waypoint copy
  and the drone position integrate their own velocity. The lower-left 6x12 block is typeset as a garbled
  bidiagonal ([1 -1 0 ..; 0 1 -1 ..; ..]); read literally its second row would compute x - y_ref, which is
  meaningless. The text says it "computes the difference in position and velocity between the waypoint and
  the drone", and with the interleaved (ref, drone) order that is kron(I6, [1, -1]); its first row
  [1, -1, 0, ...] and last entry (-1 in column 12, v_z) agree with the typeset matrix. With the I6 on the
  cumulative block: cum_{k+1} = cum_k + (ref_k - drone_k) per axis, for positions and velocities (no dt).
* B (eq. 7): a_x, a_y, a_z act on the drone position (dt^2/2) and velocity (dt) entries only: rows 1/7,
  3/9, 5/11, exactly b1..b3 of eq. (7).
* A_r (eq. 8): typeset as [[dt, 0], [dt, 0]] (x) I3 which matches a (ref, ref, ref, drone, drone, drone)
  order, not the interleaved order of eq. (3). We implement its meaning for the interleaved order,
  I3 (x) [[dt, 0], [dt, 0]] and I3 (x) [[1, 0], [1, 0]]: both position copies advance with the *reference*
  velocity, both velocity slots copy v_ref, the cumulative-error references are zero (0_{6x18} rows).
* Q, Q_N, R (eqs. 11-13): diag(0_12, q_cum x3, 0_3), diag(0_12, q_cum_terminal x3, 0_3), diag(r x3).
  With these weights the reference z_k only enters through its (always zero) cumulative entries, so the
  tracking is produced by the ref copies inside x and the cumulative rows of A; q = -Q z is still computed
  so that non-zero weights on other states (set_weights) behave as eq. (2) says.
* u_N of eq. (2): u_N appears in neither the cost (the sum stops at N-1) nor a constraint (x_{N+1} is not
  defined), so it is undetermined; it is dropped. Decision variables are [x_0..x_N, u_0..u_{N-1}].
* State bounds (Table 1) are imposed on x_1..x_N, not on x_0: x_0 = x-bar is the measurement, and bounding
  it would make the QP infeasible whenever the measured speed exceeds a limit (e.g. a gust pushes v_z to
  2.05 m/s) although the drone can still be brought back within the limits. Only finite bounds produce
  constraint rows (infinite bounds stay infinite, i.e. they are simply absent). Beyond |a_max| dt over the
  limit it would still be infeasible, so the measured velocity is clipped into +-v_max before it enters x_0
  (as the authors' code did; ``MpcResult.velocity_clipped``).
* Numerics (not the formulation): the QP variables are x~ = D^-1 (x - shift) (positions relative to the drone,
  cumulative errors / ``cum_scale``), OSQP polishes, and with ``verify`` a solution whose polishing failed is
  re-solved cold at ``verify_eps``: with eps 1e-3 and a warm start far from the new problem (a waypoint jump)
  OSQP reported 'solved' on u_0 off by up to 1.2 m/s^2 (test_mpc.py compares with the exact optimum).
* x-bar = [wp_x, x, wp_y, y, wp_z, z, wp_vx, vx, wp_vy, vy, wp_vz, vz, 0, 0, 0, 0, 0, 0] and z-bar as eq.
  (15): each solve starts with zero cumulative errors, as eq. (15) and the paper's behaviour imply.
  ``carry_cumulative_errors=True`` instead starts each solve from cum = sum over previous solves of the
  measured error (ref - drone) at solve time, which is exactly the predicted x_1* cumulative entries of the
  previous solution; it turns the cumulative states into a true integral action (with wind-up: the caller
  should call ``reset_cumulative_errors()`` when the waypoint jumps). It assumes solve() is called every dt.
* v_z command "taken from x_5*": the drone's v_z entry (index 11) of the predicted state at step 5
  (x_pred[5, 11]; x_pred[0] is the measured state), i.e. the speed planned 0.5 s ahead.
* u0 and vz_command are clipped to +-a_max / +-v_max_z: OSQP meets the bounds only within its tolerance,
  which is relative to the largest entries (the cumulative errors reach 1e2-1e3 for far waypoints), e.g.
  v_z = 2.05 m/s with eps 1e-3. x_pred / u_pred are returned unclipped.

Solver: OSQP, set up once (P and the constraint matrix constant, sparse CSC); per cycle only q, l, u change
(``update(q=, l=, u=)``) and the solver is warm-started. ``set_weights`` updates P's values in place
(``update(Px=)``; P is diagonal and stored with every diagonal entry, so the sparsity never changes),
``set_limits`` only changes l/u unless a bound switches between finite and infinite (rows appear or
vanish: rebuild), ``set_horizon`` rebuilds. ``rebuild_every_cycle=True`` builds and sets up the whole QP
from scratch at every solve, as the paper's code did (used by benchmarks/bench_mpc.py for comparison).
Works with osqp 0.6.x and 1.x.
"""
import math
import time

import numpy as np
import scipy.sparse as sparse

import osqp

from anafi_control.frames import world_to_stability

NX = 18
NU = 3

#: indices in the 18-state vector of eq. (4)
REF_POS = (0, 2, 4)
DRONE_POS = (1, 3, 5)
REF_VEL = (6, 8, 10)
DRONE_VEL = (7, 9, 11)
CUM_POS = (12, 13, 14)
CUM_VEL = (15, 16, 17)
VZ_INDEX = 11

DEFAULT_PARAMS = {
    'N': 30,                    # horizon [steps]
    'dt': 0.1,                  # step [s]
    'q_cum': 1e-3,              # Q weight of x/y/z_cum (eq. 11), scalar or 3 values
    'q_cum_terminal': 5.0,      # Q_N weight of x/y/z_cum (eq. 12)
    'q_cum_vel': 0.0,           # Q weight of vx/vy/vz_cum (0 in the paper)
    'q_cum_vel_terminal': 0.0,  # Q_N weight of vx/vy/vz_cum (0 in the paper)
    'r': 0.2,                   # R weight of a_x, a_y, a_z (eq. 13)
    'v_max': (10.0, 10.0, 2.0),  # |v_x|, |v_y|, |v_z| limits of the drone [m/s] (Table 1), inf allowed
    'a_max': (5.0, 5.0, 5.0),   # |a_x|, |a_y|, |a_z| limits [m/s^2] (Table 1), inf allowed
    'gravity': 9.81,            # [m/s^2], eqs. (9)-(10)
    'vz_step': 5,               # v_z command taken from x_pred[vz_step]
    'carry_cumulative_errors': False,
    'rebuild_every_cycle': False,
    'accept_inaccurate': True,  # treat OSQP 'solved inaccurate' as ok (the authors' code did)
    'paper_timing': False,      # solve with the inputs of the previous call (the authors' node), see solve()
    'cum_scale': 30.0,          # QP variable of the cumulative errors = cum / cum_scale (1 = unscaled)
    'eps_abs': 1e-3,
    'eps_rel': 1e-3,
    'max_iter': 4000,
    'warm_start': True,
    'polish': True,
    'verify': True,             # polish failed -> re-solve cold with verify_eps (wrong warm starts)
    'verify_eps': 1e-5,         # eps_abs = eps_rel of the cold re-solve
    'verbose': False,
}

try:
    OSQP_INFTY = float(osqp.constant('OSQP_INFTY'))
except Exception:  # osqp 0.6 without constant()
    OSQP_INFTY = 1e30

OSQP_VERSION = tuple(int(p) for p in osqp.__version__.split('.')[:2] if p.isdigit())
_OSQP_1X = OSQP_VERSION >= (1, 0)


# --------------------------------------------------------------------------- model matrices (eqs. 5-13)

def state_matrix(dt):
    """A of eq. (5), 18x18: mass point on the first 12 states, cum_{k+1} = cum_k + (ref_k - drone_k)."""
    A = np.zeros((NX, NX))
    A[:12, :12] = np.block([[np.eye(6), dt * np.eye(6)], [np.zeros((6, 6)), np.eye(6)]])
    A[12:, :12] = np.kron(np.eye(6), np.array([[1.0, -1.0]]))
    A[12:, 12:] = np.eye(6)
    return A


def input_matrix(dt):
    """B = [b1, b2, b3] of eq. (7), 18x3: accelerations into the drone position (dt^2/2) and velocity (dt)."""
    B = np.zeros((NX, NU))
    for axis in range(3):
        B[DRONE_POS[axis], axis] = 0.5 * dt * dt
        B[DRONE_VEL[axis], axis] = dt
    return B


def reference_matrix(dt):
    """A_r of eq. (8), 18x18: constant-velocity waypoint in both copies, zero cumulative references."""
    Ar = np.zeros((NX, NX))
    Ar[:6, :6] = np.eye(6)
    Ar[:6, 6:12] = np.kron(np.eye(3), np.array([[dt, 0.0], [dt, 0.0]]))
    Ar[6:12, 6:12] = np.kron(np.eye(3), np.array([[1.0, 0.0], [1.0, 0.0]]))
    return Ar


def state_weights(q_cum=1e-3, q_cum_vel=0.0):
    """Q of eq. (11): diag(0_12, q_cum (x, y, z), q_cum_vel (vx, vy, vz))."""
    return np.diag(_weight_diag(q_cum, q_cum_vel))


def terminal_weights(q_cum_terminal=5.0, q_cum_vel_terminal=0.0):
    """Q_N of eq. (12): diag(0_12, q_cum_terminal x3, q_cum_vel_terminal x3)."""
    return np.diag(_weight_diag(q_cum_terminal, q_cum_vel_terminal))


def input_weights(r=0.2):
    """R of eq. (13): diag(r x3)."""
    return np.diag(_vec3(r, 'r'))


def _weight_diag(pos, vel):
    d = np.zeros(NX)
    d[12:15] = _vec3(pos, 'cumulative position weight')
    d[15:18] = _vec3(vel, 'cumulative velocity weight')
    return d


def initial_state(drone_pos, drone_vel, wp_pos, wp_vel, cum=None):
    """x-bar: [wp_x, x, wp_y, y, wp_z, z, wp_vx, vx, wp_vy, vy, wp_vz, vz, cum (6, default 0)]."""
    x = np.zeros(NX)
    x[list(REF_POS)] = wp_pos
    x[list(DRONE_POS)] = drone_pos
    x[list(REF_VEL)] = wp_vel
    x[list(DRONE_VEL)] = drone_vel
    if cum is not None:
        x[12:] = cum
    return x


def initial_reference(wp_pos, wp_vel):
    """z-bar of eq. (15): both copies at the waypoint, cumulative references zero."""
    z = np.zeros(NX)
    z[list(REF_POS)] = wp_pos
    z[list(DRONE_POS)] = wp_pos
    z[list(REF_VEL)] = wp_vel
    z[list(DRONE_VEL)] = wp_vel
    return z


def reference_trajectory(z_bar, Ar, N):
    """z_0..z_N with z_{k+1} = A_r z_k, shape (N+1, 18)."""
    Z = np.empty((N + 1, NX))
    Z[0] = z_bar
    for k in range(N):
        Z[k + 1] = Ar.dot(Z[k])
    return Z


def state_bounds(v_max):
    """x_min, x_max of Table 1: only the drone velocities are bounded (+-v_max); everything else +-inf."""
    xmax = np.full(NX, np.inf)
    xmax[list(DRONE_VEL)] = _vec3(v_max, 'v_max', allow_inf=True)
    return -xmax, xmax


def input_bounds(a_max):
    """u_min, u_max of Table 1: +-a_max."""
    umax = np.array(_vec3(a_max, 'a_max', allow_inf=True), dtype=float)
    return -umax, umax


# --------------------------------------------------------------------------- stacked QP

class QpProblem(object):
    """OSQP data of eq. (2): min 1/2 v'Pv + q'v s.t. l <= Aqp v <= u, v = [x_0..x_N, u_0..u_{N-1}].

    Rows of Aqp: n_eq = 18(N+1) equalities (-x_0 = -x-bar, A x_k + B u_k - x_{k+1} = 0), then the finite
    state bounds of x_1..x_N (``bounded_states`` indices per step), then the finite input bounds of
    u_0..u_{N-1} (``bounded_inputs``).
    """

    __slots__ = ('P', 'q', 'A', 'l', 'u', 'N', 'n_eq', 'bounded_states', 'bounded_inputs')

    def __init__(self, **kw):
        for k in self.__slots__:
            setattr(self, k, kw[k])

    @property
    def n_var(self):
        return NX * (self.N + 1) + NU * self.N


def cost_diagonal(Q, Q_N, R, N):
    """Diagonal of P: Q for x_0..x_{N-1}, Q_N for x_N, R for u_0..u_{N-1} (all entries kept, zeros too)."""
    for M in (Q, Q_N, R):
        if np.count_nonzero(M - np.diag(np.diag(M))):
            raise ValueError('Q, Q_N and R must be diagonal')
    return np.concatenate([np.tile(np.diag(Q), N), np.diag(Q_N), np.tile(np.diag(R), N)])


def linear_cost(Q, Q_N, Z):
    """q of the stacked QP from the reference trajectory Z (N+1, 18): -Q z_k, -Q_N z_N, 0 for the inputs."""
    N = Z.shape[0] - 1
    qx = -np.concatenate([(Z[:N] * np.diag(Q)).ravel(), Z[N] * np.diag(Q_N)])
    return np.concatenate([qx, np.zeros(NU * N)])


def build_qp(A, B, Q, Q_N, R, N, xmin, xmax, umin, umax, x_bar, Z):
    """Stack eq. (2) into OSQP form (see QpProblem). P is diagonal CSC with every diagonal entry stored."""
    n_var = NX * (N + 1) + NU * N
    pdiag = cost_diagonal(Q, Q_N, R, N)
    P = sparse.csc_matrix((pdiag, np.arange(n_var), np.arange(n_var + 1)), shape=(n_var, n_var))
    q = linear_cost(Q, Q_N, Z)

    Ax = sparse.kron(sparse.eye(N + 1), -sparse.eye(NX)) + \
        sparse.kron(sparse.eye(N + 1, k=-1), sparse.csc_matrix(A))
    Bu = sparse.kron(sparse.vstack([sparse.csc_matrix((1, N)), sparse.eye(N)]), sparse.csc_matrix(B))
    blocks = [sparse.hstack([Ax, Bu])]
    leq = np.concatenate([-np.asarray(x_bar, dtype=float), np.zeros(NX * N)])
    lo, hi = [leq], [leq.copy()]

    bx = np.flatnonzero(np.isfinite(xmin) | np.isfinite(xmax))
    if bx.size:
        Sx = sparse.csc_matrix((np.ones(bx.size), (np.arange(bx.size), bx)), shape=(bx.size, NX))
        sel = sparse.hstack([sparse.csc_matrix((N, 1)), sparse.eye(N)])
        blocks.append(sparse.hstack([sparse.kron(sel, Sx), sparse.csc_matrix((N * bx.size, NU * N))]))
        lo.append(np.tile(xmin[bx], N))
        hi.append(np.tile(xmax[bx], N))
    bu = np.flatnonzero(np.isfinite(umin) | np.isfinite(umax))
    if bu.size:
        Su = sparse.csc_matrix((np.ones(bu.size), (np.arange(bu.size), bu)), shape=(bu.size, NU))
        blocks.append(sparse.hstack([sparse.csc_matrix((N * bu.size, NX * (N + 1))),
                                     sparse.kron(sparse.eye(N), Su)]))
        lo.append(np.tile(umin[bu], N))
        hi.append(np.tile(umax[bu], N))
    Aqp = sparse.vstack(blocks).tocsc()
    Aqp.sort_indices()
    l = np.clip(np.concatenate(lo), -OSQP_INFTY, OSQP_INFTY)
    u = np.clip(np.concatenate(hi), -OSQP_INFTY, OSQP_INFTY)
    return QpProblem(P=P, q=q, A=Aqp, l=l, u=u, N=N, n_eq=NX * (N + 1), bounded_states=bx, bounded_inputs=bu)


# --------------------------------------------------------------------------- controller

class MpcResult(object):
    """Outcome of one solve. When ``ok`` is False the caller must hover; u0 and vz_command are then 0."""

    __slots__ = ('ok', 'status', 'iterations', 'solve_time', 'setup_time', 'run_time', 'u0', 'x_pred',
                 'z_ref', 'vz_command', 'u_pred', 'inputs', 'delayed', 'velocity_clipped', 'inaccurate', 'resolved')

    def __init__(self, ok=False, status='', iterations=0, solve_time=float('nan'), setup_time=0.0,
                 run_time=0.0, u0=(0.0, 0.0, 0.0), x_pred=None, z_ref=None, vz_command=0.0, u_pred=None,
                 inputs=None, delayed=False, velocity_clipped=False, inaccurate=False, resolved=False):
        self.ok = ok                  # bool: solution usable
        self.status = status          # OSQP status string or reason of failure
        self.iterations = iterations  # ADMM iterations
        self.solve_time = solve_time  # [s] OSQP info.solve_time
        self.setup_time = setup_time  # [s] OSQP setup time when the QP was (re)built in this call, else 0
        self.run_time = run_time      # [s] wall time of the whole solve() call
        self.u0 = u0                  # (a_x, a_y, a_z) [m/s^2] world ENU
        self.x_pred = x_pred          # (N+1, 18) predicted states or None
        self.z_ref = z_ref            # (N+1, 18) reference trajectory or None
        self.vz_command = vz_command  # [m/s] x_pred[vz_step, 11]
        self.u_pred = u_pred          # (N, 3) predicted inputs or None
        self.inputs = inputs          # (drone_pos, drone_vel, wp_pos, wp_vel) the QP was solved with (vel
                                      # unclipped), or None
        self.delayed = delayed        # True: inputs are those of the previous call (paper_timing)
        self.velocity_clipped = velocity_clipped  # the measured velocity was clipped into +-v_max for x_0
        self.inaccurate = inaccurate  # OSQP said 'solved inaccurate' (accepted with accept_inaccurate)
        self.resolved = resolved      # verify: the warm-started solution was not verified, re-solved cold

    def __repr__(self):
        return 'MpcResult(ok=%r, status=%r, iterations=%r, u0=%r, vz_command=%r)' % (
            self.ok, self.status, self.iterations, self.u0, self.vz_command)


class CumulativeErrorMpc(object):
    """Constrained linear-quadratic MPC of eq. (2) with cumulative error states, solved by OSQP.

    ``params``: None, a dict or an object with attributes, keys as DEFAULT_PARAMS (unknown dict keys and
    bad values raise ValueError).
    """

    def __init__(self, params=None):
        p = dict(DEFAULT_PARAMS)
        if params is not None:
            if isinstance(params, dict):
                unknown = sorted(set(params) - set(DEFAULT_PARAMS))
                if unknown:
                    raise ValueError('unknown MPC parameter(s): %s' % ', '.join(unknown))
                p.update(params)
            else:
                for key in DEFAULT_PARAMS:
                    if hasattr(params, key):
                        p[key] = getattr(params, key)
        self._p = p
        dt = float(p['dt'])
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError('dt must be a positive number of seconds, got %r' % (p['dt'],))
        g = float(p['gravity'])
        if not (math.isfinite(g) and g > 0.0):
            raise ValueError('gravity must be positive, got %r' % (p['gravity'],))
        self._vz_step = _positive_int(p['vz_step'], 'vz_step', minimum=0)
        self._N = self._check_horizon(p['N'])
        self.dt = dt
        self.gravity = g
        self.carry_cumulative_errors = bool(p['carry_cumulative_errors'])
        self.rebuild_every_cycle = bool(p['rebuild_every_cycle'])
        self.accept_inaccurate = bool(p['accept_inaccurate'])
        self.paper_timing = bool(p['paper_timing'])
        self.verify = bool(p['verify'])
        self._verify_eps = float(p['verify_eps'])
        if not (math.isfinite(self._verify_eps) and self._verify_eps > 0.0):
            raise ValueError('verify_eps must be positive, got %r' % (p['verify_eps'],))
        cs = float(p['cum_scale'])
        if not (math.isfinite(cs) and cs > 0.0):
            raise ValueError('cum_scale must be a positive number, got %r' % (p['cum_scale'],))
        self._scale = np.ones(NX)
        self._scale[12:] = cs
        self._pending = None
        self._settings = _osqp_settings(p)
        self.A = state_matrix(dt)
        self.B = input_matrix(dt)
        self.A_r = reference_matrix(dt)
        self._set_weight_matrices(p['q_cum'], p['q_cum_terminal'], p['q_cum_vel'], p['q_cum_vel_terminal'],
                                  p['r'])
        self._set_limit_vectors(p['v_max'], p['a_max'])
        self._cum = np.zeros(6)
        self._solver = None
        self.qp = None
        if not self.rebuild_every_cycle:
            self._setup()

    # ----------------------------------------------------------------- configuration

    @property
    def N(self):
        """Horizon [steps]."""
        return self._N

    @property
    def params(self):
        """Current parameters (a copy)."""
        return dict(self._p)

    @property
    def cumulative_errors(self):
        """Cumulative errors carried into the next solve (zeros unless carry_cumulative_errors)."""
        return self._cum.copy()

    def set_weights(self, q_cum=None, q_cum_terminal=None, r=None, q_cum_vel=None, q_cum_vel_terminal=None):
        """Change Q, Q_N, R (scalars or 3 values; None keeps). P's values are updated in place (no rebuild)."""
        new = dict(q_cum=q_cum, q_cum_terminal=q_cum_terminal, r=r, q_cum_vel=q_cum_vel,
                   q_cum_vel_terminal=q_cum_vel_terminal)
        vals = dict((k, self._p[k] if v is None else v) for k, v in new.items())
        self._set_weight_matrices(vals['q_cum'], vals['q_cum_terminal'], vals['q_cum_vel'],
                                  vals['q_cum_vel_terminal'], vals['r'])
        self._p.update(vals)
        if self._solver is not None:
            self._scaled_qp_data()
            pdiag = cost_diagonal(self._Qs, self._QNs, self.R, self._N)
            try:
                self._solver.update(Px=pdiag)
                self.qp.P.data[:] = pdiag
            except Exception:  # pragma: no cover - an osqp build refusing the update: rebuild instead
                self._setup()

    def set_limits(self, v_max=None, a_max=None):
        """Change the +-v_max / +-a_max limits (3 values each, inf allowed; None keeps).

        Only l/u change unless a bound switches between finite and infinite (then the solver is rebuilt).
        """
        old_pattern = (np.isfinite(self.x_max).tolist(), np.isfinite(self.u_max).tolist())
        v = self._p['v_max'] if v_max is None else v_max
        a = self._p['a_max'] if a_max is None else a_max
        self._set_limit_vectors(v, a)
        self._p['v_max'] = tuple(_vec3(v, 'v_max', allow_inf=True))
        self._p['a_max'] = tuple(_vec3(a, 'a_max', allow_inf=True))
        if self._solver is not None:
            if (np.isfinite(self.x_max).tolist(), np.isfinite(self.u_max).tolist()) != old_pattern:
                self._setup()
            else:
                self._scaled_qp_data()
                self._bounds_into(self.qp)

    def set_max_iter(self, max_iter):
        """Change OSQP's iteration limit (>= 1) of the persistent solver (no rebuild). A solve that hits it
        reports 'maximum iterations reached': not ok, the controller's failsafe takes over."""
        self._settings['max_iter'] = _positive_int(max_iter, 'max_iter', minimum=1)
        self._p['max_iter'] = self._settings['max_iter']
        if self._solver is not None:
            self._solver.update_settings(max_iter=self._settings['max_iter'])

    def set_horizon(self, N):
        """Change the horizon; the QP structure changes, so the solver is rebuilt."""
        self._N = self._check_horizon(N)
        self._p['N'] = self._N
        if not self.rebuild_every_cycle:
            self._setup()

    def reset_cumulative_errors(self):
        """Forget carried cumulative errors (only relevant with carry_cumulative_errors)."""
        self._cum[:] = 0.0

    # ----------------------------------------------------------------- solve

    def reference(self, wp_pos, wp_vel):
        """Reference trajectory z_0..z_N (N+1, 18) of a waypoint (eq. 3, 8, 15)."""
        return reference_trajectory(initial_reference(wp_pos, wp_vel), self.A_r, self._N)

    def reset_timing(self):
        """Forget the inputs held for the next solve (paper_timing): the next solve uses its own inputs."""
        self._pending = None

    def solve(self, drone_pos, drone_vel, wp_pos, wp_vel):
        """One MPC cycle from the drone state and the waypoint (ENU, m and m/s). Never raises on bad input.

        ``paper_timing``: the QP is solved with the inputs of the previous call (the authors' node solved the
        QP prepared in the previous cycle and only then loaded the newest state and waypoint), and these
        inputs are kept for the next call; the first call after construction or ``reset_timing()`` uses its
        own inputs. The measured velocity is clipped into +-v_max before it enters x_0 (as the authors' code
        did), so a fast start never makes the QP infeasible.
        """
        t0 = time.perf_counter()
        vecs, error = self._checked_inputs(drone_pos, drone_vel, wp_pos, wp_vel)
        if error:
            return MpcResult(status=error, run_time=time.perf_counter() - t0)
        delayed = False
        if self.paper_timing:
            pending, self._pending = self._pending, vecs
            if pending is not None:
                vecs, delayed = pending, True
        dp, dv, wp, wv = vecs
        vel = np.minimum(np.maximum(dv, self.x_min[list(DRONE_VEL)]), self.x_max[list(DRONE_VEL)])   # clip
        clipped = bool(np.any(vel != dv))
        cum0 = self._cum.copy() if self.carry_cumulative_errors else np.zeros(6)
        x_bar = initial_state(dp, vel, wp, wv, cum0)
        Z = self.reference(wp, wv)
        if self.carry_cumulative_errors:
            # x_1* cumulative entries = cum_0 + (ref_0 - drone_0): the measured error accumulated per cycle
            self._cum = self.A[12:].dot(x_bar)
        # the QP in the drone-centred, scaled variables (see _scaled_qp_data): same problem, better numbers
        shift = np.zeros(NX)
        shift[list(REF_POS)] = dp
        shift[list(DRONE_POS)] = dp
        result = MpcResult(z_ref=Z, inputs=tuple(v.copy() for v in vecs), delayed=delayed,
                           velocity_clipped=clipped)
        try:
            res, qp, extra = self._solve_qp((x_bar - shift) / self._scale, (Z - shift) / self._scale, result)
        except Exception as exc:  # solver refused: hover, keep running
            self._reset_warm_start()
            result.status = 'solver error: %s' % (exc,)
            result.run_time = time.perf_counter() - t0
            return result
        self._read_solution(res, qp, shift, extra, result)
        if not result.ok:
            self._reset_warm_start()
        result.run_time = time.perf_counter() - t0
        return result

    def _checked_inputs(self, drone_pos, drone_vel, wp_pos, wp_vel):
        """(the four inputs as 3-vectors, None) or (None, the reason they are refused)."""
        try:
            vecs = [np.asarray(v, dtype=float).reshape(3) for v in (drone_pos, drone_vel, wp_pos, wp_vel)]
        except (TypeError, ValueError):
            self._pending = None
            return None, 'invalid input (need four 3-vectors)'
        if not all(np.all(np.isfinite(v)) for v in vecs):
            self._pending = None
            return None, 'non-finite input'
        return vecs, None

    def _solve_qp(self, xs, Zs, result):
        """(OSQP's result, the QP, (iterations, time) of a first solve that a verifying re-solve replaced) for the
        scaled initial state ``xs`` and reference ``Zs``; sets ``result``'s setup time. May raise."""
        result.setup_time = 0.0
        if self.rebuild_every_cycle:
            solver, qp, result.setup_time = self._build_and_setup(xs, Zs)
        else:
            solver, qp = self._solver, self.qp
            qp.q = linear_cost(self._Qs, self._QNs, Zs)
            qp.l[:NX] = -xs
            qp.u[:NX] = -xs
            solver.update(q=qp.q, l=qp.l, u=qp.u)
        res = solver.solve(raise_error=False) if _OSQP_1X else solver.solve()
        extra = (0, 0.0)
        if self.verify and int(getattr(res.info, 'status_polish', 0)) != 1:
            # the ADMM iterate did not lead to an exact (polished) solution: with a warm start far from
            # the new problem OSQP can report 'solved' on a clearly wrong answer -> cold, tighter re-solve
            first = (int(getattr(res.info, 'iter', 0)), float(getattr(res.info, 'solve_time', 0.0)))
            self._reset_warm_start()
            solver.update_settings(eps_abs=self._verify_eps, eps_rel=self._verify_eps)
            try:
                res = solver.solve(raise_error=False) if _OSQP_1X else solver.solve()
            finally:
                solver.update_settings(eps_abs=self._settings['eps_abs'], eps_rel=self._settings['eps_rel'])
            result.resolved = True
            extra = first
        return res, qp, extra

    def _read_solution(self, res, qp, shift, extra, result):
        """``result`` from OSQP's ``res``: status, iterations, predictions and the first command (ok when the
        solution is accepted and finite)."""
        info = res.info
        status = str(info.status)
        extra_iter, extra_time = extra
        result.status = status
        result.iterations = int(getattr(info, 'iter', 0)) + extra_iter
        result.solve_time = float(getattr(info, 'solve_time', float('nan'))) + extra_time
        accepted = ('solved', 'solved inaccurate') if self.accept_inaccurate else ('solved',)
        if status.lower() not in accepted or res.x is None:
            return
        sol = np.array(res.x, dtype=float, copy=True)
        n_x = NX * (self._N + 1)
        if sol.shape != (qp.n_var,) or not np.all(np.isfinite(sol)):
            result.status = status + ' (non-finite solution)'
            return
        result.x_pred = sol[:n_x].reshape(self._N + 1, NX) * self._scale + shift
        result.u_pred = sol[n_x:].reshape(self._N, NU)
        # clipped to the limits: OSQP meets bounds only within its tolerance
        result.u0 = tuple(float(a) for a in np.minimum(np.maximum(result.u_pred[0], self.u_min), self.u_max))
        vz, lo, hi = result.x_pred[self._vz_step, VZ_INDEX], self.x_min[VZ_INDEX], self.x_max[VZ_INDEX]
        result.vz_command = float(lo if vz < lo else (hi if vz > hi else vz))
        result.inaccurate = status.lower() != 'solved'
        result.ok = True

    # ----------------------------------------------------------------- internals

    def _check_horizon(self, N):
        N = _positive_int(N, 'N', minimum=1)
        if N < self._vz_step:
            raise ValueError('horizon N=%d shorter than vz_step=%d' % (N, self._vz_step))
        return N

    def _set_weight_matrices(self, q_cum, q_cum_terminal, q_cum_vel, q_cum_vel_terminal, r):
        for name, val in (('q_cum', q_cum), ('q_cum_terminal', q_cum_terminal), ('q_cum_vel', q_cum_vel),
                          ('q_cum_vel_terminal', q_cum_vel_terminal)):
            if np.any(np.asarray(_vec3(val, name)) < 0.0):
                raise ValueError('%s must be >= 0, got %r' % (name, val))
        if np.any(np.asarray(_vec3(r, 'r')) <= 0.0):
            raise ValueError('r must be > 0, got %r' % (r,))
        self.Q = state_weights(q_cum, q_cum_vel)
        self.Q_N = terminal_weights(q_cum_terminal, q_cum_vel_terminal)
        self.R = input_weights(r)

    def _set_limit_vectors(self, v_max, a_max):
        for name, val in (('v_max', v_max), ('a_max', a_max)):
            arr = np.asarray(_vec3(val, name, allow_inf=True))
            if np.any(np.isnan(arr)) or np.any(arr <= 0.0):
                raise ValueError('%s must be > 0 (inf allowed), got %r' % (name, val))
        self.x_min, self.x_max = state_bounds(v_max)
        self.u_min, self.u_max = input_bounds(a_max)

    def _bounds_into(self, qp):
        """Write the current limits into the bound rows of ``qp`` (same finiteness pattern)."""
        N, bx, bu = qp.N, qp.bounded_states, qp.bounded_inputs
        i = qp.n_eq
        d = self._scale
        for lo, hi, idx in ((self.x_min / d, self.x_max / d, bx), (self.u_min, self.u_max, bu)):
            n = N * idx.size
            qp.l[i:i + n] = np.clip(np.tile(lo[idx], N), -OSQP_INFTY, OSQP_INFTY)
            qp.u[i:i + n] = np.clip(np.tile(hi[idx], N), -OSQP_INFTY, OSQP_INFTY)
            i += n

    def _scaled_qp_data(self):
        """A, B, Q, Q_N, x_min, x_max of the QP variables x~ = D^-1 (x - shift), D = diag(1 x12, cum_scale
        x6) and shift = the drone's measured position in every position slot (the problem is translation
        invariant: only differences ref - drone enter the cumulative errors and the cost). Same optimum in
        u; x = D x~ + shift. Keeps the QP's numbers O(error) instead of O(position) and O(N error)."""
        d = self._scale
        self._As = self.A * d[None, :] / d[:, None]
        self._Bs = self.B / d[:, None]
        self._Qs = self.Q * np.outer(d, d)
        self._QNs = self.Q_N * np.outer(d, d)
        return self._As, self._Bs, self._Qs, self._QNs, self.x_min / d, self.x_max / d

    def _build_and_setup(self, x_bar, Z):
        """Build and set up the QP; ``x_bar``, ``Z`` in the scaled, drone-centred variables."""
        t = time.perf_counter()
        As, Bs, Qs, QNs, xmin, xmax = self._scaled_qp_data()
        qp = build_qp(As, Bs, Qs, QNs, self.R, self._N, xmin, xmax, self.u_min, self.u_max, x_bar, Z)
        solver = osqp.OSQP()
        solver.setup(qp.P, qp.q, qp.A, qp.l, qp.u, **self._settings)
        self.qp = qp
        return solver, qp, time.perf_counter() - t

    def _setup(self):
        """(Re)build the QP at a neutral state (hover at the origin) and set up the persistent solver."""
        zero = np.zeros(3)
        self._solver, self.qp, _ = self._build_and_setup(initial_state(zero, zero, zero, zero),
                                                         self.reference(zero, zero))

    def _reset_warm_start(self):
        if self._solver is not None and self.qp is not None:
            try:
                self._solver.warm_start(x=np.zeros(self.qp.n_var), y=np.zeros(self.qp.A.shape[0]))
            except Exception:  # pragma: no cover
                pass


def _osqp_settings(p):
    s = {'eps_abs': float(p['eps_abs']), 'eps_rel': float(p['eps_rel']),
         'max_iter': _positive_int(p['max_iter'], 'max_iter', minimum=1), 'verbose': bool(p['verbose'])}
    if not (s['eps_abs'] >= 0.0 and s['eps_rel'] >= 0.0 and s['eps_abs'] + s['eps_rel'] > 0.0):
        raise ValueError('eps_abs/eps_rel must be >= 0 and not both 0')
    if _OSQP_1X:
        s['warm_starting'] = bool(p['warm_start'])
        s['polishing'] = bool(p['polish'])
    else:
        s['warm_start'] = bool(p['warm_start'])
        s['polish'] = bool(p['polish'])
    return s


def _positive_int(value, name, minimum):
    try:
        iv = int(value)
    except (TypeError, ValueError):
        raise ValueError('%s must be an integer, got %r' % (name, value))
    if iv != value or iv < minimum:
        raise ValueError('%s must be an integer >= %d, got %r' % (name, minimum, value))
    return iv


def _vec3(value, name, allow_inf=False):
    """Scalar or 3 values -> list of 3 floats (finite unless allow_inf); ValueError otherwise."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError('%s must be a number or 3 numbers, got %r' % (name, value))
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    if arr.shape != (3,):
        raise ValueError('%s must be a number or 3 numbers, got %r' % (name, value))
    if np.any(np.isnan(arr)) or (not allow_inf and not np.all(np.isfinite(arr))):
        raise ValueError('%s must be finite, got %r' % (name, value))
    return [float(a) for a in arr]


# --------------------------------------------------------------------------- output mapping (eqs. 9-10)

def attitude_from_acceleration(ax_world, ay_world, yaw_rad, g=9.81):
    """World ENU accelerations [m/s^2] + heading [rad] -> (roll_deg, pitch_deg) of the ROS PilotingCommand.

    The accelerations are rotated into the stability axes (x forward, y left). Eq. (9): pitch =
    asin(a_fwd / g), + = nose down = forward, as the PilotingCommand. Eq. (10) writes roll = asin(a_y / g)
    with a_y in the stability axes (+ = left); the PilotingCommand's + roll is to the RIGHT (anafi_ros.md),
    so roll = -asin(a_left / g). Arguments of asin are clamped to [-1, 1]. Non-finite input: ValueError.
    """
    if not (math.isfinite(ax_world) and math.isfinite(ay_world) and math.isfinite(yaw_rad)
            and math.isfinite(g) and g > 0.0):
        raise ValueError('attitude_from_acceleration needs finite inputs and g > 0')
    a_fwd, a_left = world_to_stability(ax_world, ay_world, yaw_rad)
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, a_fwd / g))))
    roll = -math.degrees(math.asin(max(-1.0, min(1.0, a_left / g))))
    return roll, pitch


def piloting_from_result(result, yaw_rad, g=9.81):
    """(roll_deg, pitch_deg, gaz_m_s) of an MpcResult at heading ``yaw_rad``; hover (0, 0, 0) if not ok."""
    if not result.ok or not math.isfinite(yaw_rad):
        return 0.0, 0.0, 0.0
    roll, pitch = attitude_from_acceleration(result.u0[0], result.u0[1], yaw_rad, g)
    return roll, pitch, result.vz_command
