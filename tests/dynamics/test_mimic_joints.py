"""Mimic joints as reduced coordinates (robotgen.model.coupling): q_joints = S q + c.

Every reference is the full model with each mimic joint an ordinary joint, evaluated at
q_joints = S q + c, qd_joints = S qd, qdd_joints = S qdd and taken to the coordinates with
S: Pinocchio on random branched trees (straight-line kernels, and past 12 joints the loops of
chain_loops) and on a URDF gripper read from a file; MuJoCo's own compiled model (mj_fullM,
qfrc_bias, mj_jacSite) of an MJCF with joint equality constraints, at the full configuration
(MuJoCo enforces the constraint softly, so its constrained motion is no reference). Plus the
properties: Mdot - 2C skew, forward then inverse dynamics, the derivatives against central
differences. Evaluated through CasADi (Kernel.function), no compile."""

from __future__ import annotations

from dataclasses import replace
from fractions import Fraction

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from test_tree_pinocchio import pinocchio_model, random_tree

from robotgen.frontend.mjcf import read_mjcf, read_mjcf_tree
from robotgen.frontend.urdf import read_urdf, read_urdf_tree
from robotgen.model.coupling import Mimic, couple
from robotgen.model.derivatives import DerivativeSettings
from robotgen.symbolic import leaf_kernels

H = 1e-6
STATES = 4


