"""Module names that would break the build or what it meets: keywords, standard headers and
modules they would hide, C's entry point, a trailing newline, names too long for a file. Each
is refused where the spec gives it (exit 1), or by --name (exit 2) with a name that works."""

from __future__ import annotations

from pathlib import Path

import pytest

from robotgen.cli import main
from robotgen.errors import UserErrors
from robotgen.frontend import load_system
from robotgen.frontend.urdf import load_urdf_system
from robotgen.model.names import name_problem

SPECS = Path(__file__).resolve().parents[2] / "specs"


@pytest.mark.parametrize(
    "name, words",
    [
        ("int", "C keyword"),
        ("double", "C keyword"),
        ("import", "Python keyword"),
        ("lambda", "Python keyword"),
        ("math", "<math.h>"),
        ("stdio", "<stdio.h>"),
        ("os", "Python module 'os'"),
        ("casadi", "Python module"),
        ("numpy", "Python module"),
        ("main", "entry point"),
        ("__init__", "starts with __"),
        ('"x\\n"', "not a module name"),
        ("Arm", "must match"),
        ("a" * 300, "300 characters"),
    ],
)
def test_spec_names_that_would_break_the_build(tmp_path, name, words):
    text = (SPECS / "two_link.yaml").read_text().replace("name: two_link", f"name: {name}")
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    with pytest.raises(UserErrors) as caught:
        load_system(str(path))
    (error,) = caught.value.errors
    line = text.splitlines().index(f"name: {name}") + 1
    assert (error.location.line, error.location.col) == (line, 7) and words in error.message, str(error)
    out = tmp_path / "out"
    assert main(["build", str(path), "-o", str(out)]) == 1 and not out.exists()


def test_every_example_name_is_fine():
    for spec in sorted(SPECS.glob("*.yaml")):
        assert name_problem(load_system(str(spec)).name) is None


def test_name_option_is_checked_and_a_working_one_suggested(tmp_path, capsys):
    urdf = tmp_path / "r.urdf"
    urdf.write_text(
        '<robot name="math"><link name="base"/><link name="tip"><inertial><mass value="1"/>'
        '<inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        '<joint name="j" type="revolute"><parent link="base"/><child link="tip"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>'
    )
    assert main(["build", str(urdf), "--tip", "tip", "--name", "math", "--no-compile", "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "hides the standard header <math.h>" in err and "try --name math_robot" in err
    assert load_urdf_system(str(urdf), "tip").name == "math_robot"  # the robot's own name, made safe
