"""Generated modules against closed forms written out by hand.

two_link: the planar two-link arm of Spong, Hutchinson & Vidyasagar, "Robot Modeling and
Control" (2006) sec. 7.4.2 (Siciliano et al., "Robotics" (2009) sec. 7.3.2 is the same):
    M11 = m1 lc1^2 + m2 (l1^2 + lc2^2 + 2 l1 lc2 cos q2) + I1 + I2
    M12 = m2 (lc2^2 + l1 lc2 cos q2) + I2,     M22 = m2 lc2^2 + I2
    h   = -m2 l1 lc2 sin q2
    C   = [[h qd2, h (qd1 + qd2)], [-h qd1, 0]]          (Christoffel symbols)
    N   = dV/dq with V = -sum_i m_i g . p_ci               (gravity g in the x-y plane)
The numbers are read from specs/two_link.yaml (not from robotgen): l_i = a_i,
lc_i = a_i + com_x,i (standard DH puts link frame i at the distal end), I_i = izz_i.

styx_finger: Deno et al. 1990 eq 3.1 with k = m2 l1 l2. The Christoffel symbols
c_ijk = (dM_ij/dq_k + dM_ik/dq_j - dM_jk/dq_i) / 2, with dM12/dth1 = -k s, dM12/dth2 = k s
(s = sin(th1 - th2)) and constant M11, M22, give by hand
    C = k sin(th1 - th2) [[0, dth2], [-dth1, 0]],
so C qd = k s [dth2^2, -dth1^2], the centripetal terms of the absolute-angle two-link.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SPECS
from reference import dh_chain, load_doc, root_define

N_STATES = 100
TOL = dict(rtol=1e-12, atol=1e-12)


# ----------------------------------------------------------------------------- two-link


@pytest.fixture(scope="module")
def two_link(build_module):
    return build_module(SPECS / "two_link.yaml")


@pytest.fixture(scope="module")
def tl_params():
    ch = dh_chain(SPECS / "two_link.yaml")
    assert ch.nq == 2
    for j in ch.joints:  # the closed form below assumes a planar arm in x-y
        assert not j.prismatic and j.alpha == 0 and j.d == 0 and j.theta == 0
        assert j.com[1] == 0 and j.com[2] == 0 and j.armature == 0
        assert j.viscous == 0 and j.coulomb == 0
    assert ch.gravity[2] == 0
    j1, j2 = ch.joints
    return dict(
        m1=j1.mass,
        m2=j2.mass,
        l1=j1.a,
        l2=j2.a,
        lc1=j1.a + j1.com[0],
        lc2=j2.a + j2.com[0],
        I1=j1.inertia[2, 2],
        I2=j2.inertia[2, 2],
        gx=ch.gravity[0],
        gy=ch.gravity[1],
    )


def tl_mass(p, q):
    c2 = np.cos(q[:, 1])
    M = np.empty((len(q), 2, 2))
    M[:, 0, 0] = (
        p["m1"] * p["lc1"] ** 2
        + p["m2"] * (p["l1"] ** 2 + p["lc2"] ** 2 + 2 * p["l1"] * p["lc2"] * c2)
        + p["I1"]
        + p["I2"]
    )
    M[:, 0, 1] = M[:, 1, 0] = p["m2"] * (p["lc2"] ** 2 + p["l1"] * p["lc2"] * c2) + p["I2"]
    M[:, 1, 1] = p["m2"] * p["lc2"] ** 2 + p["I2"]
    return M


def tl_coriolis(p, q, qd):
    h = -p["m2"] * p["l1"] * p["lc2"] * np.sin(q[:, 1])
    C = np.zeros((len(q), 2, 2))
    C[:, 0, 0] = h * qd[:, 1]
    C[:, 0, 1] = h * (qd[:, 0] + qd[:, 1])
    C[:, 1, 0] = -h * qd[:, 0]
    return C


def tl_gravity(p, q):
    s1, c1 = np.sin(q[:, 0]), np.cos(q[:, 0])
    s12, c12 = np.sin(q[:, 0] + q[:, 1]), np.cos(q[:, 0] + q[:, 1])
    gx, gy = p["gx"], p["gy"]
    # d/dq of -g . p_c with p_c1 = lc1 (c1, s1), p_c2 = l1 (c1, s1) + lc2 (c12, s12)
    d12 = -p["m2"] * p["lc2"] * (-gx * s12 + gy * c12)
    d1 = -(p["m1"] * p["lc1"] + p["m2"] * p["l1"]) * (-gx * s1 + gy * c1) + d12
    return np.stack([d1, d12], axis=1)


def _states(rng, n=N_STATES, nq=2):
    q = rng.uniform(-np.pi, np.pi, (n, nq))
    qd = rng.uniform(-3, 3, (n, nq))
    qdd = rng.uniform(-10, 10, (n, nq))
    return q, qd, qdd


def test_two_link_gravity_sign(tl_params):
    # Outstretched along +x with gravity along -y: holding torque is +(m1 lc1 + m2 (l1 + lc2)) g.
    p = tl_params
    g = tl_gravity(p, np.zeros((1, 2)))[0]
    expect = (p["m1"] * p["lc1"] + p["m2"] * (p["l1"] + p["lc2"])) * -p["gy"]
    assert g[0] == pytest.approx(expect) and g[0] > 0


def test_two_link_mass(two_link, tl_params):
    q, _, _ = _states(np.random.default_rng(1))
    np.testing.assert_allclose(two_link.mass(q), tl_mass(tl_params, q), **TOL)


def test_two_link_coriolis(two_link, tl_params):
    q, qd, _ = _states(np.random.default_rng(2))
    np.testing.assert_allclose(two_link.coriolis(q, qd), tl_coriolis(tl_params, q, qd), **TOL)


def test_two_link_gravity(two_link, tl_params):
    q, _, _ = _states(np.random.default_rng(3))
    np.testing.assert_allclose(two_link.gravity(q), tl_gravity(tl_params, q), **TOL)


def test_two_link_nonlinear(two_link, tl_params):
    q, qd, _ = _states(np.random.default_rng(4))
    expect = np.einsum("bij,bj->bi", tl_coriolis(tl_params, q, qd), qd) + tl_gravity(tl_params, q)
    np.testing.assert_allclose(two_link.nonlinear(q, qd), expect, **TOL)


def test_two_link_inverse_dynamics(two_link, tl_params):
    p = tl_params
    q, qd, qdd = _states(np.random.default_rng(5))
    expect = (
        np.einsum("bij,bj->bi", tl_mass(p, q), qdd)
        + np.einsum("bij,bj->bi", tl_coriolis(p, q, qd), qd)
        + tl_gravity(p, q)
    )
    np.testing.assert_allclose(two_link.inverse_dynamics(q, qd, qdd), expect, **TOL)


def test_two_link_forward_dynamics(two_link, tl_params):
    p = tl_params
    q, qd, _ = _states(np.random.default_rng(6))
    tau = np.random.default_rng(7).uniform(-20, 20, q.shape)
    rhs = tau - np.einsum("bij,bj->bi", tl_coriolis(p, q, qd), qd) - tl_gravity(p, q)
    expect = np.linalg.solve(tl_mass(p, q), rhs[..., None])[..., 0]
    np.testing.assert_allclose(two_link.forward_dynamics(q, qd, tau), expect, rtol=1e-11, atol=1e-11)


def test_two_link_fk_and_jacobian(two_link, tl_params):
    p = tl_params
    q, _, _ = _states(np.random.default_rng(8))
    s1, c1 = np.sin(q[:, 0]), np.cos(q[:, 0])
    s12, c12 = np.sin(q.sum(1)), np.cos(q.sum(1))
    T = two_link.fk(q)
    np.testing.assert_allclose(T[:, 0, 3], p["l1"] * c1 + p["l2"] * c12, **TOL)
    np.testing.assert_allclose(T[:, 1, 3], p["l1"] * s1 + p["l2"] * s12, **TOL)
    np.testing.assert_allclose(T[:, 2, 3], 0, atol=1e-12)
    np.testing.assert_allclose(T[:, :2, 0], np.stack([c12, s12], 1), **TOL)
    J = two_link.jacobian(q)
    expect = np.zeros((len(q), 6, 2))
    expect[:, 0, 0] = -p["l1"] * s1 - p["l2"] * s12
    expect[:, 0, 1] = -p["l2"] * s12
    expect[:, 1, 0] = p["l1"] * c1 + p["l2"] * c12
    expect[:, 1, 1] = p["l2"] * c12
    expect[:, 5, :] = 1
    np.testing.assert_allclose(J, expect, **TOL)


def test_two_link_single_equals_batch(two_link):
    q, qd, qdd = _states(np.random.default_rng(9), n=5)
    batch = two_link.inverse_dynamics(q, qd, qdd)
    for i in range(5):
        single = two_link.inverse_dynamics(q[i], qd[i], qdd[i])
        assert single.shape == (2,)
        np.testing.assert_array_equal(single, batch[i])
    assert two_link.mass(q[0]).shape == (2, 2)
    assert two_link.nq == 2


# ----------------------------------------------------------------------------- styx finger


@pytest.fixture(scope="module")
def finger(build_module):
    return build_module(SPECS / "styx_finger.yaml")


@pytest.fixture(scope="module")
def finger_params():
    f = root_define(load_doc(SPECS / "styx_finger.yaml"))["formulas"]
    assert "C" not in f and "N" not in f, "this test checks the Christoffel C and zero N"
    return {k: float(v) for k, v in f["parameters"].items()}


def finger_mass(p, q):
    """Deno et al. 1990, eq 3.1, as printed."""
    k = p["m2"] * p["l1"] * p["l2"] * np.cos(q[:, 0] - q[:, 1])
    M = np.empty((len(q), 2, 2))
    M[:, 0, 0] = p["m1"] * p["l1"] ** 2 + p["m2"] * p["l2"] ** 2
    M[:, 0, 1] = M[:, 1, 0] = k
    M[:, 1, 1] = p["m2"] * p["l2"] ** 2
    return M


def finger_coriolis(p, q, qd):
    ks = p["m2"] * p["l1"] * p["l2"] * np.sin(q[:, 0] - q[:, 1])
    C = np.zeros((len(q), 2, 2))
    C[:, 0, 1] = ks * qd[:, 1]
    C[:, 1, 0] = -ks * qd[:, 0]
    return C


def test_finger_mass(finger, finger_params):
    q, _, _ = _states(np.random.default_rng(11))
    np.testing.assert_allclose(finger.mass(q), finger_mass(finger_params, q), **TOL)


def test_finger_coriolis_christoffel(finger, finger_params):
    q, qd, _ = _states(np.random.default_rng(12))
    np.testing.assert_allclose(finger.coriolis(q, qd), finger_coriolis(finger_params, q, qd), **TOL)


def test_finger_nonlinear_and_gravity_zero(finger, finger_params):
    q, qd, _ = _states(np.random.default_rng(13))
    np.testing.assert_allclose(finger.gravity(q), 0, atol=1e-15)
    expect = np.einsum("bij,bj->bi", finger_coriolis(finger_params, q, qd), qd)
    np.testing.assert_allclose(finger.nonlinear(q, qd), expect, **TOL)


def test_finger_inverse_and_forward_dynamics(finger, finger_params):
    p = finger_params
    q, qd, qdd = _states(np.random.default_rng(14))
    M, C = finger_mass(p, q), finger_coriolis(p, q, qd)
    tau = np.einsum("bij,bj->bi", M, qdd) + np.einsum("bij,bj->bi", C, qd)
    np.testing.assert_allclose(finger.inverse_dynamics(q, qd, qdd), tau, **TOL)
    np.testing.assert_allclose(finger.forward_dynamics(q, qd, tau), qdd, rtol=1e-9, atol=1e-9)


def test_finger_kinematics(finger, finger_params):
    p = finger_params
    q, _, _ = _states(np.random.default_rng(15))
    s1, c1, s2, c2 = np.sin(q[:, 0]), np.cos(q[:, 0]), np.sin(q[:, 1]), np.cos(q[:, 1])
    x = np.stack([p["l1"] * c1 + p["l2"] * c2, p["l1"] * s1 + p["l2"] * s2], 1)
    np.testing.assert_allclose(finger.kinematics(q), x, **TOL)
    J = np.stack([np.stack([-p["l1"] * s1, -p["l2"] * s2], 1), np.stack([p["l1"] * c1, p["l2"] * c2], 1)], 1)
    np.testing.assert_allclose(finger.kinematics_jacobian(q), J, **TOL)