def rel_err(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


def central(f, x: np.ndarray) -> np.ndarray:
    return np.stack(
        [(np.asarray(f(x + H * e), float) - np.asarray(f(x - H * e), float)) / (2 * H) for e in np.eye(len(x))], axis=-1
    )


def functions(tree, derivatives: bool = False) -> dict:
    kernels = leaf_kernels(tree, derivatives=DerivativeSettings(include=True) if derivatives else None)
    return {k.name: k for k in kernels}


def value(f, *args) -> np.ndarray | list[np.ndarray]:
    out = f(*args)
    return [np.array(o) for o in out] if isinstance(out, (list, tuple)) else np.array(out)


# --- random trees against Pinocchio -----------------------------------------------------------

# depth first (Pinocchio's algorithms assume each subtree's joints contiguous)
SHORT = [-1, 0, 1, 2, 1, 4, 5, 6]
LONG = [-1, 0, 1, 2, 3, 2, 5, 6, 7, 1, 9, 10, 11, 12, 13, 14]
# (joint, leader, multiplier, offset): a mimic of a mimic (7 -> 5 -> 2), multipliers -1 and 0.5
SHORT_MIMICS = [Mimic(5, 2, -1.0, 0.3), Mimic(7, 5, 0.5, -0.1)]
LONG_MIMICS = [Mimic(5, 2, -1.0, 0.3), Mimic(7, 5, 0.5, -0.1), Mimic(15, 1, 2.0, 0.0), Mimic(12, 11, 1.0, 0.25)]


def coupled_tree(parents, mimics, seed: int):
    """A random tree with friction and armature on every joint (the mimic joints' too)."""
    tree = random_tree(seed, parents)
    joints = tuple(replace(j, viscous=0.1 * i, coulomb=0.05, armature=0.02 * i) for i, j in enumerate(tree.joints))
    return replace(tree, joints=joints, coupling=couple(len(joints), mimics))


def reference(tree, q, qd, qdd):
    """Pinocchio's full model at q_joints = S q + c, taken to the coordinates, plus robotgen's
    armature and friction of every joint."""
    model, fid = pinocchio_model(tree)
    data = model.createData()
    S, c = tree.coupling.matrix(), tree.coupling.offsets()
    qf, vf, af = S @ q + c, S @ qd, S @ qdd
    armature = np.array([j.armature for j in tree.joints])
    friction = np.array(
        [j.viscous * v + j.coulomb * np.tanh(v / tree.coulomb_smoothing) for j, v in zip(tree.joints, vf)]
    )
    M = pin.crba(model, data, qf)
    M = np.triu(M) + np.triu(M, 1).T + np.diag(armature)
    pin.computeJointJacobians(model, data, qf)
    pin.updateFramePlacements(model, data)
    J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
    pin.forwardKinematics(model, data, qf, vf, 0 * vf)
    acc = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
    return {
        "mass": S.T @ M @ S,
        "gravity": S.T @ pin.computeGeneralizedGravity(model, data, qf),
        "inverse_dynamics": S.T @ (pin.rnea(model, data, qf, vf, af) + armature * af + friction),
        "nonlinear": S.T @ (pin.rnea(model, data, qf, vf, 0 * af) + friction),
        "coriolis": S.T @ pin.computeCoriolisMatrix(model, data, qf, vf) @ S,
        "jacobian": J @ S,
        "jacobian_dot_qd": np.r_[acc.linear, acc.angular],
    }


@pytest.mark.parametrize(
    "parents, mimics, looped", [(SHORT, SHORT_MIMICS, False), (LONG, LONG_MIMICS, True)], ids=["straight_line", "loops"]
)
def test_coupled_tree_matches_pinocchio_projected(parents, mimics, looped):
    tree = coupled_tree(parents, mimics, seed=0)
    assert tree.n_joints == len(parents) and tree.nq == len(parents) - len(mimics)
    f = functions(tree)
    assert (f["mass"].schedule is not None) == looped  # the Coriolis matrix is loops in both (past 2500 operations)
    n = tree.nq
    rng = np.random.default_rng(1)
    worst: dict[str, float] = {}
    for _ in range(STATES):
        q, qd, qdd = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n)
        expected = reference(tree, q, qd, qdd)
        got = {
            "mass": value(f["mass"].function, q).reshape(n, n),
            "gravity": value(f["gravity"].function, q),
            "inverse_dynamics": value(f["inverse_dynamics"].function, q, qd, qdd),
            "nonlinear": value(f["nonlinear"].function, q, qd),
            "coriolis": value(f["coriolis"].function, q, qd).reshape(n, n),
            "jacobian": value(f["jacobian"].function, q).reshape(6, n),
            "jacobian_dot_qd": value(f["jacobian_dot_qd"].function, q, qd),
        }
        servo = value(f["servo_terms"].function, q, qd)
        got.update(servo_mass=servo[0].reshape(n, n), servo_nonlinear=servo[1], servo_jacobian=servo[2].reshape(6, n))
        expected.update(
            servo_mass=expected["mass"], servo_nonlinear=expected["nonlinear"], servo_jacobian=expected["jacobian"]
        )
        for key in got:
            worst[key] = max(worst.get(key, 0.0), rel_err(got[key].ravel(), expected[key].ravel()))
        # forward dynamics, then inverse dynamics: the round trip
        qdd_back = value(f["forward_dynamics"].function, q, qd, expected["inverse_dynamics"])
        worst["round_trip"] = max(worst.get("round_trip", 0.0), rel_err(qdd_back.ravel(), qdd))
    print({k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) <= 1e-12, worst


def test_mdot_minus_2c_is_skew_and_the_derivatives_match_finite_differences():
    """Mdot by central differences of the reduced M along qd; every derivative kernel against
    central differences of the reduced kernels."""
    tree = coupled_tree(SHORT, SHORT_MIMICS, seed=2)
    f = {name: k.function for name, k in functions(tree, derivatives=True).items()}
    n = tree.nq
    rng = np.random.default_rng(5)
    for _ in range(3):
        q, qd, x = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n)
        M = lambda v: value(f["mass"], v).reshape(n, n)  # noqa: E731
        Mdot = (M(q + H * qd) - M(q - H * qd)) / (2 * H)
        K = Mdot - 2 * value(f["coriolis"], q, qd).reshape(n, n)
        assert np.abs(K + K.T).max() <= 1e-7 * np.abs(K).max()
        assert np.abs(K).max() > 1e-3  # not skew by vanishing
        tau = lambda q_, qd_, qdd_: value(f["inverse_dynamics"], q_, qd_, qdd_).ravel()  # noqa: E731
        fd = lambda q_, qd_, t_: value(f["forward_dynamics"], q_, qd_, t_).ravel()  # noqa: E731
        dq, dqd = (a.reshape(n, n) for a in value(f["inverse_dynamics_derivatives"], q, qd, x))
        assert rel_err(dq, central(lambda v: tau(v, qd, x), q)) <= 1e-7
        assert rel_err(dqd, central(lambda v: tau(q, v, x), qd)) <= 1e-7
        fq, fqd, ftau = (a.reshape(n, n) for a in value(f["forward_dynamics_derivatives"], q, qd, x))
        assert rel_err(fq, central(lambda v: fd(v, qd, x), q)) <= 1e-6
        assert rel_err(fqd, central(lambda v: fd(q, v, x), qd)) <= 1e-6
        assert rel_err(ftau, central(lambda v: fd(q, qd, v), x)) <= 1e-6
        Jdot = value(f["jacobian_derivative"], q, qd).reshape(6, n)
        J = lambda v: value(f["jacobian"], v).reshape(6, n)  # noqa: E731
        assert rel_err(Jdot, (J(q + H * qd) - J(q - H * qd)) / (2 * H)) <= 1e-7
        np.testing.assert_allclose(Jdot @ qd, value(f["jacobian_dot_qd"], q, qd).ravel(), rtol=0, atol=1e-12)


