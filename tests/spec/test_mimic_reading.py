"""Reading mimic joints (URDF <mimic>, MJCF joint equality constraints) into a coupling
q_joints = S q + c: the composition of a mimic of a mimic (exact, rounded once), what each
reader refuses and where (FILE:LINE:COL, exit 1), and what robotgen's laws and plants do with
a chain that has them."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from robotgen.cli import main
from robotgen.errors import UserError
from robotgen.frontend import load_system
from robotgen.frontend.mjcf import read_mjcf, read_mjcf_tree
from robotgen.frontend.urdf import read_urdf, read_urdf_tree
from robotgen.model.coupling import Mimic, MimicCycle, couple
from robotgen.simulation.mujoco.model import plant_model
from robotgen.symbolic import kernels_for


def messages(err: str) -> str:
    return "".join(l for l in err.splitlines(True) if not l.startswith("robotgen: ["))


# --- the coupling --------------------------------------------------------------------------------


def test_a_mimic_of_a_mimic_composes_exactly_and_rounds_once():
    # joint 3 follows 2 (0.1 q_2 + 0.1), which follows 0 (3 q_0 + 0.1): q_3 = 0.3 q_0 + 0.11
    c = couple(4, [Mimic(3, 2, 0.1, 0.1), Mimic(2, 0, 3.0, 0.1)])
    assert c.independent == (0, 1) and c.coordinate == (0, 1, 0, 0)
    assert c.multiplier[3] == float(Fraction(0.1) * Fraction(3.0))
    assert c.offset[3] == 0.11 and 0.1 * 0.1 + 0.1 == 0.11000000000000001  # one rounding, not two
    S = c.matrix()
    np.testing.assert_array_equal(S, [[1, 0], [0, 1], [3, 0], [c.multiplier[3], 0]])
    np.testing.assert_array_equal(c.offsets(), [0, 0, 0.1, 0.11])
    assert couple(3, []) is None
    with pytest.raises(MimicCycle) as e:
        couple(4, [Mimic(1, 3, 1.0, 0.0), Mimic(3, 2, 1.0, 0.0), Mimic(2, 1, 1.0, 0.0)])
    assert sorted(e.value.joints) == [1, 2, 3]


# --- URDF ------------------------------------------------------------------------------------------

LINK = (
    '<link name="{0}"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/>'
    "</inertial></link>"
)


def joint(name, type_, parent, child, extra=""):
    return (
        f'<joint name="{name}" type="{type_}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0 0.2 0"/><axis xyz="0 0 1"/>{extra}</joint>'
    )


def urdf(tmp_path, *joints, links=("base", "l1", "l2")):
    """Links on lines 3.., then one joint per line."""
    path = tmp_path / "r.urdf"
    path.write_text(
        '<?xml version="1.0"?>\n<robot name="r">\n'
        + "\n".join(LINK.format(n) for n in links)
        + "\n"
        + "\n".join(joints)
        + "\n</robot>\n"
    )
    return str(path)


J1 = joint("j1", "revolute", "base", "l1")
URDF_ERRORS = {
    "missing_leader": (
        [J1, joint("j2", "revolute", "l1", "l2", '<mimic joint="j_1"/>')],
        "joint 'j2' mimics 'j_1', which is not a joint of the URDF; nearest: 'j1'",
    ),
    "cycle": (
        [
            J1,
            joint("j2", "revolute", "l1", "l2", '<mimic joint="j3"/>'),
            joint("j3", "revolute", "l1", "l3", '<mimic joint="j2"/>'),
        ],
        "mimic joints follow each other in a cycle: 'j2' -> 'j3' -> 'j2'",
    ),
    "itself": (
        [J1, joint("j2", "revolute", "l1", "l2", '<mimic joint="j2"/>')],
        "mimic joints follow each other in a cycle: 'j2' -> 'j2'",
    ),
    "fixed_leader": (
        [joint("j1", "fixed", "base", "l1"), joint("j2", "revolute", "l1", "l2", '<mimic joint="j1"/>')],
        "joint 'j2' mimics 'j1', a fixed joint: make 'j2' fixed too",
    ),
    "zero_multiplier": (
        [J1, joint("j2", "revolute", "l1", "l2", '<mimic joint="j1" multiplier="0" offset="1"/>')],
        "joint 'j2' mimics 'j1' with multiplier 0, which holds it at its offset",
    ),
    "no_joint_attribute": (
        [J1, joint("j2", "revolute", "l1", "l2", '<mimic multiplier="2"/>')],
        "<mimic> needs the attribute 'joint'",
    ),
    "not_finite": (
        [J1, joint("j2", "revolute", "l1", "l2", '<mimic joint="j1" offset="nan"/>')],
        "<mimic> attribute 'offset' must hold finite numbers, got 'nan'",
    ),
}


@pytest.mark.parametrize("case", sorted(URDF_ERRORS))
def test_urdf_mimic_errors_are_located_at_the_mimic(case, tmp_path, capsys):
    joints, expected = URDF_ERRORS[case]
    path = urdf(tmp_path, *joints, links=("base", "l1", "l2", "l3") if case == "cycle" else ("base", "l1", "l2"))
    out = tmp_path / "out"
    assert main(["build", path, "--tree", "-o", str(out), "--no-compile", "-q"]) == 1
    err = messages(capsys.readouterr().err)
    # at j2's <mimic>, the file's first: links on lines 3-5 (3-6), j1 next, then j2
    line = 7 if case != "cycle" else 8
    col = joints[1].index("<mimic") + 1
    assert err.startswith(f"{path}:{line}:{col}: {expected}"), err
    assert err.count("\n") == 1 and not out.exists()


def test_urdf_mimic_leader_above_the_base_is_refused(tmp_path):
    j3 = joint("j3", "revolute", "l2", "l3", '<mimic joint="j1"/>')
    path = urdf(tmp_path, J1, joint("j2", "revolute", "l1", "l2"), j3, links=("base", "l1", "l2", "l3"))
    with pytest.raises(UserError, match="joint 'j3' mimics 'j1', which is not below base link 'l1'") as e:
        read_urdf_tree(path, base="l1")
    assert (e.value.location.line, e.value.location.col) == (9, j3.index("<mimic") + 1)
    # as a chain from that base, the same
    with pytest.raises(UserError, match="not below base link 'l1'"):
        read_urdf(path, "l3", base="l1")


def test_a_chain_to_the_mimicking_link_takes_its_leader_as_a_branch(tmp_path):
    """j2, on the path to l2, mimics j3, off it: the chain keeps j3 as a branch, and the
    coordinate is j3's."""
    path = urdf(
        tmp_path,
        J1,
        joint("j2", "revolute", "l1", "l2", '<mimic joint="j3" multiplier="-1"/>'),
        joint("j3", "prismatic", "l1", "l3"),
        links=("base", "l1", "l2", "l3"),
    )
    tree = read_urdf(path, "l2").tree
    assert [(j.name, j.parent) for j in tree.joints] == [("j1", -1), ("j2", 0), ("j3", 0)]
    assert [j.name for j in tree.coordinate_joints] == ["j1", "j3"] and tree.nq == 2
    assert tree.coupling.multiplier == (1.0, -1.0, 1.0) and tree.coupling.coordinate == (0, 1, 1)
    assert tree.tip_link == "l2" and tree.tip == 1 and tree.locked_joints == ()


