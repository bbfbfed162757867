"""The MJCF reader's mapping on small hand-written models, against closed forms and MuJoCo:
q = qpos with a joint's ref (qpos0) folded into its origin, several joints in one body,
joints held at qpos = 0 off the chain and above the base, <option> flags, the friction
mapping, and the notes and warnings for what robotgen leaves out."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from robotgen.errors import UserError
from robotgen.frontend.mjcf import load_mjcf_system, read_mjcf, read_mjcf_tree
from robotgen.symbolic import leaf_kernels

G = 9.81


def write(tmp_path, text: str, name: str = "robot.xml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def kernels(tree):
    return {k.name: k.function for k in leaf_kernels(tree)}


# A pendulum drawn hanging straight down at qpos = ref = 30 degrees, its centre of mass 1 m
# below the hinge's anchor (jnt_pos is 0.5 m above the body's origin, the COM 0.5 m below).
PENDULUM = """<mujoco model="Ref Pendulum">
  <compiler angle="degree"/>
  <worldbody>
    <body name="pole" pos="0 0 2">
      <joint name="swing" type="hinge" axis="0 1 0" pos="0 0 0.5" ref="30" armature="0.3" damping="0.7"
             frictionloss="0.2"/>
      <inertial pos="0 0 -0.5" mass="2" diaginertia="0.01 0.01 0.01"/>
      <site name="end" pos="0 0 -0.5"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_q_is_qpos_with_the_ref_folded_in(tmp_path):
    """gravity(q) = m g l sin(q - ref) and M = I + m l^2 + armature: the pendulum hangs still
    at q = ref (where the file draws it), so robotgen's q is MuJoCo's qpos."""
    robot = read_mjcf(str(write(tmp_path, PENDULUM)), "end")
    tree, f = robot.tree, kernels(robot.tree)
    ref = math.radians(30)
    for q in (ref, ref + 0.4, ref - 2.0, 0.0):
        assert float(f["gravity"]([q])) == pytest.approx(2 * G * 1.0 * math.sin(q - ref), abs=1e-12)
        assert float(f["mass"]([q])) == pytest.approx(0.01 + 2 * 1.0 + 0.3, rel=1e-14)
    joint = tree.joints[0]
    assert (joint.armature, joint.viscous, joint.coulomb, joint.damping) == (0.3, 0.7, 0.2, 0.7)
    # the site 0.5 m below the body's origin, 1 m below the anchor at (0, 0, 2.5)
    T = np.array(f["fk"]([ref + math.pi / 2])).reshape(4, 4)
    np.testing.assert_allclose(T[:3, 3], [-1.0, 0.0, 2.5], atol=1e-15)
    assert robot.model_name == "Ref Pendulum"


def test_the_module_is_named_after_the_model_or_the_file(tmp_path):
    named = load_mjcf_system(str(write(tmp_path, PENDULUM)), "end")
    assert named.name == "ref_pendulum"
    assert any("note: module name 'ref_pendulum' (from <mujoco model=\"Ref Pendulum\">)" in w for w in named.warnings)
    unnamed = load_mjcf_system(str(write(tmp_path, PENDULUM.replace(' model="Ref Pendulum"', ""), "my_arm.xml")), "end")
    assert unnamed.name == "my_arm"
    assert load_mjcf_system(str(write(tmp_path, PENDULUM)), "end", name="p").name == "p"


def test_several_joints_in_one_body_in_mujocos_order(tmp_path):
    """A slide along x, then a hinge about z through jnt_pos = (0.5, 0, 0): the site at (1, 0, 0)
    of the body is at (q1 + 0.5 + 0.5 cos q2, 0.5 sin q2, 0); the other order differs."""
    text = """<mujoco>
  <worldbody>
    <body name="cart">
      <joint name="{0}" type="{1}" axis="{2}" pos="{3}"/>
      <joint name="{4}" type="{5}" axis="{6}" pos="{7}"/>
      <inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>
      <site name="s" pos="1 0 0"/>
    </body>
  </worldbody>
</mujoco>"""
    slide, hinge = ("x", "slide", "1 0 0", "0 0 0"), ("h", "hinge", "0 0 1", "0.5 0 0")
    tree = read_mjcf_tree(str(write(tmp_path, text.format(*slide, *hinge))), tip="s").tree
    assert [j.name for j in tree.joints] == ["x", "h"] and [j.parent for j in tree.joints] == [-1, 0]
    assert tree.joints[0].body.mass == 0.0  # the massless body between the two joints
    fk = kernels(tree)["fk"]
    for q1, q2 in ((0.3, 0.0), (-0.2, 1.1), (0.7, -2.5)):
        p = np.array(fk([q1, q2])).reshape(4, 4)[:3, 3]
        np.testing.assert_allclose(p, [q1 + 0.5 + 0.5 * math.cos(q2), 0.5 * math.sin(q2), 0.0], atol=1e-15)
    reversed_ = read_mjcf_tree(str(write(tmp_path, text.format(*hinge, *slide))), tip="s").tree
    p = np.array(kernels(reversed_)["fk"]([1.1, 0.3])).reshape(4, 4)[:3, 3]  # h first, then x in the turned frame
    np.testing.assert_allclose(
        p, [0.5 + 0.5 * math.cos(1.1) + 0.3 * math.cos(1.1), 0.5 * math.sin(1.1) + 0.3 * math.sin(1.1), 0.0], atol=1e-15
    )


