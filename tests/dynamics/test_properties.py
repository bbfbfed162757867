"""Structural properties of every example spec's compiled module, on 1000 random states.

References are exact derivatives, not finite differences: the symbolic layer's CasADi graph
of a quantity (robotgen.symbolic.kernels_for) is differentiated by CasADi's automatic
differentiation and evaluated numerically, then compared with the COMPILED module (the C
code behind the Python extension). So the test checks the emitted C against derivatives of
the graphs it was printed from, plus identities that do not depend on robotgen at all
(symmetry, positive definiteness, skew symmetry, M qdd + C qd + N = tau, friction law).
"""

from __future__ import annotations

import zlib

import casadi as ca
import numpy as np
import pytest
from conftest import EXAMPLE_SPECS
from reference import dh_chain, dh_fk, friction_torque, load_doc, random_q, root_define

N_STATES = 1000


class Case:
    """One spec: compiled module, CasADi kernels, random states."""

    def __init__(self, spec, module):
        from robotgen.frontend import load_system
        from robotgen.symbolic import kernels_for

        self.spec = spec
        self.mod = module
        self.n = n = module.nq
        self.kernels = {k.name: k.function for k in kernels_for(load_system(str(spec)))}
        rng = np.random.default_rng(zlib.crc32(spec.name.encode()))
        define = root_define(load_doc(spec))
        is_dh = "chain" in define and define["chain"]["convention"] == "dh_standard"
        self.chain = dh_chain(spec) if is_dh else None
        self.q = random_q(self.chain, rng, N_STATES) if is_dh else rng.uniform(-np.pi, np.pi, (N_STATES, n))
        self.qd = rng.uniform(-2, 2, (N_STATES, n))
        self.qdd = rng.uniform(-5, 5, (N_STATES, n))

    # CasADi helpers: evaluate a symbolic derivative over the whole batch with Function.map
    def ad(self, kernel: str, make, n_in: int) -> np.ndarray:
        """make(kernel_output, q, qd) -> SX expression, evaluated on the batch of q (n_in = 1)
        or (q, qd) (n_in = 2); the per-state results are concatenated column-wise."""
        f = self.kernels[kernel]
        q = ca.SX.sym("q", self.n)
        qd = ca.SX.sym("qd", self.n)
        expr = make(f(q), q, qd)
        args = [q, qd][:n_in]
        F = ca.Function("F", args, [ca.densify(expr)]).map(N_STATES)
        vals = [self.q.T, self.qd.T][:n_in]
        return np.asarray(F(*vals))  # (rows, B) for a column expression, (rows, cols * B) else


CASES: dict = {}


@pytest.fixture(scope="module", params=EXAMPLE_SPECS, ids=lambda p: p.stem)
def case(request, build_module):
    spec = request.param
    if spec not in CASES:
        CASES[spec] = Case(spec, build_module(spec))
    return CASES[spec]


def _mv(A, x):
    return np.einsum("bij,bj->bi", A, x)


def _scale(*arrays):
    return max(1.0, *(float(np.max(np.abs(a))) for a in arrays))


def test_mass_symmetric_positive_definite(case):
    M = case.mod.mass(case.q)
    assert M.shape == (N_STATES, case.n, case.n)
    np.testing.assert_allclose(M, np.swapaxes(M, 1, 2), rtol=0, atol=1e-13 * _scale(M))
    eig = np.linalg.eigvalsh(M)
    assert eig.min() > 0, f"M not positive definite: min eigenvalue {eig.min()}"


def _mass_derivatives(case):
    """dM/dq_k by AD of the mass kernel: array (B, n, n, n) indexed [b, i, j, k]."""
    n = case.n
    out = case.ad("mass", lambda Mf, q, qd: ca.jacobian(Mf, q), 1)
    # out: (n*n, n*B), column b*n + k
    return out.reshape(n * n, N_STATES, n).transpose(1, 0, 2).reshape(N_STATES, n, n, n)


def test_mdot_minus_2c_skew(case):
    n = case.n
    dM = _mass_derivatives(case)
    Mdot = np.einsum("bijk,bk->bij", dM, case.qd)
    C = case.mod.coriolis(case.q, case.qd)
    S = Mdot - 2 * C
    tol = 1e-11 * _scale(Mdot, C)
    np.testing.assert_allclose(S + np.swapaxes(S, 1, 2), 0, atol=tol)
    assert C.shape == (N_STATES, n, n)


def test_coriolis_is_christoffel(case):
    """C_ij = sum_k (dM_ij/dq_k + dM_ik/dq_j - dM_jk/dq_i) qd_k / 2 (Christoffel symbols of M)."""
    dM = _mass_derivatives(case)  # [b, i, j, k] = dM_ij / dq_k
    c = 0.5 * (dM + np.swapaxes(dM, 2, 3) - np.transpose(dM, (0, 3, 2, 1)))
    # c[b,i,j,k] = (dM_ij/dq_k + dM_ik/dq_j - dM_jk/dq_i) / 2
    expect = np.einsum("bijk,bk->bij", c, case.qd)
    C = case.mod.coriolis(case.q, case.qd)
    np.testing.assert_allclose(C, expect, rtol=0, atol=1e-11 * _scale(expect))


