"""MJCF files read through MuJoCo's compiler against MuJoCo itself, at random states: the mass
matrix (mj_fullM, which holds the armature on its diagonal), the bias forces qfrc_bias (C qd +
gravity), gravity alone (qd = 0), the tip's Jacobian (mj_jacSite or mj_jacBody: rows
translation then rotation, in world axes, turned into the base's) and forward dynamics (qacc
under qfrc_applied = tau), each to 1e-9 relative. The models are dm_control's suite (its
files, not its Python) and example-robot-data URDFs that MuJoCo's compiler loaded and saved
as MJCF (mj_saveLastXML). robotgen's graphs are evaluated with CasADi; tests/cli/test_mjcf_cli.py
builds and imports a module.

The references:
- M, qfrc_bias, gravity and the Jacobian come from MuJoCo's model of the whole file
  (MjModel.from_xml_path), with the joints robotgen does not keep held where robotgen holds
  them (qpos = 0 for a hinge or slide, qpos0 for a ball or free joint) and at rest: the rows
  and columns of the kept joints are then those of the model robotgen builds;
- forward dynamics comes from MuJoCo's model with those joints deleted (MjSpec), which welds
  their bodies where the file draws them (qpos0, which is 0 for every held hinge and slide
  here: asserted), with constraints (contacts, limits, friction loss), springs, actuators and
  fluid forces switched off, since robotgen's model has none of them; damping stays.
- robotgen's friction: its viscous term is MuJoCo's damping, which MuJoCo keeps out of
  qfrc_bias (in qfrc_passive), so it is taken off robotgen's C qd + N. Its smooth Coulomb term
  (from frictionloss) has no counterpart in MuJoCo's unconstrained qacc, so forward dynamics
  is given tau plus that term.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest
from robots import robots_dir

from robotgen.frontend.mjcf import read_mjcf, read_mjcf_tree
from robotgen.symbolic import leaf_kernels

SUITE = Path(importlib.util.find_spec("dm_control").submodule_search_locations[0]) / "suite"
TOLERANCE = 1e-9
HINGE_OR_SLIDE = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)

# (file, tip, base, tree): every suite model whose joints below some body are hinges and slides
SUITE_CASES = {
    "acrobot": ("acrobot.xml", "tip", None, False),
    "acrobot_tree": ("acrobot.xml", None, None, True),
    "cartpole": ("cartpole.xml", "pole_1", None, False),
    "pendulum": ("pendulum.xml", "pole", None, False),
    "reacher": ("reacher.xml", "finger", None, False),  # a welded body folded into its parent
    "finger": ("finger.xml", None, None, True),  # ref = -90 degrees, frictionloss, two subtrees
    "finger_tip_site": ("finger.xml", "tip", None, False),
    "manipulator_arm": ("manipulator.xml", "grasp", None, False),  # fingers held, scene left out
    "stacker_arm": ("stacker.xml", "hand", None, False),
    "swimmer": ("swimmer.xml", None, None, True),  # three joints in one body
    "cheetah": ("cheetah.xml", None, None, True),  # its planar root: slide, slide, hinge in the torso
    "cheetah_legs": ("cheetah.xml", None, "torso", True),
    "walker_legs": ("walker.xml", None, "torso", True),
    "hopper": ("hopper.xml", None, None, True),
    "fish_fins": ("fish.xml", None, "torso", True),  # below a free joint; two joints per fin
    "ball_in_cup": ("ball_in_cup.xml", None, None, True),
    "point_mass": ("point_mass.xml", None, None, True),
    "humanoid_limbs": ("humanoid.xml", None, "torso", True),  # 21 joints below a free joint
    "humanoid_cmu_arm": ("humanoid_CMU.xml", "lfingers", "thorax", False),  # 56 joints capped to one arm
}
# example-robot-data URDFs: (URDF, tip, base, tree). MuJoCo fuses fixed links (tool0,
# panda_hand) into their parents, so tips are the last moving links.
URDF_CASES = {
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "wrist_3_link", None, False),
    "ur5_from_shoulder": ("ur_description/urdf/ur5_robot.urdf", "wrist_3_link", "shoulder_link", False),
    "panda": ("panda_description/urdf/panda.urdf", "panda_link7", None, False),  # fingers held
    "kinova": ("kinova_description/robots/kinova.urdf", "j2s6s200_link_6", None, False),
    "z1": ("z1_description/urdf/z1.urdf", "gripperMover", None, False),  # frictionloss on every joint
    "xarm7": ("xarm_description/urdf/xarm7.urdf", "link7", None, True),
    "so101": ("so_arm_description/urdf/so101.urdf", None, None, True),
    "double_pendulum": ("double_pendulum_description/urdf/double_pendulum.urdf", "link2", None, False),
}


@pytest.fixture(autouse=True)
def _in_tmp_path(tmp_path, monkeypatch):
    """MuJoCo's C compiler appends its warnings (cheetah's settotalmass, xArm7's empty limits)
    to MUJOCO_LOG.TXT in the working directory: keep it out of the repository."""
    monkeypatch.chdir(tmp_path)


def mjcf_from_urdf(urdf: Path, folder: Path) -> Path:
    """The URDF loaded by MuJoCo's compiler (<visual> and <collision> removed: no mesh files
    needed, and no geom-derived inertia) and saved as the MJCF MuJoCo wrote for it."""
    text = re.sub(r"<(visual|collision)>.*?</\1>", "", urdf.read_text(), flags=re.S)
    model = mujoco.MjModel.from_xml_string(text)
    out = folder / f"{urdf.stem}.xml"
    mujoco.mj_saveLastXML(str(out), model)
    return out


def read(path: Path, tip, base, tree):
    return read_mjcf_tree(str(path), base, tip) if tree else read_mjcf(str(path), tip, base)


def welded(path: Path, kept: list[str]) -> mujoco.MjModel:
    """MuJoCo's model of ``path`` with every joint but ``kept`` deleted (its body welded where
    the file draws it), and what referred to joints (actuators, sensors, tendons, equality
    constraints, keyframes) removed with them; constraints, springs, actuation and fluid
    forces switched off."""
    spec = mujoco.MjSpec.from_file(str(path))
    for group in (spec.actuators, spec.sensors, spec.equalities, spec.tendons, spec.keys):
        for element in list(group):
            spec.delete(element)
    for joint in list(spec.joints):
        if joint.name not in kept:
            spec.delete(joint)
    model = spec.compile()
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= int(off.mjDSBL_CONSTRAINT) | int(off.mjDSBL_SPRING) | int(off.mjDSBL_ACTUATION)
    model.opt.density = model.opt.viscosity = 0.0
    return model


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


def agreement(path: Path, tip, base, tree, samples: int = 6, seed: int = 0) -> dict[str, float]:
    """The largest relative difference of each quantity from MuJoCo's over random states."""
    robot = read(path, tip, base, tree).tree
    f = {k.name: k.function for k in leaf_kernels(robot)}
    n = robot.nq
    names = [j.name for j in robot.joints]

    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    ids = [model.joint(name).id for name in names]
    qadr, vadr = model.jnt_qposadr[ids], model.jnt_dofadr[ids]
    held = model.qpos0.copy()
    for j in range(model.njnt):
        if model.jnt_type[j] in HINGE_OR_SLIDE:
            held[model.jnt_qposadr[j]] = 0.0
    base_body = model.body(robot.base_link).id
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, robot.tip_link)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, robot.tip_link)

    others = [
        j
        for j in range(model.njnt)
        if j not in ids
        and model.jnt_type[j] in HINGE_OR_SLIDE
        and model.body(robot.base_link).id in ancestors(model, model.jnt_bodyid[j])
    ]
    assert all(model.qpos0[model.jnt_qposadr[j]] == 0 for j in others)  # welding holds them at qpos = 0
    plant = welded(path, names)
    assert [plant.joint(j).name for j in range(plant.njnt)] == names
    plant_data = mujoco.MjData(plant)

    viscous = np.array([j.viscous for j in robot.joints])
    coulomb = np.array([j.coulomb for j in robot.joints])
    slide = np.array([j.type == "prismatic" for j in robot.joints])
    rng = np.random.default_rng(seed)
    worst = dict.fromkeys(("M", "bias", "gravity", "jacobian", "forward_dynamics"), 0.0)
    for _ in range(samples):
        q = np.where(slide, rng.uniform(-0.5, 0.5, n), rng.uniform(-np.pi, np.pi, n))
        qd, tau = rng.normal(size=n), rng.normal(size=n)
        data.qpos[:], data.qvel[:] = held, 0.0
        data.qpos[qadr], data.qvel[vadr] = q, qd
        mujoco.mj_forward(model, data)
        M = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, M)
        worst["M"] = max(worst["M"], relative(np.array(f["mass"](q)).reshape(n, n), M[np.ix_(vadr, vadr)]))
        friction = viscous * qd + coulomb * np.tanh(qd / robot.coulomb_smoothing)
        bias = np.array(f["nonlinear"](q, qd)).ravel() - friction
        worst["bias"] = max(worst["bias"], relative(bias, data.qfrc_bias[vadr]))
        jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        if site >= 0:
            mujoco.mj_jacSite(model, data, jp, jr, site)
        else:
            mujoco.mj_jacBody(model, data, jp, jr, body)
        R = data.xmat[base_body].reshape(3, 3)  # world <- base
        J = np.vstack([R.T @ jp[:, vadr], R.T @ jr[:, vadr]])
        worst["jacobian"] = max(worst["jacobian"], relative(np.array(f["jacobian"](q)).reshape(6, n), J))
        data.qvel[:] = 0.0
        mujoco.mj_forward(model, data)
        worst["gravity"] = max(worst["gravity"], relative(np.array(f["gravity"](q)).ravel(), data.qfrc_bias[vadr]))

        plant_data.qpos[:], plant_data.qvel[:], plant_data.qfrc_applied[:] = q, qd, tau
        mujoco.mj_forward(plant, plant_data)
        qdd = np.array(f["forward_dynamics"](q, qd, tau + coulomb * np.tanh(qd / robot.coulomb_smoothing))).ravel()
        worst["forward_dynamics"] = max(worst["forward_dynamics"], relative(qdd, plant_data.qacc))
    return worst


