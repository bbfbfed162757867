"""PUMA 560 against Pinocchio, built independently here from the DH numbers of the spec.

The Pinocchio model (tests/reference.py: pinocchio_model) is itself checked against the
published gravity load of the Robotics Toolbox at the nominal pose qn, so a wrong DH ->
Pinocchio translation cannot make the comparison pass by accident.

Friction: Pinocchio has no tanh-Coulomb model, so M, gravity and RNEA are compared on a copy
of the spec with friction removed (and a unique module name); fk and the Jacobian do not
depend on friction.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from conftest import SPECS
from reference import PinRef, dh_chain, load_doc, random_q, root_define

PUMA = SPECS / "puma560.yaml"
QN = np.array([0, np.pi / 4, np.pi, 0, np.pi / 4, 0])
# Robotics Toolbox (Corke), p560.gravload(qn) with g = 9.81, rounded as published.
GRAVLOAD_QN = np.array([0, 31.6399, 6.0351, 0, 0.0283, 0])
TOL = 1e-9


@pytest.fixture(scope="module")
def spec_nofriction(tmp_path_factory):
    doc = load_doc(PUMA)
    doc["name"] = doc["name"] + "_nofriction"
    for j in root_define(doc)["chain"]["joints"]:
        j.pop("friction", None)
    path = tmp_path_factory.mktemp("puma_nofriction") / "puma560_nofriction.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def puma(build_module, spec_nofriction):
    return build_module(spec_nofriction)


@pytest.fixture(scope="module")
def ref(spec_nofriction):
    chain = dh_chain(spec_nofriction)
    assert all(j.viscous == 0 and j.coulomb == 0 for j in chain.joints)
    return PinRef(chain)


def test_reference_matches_published_gravity(ref):
    """The reference itself: Pinocchio's gravity at qn equals Corke's published value."""
    np.testing.assert_allclose(ref.gravity(QN), GRAVLOAD_QN, atol=1e-3)


def test_reference_armature_in_mass(ref):
    """Pinocchio adds model.armature to crba's diagonal; check it is Jm G^2 from the spec."""
    M = ref.mass(QN)
    arm = ref.model.armature.copy()
    ref.model.armature[:] = 0
    try:
        M0 = ref.mass(QN)
    finally:
        ref.model.armature[:] = arm
    np.testing.assert_allclose(np.diag(M - M0), [j.armature for j in ref.chain.joints], rtol=1e-14)
    assert arm[1] == pytest.approx(200e-6 * 107.815**2)


def test_gravity_at_qn(puma, ref):
    np.testing.assert_allclose(puma.gravity(QN), ref.gravity(QN), rtol=0, atol=TOL)


def test_mass_at_qn(puma, ref):
    np.testing.assert_allclose(puma.mass(QN), ref.mass(QN), rtol=0, atol=TOL)


@pytest.fixture(scope="module")
def states(ref):
    rng = np.random.default_rng(560)
    n = 100
    q = random_q(ref.chain, rng, n)
    qd = rng.uniform(-2, 2, (n, 6))
    qdd = rng.uniform(-5, 5, (n, 6))
    return q, qd, qdd


def test_mass_random(puma, ref, states):
    q, _, _ = states
    expect = np.stack([ref.mass(x) for x in q])
    np.testing.assert_allclose(puma.mass(q), expect, rtol=0, atol=TOL)


def test_gravity_random(puma, ref, states):
    q, _, _ = states
    expect = np.stack([ref.gravity(x) for x in q])
    np.testing.assert_allclose(puma.gravity(q), expect, rtol=0, atol=TOL)


def test_inverse_dynamics_random(puma, ref, states):
    q, qd, qdd = states
    expect = np.stack([ref.rnea(*s) for s in zip(q, qd, qdd)])
    np.testing.assert_allclose(puma.inverse_dynamics(q, qd, qdd), expect, rtol=0, atol=TOL)


def test_nonlinear_random(puma, ref, states):
    q, qd, _ = states
    expect = np.stack([ref.rnea(a, b, np.zeros(6)) for a, b in zip(q, qd)])
    np.testing.assert_allclose(puma.nonlinear(q, qd), expect, rtol=0, atol=TOL)


def test_fk_random(puma, ref, states):
    q, _, _ = states
    expect = np.stack([ref.fk(x) for x in q])
    np.testing.assert_allclose(puma.fk(q), expect, rtol=0, atol=TOL)


def test_jacobian_random(puma, ref, states):
    q, _, _ = states
    expect = np.stack([ref.jacobian(x) for x in q])
    np.testing.assert_allclose(puma.jacobian(q), expect, rtol=0, atol=TOL)


def test_jacobian_dot_qd_random(puma, ref, states):
    import pinocchio as pin

    q, qd, _ = states
    m, d = ref.model, ref.data
    expect = []
    for a, b in zip(q, qd):
        pin.forwardKinematics(m, d, a, b, np.zeros(6))
        pin.updateFramePlacements(m, d)
        # classical (not spatial) acceleration of the tool origin at qdd = 0 is Jdot qd
        acc = pin.getFrameClassicalAcceleration(m, d, ref.fid, pin.LOCAL_WORLD_ALIGNED)
        expect.append(acc.vector)
    np.testing.assert_allclose(puma.jacobian_dot_qd(q, qd), np.stack(expect), rtol=0, atol=TOL)


def test_friction_spec_adds_exactly_the_friction_law(build_module, puma, states):
    """The full spec (with friction) differs from the friction-free build only by
    viscous qd + coulomb tanh(qd / smoothing), with the joint-side values of the YAML."""
    from reference import friction_torque

    full = build_module(PUMA)
    chain = dh_chain(PUMA)
    q, qd, qdd = states
    diff = full.inverse_dynamics(q, qd, qdd) - puma.inverse_dynamics(q, qd, qdd)
    np.testing.assert_allclose(diff, friction_torque(chain, qd), rtol=0, atol=TOL)
    # the documented conversion from the toolbox's motor-side values
    G = np.array([62.6111, 107.815, 53.7063, 76.0364, 71.923, 76.686])
    B = np.array([1.48e-3, 0.817e-3, 1.38e-3, 71.2e-6, 82.6e-6, 36.7e-6])
    Tc = np.array(
        [
            [0.395, -0.435],
            [0.126, -0.071],
            [0.132, -0.105],
            [11.2e-3, -16.9e-3],
            [9.26e-3, -14.5e-3],
            [3.96e-3, -10.5e-3],
        ]
    )
    np.testing.assert_allclose([j.viscous for j in chain.joints], B * G**2, rtol=1e-12)
    np.testing.assert_allclose([j.coulomb for j in chain.joints], np.abs(Tc).mean(1) * G, rtol=1e-12)
