"""A spatial grasp (specs/tripod_grasp.yaml): three Cartesian fingers hold a box at three
body points. The composite attributes of the grasp equal an independent Lagrangian
computation in the box's minimal coordinates, internal forces move nothing, and computed
torque at the box tracks all six coordinates."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import yaml

from robotgen.model.simulation import SimulationSettings
from robotgen.simulation.tree import run

SPEC = Path(__file__).resolve().parents[2] / "specs" / "tripod_grasp.yaml"


def rot(rpy):
    """Rz(yaw) Ry(pitch) Rx(roll), written out independently of robotgen."""
    r, p, y = rpy[0], rpy[1], rpy[2]
    Rx = ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, ca.cos(r), -ca.sin(r)), ca.horzcat(0, ca.sin(r), ca.cos(r)))
    Ry = ca.vertcat(ca.horzcat(ca.cos(p), 0, ca.sin(p)), ca.horzcat(0, 1, 0), ca.horzcat(-ca.sin(p), 0, ca.cos(p)))
    Rz = ca.vertcat(ca.horzcat(ca.cos(y), -ca.sin(y), 0), ca.horzcat(ca.sin(y), ca.cos(y), 0), ca.horzcat(0, 0, 1))
    return Rz @ Ry @ Rx


def lagrangian_reference():
    """M(x), N(x) of box + fingertip point masses with the fingertips at p + R c_k:
    T = 1/2 sum m_f |dp_k/dt|^2 + 1/2 m |pdot|^2 + 1/2 w_b^T I w_b, w_b from R^T Rdot,
    V = sum m_f g z_k + m g z; M = d2T/dxd2, N = dV/dx."""
    spec = yaml.safe_load(SPEC.read_text())
    nodes = spec["nodes"]
    points = np.array(nodes["hand"]["attach"]["constraint"]["point_contacts"]["points"], float)
    m_f = nodes["f1"]["define"]["formulas"]["parameters"]["m"]
    body = nodes["box"]["define"]["rigid_body"]["spatial"]
    m_b, I = body["mass"], np.diag([body["inertia"][k] for k in ("ixx", "iyy", "izz")])
    x, xd = ca.SX.sym("x", 6), ca.SX.sym("xd", 6)
    R = rot(x[3:])
    Rdot = ca.reshape(ca.jtimes(ca.reshape(R, 9, 1), x, xd), 3, 3)
    W = R.T @ Rdot  # skew(w_body)
    w_b = ca.vertcat(W[2, 1], W[0, 2], W[1, 0])
    tips = [x[:3] + R @ ca.DM(c) for c in points]
    T = 0.5 * m_b * ca.dot(xd[:3], xd[:3]) + 0.5 * w_b.T @ ca.DM(I) @ w_b
    V = m_b * 9.81 * x[2]
    for p in tips:
        v = ca.jtimes(p, x, xd)
        T += 0.5 * m_f * ca.dot(v, v)
        V += m_f * 9.81 * p[2]
    M = ca.hessian(T, xd)[0]
    theta = ca.vertcat(*tips)
    return ca.Function("ref", [x], [M, ca.gradient(V, x), theta])


def test_grasp_attributes_equal_lagrangian(build_module):
    mod = build_module(SPEC)
    ref = lagrangian_reference()
    rng = np.random.default_rng(0)
    for _ in range(30):
        x = np.array([0, 0, 0.3, 0, 0, 0]) + rng.normal(size=6) * [0.05, 0.05, 0.05, 0.3, 0.3, 0.5]
        M_ref, N_ref, theta_ref = (np.array(a) for a in ref(x))
        theta = mod.plant_inverse(x)
        np.testing.assert_allclose(theta, theta_ref.ravel(), atol=1e-12)
        np.testing.assert_allclose(mod.plant_position(theta), x, atol=1e-12)
        np.testing.assert_allclose(mod.hand_mass(theta), M_ref, atol=1e-12)
        np.testing.assert_allclose(mod.hand_n(theta, np.zeros(9)), N_ref.ravel(), atol=1e-11)


def test_internal_forces_move_nothing(build_module):
    mod = build_module(SPEC)
    x = np.array([0.01, -0.02, 0.3, 0.1, -0.2, 0.3])
    theta = mod.plant_inverse(x)
    f_e = np.random.default_rng(1).normal(size=6)
    base = mod.hand_write(theta, np.zeros(9), x, np.zeros(6), np.zeros(6), f_e, np.zeros(3))
    for k in range(3):
        f_i = np.eye(3)[k] * 5.0
        tau = mod.hand_write(theta, np.zeros(9), x, np.zeros(6), np.zeros(6), f_e, f_i)
        assert np.abs(tau - base).max() > 1.0  # a real squeeze of the fingers
        a0 = mod.plant_dynamics(theta, np.zeros(6), base)[1]
        a1 = mod.plant_dynamics(theta, np.zeros(6), tau)[1]
        np.testing.assert_allclose(a1, a0, atol=1e-12)


def test_computed_torque_tracks_six_coordinates(build_module):
    mod = build_module(SPEC)
    result = run(
        mod,
        SimulationSettings(
            duration=1.5,
            dt=1e-3,
            start=(0, 0, 0.3, 0, 0, 0),
            initial_error=(0.005, -0.005, 0.005, 0.05, -0.05, 0.05),
            amplitude=(0.02, 0.02, 0.02, 0.2, 0.2, 0.3),
            frequency=(0.5, 0.3, 0.4, 0.25, 0.35, 0.2),
        ),
    )
    e = np.linalg.norm(result.error, axis=1)
    print(f"tripod grasp: |e| {e[0]:.2e} at 0 s, {e[500]:.2e} at 0.5 s, {e[-1]:.2e} at 1.5 s")
    assert e[0] > 0.05 and e[-1] < 1e-4 and e[1000] < 1e-3