# --- MJCF ------------------------------------------------------------------------------------------


def mjcf(tmp_path, *equalities: str) -> str:
    """Three hinges in a chain; the equality constraints one a line from line 18."""
    path = tmp_path / "m.xml"
    path.write_text(f"""<mujoco model="m">
  <compiler angle="radian"/>
  <worldbody>
    <body name="b1">
      <joint name="a" axis="0 0 1"/>
      <geom type="sphere" size="0.1"/>
      <body name="b2" pos="0.3 0 0">
        <joint name="b" axis="0 1 0" ref="0.5"/>
        <geom type="sphere" size="0.1"/>
        <body name="b3" pos="0.3 0 0">
          <joint name="c" axis="0 1 0"/>
          <geom type="sphere" size="0.1"/>
        </body>
      </body>
    </body>
  </worldbody>
  <equality>
    {chr(10).join("    " * (k > 0) + e for k, e in enumerate(equalities))}
  </equality>
</mujoco>
""")
    return str(path)


MJCF_ERRORS = {  # the constraints, the line of the one at fault, the message
    "quadratic": (
        ['<joint name="e" joint1="c" joint2="b" polycoef="0 1 0.5 0 0"/>'],
        18,
        "equality constraint 'e' is a polynomial of degree 2 in joint 'b' (polycoef=\"0 1 0.5 0 0\"); robotgen "
        'couples joints linearly, polycoef="a0 a1 0 0 0"',
    ),
    "no_joint2": (
        ['<joint name="e" joint1="c" polycoef="0.2 0 0 0 0"/>'],
        18,
        "equality constraint 'e' holds joint 'c' at a constant (no joint2), which robotgen does not model: "
        "a body without that joint says so",
    ),
    "zero_a1": (
        ['<joint name="e" joint1="c" joint2="b" polycoef="0.2 0 0 0 0"/>'],
        18,
        "equality constraint 'e' holds joint 'c' at a constant (its polycoef's a1 is 0), which robotgen does not model",
    ),
    "cycle": (
        ['<joint name="e" joint1="c" joint2="b"/>', '<joint name="f" joint1="b" joint2="c"/>'],
        18,
        "joint equality constraints couple joints round a cycle: 'c' -> 'b' -> 'c'",
    ),
    "twice": (
        ['<joint name="e" joint1="c" joint2="b"/>', '<joint name="f" joint1="c" joint2="a"/>'],
        19,
        "equality constraint 'f' couples joint 'c', which equality constraint 'e' couples already",
    ),
}


