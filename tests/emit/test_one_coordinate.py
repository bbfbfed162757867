"""A one-coordinate chain (a pendulum read from a URDF) returns the documented shapes, not
collapsed ones: M and C (1, 1), J (6, 1), the derivatives (1, 1), A (2, 2) and B (2, 1), and
a batch puts B in front; out= takes those shapes. The values against the pendulum's closed
forms."""

from __future__ import annotations

import importlib
import sys

import numpy as np
import pytest

from robotgen.cli import main

PENDULUM = """<?xml version="1.0"?>
<robot name="pendulum">
  <link name="base"/>
  <link name="arm"><inertial><origin xyz="0 0 -0.5"/><mass value="2"/>
    <inertia ixx="0.01" iyy="0.02" izz="0.03" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tip"/>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="5"/></joint>
  <joint name="end" type="fixed"><parent link="arm"/><child link="tip"/><origin xyz="0 0 -1"/></joint>
</robot>
"""
M = 0.02 + 2 * 0.5**2  # I_yy + m l^2
SHAPES = {  # docs/python-api.md with nq = 1
    "fk": (4, 4),
    "jacobian": (6, 1),
    "jacobian_hand": (6, 1),
    "jacobian_dot_qd": (6,),
    "mass": (1, 1),
    "coriolis": (1, 1),
    "gravity": (1,),
    "nonlinear": (1,),
    "inverse_dynamics": (1,),
    "forward_dynamics": (1,),
    "servo_terms": ((1, 1), (1,), (6, 1), (6,)),
    "inverse_dynamics_derivatives": ((1, 1), (1, 1)),
    "forward_dynamics_derivatives": ((1, 1), (1, 1), (1, 1)),
    "mass_inverse": (1, 1),
    "discrete_dynamics": ((1,), (1,)),
    "discrete_dynamics_derivatives": ((1,), (1,), (2, 2), (2, 1)),
    "jacobian_derivative": (6, 1),
}


@pytest.fixture(scope="module")
def pendulum(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pendulum")
    (tmp / "pendulum.urdf").write_text(PENDULUM)
    out = tmp / "out"
    assert main(["build", str(tmp / "pendulum.urdf"), "--tip", "tip", "-o", str(out), "-q"]) == 0
    sys.path.insert(0, str(out))
    try:
        importlib.invalidate_caches()
        return importlib.import_module("pendulum")
    finally:
        sys.path.remove(str(out))


def call(module, name: str, batch: int | None = None, **kw):
    lead = () if batch is None else (batch,)
    rng = np.random.default_rng(4)
    args = {
        "q": rng.uniform(-1, 1, (*lead, 1)),
        "qd": rng.uniform(-1, 1, (*lead, 1)),
        "qdd": rng.uniform(-1, 1, (*lead, 1)),
        "tau": rng.uniform(-1, 1, (*lead, 1)),
        "dt": 0.01,
    }
    inputs = {
        "fk": "q",
        "jacobian": "q",
        "jacobian_hand": "q",
        "mass": "q",
        "gravity": "q",
        "mass_inverse": "q",
        "inverse_dynamics": "q qd qdd",
        "inverse_dynamics_derivatives": "q qd qdd",
        "forward_dynamics": "q qd tau",
        "forward_dynamics_derivatives": "q qd tau",
        "discrete_dynamics": "q qd tau dt",
        "discrete_dynamics_derivatives": "q qd tau dt",
    }.get(name, "q qd")
    return getattr(module, name)(*(args[a] for a in inputs.split()), **kw)


def test_every_function_returns_the_documented_shape(pendulum):
    assert pendulum.nq == 1
    assert sorted(pendulum.info()["functions"]) == sorted(SHAPES)
    for name, shape in SHAPES.items():
        single, batched = call(pendulum, name), call(pendulum, name, batch=3)
        if isinstance(shape[0], tuple):
            assert [r.shape for r in single] == list(shape), name
            assert [r.shape for r in batched] == [(3, *s) for s in shape], name
        else:
            assert single.shape == shape and batched.shape == (3, *shape), name


def test_out_takes_the_documented_shapes(pendulum):
    q, qd = np.array([0.4]), np.array([-0.3])
    M_out = np.empty((1, 1))
    assert pendulum.mass(q, out=M_out) is M_out
    np.testing.assert_allclose(M_out, [[M]], rtol=1e-15)
    terms = (np.empty((1, 1)), np.empty(1), np.empty((6, 1)), np.empty(6))
    got = pendulum.servo_terms(q, qd, out=terms)
    assert all(a is b for a, b in zip(got, terms))
    batch = np.empty((5, 6, 1))
    pendulum.jacobian(np.zeros((5, 1)), out=batch)
    np.testing.assert_allclose(batch[:, :, 0], np.tile([-1.0, 0, 0, 0, 1, 0], (5, 1)), atol=1e-15)
    with pytest.raises(ValueError, match=r"mass\(\): out for 'mass' must have shape \(1, 1\), got \(1,\)"):
        pendulum.mass(q, out=np.empty(1))
    with pytest.raises(ValueError, match=r"out for 'jacobian' must have shape \(6, 1\), got \(6,\)"):
        pendulum.jacobian(q, out=np.empty(6))


def test_the_pendulums_closed_forms(pendulum):
    """Hinge about y, centre of mass 0.5 below it, tip 1 below it: M = I_yy + m l^2,
    g = m g l sin q, tip at (-sin q, 0, -cos q), J = [(-cos q, 0, sin q); (0, 1, 0)]."""
    for t in (-2.0, 0.3, 1.1):
        q = np.array([t])
        np.testing.assert_allclose(pendulum.mass(q), [[M]], rtol=1e-15)
        np.testing.assert_allclose(pendulum.mass_inverse(q), [[1 / M]], rtol=1e-15)
        np.testing.assert_allclose(pendulum.gravity(q), [2 * 9.81 * 0.5 * np.sin(t)], rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(pendulum.fk(q)[:3, 3], [-np.sin(t), 0, -np.cos(t)], atol=1e-15)
        np.testing.assert_allclose(pendulum.jacobian(q), [[-np.cos(t)], [0], [np.sin(t)], [0], [1], [0]], atol=1e-15)
        np.testing.assert_allclose(pendulum.coriolis(q, np.array([2.0])), [[0.0]], atol=1e-15)