def test_loops_derivatives_of_a_long_coupled_tree_match_finite_differences():
    """Past the straight-line sizes: forward dynamics' derivatives as a schedule, forward
    dynamics by the coupled solve after the loops."""
    tree = coupled_tree(LONG, LONG_MIMICS, seed=3)
    kernels = functions(tree, derivatives=True)
    assert kernels["forward_dynamics"].schedule is not None
    f = {name: k.function for name, k in kernels.items()}
    n = tree.nq
    rng = np.random.default_rng(6)
    q, qd, x = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n)
    fd = lambda q_, qd_, t_: value(f["forward_dynamics"], q_, qd_, t_).ravel()  # noqa: E731
    fq, fqd, ftau = (a.reshape(n, n) for a in value(f["forward_dynamics_derivatives"], q, qd, x))
    assert rel_err(fq, central(lambda v: fd(v, qd, x), q)) <= 1e-6
    assert rel_err(fqd, central(lambda v: fd(q, v, x), qd)) <= 1e-6
    np.testing.assert_allclose(ftau @ value(f["mass"], q).reshape(n, n), np.eye(n), rtol=0, atol=1e-10)


# --- a URDF gripper: fingers and a four-bar-like linkage ------------------------------------------


def _link(name: str, mass: float, com: str = "0 0 0") -> str:
    return (
        f'<link name="{name}"><inertial><origin xyz="{com}"/><mass value="{mass}"/>'
        f'<inertia ixx="0.01" iyy="0.02" izz="0.015" ixy="0.001" ixz="0" iyz="0.002"/></inertial></link>'
    )


def _joint(name, kind, parent, child, xyz, axis, extra=""):
    limit = '<limit lower="-3" upper="3" effort="10" velocity="10"/>' if kind != "continuous" else ""
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="0.1 -0.2 0.3"/><axis xyz="{axis}"/>{limit}{extra}</joint>'
    )


GRIPPER = "\n".join(
    [
        '<?xml version="1.0"?>',
        '<robot name="gripper">',
        '<link name="base"/>',
        _link("arm", 2.0, "0.2 0 0"),
        _link("palm", 0.5, "0 0 0.02"),
        _link("left", 0.1, "0 0.01 0.03"),
        _link("right", 0.12, "0 -0.01 0.03"),
        _link("crank", 0.05, "0.03 0 0"),
        _link("rocker", 0.04, "0.02 0.01 0"),
        _link("coupler", 0.03, "0.01 0 0"),
        _joint("shoulder", "revolute", "base", "arm", "0 0 0.1", "0 1 0", '<dynamics damping="0.3"/>'),
        _joint("wrist", "continuous", "arm", "palm", "0.4 0 0", "1 0 0"),
        _joint("left_finger", "prismatic", "palm", "left", "0.05 0.02 0", "0 1 0"),
        _joint(
            "right_finger",
            "prismatic",
            "palm",
            "right",
            "0.05 -0.02 0",
            "0 -1 0",
            '<dynamics damping="0.2" friction="0.05"/><mimic joint="left_finger"/>',
        ),
        _joint("crank", "revolute", "palm", "crank", "0.1 0 0", "0 0 1"),
        _joint(
            "rocker",
            "revolute",
            "crank",
            "rocker",
            "0.06 0 0",
            "0 0 1",
            '<mimic joint="crank" multiplier="-1" offset="0.3"/>',
        ),
        _joint(
            "coupler",
            "revolute",
            "rocker",
            "coupler",
            "0.05 0 0",
            "0 0 1",
            '<mimic joint="rocker" multiplier="0.5" offset="-0.1"/>',
        ),
        "</robot>",
        "",
    ]
)
# each joint's (coordinate, multiplier, offset), worked out by hand from the file: the coupler
# follows the rocker, which follows the crank: 0.5 (-q + 0.3) - 0.1 = -0.5 q + 0.05, the offset
# exact on the file's doubles and rounded once (0.04999999999999999, not 0.05)
COUPLED = {
    "shoulder": ("shoulder", 1.0, 0.0),
    "wrist": ("wrist", 1.0, 0.0),
    "left_finger": ("left_finger", 1.0, 0.0),
    "right_finger": ("left_finger", 1.0, 0.0),
    "crank": ("crank", 1.0, 0.0),
    "rocker": ("crank", -1.0, 0.3),
    "coupler": ("crank", -0.5, float(Fraction(0.5) * Fraction(0.3) - Fraction(0.1))),
}


