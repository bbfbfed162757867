"""The symbolic algorithms on random branched trees (revolute joints about arbitrary axes,
a prismatic joint, arbitrary joint origins and inertias) against Pinocchio built from the
same canonical model. Evaluated with CasADi, so it checks the graphs, not the emitted C."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from robotgen.model.chain import Body, Joint, KinematicTree
from robotgen.model.derivatives import DerivativeSettings
from robotgen.symbolic import leaf_kernels

PARENTS = [-1, 0, 1, 2, 1, 4, 5, 6]


def random_rotation(rng) -> np.ndarray:
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return Q if np.linalg.det(Q) > 0 else -Q


def random_tree(seed: int, parents: list[int] = PARENTS) -> KinematicTree:
    rng = np.random.default_rng(seed)
    joints = []
    for i, parent in enumerate(parents):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = random_rotation(rng), rng.normal(size=3) * 0.3
        axis = rng.normal(size=3)
        R = random_rotation(rng)
        body = Body(rng.uniform(0.5, 2.0), rng.normal(size=3) * 0.1, R @ np.diag(rng.uniform(0.01, 0.1, 3)) @ R.T)
        joints.append(
            Joint(f"j{i}", "prismatic" if i == 3 else "revolute", parent, T, axis / np.linalg.norm(axis), body)
        )
    tool = np.eye(4)
    tool[:3, :3], tool[:3, 3] = random_rotation(rng), [0.1, 0.2, 0.05]
    return KinematicTree("t", tuple(joints), 6, tool, np.array([0.3, -0.2, -9.81]))


def with_coordinate_axes(tree: KinematicTree) -> KinematicTree:
    """The tree with every revolute axis turned onto a coordinate axis (z, x, -y, -z, y, -x, ...):
    the axes the kernels turn inertias about by double angles."""
    axes = [np.array(a, dtype=float) for a in ((0, 0, 1), (1, 0, 0), (0, -1, 0), (0, 0, -1), (0, 1, 0), (-1, 0, 0))]
    joints = tuple(j if j.type == "prismatic" else replace(j, axis=axes[i % 6]) for i, j in enumerate(tree.joints))
    return replace(tree, joints=joints)


def pinocchio_model(tree: KinematicTree):
    model = pin.Model()
    model.gravity.linear = tree.gravity
    ids = []
    for j in tree.joints:
        jm = (pin.JointModelPrismaticUnaligned if j.type == "prismatic" else pin.JointModelRevoluteUnaligned)(j.axis)
        jid = model.addJoint(
            0 if j.parent < 0 else ids[j.parent], jm, pin.SE3(j.origin[:3, :3], j.origin[:3, 3]), j.name
        )
        model.appendBodyToJoint(jid, pin.Inertia(j.body.mass, j.body.com, j.body.inertia), pin.SE3.Identity())
        ids.append(jid)
    tool = pin.SE3(tree.tool[:3, :3], tree.tool[:3, 3])
    fid = model.addFrame(pin.Frame("tip", ids[tree.tip], 0, tool, pin.FrameType.OP_FRAME))
    return model, fid


@pytest.mark.parametrize(
    "seed, axes", [(0, "oblique"), (1, "oblique"), (2, "oblique"), (3, "coordinate"), (4, "coordinate")]
)
def test_branched_tree_matches_pinocchio(seed, axes):
    tree = random_tree(seed) if axes == "oblique" else with_coordinate_axes(random_tree(seed))
    f = {k.name: k.function for k in leaf_kernels(tree)}
    model, fid = pinocchio_model(tree)
    data = model.createData()
    n = tree.nq
    rng = np.random.default_rng(100 + seed)
    for _ in range(20):
        q, qd, qdd = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n)
        Mp = pin.crba(model, data, q)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        tau = pin.rnea(model, data, q, qd, qdd)
        np.testing.assert_allclose(np.array(f["mass"](q)).reshape(n, n), Mp, atol=1e-12)
        np.testing.assert_allclose(np.array(f["inverse_dynamics"](q, qd, qdd)).ravel(), tau, atol=1e-11)
        np.testing.assert_allclose(
            np.array(f["gravity"](q)).ravel(), pin.computeGeneralizedGravity(model, data, q), atol=1e-11
        )
        np.testing.assert_allclose(
            np.array(f["coriolis"](q, qd)).reshape(n, n), pin.computeCoriolisMatrix(model, data, q, qd), atol=1e-12
        )
        np.testing.assert_allclose(np.array(f["forward_dynamics"](q, qd, tau)).ravel(), qdd, atol=1e-10)
        pin.framesForwardKinematics(model, data, q)
        np.testing.assert_allclose(np.array(f["fk"](q)).reshape(4, 4), data.oMf[fid].homogeneous, atol=1e-12)
        J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(np.array(f["jacobian"](q)).reshape(6, n), J, atol=1e-12)
        R = data.oMf[fid].rotation
        Jh = np.vstack([R.T @ J[:3], R.T @ J[3:]])
        np.testing.assert_allclose(np.array(f["jacobian_hand"](q)).reshape(6, n), Jh, atol=1e-12)
        pin.forwardKinematics(model, data, q, qd, np.zeros(n))
        acc = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED).vector
        np.testing.assert_allclose(np.array(f["jacobian_dot_qd"](q, qd)).ravel(), acc, atol=1e-12)


# 18 joints, two roots, branches of several lengths: past 12 joints its dynamics are loops
LONG_PARENTS = [-1, 0, 1, 2, 1, 4, 5, 6, 0, 8, 9, 10, 9, 12, 13, -1, 15, 16]


def test_long_branched_tree_as_loops_matches_pinocchio(tmp_path):
    """The loops of chain_loops on a tree (parent tables, listed ancestor pairs), as CasADi
    graphs and as compiled C, against Pinocchio."""
    import importlib.util

    from robotgen.emit import compile as emit_compile
    from robotgen.emit.build import emit

    tree = random_tree(7, LONG_PARENTS)
    kernels = leaf_kernels(tree)
    for name in ("mass", "coriolis", "inverse_dynamics", "nonlinear", "forward_dynamics", "servo_terms"):
        assert next(k for k in kernels if k.name == name).schedule is not None, name
    emit(tmp_path / "long_tree", "long_tree", kernels, nq=tree.nq)
    # the zeroed accumulators and untouched outputs of M and C are printed as fill loops
    assert "for (int rg_e = " in (tmp_path / "long_tree" / "long_tree.c").read_text()
    spec = importlib.util.spec_from_file_location(
        "long_tree", tmp_path / "long_tree" / f"long_tree{emit_compile.extension_suffix()}"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    f = {k.name: k.function for k in kernels}
    model, _ = pinocchio_model(tree)
    data = model.createData()
    n = tree.nq
    rng = np.random.default_rng(18)
    for _ in range(10):
        q, qd, qdd = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n)
        Mp = pin.crba(model, data, q)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        tau = pin.rnea(model, data, q, qd, qdd)
        h = pin.rnea(model, data, q, qd, np.zeros(n))
        C = pin.computeCoriolisMatrix(model, data, q, qd)
        for M, t, hh, CC, a in [
            (
                np.array(f["mass"](q)).reshape(n, n),
                np.array(f["inverse_dynamics"](q, qd, qdd)).ravel(),
                np.array(f["nonlinear"](q, qd)).ravel(),
                np.array(f["coriolis"](q, qd)).reshape(n, n),
                np.array(f["forward_dynamics"](q, qd, tau)).ravel(),
            ),
            (
                module.mass(q),
                module.inverse_dynamics(q, qd, qdd),
                module.nonlinear(q, qd),
                module.coriolis(q, qd),
                module.forward_dynamics(q, qd, tau),
            ),
        ]:
            np.testing.assert_allclose(M, Mp, atol=1e-11)
            np.testing.assert_allclose(t, tau, atol=1e-10)
            np.testing.assert_allclose(hh, h, atol=1e-10)
            np.testing.assert_allclose(CC, C, atol=1e-11)
            np.testing.assert_allclose(a, qdd, atol=1e-8)
        Ms, hs, _, _ = module.servo_terms(q, qd)
        np.testing.assert_allclose(Ms, Mp, atol=1e-11)
        np.testing.assert_allclose(hs, h, atol=1e-10)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_branched_tree_derivatives_match_pinocchio(seed):
    """The derivative functions on a branched tree with a prismatic joint: the recursion of
    rnea_derivatives (and the reverse sweeps, whichever is chosen) against
    computeRNEADerivatives and computeABADerivatives, 1e-9 relative."""
    tree = random_tree(seed)
    f = {k.name: k.function for k in leaf_kernels(tree, derivatives=DerivativeSettings(include=True))}
    model, fid = pinocchio_model(tree)
    data = model.createData()
    n = tree.nq
    rng = np.random.default_rng(200 + seed)

    def close(a, b):
        assert np.abs(np.array(a).reshape(b.shape) - b).max() <= 1e-9 * max(1.0, np.abs(b).max())

    for _ in range(20):
        q, qd, x = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n)
        dq, dqd = f["inverse_dynamics_derivatives"](q, qd, x)
        pin.computeRNEADerivatives(model, data, q, qd, x)
        close(dq, data.dtau_dq)
        close(dqd, data.dtau_dv)
        fq, fqd, ftau = f["forward_dynamics_derivatives"](q, qd, x)
        pin.computeABADerivatives(model, data, q, qd, x)
        Minv = np.triu(data.Minv) + np.triu(data.Minv, 1).T
        close(fq, data.ddq_dq)
        close(fqd, data.ddq_dv)
        close(ftau, Minv)
        close(f["mass_inverse"](q), Minv)
        pin.computeJointJacobiansTimeVariation(model, data, q, qd)
        pin.updateFramePlacements(model, data)
        close(
            f["jacobian_derivative"](q, qd),
            pin.getFrameJacobianTimeVariation(model, data, fid, pin.LOCAL_WORLD_ALIGNED),
        )


@pytest.mark.parametrize("seed", [0, 1])
def test_derivative_algorithms_agree(seed):
    """Both candidates for d tau/d(q, qd), the recursion and the reverse sweeps of
    Newton-Euler, whichever the op count picks for the module."""
    import casadi as ca

    from robotgen.symbolic.differentiation import reverse_jacobian
    from robotgen.symbolic.rigid_body.chain import ChainGraphs, Symbols
    from robotgen.symbolic.rigid_body.rnea_derivatives import rnea_derivatives

    tree = random_tree(seed)
    g = ChainGraphs(tree, Symbols.make(tree.nq))
    s = g.sym
    tau = g.inverse_dynamics()
    f = ca.Function(
        "f",
        [s.q, s.qd, s.qdd],
        [
            *rnea_derivatives(g.tree, g.motions, g.inertias, s.qd, s.qdd),
            reverse_jacobian(tau, s.q),
            reverse_jacobian(tau, s.qd),
        ],
    )
    rng = np.random.default_rng(seed)
    for _ in range(10):
        a, b, c, d = (np.array(m) for m in f(*(rng.normal(size=tree.nq) for _ in range(3))))
        np.testing.assert_allclose(a, c, atol=1e-10 * max(1, np.abs(c).max()))
        np.testing.assert_allclose(b, d, atol=1e-10 * max(1, np.abs(d).max()))
