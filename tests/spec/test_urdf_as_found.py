"""URDFs as they are found (issue 33, "Robots as found"), on small files: elements without
rigid-body meaning inside <link> and <joint> skipped with one located note per element name,
those that would change the dynamics refused; "no limit" markers in <limit>; an XML
declaration after whitespace or a comment; --base the same for chains and trees."""

from __future__ import annotations

import numpy as np
import pytest

from robotgen.cli import main
from robotgen.errors import UserError
from robotgen.frontend.urdf import read_urdf, read_urdf_tree

INERTIAL = (
    '<inertial><origin xyz="0.1 0 0"/><mass value="1"/>'
    '<inertia ixx="0.1" iyy="0.2" izz="0.3" ixy="0" ixz="0" iyz="0"/></inertial>'
)


def link(name: str, extra: str = "") -> str:
    return f'<link name="{name}">{INERTIAL}{extra}</link>'


def joint(
    name: str, parent: str, child: str, extra: str = "", type_: str = "revolute", limit: str = 'lower="-1" upper="1"'
) -> str:
    return (
        f'<joint name="{name}" type="{type_}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0 0 0.5" rpy="0.1 0.2 0.3"/><axis xyz="0 1 0"/><limit {limit} effort="5" velocity="2"/>'
        f"{extra}</joint>"
    )


def robot(lines: list[str], head: str = '<?xml version="1.0"?>\n') -> str:
    """A file: ``head``, <robot> on its own line, then one line per entry of ``lines``."""
    return head + '<robot name="r">\n' + "\n".join(lines) + "\n</robot>\n"


def write(tmp_path, text: str, name: str = "r.urdf"):
    path = tmp_path / name
    path.write_text(text)
    return path


def same_model(a, b) -> None:
    assert [j.name for j in a.joints] == [j.name for j in b.joints]
    for x, y in zip(a.joints, b.joints, strict=True):
        np.testing.assert_array_equal(x.origin, y.origin)
        np.testing.assert_array_equal(x.axis, y.axis)
        assert x.body.mass == y.body.mass and x.viscous == y.viscous and x.coulomb == y.coulomb
        np.testing.assert_array_equal(x.body.com, y.body.com)
        np.testing.assert_array_equal(x.body.inertia, y.body.inertia)


# --- elements inside <link> and <joint> -----------------------------------------------------

CONTACT = '<contact><lateral_friction value="1"/><stiffness value="3e4"/><damping value="1e3"/></contact>'
PLAIN = [
    link("base"),
    link("l1"),
    link("l2"),
    link("l3"),
    joint("j1", "base", "l1"),
    joint("j2", "l1", "l2"),
    joint("j3", "l2", "l3"),
]
LINK_ORIGIN = '<origin xyz="0 0 0" rpy="0 -0 0"/>'
DECORATED = [  # lines 3-9 of the file
    link("base", CONTACT),
    link("l1", '<self_filter><origin xyz="0 0 0"/><geometry><box size="1 1 1"/></geometry></self_filter>'),
    link("l2", CONTACT + LINK_ORIGIN + "<gravity>1</gravity><kinematic>0</kinematic>"),
    link("l3", CONTACT + '<collision_checking><capsule name="c"/></collision_checking>'),
    joint("j1", "base", "l1", '<joint_properties damping="0.0" friction=".0"/>'),
    joint("j2", "l1", "l2", '<joint_properties damping="0" friction="0"/><vendor:hint level="2"/>'),
    joint("j3", "l2", "l3", '<axis xyz="0 1 0"/>'),  # a second <axis> that says the same
]


