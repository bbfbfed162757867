"""Unsupported URDF constructs give a clear error naming the element, exit status 1, and
no output directory."""
from __future__ import annotations

import pytest

from robotgen.cli import main

LINK = '<link name="{0}"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'


def urdf(*joints: str, links=("base", "l1", "l2")) -> str:
    body = "\n".join(LINK.format(n) for n in links)
    return f'<?xml version="1.0"?>\n<robot name="r">\n{body}\n' + "\n".join(joints) + "\n</robot>\n"


def joint(name, type_, parent, child, extra=""):
    return (f'<joint name="{name}" type="{type_}"><parent link="{parent}"/><child link="{child}"/>'
            f'<axis xyz="0 0 1"/>{extra}</joint>')


OK1 = joint("j1", "revolute", "base", "l1", '<limit lower="-1" upper="1" effort="1" velocity="1"/>')
CASES = {
    "floating": ([OK1, joint("j2", "floating", "l1", "l2")], "l2", "j2' is a floating joint"),
    "planar": ([OK1, joint("j2", "planar", "l1", "l2")], "l2", "j2' is a planar joint"),
    "mimic": ([OK1, joint("j2", "revolute", "l1", "l2", '<mimic joint="j1"/>')], "l2", "mimic joint"),
    "closed_loop": ([OK1, joint("j2", "revolute", "l1", "l2"), joint("j3", "revolute", "base", "l2")],
                    "l2", "closed loops are not supported"),
    "tip_not_below_base": ([OK1, joint("j2", "revolute", "base", "l2")], "l2", "is not below base link"),
    "unknown_type": ([OK1, joint("j2", "spherical", "l1", "l2")], "l2", "unknown type 'spherical'"),
    "unknown_element": ([OK1, joint("j2", "revolute", "l1", "l2", "<spring k='1'/>")], "l2",
                        "<spring> is not supported inside <joint>"),
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
    err = capsys.readouterr().err
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
    err = capsys.readouterr().err
    assert err.startswith(f"{path}:3:") and "not well-formed" in err, err


def test_urdf_without_tip_is_a_usage_error(tmp_path, capsys):
    path = tmp_path / "r.urdf"
    path.write_text(urdf(OK1))
    assert main(["build", str(path)]) == 2