# An arm whose off-chain finger has ref = 45 degrees, on a base body below a hinge with
# ref = 90 degrees: robotgen holds both at qpos = 0, not where the file draws them.
HELD = """<mujoco>
  <compiler angle="degree"/>
  <worldbody>
    <body name="mount">
      <joint name="turntable" type="hinge" axis="1 0 0" ref="90"/>
      <geom type="box" size=".1 .1 .1" mass="3"/>
      <body name="arm" pos="0 0 0.2">
        <joint name="shoulder" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03" mass="1"/>
        <body name="hand" pos="0.4 0 0" euler="0 0 30">
          <joint name="wrist" type="hinge" axis="0 0 1"/>
          <geom type="box" size=".05 .02 .02" pos="0.05 0 0" mass="0.5"/>
          <body name="finger" pos="0.1 0 0">
            <joint name="finger" type="hinge" axis="0 1 0" ref="45"/>
            <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.01" mass="0.2"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>"""


def test_joints_held_off_the_chain_and_above_the_base_are_at_qpos_zero(tmp_path):
    path = write(tmp_path, HELD)
    robot = read_mjcf(str(path), "hand", base="mount")
    tree = robot.tree
    assert [j.name for j in tree.joints] == ["shoulder", "wrist"] and tree.locked_joints == ("finger",)
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    f = kernels(tree)
    held_away = []
    for q in ([0.3, -0.4], [1.2, 2.0]):
        data.qpos[:] = 0.0  # turntable and finger at qpos = 0
        data.qpos[1:3] = q
        mujoco.mj_forward(model, data)
        M = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, M)
        np.testing.assert_allclose(np.array(f["mass"](q)).reshape(2, 2), M[1:3, 1:3], rtol=1e-12)
        R = data.xmat[model.body("mount").id].reshape(3, 3)
        np.testing.assert_allclose(tree.gravity, R.T @ model.opt.gravity, atol=1e-14)
        np.testing.assert_allclose(np.array(f["gravity"](q)).ravel(), data.qfrc_bias[1:3], rtol=1e-12, atol=1e-15)
        data.qpos[3] = model.qpos0[3]  # the finger where the file draws it: another M
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, M)
        held_away.append(np.abs(np.array(f["mass"](q)).reshape(2, 2) - M[1:3, 1:3]).max())
    assert min(held_away) > 1e-4
    np.testing.assert_allclose(tree.gravity, [0.0, G, 0.0], atol=1e-15)  # Rx(-90)^T (0, 0, -g): turned by -90 about x


def test_option_flags_switch_off_what_they_disable(tmp_path):
    text = PENDULUM.replace(
        "<worldbody>",
        '<option><flag gravity="disable" damper="disable" frictionloss="disable"/></option>\n  <worldbody>',
    )
    tree = read_mjcf(str(write(tmp_path, text)), "end").tree
    assert list(tree.gravity) == [0.0, 0.0, 0.0]
    assert (tree.joints[0].viscous, tree.joints[0].coulomb, tree.joints[0].armature) == (0.0, 0.0, 0.3)
    tilted = read_mjcf(
        str(write(tmp_path, PENDULUM.replace("<worldbody>", '<option gravity="1 2 -3"/>\n  <worldbody>'))), "end"
    ).tree
    assert list(tilted.gravity) == [1.0, 2.0, -3.0]


