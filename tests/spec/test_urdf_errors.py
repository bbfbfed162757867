"""Unsupported URDF constructs give a clear error naming the element, exit status 1, and
no output directory."""

from __future__ import annotations

import numpy as np
import pytest

from robotgen.cli import main


def messages(err: str) -> str:
    """stderr without the build's progress lines ("robotgen: [  1.2 s] ..."), which -q silences."""
    return "".join(l for l in err.splitlines(True) if not l.startswith("robotgen: ["))


LINK = '<link name="{0}"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'


def urdf(*joints: str, links=("base", "l1", "l2")) -> str:
    body = "\n".join(LINK.format(n) for n in links)
    return f'<?xml version="1.0"?>\n<robot name="r">\n{body}\n' + "\n".join(joints) + "\n</robot>\n"


def joint(name, type_, parent, child, extra=""):
    return (
        f'<joint name="{name}" type="{type_}"><parent link="{parent}"/><child link="{child}"/>'
        f'<axis xyz="0 0 1"/>{extra}</joint>'
    )


OK1 = joint("j1", "revolute", "base", "l1", '<limit lower="-1" upper="1" effort="1" velocity="1"/>')
CASES = {
    "floating": ([OK1, joint("j2", "floating", "l1", "l2")], "l2", "j2' is a floating joint"),
    "planar": ([OK1, joint("j2", "planar", "l1", "l2")], "l2", "j2' is a planar joint"),
    "mimic_of_nothing": (
        [OK1, joint("j2", "revolute", "l1", "l2", '<mimic joint="j9"/>')],
        "l2",
        "joint 'j2' mimics 'j9', which is not a joint of the URDF",
    ),
    "closed_loop": (
        [OK1, joint("j2", "revolute", "l1", "l2"), joint("j3", "revolute", "base", "l2")],
        "l2",
        "closed loops are not supported",
    ),
    "tip_not_below_base": ([OK1, joint("j2", "revolute", "base", "l2")], "l2", "is not below base link"),
    "unknown_type": ([OK1, joint("j2", "spherical", "l1", "l2")], "l2", "unknown type 'spherical'"),
    "unknown_element": (
        [OK1, joint("j2", "revolute", "l1", "l2", "<spring k='1'/>")],
        "l2",
        "<spring> is not supported inside <joint>",
    ),
    "non_finite_origin": (
        [OK1, joint("j2", "revolute", "l1", "l2", '<origin xyz="nan 0 0"/>')],
        "l2",
        "<origin> attribute 'xyz' must hold finite numbers, got 'nan 0 0'",
    ),
    "unknown_link": ([OK1, joint("j2", "revolute", "l1", "nowhere")], "l1", "unknown link 'nowhere'"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_unsupported_construct(case, tmp_path, capsys):
    joints, tip, expected = CASES[case]
    path = tmp_path / f"{case}.urdf"
    path.write_text(urdf(*joints))
    base = "l1" if case == "tip_not_below_base" else None
    out = tmp_path / "out"
    argv = ["build", str(path), "--tip", tip, "-o", str(out)] + (["--base", base] if base else [])
    assert main(argv) == 1
    err = messages(capsys.readouterr().err)
    assert expected in err, err
    assert err.startswith(f"{path}:"), err
    line = int(err.split(":")[1])
    assert line >= 3  # points into the robot, not at the file's start
    assert "Traceback" not in err
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [path]


def test_malformed_xml(tmp_path, capsys):
    path = tmp_path / "bad.urdf"
    path.write_text('<robot name="r">\n<link name="a">\n</robot>\n')
    assert main(["build", str(path), "--tip", "a", "-o", str(tmp_path / "out")]) == 1
    err = messages(capsys.readouterr().err)
    assert err.startswith(f"{path}:3:") and "not well-formed" in err, err


def test_urdf_without_tip_is_a_usage_error(tmp_path, capsys):
    path = tmp_path / "r.urdf"
    path.write_text(urdf(OK1))
    assert main(["build", str(path)]) == 2


def test_unknown_element_inside_a_joint_fails_beside_ignored_ones_under_robot(tmp_path, capsys):
    """Elements under <robot> robotgen does not know are ignored; one inside <joint> that would
    change the dynamics (a spring) stays an error, with the reason."""
    text = urdf(OK1, joint("j2", "revolute", "l1", "l2", "<spring k='1'/>"))
    text = text.replace('<robot name="r">\n', '<robot name="r">\n<ros2_control name="hw"/>\n<vendor_tag/>\n')
    path = tmp_path / "r.urdf"
    path.write_text(text)
    out = tmp_path / "out"
    assert main(["build", str(path), "--tip", "l2", "-o", str(out)]) == 1
    err = messages(capsys.readouterr().err)
    # lines: 3-4 the ignored elements, 5-7 links, 8 j1, 9 j2
    assert err == (
        f"{path}:9:90: <spring> is not supported inside <joint>: it would change the joint's dynamics, "
        "which URDF gives as <dynamics damping=... friction=...> only\n"
    ), err
    assert not out.exists()


def test_mimic_joint_off_the_chain_moves_with_its_leader_or_is_locked_with_it(tmp_path):
    """A mimic joint off the chain whose leader is on it moves with the chain (a branch coupled to
    the leader's coordinate); one whose leader is locked off the chain is locked at q = 0 with it:
    its link's inertia joins the body of the joint carrying it."""
    from robotgen.frontend.urdf import read_urdf

    off = joint("j3", "revolute", "l1", "l3", '<origin xyz="0 0.5 0"/><mimic joint="j1" multiplier="-2"/>')
    path = tmp_path / "r.urdf"
    path.write_text(urdf(OK1, joint("j2", "revolute", "l1", "l2"), off, links=("base", "l1", "l2", "l3")))
    tree = read_urdf(str(path), "l2").tree
    assert [(j.name, j.parent) for j in tree.joints] == [("j1", -1), ("j2", 0), ("j3", 0)]
    assert tree.nq == 2 and tree.locked_joints == ()
    assert (tree.coupling.coordinate, tree.coupling.multiplier) == ((0, 1, 0), (1.0, 1.0, -2.0))
    # following j2, which a chain to l1 locks: locked with it
    path.write_text(
        urdf(
            OK1,
            joint("j2", "revolute", "l1", "l2"),
            off.replace('joint="j1"', 'joint="j2"'),
            links=("base", "l1", "l2", "l3"),
        )
    )
    tree = read_urdf(str(path), "l1").tree
    assert [j.name for j in tree.joints] == ["j1"] and tree.coupling is None
    assert tree.locked_joints == ("j2", "j3")
    body = tree.joints[0].body  # l1 and l2 at the origin, l3 0.5 along y: com 1/6 along y
    assert body.mass == 3.0
    np.testing.assert_allclose(body.com, [0.0, 0.5 / 3, 0.0], rtol=0, atol=1e-16)
    # 0.1 each plus m d^2 off y: 2 (1/6)^2 + (1/3)^2 = 1/6
    np.testing.assert_allclose(body.inertia, np.diag([0.3 + 1 / 6, 0.3, 0.3 + 1 / 6]), rtol=0, atol=1e-15)
