"""anafi_control.mpc: matrices of eqs. (5)-(13) element by element, stacked QP, closed loops on the model,
cumulative-error carry option, output mapping (eqs. 9-10) at several headings."""
import math

import numpy as np
import pytest

from anafi_control import mpc
from anafi_control.mpc import CumulativeErrorMpc, attitude_from_acceleration, piloting_from_result

DT = 0.1


def _from_entries(entries, shape=(18, 18)):
    M = np.zeros(shape)
    for (i, j), v in entries.items():
        M[i, j] = v
    return M


# ----------------------------------------------------------------------------- model matrices

def test_state_matrix_eq5_element_by_element():
    entries = {}
    for i in range(18):
        entries[(i, i)] = 1.0
    # mass point: position slot i integrates velocity slot i + 6 (ref copies and drone alike)
    entries.update({(0, 6): 0.1, (1, 7): 0.1, (2, 8): 0.1, (3, 9): 0.1, (4, 10): 0.1, (5, 11): 0.1})
    # cum_{k+1} = cum_k + (ref_k - drone_k)
    entries.update({(12, 0): 1.0, (12, 1): -1.0, (13, 2): 1.0, (13, 3): -1.0, (14, 4): 1.0, (14, 5): -1.0,
                    (15, 6): 1.0, (15, 7): -1.0, (16, 8): 1.0, (16, 9): -1.0, (17, 10): 1.0, (17, 11): -1.0})
    A = mpc.state_matrix(DT)
    np.testing.assert_array_equal(A, _from_entries(entries))
    # a few rows literally
    assert A[1].tolist() == [0, 1, 0, 0, 0, 0, 0, 0.1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]
    assert A[12].tolist() == [1, -1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0]
    assert A[17].tolist() == [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, -1, 0, 0, 0, 0, 0, 1]