def test_elements_without_rigid_body_meaning_are_skipped_with_one_note_per_name(tmp_path, capsys):
    path = write(tmp_path, robot(DECORATED))
    assert main(["check", str(path), "--tip", "l3"]) == 0
    err = capsys.readouterr().err.splitlines()

    def at(line: int, start: str) -> str:
        return f"{path}:{line}:{DECORATED[line - 3].index(start) + 1}"

    assert err == [
        f"{at(3, '<contact')}: note: skipped 3 <contact> elements inside <link> (a simulator's contact parameters): "
        "no rigid-body meaning for robotgen",
        f"{at(4, '<self_filter')}: note: skipped <self_filter> inside <link> (collision filtering): no rigid-body "
        "meaning for robotgen",
        f"{at(5, LINK_ORIGIN)}: note: skipped <origin> inside <link> (not URDF: a link's frame is where its joint puts "
        "it): no rigid-body meaning for robotgen",
        f"{at(5, '<gravity')}: note: skipped <gravity> inside <link> (Gazebo's flag, at its default 1): no rigid-body "
        "meaning for robotgen",
        f"{at(5, '<kinematic')}: note: skipped <kinematic> inside <link> (Gazebo's flag, at its default 0): no "
        "rigid-body meaning for robotgen",
        f"{at(6, '<collision_checking')}: note: skipped <collision_checking> inside <link> (collision settings): no "
        "rigid-body meaning for robotgen",
        f"{at(7, '<joint_properties')}: note: skipped 2 <joint_properties> elements inside <joint> (the pre-1.0 form "
        "of <dynamics>, with damping and friction 0): no rigid-body meaning for robotgen",
        f"{at(8, '<vendor:hint')}: note: skipped <vendor:hint> inside <joint> (not a URDF element): no rigid-body "
        "meaning for robotgen",
    ], err
    # the model is the one of the file without them, as a chain and as a tree
    plain = write(tmp_path, robot(PLAIN), "plain.urdf")
    same_model(read_urdf(str(path), "l3").tree, read_urdf(str(plain), "l3").tree)
    same_model(read_urdf_tree(str(path)).tree, read_urdf_tree(str(plain)).tree)
    assert read_urdf(str(plain), "l3").notes == ()


