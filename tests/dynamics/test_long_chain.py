"""A 16-joint DH chain (one prismatic joint, armature, off-diagonal inertias): its kernels are
loops (robotgen.symbolic.rigid_body.chain_loops) and are checked against Pinocchio built from
the same DH numbers (tests/reference.py), and C against the Christoffel property."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from reference import PinRef, dh_chain, random_q

N = 16
TOL = 1e-9


def _spec(path):
    rng = np.random.default_rng(16)
    joints = []
    for i in range(N):
        prismatic = i == 5
        m = round(float(rng.uniform(0.4, 1.5)), 3)
        a, b, c = rng.uniform(0.03, 0.1, 3)
        ixx, iyy, izz = m / 12 * (b * b + c * c), m / 12 * (a * a + c * c), m / 12 * (a * a + b * b)
        off = 0.1 * min(ixx, iyy, izz)
        joint = {
            "name": f"j{i + 1}",
            "type": "prismatic" if prismatic else "revolute",
            "dh": {
                "a": round(float(rng.uniform(0, 0.12)), 3),
                "alpha": ["pi/2", "-pi/2", "0", "0.3"][i % 4],
                "d": round(float(rng.uniform(0.02, 0.1)), 3),
                "theta": 0,
            },
            "link": {
                "mass": m,
                "com": [round(float(x), 3) for x in rng.uniform(-0.03, 0.03, 3)],
                "inertia": {
                    "ixx": float(ixx),
                    "iyy": float(iyy),
                    "izz": float(izz),
                    "ixy": float(off),
                    "ixz": float(-off / 2),
                    "iyz": float(off / 3),
                },
            },
            "motor": {"inertia": 0.001 * (i % 3), "gear_ratio": 10},
        }
        if prismatic:
            joint["limits"] = {"lower": 0.0, "upper": 0.3}
        joints.append(joint)
    doc = {
        "robotgen": 1,
        "name": "long_chain",
        "root": "arm",
        "nodes": {"arm": {"define": {"chain": {"convention": "dh_standard", "joints": joints}}}},
    }
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def spec(tmp_path_factory):
    return _spec(tmp_path_factory.mktemp("long") / "long_chain.yaml")


@pytest.fixture(scope="module")
def case(spec, build_module):
    chain = dh_chain(spec)
    rng = np.random.default_rng(3)
    n = 40
    q = random_q(chain, rng, n)
    return build_module(spec), PinRef(chain), q, rng.uniform(-2, 2, (n, N)), rng.uniform(-3, 3, (n, N))


def test_the_quadratic_kernels_are_loops(spec):
    from robotgen.frontend import load_system
    from robotgen.symbolic import kernels_for

    kernels = {k.name: k for k in kernels_for(load_system(str(spec)))}
    for name in ("mass", "coriolis", "nonlinear", "inverse_dynamics", "forward_dynamics", "servo_terms"):
        assert kernels[name].schedule is not None, name
    assert kernels["gravity"].schedule is None


def test_the_looped_kernels_share_one_kinematics_helper(case):
    """The kinematics (axes and inertias about the base) are printed once, and each looped
    kernel calls them instead of repeating them."""
    source = (Path(case[0].__file__).parent / "long_chain.c").read_text()
    # static, or compiled in one part and linked from the others (RG_SHARED: the file is large)
    assert (
        len(
            re.findall(
                r"^(static|RG_SHARED) void rg_kinematics\(const double \*q, double \*axes, "
                r"double \*inertias\) \{",
                source,
                re.M,
            )
        )
        == 1
    )
    for name in ("mass", "coriolis", "nonlinear", "inverse_dynamics", "forward_dynamics", "servo_terms"):
        start = source.index(f"int long_chain_{name}(")
        definition = source[start : source.index("\n}\n", start)]
        assert definition.count("  rg_kinematics(q, t0, t1);") == 1, name


def test_dynamics_against_pinocchio(case):
    mod, ref, q, qd, qdd = case
    pin = ref.pin
    for k in range(len(q)):
        M = ref.mass(q[k])
        np.testing.assert_allclose(mod.mass(q[k]), M, rtol=0, atol=TOL)
        tau = ref.rnea(q[k], qd[k], qdd[k])
        np.testing.assert_allclose(
            mod.inverse_dynamics(q[k], qd[k], qdd[k]), tau, rtol=0, atol=TOL * max(1, np.abs(tau).max())
        )
        h = ref.rnea(q[k], qd[k], np.zeros(N))
        np.testing.assert_allclose(mod.nonlinear(q[k], qd[k]), h, rtol=0, atol=TOL * max(1, np.abs(h).max()))
        # forward dynamics (articulated bodies, with armature) against M^-1 (tau - h) from Pinocchio
        np.testing.assert_allclose(mod.forward_dynamics(q[k], qd[k], tau), qdd[k], rtol=0, atol=1e-7)
        C = pin.computeCoriolisMatrix(ref.model, ref.data, q[k], qd[k])
        np.testing.assert_allclose(mod.coriolis(q[k], qd[k]), C, rtol=0, atol=TOL * max(1, np.abs(C).max()))


def test_servo_terms_equal_the_separate_functions(case):
    mod, ref, q, qd, _ = case
    M, h, J, jdqd = mod.servo_terms(q, qd)
    np.testing.assert_allclose(M, mod.mass(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(h, mod.nonlinear(q, qd), rtol=0, atol=1e-10)
    np.testing.assert_allclose(J, np.stack([ref.jacobian(x) for x in q]), rtol=0, atol=TOL)
    np.testing.assert_allclose(jdqd, mod.jacobian_dot_qd(q, qd), rtol=0, atol=1e-12)


def test_mdot_minus_2c_is_skew(case):
    """Mdot by central differences of the compiled M along qd."""
    mod, _, q, qd, _ = case
    eps = 1e-6
    for k in range(5):
        Mdot = (mod.mass(q[k] + eps * qd[k]) - mod.mass(q[k] - eps * qd[k])) / (2 * eps)
        S = Mdot - 2 * mod.coriolis(q[k], qd[k])
        assert np.abs(S + S.T).max() < 1e-6 * max(1.0, np.abs(Mdot).max())