def test_input_matrix_eq7_columns():
    B = mpc.input_matrix(DT)
    b1 = [0.0] * 1 + [0.005] + [0.0] * 5 + [0.1] + [0.0] * 10
    b2 = [0.0] * 3 + [0.005] + [0.0] * 5 + [0.1] + [0.0] * 8
    b3 = [0.0] * 5 + [0.005] + [0.0] * 5 + [0.1] + [0.0] * 6
    assert B.shape == (18, 3)
    np.testing.assert_allclose(B[:, 0], b1, rtol=0, atol=1e-15)
    np.testing.assert_allclose(B[:, 1], b2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(B[:, 2], b3, rtol=0, atol=1e-15)


def test_reference_matrix_eq8_meaning():
    entries = {(i, i): 1.0 for i in range(6)}
    # both position copies advance with the REFERENCE velocity (slots 6, 8, 10)
    entries.update({(0, 6): 0.1, (1, 6): 0.1, (2, 8): 0.1, (3, 8): 0.1, (4, 10): 0.1, (5, 10): 0.1})
    # both velocity slots copy v_ref
    entries.update({(6, 6): 1.0, (7, 6): 1.0, (8, 8): 1.0, (9, 8): 1.0, (10, 10): 1.0, (11, 10): 1.0})
    np.testing.assert_array_equal(mpc.reference_matrix(DT), _from_entries(entries))
    assert not mpc.reference_matrix(DT)[12:].any()  # cumulative references stay zero


def test_weights_eqs_11_to_13():
    np.testing.assert_array_equal(mpc.state_weights(), np.diag([0] * 12 + [1e-3] * 3 + [0] * 3))
    np.testing.assert_array_equal(mpc.terminal_weights(), np.diag([0] * 12 + [5.0] * 3 + [0] * 3))
    np.testing.assert_array_equal(mpc.input_weights(), np.diag([0.2, 0.2, 0.2]))
    c = CumulativeErrorMpc()
    np.testing.assert_array_equal(c.Q, mpc.state_weights())
    np.testing.assert_array_equal(c.Q_N, mpc.terminal_weights())
    np.testing.assert_array_equal(c.R, mpc.input_weights())


def test_limits_table1():
    xmin, xmax = mpc.state_bounds((10, 10, 2))
    expected = [np.inf] * 18
    expected[7], expected[9], expected[11] = 10.0, 10.0, 2.0
    assert xmax.tolist() == expected
    assert xmin.tolist() == [-v for v in expected]
    umin, umax = mpc.input_bounds((5, 5, 5))
    assert umax.tolist() == [5.0, 5.0, 5.0] and umin.tolist() == [-5.0, -5.0, -5.0]


def test_initial_state_and_reference_eq15():
    x = mpc.initial_state((1, 2, 3), (4, 5, 6), (7, 8, 9), (10, 11, 12))
    assert x.tolist() == [7, 1, 8, 2, 9, 3, 10, 4, 11, 5, 12, 6, 0, 0, 0, 0, 0, 0]
    z = mpc.initial_reference((7, 8, 9), (10, 11, 12))
    assert z.tolist() == [7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 0, 0, 0, 0, 0, 0]


# ----------------------------------------------------------------------------- one step by hand

def test_one_prediction_step_by_hand():
    x = np.array([2.0, 1.0, -1.0, 0.5, 5.0, 4.0,      # x_ref, x, y_ref, y, z_ref, z
                  0.5, 1.5, 0.0, -1.0, 0.2, 0.0,      # vx_ref, vx, vy_ref, vy, vz_ref, vz
                  0.3, -0.2, 0.1, 0.0, 0.4, -0.5])    # cumulative errors
    u = np.array([1.0, -2.0, 0.5])
    expected = [2.05, 1.155, -1.0, 0.39, 5.02, 4.0025,
                0.5, 1.6, 0.0, -1.2, 0.2, 0.05,
                1.3, -1.7, 1.1, -1.0, 1.4, -0.3]
    nxt = mpc.state_matrix(DT).dot(x) + mpc.input_matrix(DT).dot(u)
    np.testing.assert_allclose(nxt, expected, rtol=0, atol=1e-12)


def test_one_reference_step_by_hand():
    z = mpc.initial_reference((2.0, -1.0, 5.0), (0.5, 0.0, 0.2))
    z1 = mpc.reference_matrix(DT).dot(z)
    np.testing.assert_allclose(z1, [2.05, 2.05, -1, -1, 5.02, 5.02, 0.5, 0.5, 0, 0, 0.2, 0.2] + [0] * 6,
                               atol=1e-12)
    # the drone-copy slot moves with the reference velocity, not with its own slot
    z[7], z[12] = 9.0, 3.0
    z1 = mpc.reference_matrix(DT).dot(z)
    assert z1[1] == pytest.approx(2.05) and z1[7] == pytest.approx(0.5) and z1[12] == 0.0


# ----------------------------------------------------------------------------- stacked QP, N = 30

def test_stacked_qp_structure_n30():
    c = CumulativeErrorMpc({'cum_scale': 1.0})   # unscaled variables: the matrices of the paper literally
    d = CumulativeErrorMpc().qp.P.diagonal() / c.qp.P.diagonal()[:648].clip(1e-30)
    assert np.allclose(d[12:18 * 30:18], 900.0)  # default: cum / 30 in the QP, so its weight x 30^2
    qp = c.qp
    N, nx, nu = 30, 18, 3
    n_x = nx * (N + 1)
    assert qp.N == N and qp.n_var == n_x + nu * N == 648
    assert qp.bounded_states.tolist() == [7, 9, 11] and qp.bounded_inputs.tolist() == [0, 1, 2]
    assert qp.A.shape == (n_x + 3 * N + 3 * N, 648)
    assert qp.P.format == 'csc' and qp.A.format == 'csc'
    # P: diagonal with Q (x_0..x_{N-1}), Q_N (x_N), R (u), every diagonal entry stored
    assert qp.P.nnz == 648
    pd = qp.P.diagonal()
    np.testing.assert_array_equal(pd[:nx * N].reshape(N, nx), np.tile(np.diag(c.Q), (N, 1)))
    np.testing.assert_array_equal(pd[nx * N:n_x], np.diag(c.Q_N))
    np.testing.assert_array_equal(pd[n_x:], np.tile([0.2, 0.2, 0.2], N))
    Ad = qp.A.toarray()
    A, B = mpc.state_matrix(0.1), mpc.input_matrix(0.1)
    np.testing.assert_array_equal(Ad[:nx, :nx], -np.eye(nx))
    assert not Ad[:nx, nx:].any()
    for k in (0, 1, 17, N - 1):
        rows = slice(nx * (k + 1), nx * (k + 2))
        np.testing.assert_array_equal(Ad[rows, nx * k:nx * (k + 1)], A)
        np.testing.assert_array_equal(Ad[rows, nx * (k + 1):nx * (k + 2)], -np.eye(nx))
        np.testing.assert_array_equal(Ad[rows, n_x + nu * k:n_x + nu * (k + 1)], B)
        # nothing else in these rows
        mask = np.ones(648, bool)
        mask[nx * k:nx * (k + 2)] = False
        mask[n_x + nu * k:n_x + nu * (k + 1)] = False
        assert not Ad[rows][:, mask].any()
    # state bound rows select v_x, v_y, v_z of x_1..x_N; input rows select u_0..u_{N-1}
    for k in range(N):
        for j, idx in enumerate((7, 9, 11)):
            row = Ad[n_x + 3 * k + j]
            assert np.flatnonzero(row).tolist() == [nx * (k + 1) + idx] and row[nx * (k + 1) + idx] == 1
        for j in range(3):
            row = Ad[n_x + 3 * N + 3 * k + j]
            assert np.flatnonzero(row).tolist() == [n_x + 3 * k + j]
    assert qp.u[n_x:n_x + 3 * N].tolist() == [10.0, 10.0, 2.0] * N
    assert qp.l[n_x + 3 * N:].tolist() == [-5.0] * (3 * N)
    # -I for x_0; per step -I (18) + nnz(A) (18 + 6 + 12) + nnz(B) (6); one entry per bound row
    assert qp.A.nnz == nx + N * (nx + 36 + 6) + 6 * N


def test_infinite_bounds_have_no_rows():
    c = CumulativeErrorMpc({'v_max': (np.inf, np.inf, 2.0), 'a_max': (5.0, np.inf, 5.0)})
    assert c.qp.bounded_states.tolist() == [11] and c.qp.bounded_inputs.tolist() == [0, 2]
    assert c.qp.A.shape[0] == 18 * 31 + 30 + 60


# ----------------------------------------------------------------------------- solutions

def _rollout(c, p, v, wp, wv, steps, plant_A=None):
    """Closed loop on the model: apply u0 with x_{k+1} = A x_k + B u_k (drone), waypoint at constant wv."""
    A, B = c.A, c.B
    p, v, wp, wv = (np.array(a, dtype=float) for a in (p, v, wp, wv))
    errs, acc, vel = [], [], []
    for _ in range(steps):
        r = c.solve(p, v, wp, wv)
        assert r.ok, r.status
        x = mpc.initial_state(p, v, wp, wv)
        x = A.dot(x) + B.dot(r.u0)
        p, v = x[list(mpc.DRONE_POS)], x[list(mpc.DRONE_VEL)]
        wp, wv = x[list(mpc.REF_POS)], x[list(mpc.REF_VEL)]
        errs.append(wp - p)
        acc.append(r.u0)
        vel.append(v)
    return np.array(errs), np.array(acc), np.array(vel)


def test_far_waypoint_solution_satisfies_dynamics_and_bounds():
    c = CumulativeErrorMpc({'eps_abs': 1e-5, 'eps_rel': 1e-5})
    r = c.solve((0, 0, 0), (0, 0, 0), (100, -80, 30), (0, 0, 0))
    assert r.ok and r.status == 'solved'
    X, U = r.x_pred, r.u_pred
    assert X.shape == (31, 18) and U.shape == (30, 3) and r.z_ref.shape == (31, 18)
    np.testing.assert_allclose(X[0], mpc.initial_state((0, 0, 0), (0, 0, 0), (100, -80, 30), (0, 0, 0)),
                               atol=1e-4)
    resid = X[1:] - (X[:-1].dot(c.A.T) + U.dot(c.B.T))
    assert np.abs(resid[:, :12]).max() < 1e-3
    assert np.all(np.abs(resid[:, 12:]) < 1e-5 * (1 + np.abs(X[1:, 12:])) + 1e-3)
    tol = 1e-3
    assert np.abs(X[:, [7, 9]]).max() <= 10 + tol and np.abs(X[:, 11]).max() <= 2 + tol
    assert np.abs(U).max() <= 5 + tol
    # the far waypoint forces saturation of accelerations and of the vertical speed
    assert np.abs(U).max() > 5 - tol and np.abs(X[:, 11]).max() > 2 - tol
    assert r.u0[0] == pytest.approx(5, abs=tol) and r.u0[1] == pytest.approx(-5, abs=tol)
    assert r.vz_command == X[5, 11] or r.vz_command == 2.0
    assert abs(r.vz_command) <= 2.0
    # the waypoint copies inside x follow the reference trajectory
    ref = list(mpc.REF_POS + mpc.REF_VEL)
    np.testing.assert_allclose(X[:, ref], r.z_ref[:, ref], atol=1e-3)


def test_vz_command_is_predicted_state_5():
    c = CumulativeErrorMpc()
    r = c.solve((0, 0, 5), (0, 0, 0), (0, 0, 5.5), (0, 0, 0))
    assert r.ok
    assert r.vz_command == r.x_pred[5, 11]
    assert 0.0 < r.vz_command < 2.0  # climbing, unsaturated
    assert r.x_pred[0, 11] == pytest.approx(0.0, abs=1e-6)


def test_static_waypoint_closed_loop_converges_without_limits():
    c = CumulativeErrorMpc()
    errs, acc, vel = _rollout(c, (0, 0, 0), (0, 0, 0), (0.5, 0.3, 0.2), (0, 0, 0), 150)
    assert np.abs(acc).max() < 4.0 and np.abs(vel[:, 2]).max() < 1.5  # no limit hit
    assert np.abs(errs[-1]).max() < 1e-3
    assert np.abs(errs[-20:]).max() < 1e-2
    assert np.abs(errs[0]).max() > 0.2  # it did have to move


def test_moving_reference_tracked_with_small_error():
    c = CumulativeErrorMpc()
    errs, acc, vel = _rollout(c, (0, 0, 0), (0, 0, 0), (0, 0, 0), (3, 0, 0), 300)
    assert np.abs(errs[:30, 0]).max() > 0.3  # starting from rest it lags first
    assert np.abs(errs[-50:]).max() < 0.01
    assert vel[-1, 0] == pytest.approx(3.0, abs=0.01)


def test_carry_cumulative_errors_changes_ramp_response():
    base = CumulativeErrorMpc()
    carry = CumulativeErrorMpc({'carry_cumulative_errors': True})
    e0, _, _ = _rollout(base, (0, 0, 0), (0, 0, 0), (0, 0, 0), (3, 0, 0), 200)
    e1, _, _ = _rollout(carry, (0, 0, 0), (0, 0, 0), (0, 0, 0), (3, 0, 0), 200)
    # reset each solve: barely passes the waypoint; carried: the accumulated lag is paid back by running ahead
    assert e0[:, 0].min() > -0.1
    assert e1[:, 0].min() < -0.3
    assert np.abs(e0[:50] - e1[:50]).max() > 0.3
    assert not base.cumulative_errors.any()
    assert carry.cumulative_errors[0] != 0.0


def test_carry_uses_predicted_x1_of_previous_solution():
    c = CumulativeErrorMpc({'carry_cumulative_errors': True, 'eps_abs': 1e-6, 'eps_rel': 1e-6,
                            'max_iter': 20000})
    r1 = c.solve((0, 0, 0), (1, 0, 0), (2, 1, 0), (0, 0, 0))
    assert r1.x_pred[0, 12:].tolist() == pytest.approx([0.0] * 6, abs=1e-4)
    np.testing.assert_allclose(c.cumulative_errors, [2, 1, 0, -1, 0, 0])
    np.testing.assert_allclose(c.cumulative_errors, r1.x_pred[1, 12:], atol=1e-4)
    r2 = c.solve((0.1, 0, 0), (1, 0, 0), (2, 1, 0), (0, 0, 0))
    np.testing.assert_allclose(r2.x_pred[0, 12:], [2, 1, 0, -1, 0, 0], atol=1e-4)
    c.reset_cumulative_errors()
    assert not c.cumulative_errors.any()


@pytest.mark.parametrize('bad', [
    ((float('nan'), 0, 0), (0, 0, 0), (1, 1, 1), (0, 0, 0)),
    ((0, 0, 0), (0, float('inf'), 0), (1, 1, 1), (0, 0, 0)),
    ((0, 0, 0), (0, 0, 0), (1, 1, -float('inf')), (0, 0, 0)),
    ((0, 0, 0), (0, 0, 0), (1, 1, 1), (0, 0, float('nan'))),
    ((0, 0), (0, 0, 0), (1, 1, 1), (0, 0, 0)),
    (None, (0, 0, 0), (1, 1, 1), (0, 0, 0)),
    (('a', 'b', 'c'), (0, 0, 0), (1, 1, 1), (0, 0, 0)),
])
def test_bad_input_gives_not_ok_and_recovers(bad):
    c = CumulativeErrorMpc({'carry_cumulative_errors': True})
    r = c.solve(*bad)
    assert not r.ok and r.u0 == (0.0, 0.0, 0.0) and r.vz_command == 0.0 and r.x_pred is None
    assert r.status
    assert not c.cumulative_errors.any()  # garbage is not accumulated
    assert piloting_from_result(r, 0.0) == (0.0, 0.0, 0.0)
    good = c.solve((0, 0, 0), (0, 0, 0), (1, 1, 1), (0, 0, 0))
    assert good.ok and good.u0[0] > 0


def test_fast_start_is_clipped_into_the_velocity_bounds_not_infeasible():
    # |v_z| = 3 m/s could not be brought within 2 m/s in one step with |a_z| <= 5 m/s^2: x_0 gets v_z = 2
    c = CumulativeErrorMpc({'paper_timing': False})
    r = c.solve((0, 0, 5), (0, 0, 3.0), (0, 0, 5), (0, 0, 0))
    assert r.ok and r.velocity_clipped and r.u0[2] < -1.0
    assert r.x_pred[0, 11] == pytest.approx(2.0, abs=1e-6)
    assert r.inputs[1][2] == 3.0          # the measurement itself is kept
    r = c.solve((0, 0, 5), (-12.0, 0, 0), (0, 0, 5), (0, 0, 0))
    assert r.ok and r.velocity_clipped and r.x_pred[0, 7] == pytest.approx(-10.0, abs=1e-6) and r.u0[0] > 1.0
    r = c.solve((0, 0, 5), (0, 0, 1.5), (1, 0, 5), (0, 0, 0))
    assert r.ok and not r.velocity_clipped and r.u0[0] > 0


def test_paper_timing_solves_with_the_previous_inputs():
    tight = {'eps_abs': 1e-6, 'eps_rel': 1e-6, 'max_iter': 20000, 'paper_timing': False}
    paper = CumulativeErrorMpc(dict(tight, paper_timing=True))
    now = CumulativeErrorMpc(tight)
    seq = [((0, 0, 5), (0, 0, 0), (3, 2, 5), (0, 0, 0)), ((0.1, 0, 5), (0.5, 0, 0), (3, 2, 5), (0, 0, 0)),
           ((0.2, 0.1, 5), (1.0, 0.2, 0), (-4, 1, 8), (1, 0, 0)), ((0.3, 0.1, 5.1), (1.2, 0.3, 0.5), (-4, 1, 8), (1, 0, 0))]
    prev = None
    for k, args in enumerate(seq):
        rp, rn = paper.solve(*args), now.solve(*args)
        assert rp.ok and rn.ok
        if prev is None:                   # first call: nothing older, its own inputs
            assert not rp.delayed
            np.testing.assert_allclose(rp.u0, rn.u0, atol=1e-3)
        else:                              # the command of cycle k = the newest-input command of cycle k-1
            assert rp.delayed
            np.testing.assert_allclose(rp.inputs[2], seq[k - 1][2])
            np.testing.assert_allclose(rp.u0, prev.u0, atol=1e-3)
            np.testing.assert_allclose(rp.vz_command, prev.vz_command, atol=1e-3)
            assert np.abs(np.subtract(rp.u0, rn.u0)).max() > 0.05   # and differs from the newest one
        prev = rn
    paper.reset_timing()
    r = paper.solve(*seq[0])
    assert not r.delayed and np.allclose(r.u0, CumulativeErrorMpc(tight).solve(*seq[0]).u0, atol=1e-3)


# ----------------------------------------------------------------------------- exact optimum

def _condensed(c, x_bar, Z):
    """The same QP with the states eliminated (x_k = A^k x_0 + sum A^(k-1-j) B u_j): dense in u."""
    N, nx, nu = c.N, 18, 3
    Phi = np.zeros(((N + 1) * nx, nx))
    Gam = np.zeros(((N + 1) * nx, nu * N))
    Ak = np.eye(nx)
    powers = [np.eye(nx)]
    for k in range(N + 1):
        Phi[k * nx:(k + 1) * nx] = Ak
        Ak = c.A.dot(Ak)
        powers.append(Ak)
    for k in range(1, N + 1):
        for j in range(k):
            Gam[k * nx:(k + 1) * nx, j * nu:(j + 1) * nu] = powers[k - 1 - j].dot(c.B)
    pd = mpc.cost_diagonal(c.Q, c.Q_N, c.R, N)
    Px, Pu = pd[:(N + 1) * nx], pd[(N + 1) * nx:]
    qx = mpc.linear_cost(c.Q, c.Q_N, Z)[:(N + 1) * nx]
    H = Gam.T.dot(Px[:, None] * Gam) + np.diag(Pu)
    g = Gam.T.dot(Px * Phi.dot(x_bar) + qx)
    rows, lo, hi = [], [], []
    for k in range(1, N + 1):
        for i in np.flatnonzero(np.isfinite(c.x_max)):
            r = k * nx + i
            off = Phi[r].dot(x_bar)
            rows.append(Gam[r])
            lo.append(c.x_min[i] - off)
            hi.append(c.x_max[i] - off)
    G = np.vstack([np.array(rows), np.eye(nu * N)])
    return H, g, G, np.concatenate([lo, np.tile(c.u_min, N)]), np.concatenate([hi, np.tile(c.u_max, N)])


def exact_u0(c, x_bar, Z):
    """u_0 of the exact optimum: the condensed QP (well conditioned) by OSQP at eps 1e-10, checked by KKT."""
    import osqp
    import scipy.sparse as sparse
    H, g, G, lo, hi = _condensed(c, x_bar, Z)
    s = osqp.OSQP()
    s.setup(sparse.csc_matrix(np.triu(H)), g, sparse.csc_matrix(G), lo, hi, eps_abs=1e-10, eps_rel=1e-10,
            max_iter=200000, verbose=False, **({'polishing': True} if mpc._OSQP_1X else {'polish': True}))
    r = s.solve(raise_error=False) if mpc._OSQP_1X else s.solve()
    assert r.info.status == 'solved'
    u, y = r.x, r.y
    assert np.abs(H.dot(u) + g + G.T.dot(y)).max() < 1e-6           # stationarity
    Gu = G.dot(u)
    assert np.all(Gu >= lo - 1e-7) and np.all(Gu <= hi + 1e-7)       # feasibility
    assert np.all((y <= 1e-6) | (np.abs(Gu - hi) < 1e-6)) and np.all((y >= -1e-6) | (np.abs(Gu - lo) < 1e-6))
    return u[:3]


def _jump_sequence(seed, n=60):
    """Waypoint jumps every 6 cycles, random states around the waypoint (the wrong-warm-start case)."""
    rng = np.random.RandomState(seed)
    out = []
    for k in range(n):
        if k % 6 == 0:
            wp = np.array([rng.uniform(-30, 30), rng.uniform(-30, 30), rng.uniform(1, 40)])
        wv = rng.uniform(-3, 3, 3) if rng.rand() < 0.5 else np.zeros(3)
        v = np.append(rng.uniform(-4, 4, 2), rng.uniform(-1.9, 1.9))
        out.append((wp + rng.uniform(-6, 6, 3), v, wp, wv))
    return out


#: the MPC without its robust settings: warm start, eps 1e-3, no polish, no verification, unscaled cumulative errors
PLAIN_NUMERICS = {'polish': False, 'verify': False, 'cum_scale': 1.0, 'accept_inaccurate': False}


@pytest.mark.parametrize('seed', [0, 1])
def test_every_u0_within_0p05_of_the_exact_optimum_after_waypoint_jumps(seed):
    robust, plain = CumulativeErrorMpc({'paper_timing': False}), CumulativeErrorMpc(dict(PLAIN_NUMERICS, paper_timing=False))
    err_robust, err_plain = [], []
    for p, v, wp, wv in _jump_sequence(seed):
        u_ex = exact_u0(robust, mpc.initial_state(p, v, wp, wv), robust.reference(wp, wv))
        rn, ro = robust.solve(p, v, wp, wv), plain.solve(p, v, wp, wv)
        assert rn.ok
        err_robust.append(np.abs(np.subtract(rn.u0, u_ex)).max())
        if ro.ok:
            err_plain.append(np.abs(np.subtract(ro.u0, u_ex)).max())
    assert max(err_robust) < 0.05, max(err_robust)
    assert max(err_plain) > 0.1, max(err_plain)    # the plain numerics give the wrong answers


def test_set_weights_updates_in_place_like_a_fresh_solver():
    args = ((0, 0, 0), (0.2, 0, 0), (0.6, -0.3, 0.2), (0.5, 0, 0))
    tight = {'eps_abs': 1e-6, 'eps_rel': 1e-6, 'max_iter': 20000}
    c = CumulativeErrorMpc(tight)
    before = c.solve(*args)
    solver = c._solver
    c.set_weights(q_cum_terminal=0.5, r=1.0)
    assert c._solver is solver  # no rebuild
    after = c.solve(*args)
    fresh = CumulativeErrorMpc(dict(tight, q_cum_terminal=0.5, r=1.0)).solve(*args)
    assert after.ok and fresh.ok
    np.testing.assert_allclose(after.u0, fresh.u0, atol=1e-3)
    assert abs(after.u0[0] - before.u0[0]) > 0.1
    assert c.params['r'] == 1.0 and c.R[0, 0] == 1.0


def test_set_limits_and_horizon():
    c = CumulativeErrorMpc({'eps_abs': 1e-5, 'eps_rel': 1e-5})
    solver = c._solver
    c.set_limits(v_max=(10, 10, 1.0), a_max=(2, 2, 2))
    assert c._solver is solver
    r = c.solve((0, 0, 0), (0, 0, 0), (50, 0, 20), (0, 0, 0))
    assert r.ok
    assert np.abs(r.x_pred[:, 11]).max() <= 1.0 + 1e-3 and np.abs(r.u_pred).max() <= 2.0 + 1e-3
    assert r.u0[0] == pytest.approx(2.0, abs=1e-3)
    c.set_limits(v_max=(10, 10, np.inf))  # a row set disappears: rebuilt
    assert c._solver is not solver and c.qp.bounded_states.tolist() == [7, 9]
    c.set_horizon(12)
    r = c.solve((0, 0, 0), (0, 0, 0), (1, 0, 0), (0, 0, 0))
    assert r.ok and r.x_pred.shape == (13, 18) and r.u_pred.shape == (12, 3) and r.z_ref.shape == (13, 18)


def test_rebuild_every_cycle_solves_the_same_problem():
    tight = {'eps_abs': 1e-6, 'eps_rel': 1e-6, 'max_iter': 20000}
    a = CumulativeErrorMpc(tight)
    b = CumulativeErrorMpc(dict(tight, rebuild_every_cycle=True))
    for args in (((0, 0, 0), (0, 0, 0), (3, 2, 5), (0, 0, 0)), ((1, 0, 5), (2, 0, 0), (2, 0, 5), (3, 0, 0))):
        ra, rb = a.solve(*args), b.solve(*args)
        assert ra.ok and rb.ok and rb.setup_time > 0 and ra.setup_time == 0
        np.testing.assert_allclose(ra.u0, rb.u0, atol=1e-2)   # both within eps of the optimum
        np.testing.assert_allclose(ra.vz_command, rb.vz_command, atol=1e-2)


@pytest.mark.parametrize('params', [{'N': 0}, {'N': 4}, {'N': 2.5}, {'dt': 0.0}, {'dt': float('nan')},
                                    {'r': 0.0}, {'q_cum': -1}, {'a_max': (5, -5, 5)}, {'v_max': (1, 2)},
                                    {'v_max': (1, float('nan'), 1)}, {'eps_abs': 0, 'eps_rel': 0},
                                    {'horizon': 30}])
def test_bad_parameters_raise(params):
    with pytest.raises(ValueError):
        CumulativeErrorMpc(params)


def test_params_from_object():
    class P(object):
        N = 10
        dt = 0.05
        r = 0.5
    c = CumulativeErrorMpc(P())
    assert c.N == 10 and c.dt == 0.05 and c.R[2, 2] == 0.5
    assert c.B[1, 0] == pytest.approx(0.5 * 0.05 ** 2) and c.A[0, 6] == 0.05


# ----------------------------------------------------------------------------- output mapping

G = 9.81


def test_forward_accel_at_yaw0_pitches_nose_down():
    roll, pitch = attitude_from_acceleration(2.0, 0.0, 0.0)
    assert pitch == pytest.approx(math.degrees(math.asin(2.0 / G))) and pitch > 0
    assert roll == pytest.approx(0.0, abs=1e-9)


def test_left_accel_at_yaw0_rolls_left_negative():
    roll, pitch = attitude_from_acceleration(0.0, 2.0, 0.0)
    assert roll == pytest.approx(-math.degrees(math.asin(2.0 / G))) and roll < 0
    assert pitch == pytest.approx(0.0, abs=1e-9)


def test_yaw90_world_y_is_forward():
    roll, pitch = attitude_from_acceleration(0.0, 3.0, math.pi / 2)
    assert pitch == pytest.approx(math.degrees(math.asin(3.0 / G))) and pitch > 0
    assert roll == pytest.approx(0.0, abs=1e-9)
    # facing north, east (+x) is on the right: + roll (PilotingCommand + = right)
    roll, pitch = attitude_from_acceleration(3.0, 0.0, math.pi / 2)
    assert roll == pytest.approx(math.degrees(math.asin(3.0 / G))) and roll > 0
    assert pitch == pytest.approx(0.0, abs=1e-9)


def test_yaw180_world_x_is_backward():
    roll, pitch = attitude_from_acceleration(3.0, 0.0, math.pi)
    assert pitch == pytest.approx(-math.degrees(math.asin(3.0 / G))) and pitch < 0
    assert roll == pytest.approx(0.0, abs=1e-9)
    roll, pitch = attitude_from_acceleration(0.0, 3.0, math.pi)  # north while facing west: right
    assert roll > 0


def test_yaw_minus90_world_x_is_left():
    roll, pitch = attitude_from_acceleration(3.0, 0.0, -math.pi / 2)  # facing south, east is left
    assert roll == pytest.approx(-math.degrees(math.asin(3.0 / G))) and roll < 0
    assert pitch == pytest.approx(0.0, abs=1e-9)
    roll, pitch = attitude_from_acceleration(0.0, 3.0, -math.pi / 2)  # north is behind
    assert pitch < 0 and roll == pytest.approx(0.0, abs=1e-9)


def test_diagonal_heading_and_clamp():
    # yaw 45 deg, accel along the heading: pure pitch of asin(|a|/g)
    a = 5.0 / math.sqrt(2)
    roll, pitch = attitude_from_acceleration(a, a, math.pi / 4)
    assert pitch == pytest.approx(math.degrees(math.asin(5.0 / G))) and roll == pytest.approx(0, abs=1e-9)
    assert pitch == pytest.approx(30.64, abs=0.01)  # Table 1 max tilt
    roll, pitch = attitude_from_acceleration(50.0, -50.0, 0.0)
    assert pitch == pytest.approx(90.0) and roll == pytest.approx(90.0)
    with pytest.raises(ValueError):
        attitude_from_acceleration(float('nan'), 0.0, 0.0)


def test_piloting_from_result():
    c = CumulativeErrorMpc()
    r = c.solve((0, 0, 5), (0, 0, 0), (2, 0, 6), (0, 0, 0))
    roll, pitch, gaz = piloting_from_result(r, 0.0)
    assert pitch > 0 and roll == pytest.approx(0.0, abs=1e-3) and gaz == r.vz_command > 0
    roll, pitch, gaz = piloting_from_result(r, math.pi)
    assert pitch < 0