def _pinocchio_projected(model, names, coordinates, tip, smoothing):
    """(q, qd, qdd) of ``coordinates`` -> Pinocchio's M, g, tau (URDF damping and friction as
    robotgen reads them), C and the tip Jacobian, the joints ``names`` at COUPLED (every other
    joint at 0, as a chain locks it), taken to ``coordinates``."""
    data = model.createData()
    S, c = np.zeros((model.nv, len(coordinates))), np.zeros(model.nv)
    for name in names:
        coordinate, m, offset = COUPLED[name]
        i = model.joints[model.getJointId(name)].idx_v
        S[i, coordinates.index(coordinate)], c[i] = m, offset
    frame = model.getFrameId(tip, pin.BODY)

    def evaluate(q, qd, qdd):
        qf, vf, af = S @ q + c, S @ qd, S @ qdd
        qp = pin.integrate(model, pin.neutral(model), qf)  # the continuous wrist: (cos q, sin q)
        M = pin.crba(model, data, qp)
        M = np.triu(M) + np.triu(M, 1).T
        friction = model.damping * vf + model.friction * np.tanh(vf / smoothing)
        J = pin.computeFrameJacobian(model, data, qp, frame, pin.LOCAL_WORLD_ALIGNED)
        return {
            "mass": S.T @ M @ S,
            "gravity": S.T @ pin.computeGeneralizedGravity(model, data, qp),
            "inverse_dynamics": S.T @ (pin.rnea(model, data, qp, vf, af) + friction),
            "coriolis": S.T @ pin.computeCoriolisMatrix(model, data, qp, vf) @ S,
            "jacobian": J @ S,
        }

    return evaluate


