"""`robotgen build ROBOT.xml` end to end: dm_control's acrobot built to its tip site, the
module imported and its compiled C checked against MuJoCo; `info` and `check` on an MJCF
file; the build cache sees a change in an included file."""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path

import mujoco
import numpy as np

from robotgen.cli import main

SUITE = Path(importlib.util.find_spec("dm_control").submodule_search_locations[0]) / "suite"


def test_build_import_and_agree_with_mujoco(tmp_path, capsys):
    out = tmp_path / "acrobot"
    assert main(["build", str(SUITE / "acrobot.xml"), "--tip", "tip", "-o", str(out), "-q"]) == 0
    captured = capsys.readouterr()
    assert captured.out == f"robotgen: built acrobot (17 functions) in {out}\n"
    assert "note: ignored 1 actuator" in captured.err
    sys.path.insert(0, str(out))
    try:
        importlib.invalidate_caches()
        acrobot = importlib.import_module("acrobot")
    finally:
        sys.path.remove(str(out))
    model = mujoco.MjModel.from_xml_path(str(SUITE / "acrobot.xml"))
    off = mujoco.mjtDisableBit  # robotgen's model has no actuators, contacts or limit forces
    model.opt.disableflags |= int(off.mjDSBL_ACTUATION) | int(off.mjDSBL_CONSTRAINT)
    data = mujoco.MjData(model)
    site = model.site("tip").id
    rng = np.random.default_rng(5)
    info = acrobot.info()["nodes"]["acrobot"]
    assert [j["name"] for j in info["joints"]] == ["shoulder", "elbow"]
    damping = np.array([j["damping"] for j in info["joints"]])
    np.testing.assert_array_equal(damping, model.dof_damping)
    for _ in range(5):
        q, qd, tau = rng.uniform(-np.pi, np.pi, 2), rng.normal(size=2), rng.normal(size=2)
        data.qpos[:], data.qvel[:], data.qfrc_applied[:] = q, qd, tau
        mujoco.mj_forward(model, data)
        M = np.zeros((2, 2))
        mujoco.mj_fullM(model, data, M)
        np.testing.assert_allclose(acrobot.mass(q), M, rtol=1e-12)
        np.testing.assert_allclose(acrobot.nonlinear(q, qd) - damping * qd, data.qfrc_bias, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(acrobot.forward_dynamics(q, qd, tau), data.qacc, rtol=1e-12, atol=1e-14)
        jp, jr = np.zeros((3, 2)), np.zeros((3, 2))
        mujoco.mj_jacSite(model, data, jp, jr, site)
        np.testing.assert_allclose(acrobot.jacobian(q), np.vstack([jp, jr]), atol=1e-14)
        np.testing.assert_allclose(acrobot.fk(q)[:3, 3], data.site_xpos[site], atol=1e-14)


def test_info_and_check(capsys):
    assert main(["info", str(SUITE / "cheetah.xml"), "--tree", "--base", "torso"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("cheetah (root: cheetah; sensed joints: 6 in cheetah)\n")
    assert "    - bthigh: revolute, parent -1 [-0.523599, 1.0472]\n" in out
    assert "    - bshin: revolute, parent 0 [-0.872665, 0.872665]\n" in out
    assert main(["check", str(SUITE / "manipulator.xml"), "--tip", "grasp"]) == 0
    captured = capsys.readouterr()
    assert captured.out == f"{SUITE / 'manipulator.xml'}: ok (1 node(s), root 'planar_manipulator')\n"
    assert "note: module name 'planar_manipulator' (from <mujoco model=\"planar manipulator\">)" in captured.err


def test_a_changed_included_file_is_rebuilt(tmp_path, capsys):
    main_file = tmp_path / "arm.xml"
    main_file.write_text('<mujoco model="arm">\n  <include file="links.xml"/>\n</mujoco>\n')
    links = (
        '<mujoco><worldbody><body name="a"><joint name="j" axis="0 1 0"/>'
        '<geom type="capsule" fromto="0 0 0 {} 0 0" size="0.05"/></body></worldbody></mujoco>'
    )
    (tmp_path / "links.xml").write_text(links.format(0.5))
    argv = ["build", str(main_file), "--tip", "a", "-o", str(tmp_path / "out"), "--no-compile", "-q"]
    assert main(argv) == 0
    assert main(argv) == 0
    assert capsys.readouterr().out.endswith("is up to date\n")
    (tmp_path / "links.xml").write_text(links.format(0.6))
    assert main(argv) == 0
    assert capsys.readouterr().out.startswith("robotgen: built arm")