REFUSED = {  # (the link or joint, where the refused element starts in it, words of the message)
    "mass_in_link": (
        link("l2", '<mass value="3"/>'),
        '<mass value="3"',
        "<mass> is not supported inside <link>: inertia belongs inside a link's <inertial>",
    ),
    "inertial_in_joint": (
        joint("j2", "l1", "l2", INERTIAL),
        "<inertial>",
        "<inertial> is not supported inside <joint>: inertia",
    ),
    "damping_element": (
        joint("j2", "l1", "l2", '<damping value="0.5"/>'),
        "<damping",
        "<damping> is not supported inside <joint>: it would change the joint's dynamics",
    ),
    "spring": (
        joint("j2", "l1", "l2", '<spring stiffness="10"/>'),
        "<spring",
        "<spring> is not supported inside <joint>",
    ),
    "rotor_inertia": (
        joint("j2", "l1", "l2", '<drake:rotor_inertia value="1e-4"/>'),
        "<drake:",
        "<drake:rotor_inertia> is not supported inside <joint>: it would change the joint's dynamics",
    ),
    "xacro": (link("l2", '<xacro:default_inertial mass="2"/>'), "<xacro:", "expand it with xacro first"),
    "no_gravity": (
        link("l2", "<gravity>0</gravity>"),
        "<gravity>",
        "<gravity>0</gravity> takes the link out of gravity",
    ),
    "kinematic": (
        link("l2", "<kinematic>true</kinematic>"),
        "<kinematic>",
        "<kinematic>true</kinematic> makes the link kinematic",
    ),
    "joint_properties": (
        joint("j2", "l1", "l2", '<joint_properties damping="0.7" friction="0"/>'),
        "<joint_prop",
        '<joint_properties damping="0.7"> is the pre-1.0 form of <dynamics>; write <dynamics damping="0.7"/>',
    ),
    "inertia_scaling": (
        link("l2", '<contact><inertia_scaling value="3.0"/></contact>'),
        "<contact>",
        '<inertia_scaling value="3.0"> inside it scales the link\'s inertia in pybullet',
    ),
    "second_axis": (
        joint("j2", "l1", "l2", '<axis xyz="1 0 0"/>'),
        '<axis xyz="1',
        "<joint> has a second <axis> that differs from the first (line 7)",
    ),
    "in_inertial": (
        link("l2", "").replace("</inertial>", "<armature/></inertial>"),
        "<armature",
        "<armature> is not supported inside <inertial>",
    ),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_elements_that_would_change_the_dynamics_are_refused(case, tmp_path, capsys):
    entry, start, words = REFUSED[case]
    lines = [link("base"), link("l1"), link("l2"), joint("j1", "base", "l1"), joint("j2", "l1", "l2")]
    line = 3 + next(i for i, l in enumerate(lines) if l.split('"')[1] == entry.split('"')[1])
    lines[line - 3] = entry
    path = write(tmp_path, robot(lines))
    out = tmp_path / "out"
    assert main(["build", str(path), "--tip", "l2", "-o", str(out), "-q"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"{path}:{line}:{entry.index(start) + 1}: ") and words in err and err.count("\n") == 1, err
    assert not out.exists()


# --- "no limit" markers ---------------------------------------------------------------------


def test_no_limit_markers_read_as_no_limit_with_a_note(tmp_path, capsys):
    lines = [
        link("base"),
        link("l1"),
        link("l2"),
        link("l3"),
        link("l4"),
        joint("j1", "base", "l1", limit='lower="-1e+16" upper="1e16"'),  # line 8
        joint("j2", "l1", "l2", limit='lower="1" upper="-1"'),  # line 9: pybullet's marker
        joint("j3", "l2", "l3", limit='lower="0" upper="-1"', type_="prismatic"),  # Bullet's default
        joint("j4", "l3", "l4", limit='lower="-inf" upper="0.5"').replace('effort="5"', 'effort="1e20"'),
    ]
    path = write(tmp_path, robot(lines))
    chain = read_urdf(str(path), "l4")
    limits = [(j.limits.lower, j.limits.upper, j.limits.effort) for j in chain.tree.joints]
    assert limits == [(None, None, 5.0), (None, None, 5.0), (None, None, 5.0), (None, 0.5, None)]
    assert chain.notes == (
        f"{path}:8:{lines[5].index('<limit') + 1}: note: read as no limit, marked by a magnitude of 1e15 or more: 'j1' (lower and upper), "
        "'j4' (lower and effort)",
        f'{path}:9:{lines[6].index("<limit") + 1}: note: read as no limit, marked by lower above upper as pybullet writes it (lower="1" '
        'upper="-1" or lower="0" upper="-1"): \'j2\' (lower and upper), \'j3\' (lower and upper)',
    )
    assert read_urdf_tree(str(path)).notes == chain.notes
    # info prints a one-sided range and none where there is no limit
    assert main(["info", str(path), "--tip", "l4"]) == 0
    out = capsys.readouterr().out
    assert "    - j1: revolute, parent -1\n" in out and "    - j4: revolute, parent 2 [-inf, 0.5]\n" in out, out


def test_a_continuous_joints_lower_and_upper_are_not_read(tmp_path):
    """URDF ignores them; so does robotgen (no note, no error), and reads its velocity."""
    j1 = joint("j1", "base", "l1", type_="continuous", limit='lower="nan" upper="-1e16"')
    chain = read_urdf(str(write(tmp_path, robot([link("base"), link("l1"), j1]))), "l1")
    assert chain.notes == ()
    limits = chain.tree.joints[0].limits
    assert (limits.lower, limits.upper, limits.velocity) == (None, None, 2.0)


@pytest.mark.parametrize(
    "limit, words",
    [
        ('lower="0.5" upper="-0.5"', "lower 0.5 is above upper -0.5"),
        ('lower="2" upper="1"', "lower 2 is above upper 1"),
        ('lower="nan" upper="1"', "'lower' must hold finite numbers, got 'nan'"),
    ],
)
def test_an_inverted_finite_limit_stays_an_error(tmp_path, limit, words):
    j1 = joint("j1", "base", "l1", limit=limit)
    path = write(tmp_path, robot([link("base"), link("l1"), j1]))
    with pytest.raises(UserError) as e:
        read_urdf(str(path), "l1")
    where = (e.value.location.line, e.value.location.col)
    assert words in e.value.message and where == (5, j1.index("<limit") + 1), e.value


# --- the XML declaration ----------------------------------------------------------------------


@pytest.mark.parametrize(
    "head, what, declaration_line",
    [
        ('\n\n  <?xml version="1.0"?>\n', "whitespace", 3),
        ('<!-- generated --> <?xml version="1.0" encoding="utf-8"?>\n', "a comment", 1),
        ('\n<!-- a\ncomment -->\n<?xml version="1.0"\n      encoding="UTF-8"?><!-- after -->\n', "a comment", 4),
    ],
)
def test_a_declaration_after_whitespace_or_a_comment_is_read_with_a_note(tmp_path, head, what, declaration_line):
    lines = [link("base"), link("l1"), link("l2"), joint("j1", "base", "l1"), joint("j2", "l1", "l2")]
    path = write(tmp_path, robot(lines, head))
    chain = read_urdf(str(path), "l2")
    column = head.splitlines()[declaration_line - 1].index("<?xml") + 1
    assert chain.notes == (
        f"{path}:{declaration_line}:{column}: note: the XML declaration comes after {what}, which "
        "XML does not allow; read as if it were at the start of the file",
    )
    plain = write(tmp_path, robot(lines), "plain.urdf")
    same_model(chain.tree, read_urdf(str(plain), "l2").tree)
    # what follows keeps its line and column: an error in the last joint points at it
    bad = write(tmp_path, robot(lines[:-1] + [joint("j2", "l1", "l2", '<spring k="1"/>')], head), "bad.urdf")
    with pytest.raises(UserError) as e:
        read_urdf(str(bad), "l2")
    spring_line = head.count("\n") + 1 + len(lines)
    assert (e.value.location.line, e.value.location.col) == (spring_line, lines[-1].index("</joint>") + 1), e.value


def test_text_before_the_declaration_stays_an_error(tmp_path):
    path = write(tmp_path, robot([link("base")], 'robot\n<?xml version="1.0"?>\n'))
    with pytest.raises(UserError, match="not well-formed XML"):
        read_urdf(str(path), "base")


# --- --base: the same for chains and trees --------------------------------------------------

FLOATING = [
    link("world"),
    link("pelvis"),
    link("l1"),
    link("l2"),
    link("r1"),  # lines 3-7
    joint("root", "world", "pelvis", type_="floating"),  # line 8
    joint("jl1", "pelvis", "l1"),
    joint("jl2", "l1", "l2"),
    joint("jr1", "pelvis", "r1"),
]


def test_a_floating_joint_above_the_base_is_no_error_for_a_chain_or_a_tree(tmp_path, capsys):
    path = write(tmp_path, robot(FLOATING))
    chain = read_urdf(str(path), "l2", base="pelvis").tree
    tree = read_urdf_tree(str(path), base="pelvis", tip="l2").tree
    assert [j.name for j in chain.joints] == ["jl1", "jl2"] and chain.locked_joints == ("jr1",)
    assert [j.name for j in tree.joints] == ["jl1", "jl2", "jr1"] and tree.locked_joints == ()
    for i, k in enumerate(tree.support(tree.tip)):  # the chain is the tree's path to the tip
        np.testing.assert_array_equal(chain.joints[i].origin, tree.joints[k].origin)
    assert main(["check", str(path), "--tip", "l2", "--base", "pelvis"]) == 0
    assert main(["check", str(path), "--tree", "--base", "pelvis"]) == 0
    capsys.readouterr()
    # without a base, both name the base to choose, at the floating joint
    for argv in (["--tip", "l2"], ["--tree"]):
        assert main(["check", str(path), *argv]) == 1
        assert capsys.readouterr().err == (
            f"{path}:8:1: joint 'root' is a floating joint at the root, which robotgen does not support; read the "
            "robot below it with base='pelvis' (--base pelvis)\n"
        )


def test_a_floating_or_planar_joint_below_the_base_is_an_error_for_a_chain_or_a_tree(tmp_path):
    lines = FLOATING[:5] + [
        joint("root", "world", "pelvis"),
        FLOATING[6],
        joint("jl2", "l1", "l2", type_="planar"),
        FLOATING[8],
    ]
    path = write(tmp_path, robot(lines))
    expected = (
        "joint 'jl2' is a planar joint, which robotgen does not support below the base ('world'); a base at "
        "or below its child link 'l2' leaves it out"
    )
    for read in (lambda: read_urdf(str(path), "r1"), lambda: read_urdf_tree(str(path))):
        with pytest.raises(UserError) as e:
            read()
        assert e.value.message == expected and e.value.location.line == 10


# --- a joint that moves no mass, in a tree ---------------------------------------------------


def test_a_tree_warns_about_a_joint_that_moves_no_mass_and_forward_dynamics_names_it(tmp_path, capsys):
    """romeo's hands: a joint whose links are massless. The tree reader warns at the joint as
    the chain reader does; the module's functions that solve with M say why they fail."""
    hand = '<joint name="hand" type="revolute"><parent link="l1"/><child link="palm"/><axis xyz="0 0 1"/></joint>'
    lines = [
        link("base"),
        link("l1"),
        link("l2"),
        '<link name="palm"/>',
        joint("j1", "base", "l1"),
        joint("j2", "l1", "l2"),
        hand,
    ]  # hand: line 9
    path = write(tmp_path, robot(lines))
    out = tmp_path / "out"
    assert main(["build", str(path), "--tree", "--name", "handy", "-o", str(out), "-q"]) == 0
    warning = (
        f"{path}:9:1: warning: joint 'hand' moves no mass or inertia (massless links after it): M is singular "
        "and forward dynamics returns no finite answer"
    )
    assert capsys.readouterr().err.splitlines() == [warning]
    assert read_urdf_tree(str(path)).notes == (warning,)
    import importlib
    import sys

    sys.path.insert(0, str(out))
    try:
        importlib.invalidate_caches()
        module = importlib.import_module("handy")
    finally:
        sys.path.remove(str(out))
    q, qd, tau = np.zeros(3), np.zeros(3), np.ones(3)
    assert np.linalg.matrix_rank(module.mass(q)) == 2  # the hand's row and column are 0
    cause = (
        "the result is not finite: joint 'hand' moves no mass or inertia (massless links after it), so M is "
        "singular at every state; the outputs were set to 0 (status 2)"
    )
    for call in (
        lambda: module.forward_dynamics(q, qd, tau),
        lambda: module.mass_inverse(q),
        lambda: module.forward_dynamics_derivatives(q, qd, tau),
        lambda: module.discrete_dynamics(q, qd, tau, 0.01),
    ):
        with pytest.raises(FloatingPointError) as e:
            call()
        assert str(e.value).endswith(cause), e.value
    assert "Here joint 'hand' moves no mass" in module.forward_dynamics.__doc__
    # the functions that do not solve with M are unchanged
    module.inverse_dynamics_derivatives(q, qd, tau)
    # without the hand (a tip above it, as a chain) nothing is singular
    assert read_urdf(str(path), "l2").notes == ()


# --- info without --tip; an unknown --tip -----------------------------------------------------


def test_info_without_a_tip_lists_the_links_as_a_tree(tmp_path, capsys):
    gripper = [
        '<link name="tool"/>',
        '<link name="finger_a"/>',
        '<link name="finger_b"/>',
        '<joint name="flange" type="fixed"><parent link="l2"/><child link="tool"/></joint>',
        joint("finger_a_joint", "tool", "finger_a", type_="prismatic"),
        joint("finger_b_joint", "tool", "finger_b", '<mimic joint="finger_a_joint"/>', type_="prismatic"),
    ]
    path = write(tmp_path, robot(FLOATING + gripper).replace('<robot name="r">', '<robot name="Arm-2">'))
    assert main(["info", str(path)]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert out.splitlines() == [
        "Arm-2 (r.urdf): 8 links, 7 joints below 'world', 5 of them movable; each link with the joint that carries it",
        "world",
        "  pelvis            root            floating",
        "    l1              jl1             revolute",
        "      l2            jl2             revolute",
        "        tool        flange          fixed",
        "          finger_a  finger_a_joint  prismatic",
        "          finger_b  finger_b_joint  prismatic, mimics finger_a_joint",
        "    r1              jr1             revolute",
        "a chain: --tip LINK (the movable joints from 'world' to LINK and the joints <mimic> couples to them; the "
        "others locked at q = 0); every movable joint: --tree",
    ], out
    # --base starts the tree there; --tip or --tree give the model's info as before
    assert main(["info", str(path), "--base", "l1"]) == 0
    assert capsys.readouterr().out.splitlines()[:3] == [
        "Arm-2 (r.urdf): 5 links, 4 joints below 'l1', 3 of them movable; each link with the joint that carries it",
        "l1",
        "  l2            jl2             revolute",
    ]
    assert main(["info", str(path), "--tip", "l2", "--base", "pelvis"]) == 0
    assert "    - jl2: revolute, parent 0 [-1, 1]" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--tip", "fingr_a"], "tip link 'fingr_a' is not in the URDF; nearest: 'finger_a', 'finger_b'"),
        (["--tree", "--tip", "tol"], "tip link 'tol' is not in the URDF; nearest: 'tool'"),
        (["--tip", "l2", "--base", "pelvic"], "base link 'pelvic' is not in the URDF; nearest: 'pelvis'"),
        (["--tip", "gripper"], "tip link 'gripper' is not in the URDF"),
    ],
)
def test_an_unknown_link_lists_the_nearest_names(tmp_path, capsys, argv, message):
    links = FLOATING[:5] + ['<link name="tool"/>', '<link name="finger_a"/>', '<link name="finger_b"/>']
    joints = (
        [joint("root", "world", "pelvis")]
        + FLOATING[6:]
        + [
            '<joint name="flange" type="fixed"><parent link="l2"/><child link="tool"/></joint>',
            joint("fa", "tool", "finger_a", type_="prismatic"),
            joint("fb", "tool", "finger_b", type_="prismatic"),
        ]
    )
    path = write(tmp_path, robot(links + joints))
    assert main(["check", str(path), *argv]) == 1
    assert capsys.readouterr().err == f"{path}:2:1: {message} (robotgen info r.urdf lists its links)\n"


def test_the_info_example_of_cli_md_is_what_info_prints(tmp_path, monkeypatch, capsys):
    import shutil
    from pathlib import Path

    from robots import UR5, robots_dir

    shutil.copy(robots_dir() / UR5[0], tmp_path / "ur5_robot.urdf")
    monkeypatch.chdir(tmp_path)
    docs = (Path(__file__).resolve().parents[2] / "docs" / "cli.md").read_text()
    block = docs[docs.index("$ robotgen info ur5_robot.urdf\n") :]
    block = block[: block.index("```")].splitlines()
    build = block.index("$ robotgen build ur5_robot.urdf --tip tool")
    assert main(["info", "ur5_robot.urdf"]) == 0
    assert capsys.readouterr().out.splitlines() == block[1:build]
    assert main(["build", "ur5_robot.urdf", "--tip", "tool"]) == 1
    assert capsys.readouterr().err.splitlines() == block[build + 1 :]