@pytest.mark.parametrize("tip", [None, "right", "coupler"])
def test_urdf_gripper_matches_pinocchio_projected(tmp_path, tip):
    """As a tree, as a chain to the mimicking finger (the leading finger joins as a branch and
    gives the coordinate) and as a chain through the linkage (mimics of mimics on the path)."""
    path = tmp_path / "gripper.urdf"
    path.write_text(GRIPPER)
    tree = read_urdf_tree(str(path), tip="coupler").tree if tip is None else read_urdf(str(path), tip).tree
    names = [j.name for j in tree.joints]
    coordinates = [j.name for j in tree.coordinate_joints]
    expected_names = {
        None: list(COUPLED),
        "right": ["shoulder", "wrist", "left_finger", "right_finger"],
        "coupler": ["shoulder", "wrist", "crank", "rocker", "coupler"],
    }[tip]
    assert names == expected_names
    assert coordinates == [n for n in names if COUPLED[n][0] == n]
    for i, name in enumerate(names):  # the reader's coupling is the one worked out by hand
        coordinate, m, offset = COUPLED[name]
        assert coordinates[tree.coupling.coordinate[i]] == coordinate
        assert (tree.coupling.multiplier[i], tree.coupling.offset[i]) == (m, offset)
    model = pin.buildModelFromUrdf(str(path))  # <mimic> read as an ordinary joint
    reference_at = _pinocchio_projected(model, names, coordinates, tree.tip_link, tree.coulomb_smoothing)
    f = {name: k.function for name, k in functions(tree).items()}
    n = tree.nq
    rng = np.random.default_rng(7)
    worst: dict[str, float] = {}
    for _ in range(STATES):
        q, qd, qdd = rng.uniform(-1, 1, n), rng.normal(size=n), rng.normal(size=n)
        expected = reference_at(q, qd, qdd)
        got = {
            "mass": value(f["mass"], q).reshape(n, n),
            "gravity": value(f["gravity"], q).ravel(),
            "inverse_dynamics": value(f["inverse_dynamics"], q, qd, qdd).ravel(),
            "coriolis": value(f["coriolis"], q, qd).reshape(n, n),
            "jacobian": value(f["jacobian"], q).reshape(6, n),
        }
        for key in got:
            worst[key] = max(worst.get(key, 0.0), rel_err(got[key], expected[key]))
    print(tip, {k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) <= 1e-12, worst


# --- MJCF joint equality constraints against MuJoCo ---------------------------------------------

GRIPPER_MJCF = """<mujoco model="gripper">
  <compiler angle="radian"/>
  <option gravity="0.3 -0.2 -9.81"/>
  <worldbody>
    <body name="arm" pos="0 0 0.1">
      <joint name="shoulder" axis="0 1 0" damping="0.3" armature="0.01"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
      <body name="palm" pos="0.4 0 0" euler="0.2 0 0.1">
        <joint name="wrist" axis="1 0 0" ref="0.2"/>
        <geom type="box" size="0.05 0.08 0.02"/>
        <body name="left" pos="0.05 0.04 0">
          <joint name="left" type="slide" axis="0 1 0" ref="0.01" armature="0.002"/>
          <geom type="box" size="0.02 0.01 0.05" mass="0.1"/>
        </body>
        <body name="right" pos="0.05 -0.04 0">
          <joint name="right" type="slide" axis="0 -1 0" damping="0.5"/>
          <geom type="box" size="0.02 0.01 0.05" mass="0.12"/>
        </body>
        <body name="crank" pos="0.1 0 0">
          <joint name="crank" axis="0 0 1" ref="-0.3"/>
          <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.01"/>
          <body name="rocker" pos="0.1 0 0">
            <joint name="rocker" axis="0 0.6 0.8"/>
            <geom type="capsule" fromto="0 0 0 0.1 0.02 0" size="0.01"/>
            <site name="tip" pos="0.1 0.02 0"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <equality>
    <joint name="fingers" joint1="right" joint2="left" polycoef="0.002 1 0 0 0"/>
    <joint name="linkage" joint1="rocker" joint2="crank" polycoef="0.1 -1 0 0 0"/>
  </equality>
</mujoco>
"""


@pytest.mark.parametrize("tip", [None, "tip"])
def test_mjcf_joint_equalities_match_mujoco_projected(tmp_path, tip):
    """robotgen's reduced model against MuJoCo's M (mj_fullM, armature on its diagonal), bias
    forces (qfrc_bias, plus robotgen's damping, which MuJoCo keeps in qfrc_passive), gravity
    and the tip site's Jacobian (mj_jacSite), all at the full configuration qpos = S q + c and
    taken to the coordinates; the offsets are MuJoCo's polycoef about each joint's ref."""
    path = tmp_path / "gripper.xml"
    path.write_text(GRIPPER_MJCF)
    robot = read_mjcf_tree(str(path), tip="tip") if tip is None else read_mjcf(str(path), tip)
    tree = robot.tree
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    names = [j.name for j in tree.joints]
    assert names == (
        ["shoulder", "wrist", "left", "right", "crank", "rocker"]
        if tip is None
        else ["shoulder", "wrist", "crank", "rocker"]
    )
    # right = left - 0.01 + 0.002; rocker = 0.1 - (crank + 0.3)
    c = dict(zip(names, tree.coupling.offsets()))
    assert c["rocker"] == pytest.approx(-0.2, abs=1e-15) and (tip is not None or c["right"] == pytest.approx(-0.008))
    S = np.zeros((model.nv, tree.nq))
    dofs = [int(model.jnt_dofadr[model.joint(name).id]) for name in names]
    S[dofs] = tree.coupling.matrix()
    offset = np.zeros(model.nq)
    offset[dofs] = tree.coupling.offsets()
    f = {name: k.function for name, k in functions(tree).items()}
    n = tree.nq
    rng = np.random.default_rng(8)
    worst: dict[str, float] = {}
    for _ in range(STATES):
        q, qd = rng.uniform(-1, 1, n), rng.normal(size=n)
        data.qpos[:], data.qvel[:] = S @ q + offset, S @ qd
        mujoco.mj_forward(model, data)
        M = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, M)
        damping = model.dof_damping * data.qvel
        jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jp, jr, model.site("tip").id)
        got = {
            "mass": value(f["mass"], q).reshape(n, n),
            "bias": value(f["nonlinear"], q, qd).ravel(),
            "jacobian": value(f["jacobian"], q).reshape(6, n),
        }
        expected = {"mass": S.T @ M @ S, "bias": S.T @ (data.qfrc_bias + damping), "jacobian": np.vstack([jp, jr]) @ S}
        data.qvel[:] = 0
        mujoco.mj_forward(model, data)
        got["gravity"], expected["gravity"] = value(f["gravity"], q).ravel(), S.T @ data.qfrc_bias
        for key in got:
            worst[key] = max(worst.get(key, 0.0), rel_err(got[key], expected[key]))
    print(tip, {k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) <= 1e-9, worst