def test_nonlinear_is_c_qd_plus_gravity_plus_friction(case):
    C = case.mod.coriolis(case.q, case.qd)
    g = case.mod.gravity(case.q)
    if case.chain is not None:
        fr = friction_torque(case.chain, case.qd)
    else:
        f = root_define(load_doc(case.spec)).get("formulas", {})
        if "N" in f:
            pytest.skip("N given by formulas may depend on qd; gravity(q) = N(q, 0) only")
        fr = 0.0
    expect = _mv(C, case.qd) + g + fr
    h = case.mod.nonlinear(case.q, case.qd)
    np.testing.assert_allclose(h, expect, rtol=0, atol=1e-10 * _scale(expect))


def test_inverse_dynamics_is_m_qdd_plus_nonlinear(case):
    M = case.mod.mass(case.q)
    h = case.mod.nonlinear(case.q, case.qd)
    expect = _mv(M, case.qdd) + h
    tau = case.mod.inverse_dynamics(case.q, case.qd, case.qdd)
    np.testing.assert_allclose(tau, expect, rtol=0, atol=1e-10 * _scale(expect))


def test_forward_dynamics_inverts_inverse_dynamics(case):
    tau = case.mod.inverse_dynamics(case.q, case.qd, case.qdd)
    qdd = case.mod.forward_dynamics(case.q, case.qd, tau)
    M = case.mod.mass(case.q)
    cond = np.linalg.cond(M).max()
    np.testing.assert_allclose(qdd, case.qdd, rtol=0, atol=1e-13 * cond * _scale(case.qdd, tau))


def test_gravity_is_nonlinear_at_rest_without_friction_velocity(case):
    h0 = case.mod.nonlinear(case.q, np.zeros_like(case.qd))
    np.testing.assert_allclose(h0, case.mod.gravity(case.q), rtol=0, atol=1e-12 * _scale(h0))


def _chain_only(case):
    if not hasattr(case.mod, "fk"):
        pytest.skip("formulas robot: no fk/jacobian")


def test_fk_matches_dh_product(case):
    _chain_only(case)
    if case.chain is None:
        pytest.skip("reference DH product only for dh_standard specs")
    T = case.mod.fk(case.q)
    expect = np.stack([dh_fk(case.chain, q) for q in case.q])
    np.testing.assert_allclose(T, expect, rtol=0, atol=1e-12 * _scale(expect))


def _fk_derivative(case):
    """dT/dq_k by AD of the fk kernel: (B, 4, 4, n)."""
    n = case.n
    out = case.ad("fk", lambda Tf, q, qd: ca.jacobian(Tf, q), 1)
    return out.reshape(16, N_STATES, n).transpose(1, 0, 2).reshape(N_STATES, 4, 4, n)


def test_jacobian_linear_rows_are_dp_dq(case):
    _chain_only(case)
    dT = _fk_derivative(case)
    J = case.mod.jacobian(case.q)
    assert J.shape == (N_STATES, 6, case.n)
    np.testing.assert_allclose(J[:, :3, :], dT[:, :3, 3, :], rtol=0, atol=1e-12 * _scale(J))


def test_jacobian_angular_rows_from_rdot_rt(case):
    """skew(omega_k) = (dR/dq_k) R^T for each column k."""
    _chain_only(case)
    dT = _fk_derivative(case)
    R = case.mod.fk(case.q)[:, :3, :3]
    W = np.einsum("bijk,blj->bkil", dT[:, :3, :3, :], R)  # [b, k] = dR/dq_k R^T
    np.testing.assert_allclose(W, -np.swapaxes(W, 2, 3), atol=1e-12)
    omega = np.stack([W[..., 2, 1], W[..., 0, 2], W[..., 1, 0]], axis=1)  # (B, 3, n)
    J = case.mod.jacobian(case.q)
    np.testing.assert_allclose(J[:, 3:, :], omega, rtol=0, atol=1e-12)


def test_jacobian_dot_qd(case):
    _chain_only(case)
    n = case.n
    out = case.ad("jacobian", lambda Jf, q, qd: ca.jtimes(Jf, q, qd), 2)
    Jdot = out.T.reshape(N_STATES, 6, n)
    expect = _mv(Jdot, case.qd)
    got = case.mod.jacobian_dot_qd(case.q, case.qd)
    np.testing.assert_allclose(got, expect, rtol=0, atol=1e-11 * _scale(expect))


def test_kinematics_jacobian(case):
    if not hasattr(case.mod, "kinematics_jacobian"):
        pytest.skip("no kinematics map")
    n = case.n
    k = case.mod.kinematics(case.q[0]).shape[0]
    out = case.ad("kinematics", lambda xf, q, qd: ca.jacobian(xf, q), 1)
    expect = out.reshape(k, N_STATES, n).transpose(1, 0, 2)
    np.testing.assert_allclose(case.mod.kinematics_jacobian(case.q), expect, rtol=0, atol=1e-12)


def test_compiled_equals_casadi_graph(case):
    """The emitted C evaluates the same numbers as the graph it was printed from."""
    for name, f in case.kernels.items():
        fn = getattr(case.mod, name)
        nin = f.n_in()
        args = [case.q, case.qd, case.qdd, np.full((N_STATES, 1), 1e-3)][:nin]  # the 4th: a step dt
        got = fn(*args)
        got = got if isinstance(got, tuple) else (got,)
        want = f.map(N_STATES)(*[a.T for a in args])
        want = want if isinstance(want, tuple) else (want,)
        for g, w in zip(got, want, strict=True):
            np.testing.assert_allclose(
                np.asarray(g).reshape(N_STATES, -1), np.asarray(w).T, rtol=1e-12, atol=1e-12, err_msg=name
            )