def test_notes_and_warnings_name_what_is_left_out(tmp_path):
    text = """<mujoco model="noted">
  <option density="1.2"/>
  <worldbody>
    <body name="a">
      <joint name="j1" type="hinge" axis="0 1 0" stiffness="5" frictionloss="0.5"/>
      <geom type="capsule" fromto="0 0 0 0 0 -1" size="0.05"/>
      <body name="b" pos="0 0 -1" gravcomp="1">
        <joint name="j2" type="slide" axis="0 0 1"/>
        <geom type="sphere" size="0.1"/>
      </body>
    </body>
    <body name="ball" pos="2 0 0">
      <freejoint name="loose"/>
      <geom type="sphere" size="0.1"/>
    </body>
  </worldbody>
  <tendon>
    <fixed name="spring" stiffness="3"><joint joint="j1" coef="1"/><joint joint="j2" coef="1"/></fixed>
  </tendon>
  <equality>
    <joint name="off" joint1="j1" joint2="j2" active="false"/>
  </equality>
  <actuator>
    <motor joint="j1"/>
  </actuator>
</mujoco>"""
    path = write(tmp_path, text)
    notes = read_mjcf(str(path), "b").notes
    expected = [
        f"{path}:13:7: note: left out 1 joint of bodies that do not move with the chain: 'loose'",
        f"{path}:21:5: note: ignored 1 equality constraint that does not act on the joints robotgen keeps "
        "(inactive, or among parts held fixed): 'off'",
        f"{path}:5:7: warning: ignored the joint stiffness (springs) of 'j1': robotgen's model has no such forces",
        f"{path}:7:7: warning: ignored the gravity compensation (gravcomp) of 'b': robotgen's model has no such forces",
        f'{path}:1:1: warning: ignored fluid forces (<option density="1.2" viscosity="0">): robotgen\'s model has '
        "no such forces",
        f"{path}:18:5: warning: ignored the stiffness, damping and friction loss of tendons 'spring': robotgen's model "
        "has no such forces",
        f"{path}:24:5: note: ignored 1 actuator: robotgen's inputs are the joint forces tau (MuJoCo's qfrc_applied)",
        f"{path}:5:7: note: frictionloss becomes Coulomb friction frictionloss * tanh(qd / 0.01) ('j1' 0.5); MuJoCo's "
        "friction loss is a constraint force up to frictionloss that can also hold the joint at rest",
    ]
    assert list(notes) == expected


def test_the_digest_covers_included_files(tmp_path):
    """An included file changes the compiled model, so it changes the digest (the build
    cache's key and the manifest's spec_sha256), though the main file is the same."""
    main = write(tmp_path, '<mujoco>\n  <include file="arm.xml"/>\n</mujoco>\n', "main.xml")
    part = (
        '<mujoco><worldbody><body name="a"><joint name="j" axis="0 1 0"/><geom size="0.1" mass="{}"/>'
        "</body></worldbody></mujoco>"
    )
    write(tmp_path, part.format(1), "arm.xml")
    first = read_mjcf(str(main), "a")
    write(tmp_path, part.format(2), "arm.xml")
    second = read_mjcf(str(main), "a")
    assert first.digest != second.digest
    assert first.tree.joints[0].body.mass == 1.0 and second.tree.joints[0].body.mass == 2.0
    assert first.tree.name == "main"  # no <mujoco model>: the file's name
    # an element of an included file has no line in the main file: messages point at its start
    with pytest.raises(UserError) as error:
        read_mjcf(str(main), "a", base="a")
    assert str(error.value) == f"{main}:1:1: tip 'a' is not below base body 'a'"


def test_unnamed_joints_are_named_after_their_body(tmp_path):
    text = """<mujoco>
  <worldbody>
    <body name="arm">
      <joint axis="0 1 0"/>
      <joint name="arm_joint1" type="slide" axis="1 0 0"/>
      <joint type="slide" axis="0 0 1"/>
      <geom size="0.1" mass="1"/>
    </body>
  </worldbody>
</mujoco>"""
    tree = read_mjcf_tree(str(write(tmp_path, text))).tree
    assert [j.name for j in tree.joints] == ["arm_joint0", "arm_joint1", "arm_joint2"]
    text = text.replace('name="arm_joint1"', 'name="arm_joint2"')
    tree = read_mjcf_tree(str(write(tmp_path, text))).tree
    assert [j.name for j in tree.joints] == ["arm_joint0", "arm_joint2", "arm_joint2_1"]
    assert [j.type for j in tree.joints] == ["revolute", "prismatic", "prismatic"] and tree.tip_link == "arm"