@pytest.mark.parametrize("case", sorted(MJCF_ERRORS))
def test_mjcf_joint_equality_errors_are_located_at_the_constraint(case, tmp_path, capsys):
    constraints, line, expected = MJCF_ERRORS[case]
    path = mjcf(tmp_path, *constraints)
    assert main(["build", path, "--tree", "-o", str(tmp_path / "out"), "--no-compile", "-q"]) == 1
    err = messages(capsys.readouterr().err)
    assert err == f"{path}:{line}:5: {expected}\n", err


def test_mjcf_coupling_is_q_equals_a1_q2_plus_the_offset_about_the_refs(tmp_path):
    path = mjcf(tmp_path, '<joint name="e" joint1="c" joint2="b" polycoef="0.1 -2 0 0 0"/>')
    robot = read_mjcf_tree(path)
    tree = robot.tree
    assert [j.name for j in tree.joints] == ["a", "b", "c"] and [j.name for j in tree.coordinate_joints] == ["a", "b"]
    # qpos_c - 0 = 0.1 - 2 (qpos_b - 0.5): q_c = -2 q_b + 1.1
    assert tree.coupling.multiplier[2] == -2.0 and tree.coupling.offset[2] == float(Fraction(0.1) + 2 * Fraction(0.5))
    assert any(
        "read 1 joint equality constraint as exact coupling" in n and "'c' = -2 * 'b' + 1.1" in n for n in robot.notes
    ), robot.notes
    # a chain to b3 keeps all three; a chain to b2 takes c (which follows b) as the branch it is
    assert read_mjcf(path, "b2").tree.n_joints == 3 and read_mjcf(path, "b2").tree.nq == 2
    # an inactive constraint is not read: a note says it is ignored, and c is a coordinate
    off = mjcf(tmp_path, '<joint name="e" joint1="c" joint2="b" active="false"/>')
    assert read_mjcf_tree(off).tree.coupling is None


# --- what uses a coupled chain --------------------------------------------------------------------

SPEC = """robotgen: 1
name: gripped
root: top
nodes:
  top:
    control:
      robot: arm
      law: {law}{gains}
  arm:
    define:
      urdf: {{file: r.urdf, tip: l2}}
"""


def test_tree_laws_take_a_coupled_chain_and_the_root_laws_refuse_it(tmp_path, capsys):
    urdf(tmp_path, J1, joint("j2", "revolute", "l1", "l2", '<mimic joint="j1" multiplier="-1"/>'))
    spec = tmp_path / "s.yaml"
    spec.write_text(SPEC.format(law="computed_torque", gains="\n      kp: 100\n      kv: 20"))
    system = load_system(str(spec))
    assert system.nodes["arm"].leaf.nq == 1
    kernels = {k.name: k for k in kernels_for(system)}
    assert [(p.name, p.size) for p in kernels["servo_step"].inputs][:5] == [
        ("theta", 1),
        ("theta_dot", 1),
        ("x_e", 1),
        ("xd_e", 1),
        ("xdd_e", 1),
    ]
    # both joints about z, j2 = -j1: l2 (1 kg at 0.2 m) circles without turning, so
    # M = Izz(l1) + m r^2 = 0.1 + 0.04 at every q (0.24 with l2 turning, were j2 locked)
    for q in (0.0, 0.7, -2.0):
        assert float(kernels["arm_mass"].function(q)) == pytest.approx(0.14, rel=1e-14)
    for law in ("resolved_rate", "resolved_acceleration"):  # Whitney's, and a hand law of Lee and Lee's
        spec.write_text(SPEC.format(law=law, gains=""))
        assert main(["check", str(spec)]) == 1
        err = messages(capsys.readouterr().err)
        assert err == (
            f"{spec}:7:14: nodes.top.control.robot: law {law} resolves a chain's own joints; 'arm' "
            "has mimic joints ('j2'): a tip above them leaves them out (`robotgen docs spec-format`, "
            '"Mimic joints")\n'
        ), err


def test_the_mujoco_plant_refuses_a_coupled_chain(tmp_path):
    urdf(tmp_path, J1, joint("j2", "revolute", "l1", "l2", '<mimic joint="j1" multiplier="-1"/>'))
    spec = tmp_path / "s.yaml"
    spec.write_text(SPEC.format(law="computed_torque", gains="\n      kp: 100\n      kv: 20"))
    with pytest.raises(
        UserError,
        match="the MuJoCo plant couples no joints exactly: chain leaf 'arm' has mimic "
        "joints \\('j2'\\).*`robotgen docs spec-format`, \"Mimic joints\"",
    ):
        plant_model(load_system(str(spec)), 0.001)


def test_info_prints_each_mimic_joint(tmp_path, capsys):
    path = urdf(tmp_path, J1, joint("j2", "revolute", "l1", "l2", '<mimic joint="j1" multiplier="-1" offset="0.25"/>'))
    assert main(["info", path, "--tree"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1:] == [
        "  r: define chain, nq = 1",
        "    coordinates: j1 [rad]",
        "    - j1: revolute, parent -1",
        "    - j2: revolute, parent 0",
        "    mimic: j2 = -1 * j1 + 0.25",
    ], out
