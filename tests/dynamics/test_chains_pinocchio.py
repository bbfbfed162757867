"""The friction-free DH example chains (two_link; stanford, whose joint 3 is prismatic)
against Pinocchio built independently from the same DH numbers (tests/reference.py).
The PUMA 560 has its own file, with a friction-free copy and the published gravity check."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SPECS
from reference import PinRef, dh_chain, random_q

TOL = 1e-9


@pytest.fixture(scope="module", params=["two_link", "stanford"])
def pair(request, build_module):
    spec = SPECS / f"{request.param}.yaml"
    chain = dh_chain(spec)
    assert all(j.viscous == 0 and j.coulomb == 0 for j in chain.joints), "Pinocchio has no tanh friction"
    rng = np.random.default_rng(1981)
    n = 100
    q = random_q(chain, rng, n)
    qd = rng.uniform(-2, 2, (n, chain.nq))
    qdd = rng.uniform(-5, 5, (n, chain.nq))
    return build_module(spec), PinRef(chain), (q, qd, qdd)


def test_mass(pair):
    mod, ref, (q, _, _) = pair
    np.testing.assert_allclose(mod.mass(q), np.stack([ref.mass(x) for x in q]), rtol=0, atol=TOL)


def test_gravity(pair):
    mod, ref, (q, _, _) = pair
    np.testing.assert_allclose(mod.gravity(q), np.stack([ref.gravity(x) for x in q]), rtol=0, atol=TOL)


def test_inverse_dynamics(pair):
    mod, ref, (q, qd, qdd) = pair
    expect = np.stack([ref.rnea(*s) for s in zip(q, qd, qdd)])
    np.testing.assert_allclose(mod.inverse_dynamics(q, qd, qdd), expect, rtol=0, atol=TOL)


def test_fk_and_jacobian(pair):
    mod, ref, (q, _, _) = pair
    np.testing.assert_allclose(mod.fk(q), np.stack([ref.fk(x) for x in q]), rtol=0, atol=TOL)
    np.testing.assert_allclose(mod.jacobian(q), np.stack([ref.jacobian(x) for x in q]), rtol=0, atol=TOL)


def test_jacobian_hand(pair):
    """Whitney's hand-coordinate Jacobian: the same twist expressed in the tip frame."""
    mod, ref, (q, _, _) = pair
    if not hasattr(mod, "jacobian_hand"):
        pytest.skip("module has no jacobian_hand")
    import pinocchio as pin

    expect = np.stack([pin.computeFrameJacobian(ref.model, ref.data, x, ref.fid, pin.LOCAL) for x in q])
    np.testing.assert_allclose(mod.jacobian_hand(q), expect, rtol=0, atol=TOL)
