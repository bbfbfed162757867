"""URDFs as they come from robot vendors: <ros2_control> and vendor tags under <robot> are
ignored with one located note, mimic joints are coupled coordinates, the module name derived
from <robot name> is reported when it differs. Real files (example-robot-data's xArm7 and
Panda) are built with the CLI and checked against Pinocchio; the rules themselves on small
files. Plus: merged inertias are correctly rounded (robotgen.numeric.exact, not BLAS)."""

from __future__ import annotations

import contextlib
import importlib
import io
import re
import sys
from fractions import Fraction

import numpy as np
import pinocchio as pin
import pytest
from robots import robots_dir

from robotgen.cli import main
from robotgen.frontend.urdf import load_urdf_system, merge_bodies, read_urdf
from robotgen.model.chain import Body, KinematicTree

XARM7 = ("xarm_description/urdf/xarm7.urdf", "link7")
PANDA = "panda_description/urdf/panda.urdf"
N_STATES = 20
TOL = 1e-9


def rel_err(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


def messages(err: str) -> str:
    """stderr without the build's progress lines ("robotgen: [  1.2 s] ..."), which -q silences."""
    return "".join(l for l in err.splitlines(True) if not l.startswith("robotgen: ["))


def build(argv: list[str], module_name: str, out):
    """robotgen build ARGV -o OUT; (imported module, stderr)."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        status = main(["build", *argv, "-o", str(out)])
    assert status == 0, err.getvalue()
    sys.path.insert(0, str(out))
    try:
        importlib.invalidate_caches()
        return importlib.import_module(module_name), messages(err.getvalue())
    finally:
        sys.path.remove(str(out))


def compare_with_pinocchio(module, model, seed: int) -> dict[str, float]:
    """Worst relative error of the module's mass, gravity and inverse dynamics against
    Pinocchio's CRBA / gravity / RNEA at random states, plus robotgen's joint friction (URDF
    damping as viscous friction, URDF friction as smoothed Coulomb friction, see
    robotgen.symbolic.rigid_body.friction); robotgen's coordinates are matched to Pinocchio's by name."""
    node = next(iter(module.info()["nodes"].values()))
    names = [j["name"] for j in node["joints"]]
    perm = np.array([model.joints[model.getJointId(n)].idx_q for n in names])
    assert sorted(perm) == list(range(model.nq))
    viscous = np.array([j["viscous"] for j in node["joints"]])
    coulomb = np.array([j["coulomb"] for j in node["joints"]])
    eps = KinematicTree.coulomb_smoothing  # the URDF reader keeps the default
    lo = np.where(np.isfinite(model.lowerPositionLimit), model.lowerPositionLimit, -np.pi)[perm]
    hi = np.where(np.isfinite(model.upperPositionLimit), model.upperPositionLimit, np.pi)[perm]
    rng = np.random.default_rng(seed)
    q = rng.uniform(lo, hi, size=(N_STATES, len(names)))
    qd, qdd = rng.normal(size=q.shape) * 2.0, rng.normal(size=q.shape) * 5.0
    M, g, tau = module.mass(q), module.gravity(q), module.inverse_dynamics(q, qd, qdd)
    data = model.createData()
    worst: dict[str, float] = {}
    for k in range(N_STATES):
        qp, qdp, qddp = (np.empty(model.nq) for _ in range(3))
        qp[perm], qdp[perm], qddp[perm] = q[k], qd[k], qdd[k]
        Mp = pin.crba(model, data, qp)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        errs = {
            "mass": rel_err(M[k], Mp[np.ix_(perm, perm)]),
            "gravity": rel_err(g[k], pin.computeGeneralizedGravity(model, data, qp)[perm]),
            "inverse_dynamics": rel_err(
                tau[k], pin.rnea(model, data, qp, qdp, qddp)[perm] + viscous * qd[k] + coulomb * np.tanh(qd[k] / eps)
            ),
        }
        for key, e in errs.items():
            worst[key] = max(worst.get(key, 0.0), e)
    return worst


# --- xArm7: <ros2_control> under <robot>, robot name "UF_ROBOT" ----------------------------


@pytest.fixture(scope="module")
def xarm7(tmp_path_factory):
    path = robots_dir() / XARM7[0]
    module, err = build([str(path), "--tip", XARM7[1]], "uf_robot", tmp_path_factory.mktemp("xarm7"))
    return path, module, err


def test_xarm7_builds_with_one_note_for_ros2_control(xarm7):
    path, module, err = xarm7
    lines = err.splitlines()
    ignored = [l for l in lines if "note: ignored" in l]
    assert len(ignored) == 1, err
    # <ros2_control> is the file's only element outside URDF; it starts on line 26
    assert ignored[0] == (
        f"{path}:26:3: note: ignored 1 element robotgen does not use under <robot>: <ros2_control> (line 26)"
    ), err
    assert (
        f"{path}:6:1: note: module name 'uf_robot' (from <robot name=\"UF_ROBOT\">); "
        "pass --name to choose another" in lines
    ), err
    assert len(lines) == 2, err  # nothing else: the transmissions and gazebo tags are URDF's own
    assert module.nq == 7


def test_xarm7_matches_pinocchio(xarm7):
    path, module, _ = xarm7
    model = pin.buildModelFromUrdf(str(path))
    assert model.nq == module.nq  # no gripper in this file: nothing to lock
    worst = compare_with_pinocchio(module, model, seed=5)
    print({k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) <= TOL, worst


# --- Panda as a tree: the mimic finger joint moves with the other finger's coordinate ---------


@pytest.fixture(scope="module")
def panda_tree(tmp_path_factory):
    path = robots_dir() / PANDA
    module, err = build(
        [str(path), "--tree", "--name", "panda_tree"], "panda_tree", tmp_path_factory.mktemp("panda_tree")
    )
    return path, module, err


def test_panda_tree_couples_the_mimic_finger(panda_tree):
    path, module, err = panda_tree
    node = module.info()["nodes"]["panda_tree"]
    assert node["locked_joints"] == [] and module.nq == node["nq"] == 8
    assert [j["name"] for j in node["joints"]] == [f"panda_joint{i}" for i in range(1, 8)] + [
        "panda_finger_joint1",
        "panda_finger_joint2",
    ]
    assert node["coordinates"] == [f"panda_joint{i}" for i in range(1, 8)] + ["panda_finger_joint1"]
    assert node["coupled_joints"] == [
        {"joint": "panda_finger_joint2", "coordinate": "panda_finger_joint1", "multiplier": 1.0, "offset": 0.0}
    ]
    notes = [l for l in err.splitlines() if "mimic" in l]
    assert notes == [
        f"{path}:348:9: note: a mimic joint moves with the coordinate of the joint it follows (no "
        "coordinate of its own): 'panda_finger_joint2' = 'panda_finger_joint1'"
    ], err
    assert "module name" not in err  # --name given


def test_panda_tree_matches_pinocchio_projected_on_the_fingers_coordinate(panda_tree):
    """The compiled module (8 coordinates) against Pinocchio's model of both fingers as joints
    (buildModelFromUrdf reads <mimic> as an ordinary joint), evaluated at q_full = S q (the second
    finger at the first's q) and projected: S^T M S, S^T g, S^T tau(S qd, S qdd) with the file's
    damping and friction, S^T C S and J S."""
    path, module, _ = panda_tree
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    assert model.nq == 9 and module.nq == 8
    S = np.zeros((model.nv, 8))  # Pinocchio's joints x robotgen's coordinates, by name
    for k, name in enumerate(module.info()["nodes"]["panda_tree"]["coordinates"]):
        S[model.joints[model.getJointId(name)].idx_v, k] = 1.0
    S[model.joints[model.getJointId("panda_finger_joint2")].idx_v, 7] = 1.0
    tip = model.getFrameId(module.info()["nodes"]["panda_tree"]["tip_link"])
    rng = np.random.default_rng(9)
    lo, hi = S.T @ model.lowerPositionLimit, S.T @ model.upperPositionLimit
    q = rng.uniform(lo, hi, size=(N_STATES, 8))
    q[:, 7] = rng.uniform(0.0, 0.04, N_STATES)  # S^T doubled the finger's limits
    qd, qdd = rng.normal(size=q.shape) * 2.0, rng.normal(size=q.shape) * 5.0
    M, g, tau = module.mass(q), module.gravity(q), module.inverse_dynamics(q, qd, qdd)
    C, J = module.coriolis(q, qd), module.jacobian(q)
    worst: dict[str, float] = {}
    for k in range(N_STATES):
        qf, vf, af = S @ q[k], S @ qd[k], S @ qdd[k]
        Mp = pin.crba(model, data, qf)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        friction = model.damping * vf + model.friction * np.tanh(vf / KinematicTree.coulomb_smoothing)
        Jp = pin.computeFrameJacobian(model, data, qf, tip, pin.LOCAL_WORLD_ALIGNED)
        errs = {
            "mass": rel_err(M[k], S.T @ Mp @ S),
            "gravity": rel_err(g[k], S.T @ pin.computeGeneralizedGravity(model, data, qf)),
            "inverse_dynamics": rel_err(tau[k], S.T @ (pin.rnea(model, data, qf, vf, af) + friction)),
            "coriolis": rel_err(C[k], S.T @ pin.computeCoriolisMatrix(model, data, qf, vf) @ S),
            "jacobian": rel_err(J[k], Jp @ S),
        }
        for key, e in errs.items():
            worst[key] = max(worst.get(key, 0.0), e)
    print({k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) <= TOL, worst
    # the fingers' coordinate translates both fingers (0.015 kg each, siblings on the hand): M's
    # entry is their total mass, where the finger locked at q = 0 left one finger's
    np.testing.assert_allclose(M[:, 7, 7], 0.03, rtol=1e-12)


# --- the rules on small files ----------------------------------------------------------------

LINK = (
    '<link name="{0}"><inertial><mass value="1"/>'
    '<inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
)
JOINTS = (
    '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>'
    '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>\n'
    '<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>'
    '<origin xyz="0.5 0 0"/><axis xyz="0 1 0"/></joint>'
)


def robot_file(tmp_path, extra: str = "", name: str = "r", file: str = "r.urdf"):
    """A two-joint robot; ``extra`` lines go right after <robot> (from line 3 on)."""
    links = "\n".join(LINK.format(n) for n in ("base", "l1", "l2"))
    path = tmp_path / file
    path.write_text(f'<?xml version="1.0"?>\n<robot name="{name}">\n{extra}{links}\n{JOINTS}\n</robot>\n')
    return path


FOREIGN = (
    '<ros2_control name="hw" type="system"><joint name="j1"><spring k="1"/></joint></ros2_control>\n'
    '<vendor_tag version="2"><anything/></vendor_tag>\n'
    '<ros2_control name="hw2" type="system"/>\n'
)


def test_foreign_elements_under_robot_are_ignored_with_one_note(tmp_path, capsys):
    path = robot_file(tmp_path, FOREIGN)
    out = tmp_path / "out"
    assert main(["build", str(path), "--tip", "l2", "--no-compile", "-o", str(out)]) == 0
    err = messages(capsys.readouterr().err)
    notes = [l for l in err.splitlines() if "note:" in l]
    # each tag once, at its first line; the count is of elements; the children (a <spring>
    # inside ros2_control's <joint>) are not checked
    assert notes == [
        f"{path}:3:1: note: ignored 3 elements robotgen does not use under <robot>: "
        "<ros2_control> (line 3), <vendor_tag> (line 4)"
    ], err
    assert (out / "r.c").is_file() and (out / "r_module.c").is_file()
    # the same model as without them
    plain = load_urdf_system(str(robot_file(tmp_path, file="plain.urdf")), "l2").nodes["r"].leaf
    tree = load_urdf_system(str(path), "l2").nodes["r"].leaf
    for a, b in zip(tree.joints, plain.joints, strict=True):
        np.testing.assert_array_equal(a.origin, b.origin)
        np.testing.assert_array_equal(a.body.inertia, b.body.inertia)


def test_known_urdf_elements_under_robot_give_no_note(tmp_path):
    path = robot_file(
        tmp_path,
        '<material name="red"/>\n<gazebo><plugin/></gazebo>\n'
        '<transmission name="t"><joint name="j1"/></transmission>\n',
    )
    assert read_urdf(str(path), "l2").notes == ()


def test_module_name_note_when_the_robot_name_is_not_an_identifier(tmp_path, capsys):
    path = robot_file(tmp_path, name="UR5")
    assert main(["check", str(path), "--tip", "l2"]) == 0
    err = messages(capsys.readouterr().err)
    assert err.splitlines() == [
        f"{path}:2:1: note: module name 'ur5' (from <robot name=\"UR5\">); pass --name to choose another"
    ], err
    assert load_urdf_system(str(path), "l2").name == "ur5"
    # an explicit --name, or a robot name that is already the module name: no note
    assert main(["check", str(path), "--tip", "l2", "--name", "arm"]) == 0
    assert messages(capsys.readouterr().err) == ""
    same = robot_file(tmp_path, name="ur5", file="same.urdf")
    assert load_urdf_system(str(same), "l2").warnings == ()
    dashed = robot_file(tmp_path, name="my-arm 2", file="dashed.urdf")
    assert re.search(
        r"module name 'my_arm_2' \(from <robot name=\"my-arm 2\">\)",
        "\n".join(load_urdf_system(str(dashed), "l2").warnings),
    )


# --- constants are correctly rounded, not BLAS's -------------------------------------------


def _matmul_ref(A, B):
    """Each entry the exact dot product rounded once (Fractions; no numpy products)."""
    return np.array(
        [
            [
                float(sum((Fraction(float(a)) * Fraction(float(b)) for a, b in zip(row, col)), Fraction(0)))
                for col in np.asarray(B).T
            ]
            for row in np.asarray(A)
        ]
    )


def test_merged_bodies_are_correctly_rounded():
    rng = np.random.default_rng(1)
    mismatches_of_naive = 0
    for _ in range(20):
        Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = Q, rng.normal(size=3)
        A = rng.normal(size=(3, 3))
        b = Body(1.7, rng.normal(size=3), A @ A.T)
        merged = merge_bodies([(T, b)])
        com = np.array(
            [
                float(
                    sum(
                        (Fraction(float(T[i, k])) * Fraction(float(c)) for k, c in enumerate(b.com)),
                        Fraction(float(T[i, 3])),
                    )
                )
                for i in range(3)
            ]
        )
        inertia = _matmul_ref(_matmul_ref(Q, b.inertia), Q.T)
        np.testing.assert_array_equal(merged.com, com)
        np.testing.assert_array_equal(merged.inertia, inertia)
        naive = Q @ b.inertia @ Q.T
        mismatches_of_naive += int(np.any(naive != inertia)) + int(np.any(Q @ b.com + T[:3, 3] != com))
    assert mismatches_of_naive > 0  # the reference does tell floating-point products apart
    # two bodies: mass and com exact sums, the parallel-axis shift as in the docstring
    a, b = Body(1.0, np.array([0.0, 0.0, 0.0]), np.eye(3) * 0.1), Body(3.0, np.array([0.0, 0.0, 0.0]), np.eye(3) * 0.1)
    T = np.eye(4)
    T[:3, 3] = (0.0, 0.4, 0.0)
    m = merge_bodies([(np.eye(4), a), (T, b)])
    assert m.mass == 4.0
    np.testing.assert_array_equal(m.com, [0.0, float(Fraction(0.4) * 3 / 4), 0.0])  # (3 * 0.4) / 4 rounded once
    # 0.2 E + 1 * 0.3^2 (E - e_y e_y^T) + 3 * 0.1^2 (E - e_y e_y^T)
    np.testing.assert_allclose(m.inertia, np.diag([0.2 + 0.09 + 0.03, 0.2, 0.2 + 0.09 + 0.03]), rtol=0, atol=1e-15)