def ancestors(model, b: int) -> list[int]:
    out = [int(b)]
    while out[-1] != 0:
        out.append(int(model.body_parentid[out[-1]]))
    return out


@pytest.mark.parametrize("case", sorted(SUITE_CASES))
def test_dm_control_suite_agrees_with_mujoco(case):
    file, tip, base, tree = SUITE_CASES[case]
    worst = agreement(SUITE / file, tip, base, tree)
    print(case, {k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) < TOLERANCE, worst


@pytest.mark.parametrize("case", sorted(URDF_CASES))
def test_example_robot_data_saved_by_mujoco_agrees_with_mujoco(case, tmp_path):
    urdf, tip, base, tree = URDF_CASES[case]
    path = mjcf_from_urdf(robots_dir() / urdf, tmp_path)
    worst = agreement(path, tip, base, tree)
    print(case, {k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) < TOLERANCE, worst


def test_the_sweep_reads_what_it_claims():
    """The cases exercise what they are there for: a ref of -90 degrees, several joints in one
    body, armature and frictionloss carried over, fingers held off the chain, gravity turned
    into a base below a free joint."""
    finger = read_mjcf_tree(str(SUITE / "finger.xml")).tree
    model = mujoco.MjModel.from_xml_path(str(SUITE / "finger.xml"))
    assert model.qpos0[model.joint("proximal").qposadr[0]] == pytest.approx(-np.pi / 2)
    assert [j.coulomb for j in finger.joints] == [
        float(model.dof_frictionloss[model.joint(j.name).dofadr[0]]) for j in finger.joints
    ]
    assert max(j.coulomb for j in finger.joints) > 0
    swimmer = read_mjcf_tree(str(SUITE / "swimmer.xml")).tree
    assert [j.parent for j in swimmer.joints] == [-1, 0, 1]
    cheetah = read_mjcf_tree(str(SUITE / "cheetah.xml"), base="torso").tree
    assert {j.armature for j in cheetah.joints} == {0.1}
    arm = read_mjcf(str(SUITE / "manipulator.xml"), "grasp").tree
    assert arm.locked_joints == ("thumb", "thumbtip", "finger", "fingertip")
    humanoid = read_mjcf_tree(str(SUITE / "humanoid.xml"), base="torso").tree
    np.testing.assert_allclose(np.linalg.norm(humanoid.gravity), 9.81, rtol=1e-15)
