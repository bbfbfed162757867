"""A URDF leaf inside a YAML spec: the file is found relative to the spec, and the leaf is
the same chain as `robotgen build ROBOT.urdf --tip LINK` gives."""

from __future__ import annotations

import shutil

import numpy as np
from robots import UR5, robots_dir

from robotgen.cli import main
from robotgen.frontend import load_system
from robotgen.frontend.urdf import load_urdf_system
from robotgen.symbolic import kernels_for


def messages(err: str) -> str:
    """stderr without the build's progress lines ("robotgen: [  1.2 s] ..."), which -q silences."""
    return "".join(l for l in err.splitlines(True) if not l.startswith("robotgen: ["))


SPEC = """robotgen: 1
name: ur5_leaf
root: arm
nodes:
  arm:
    define:
      urdf: {{file: {file}, tip: tool0, base: {base}}}
"""


def test_urdf_leaf_equals_the_direct_urdf_build(tmp_path):
    shutil.copy(robots_dir() / UR5[0], tmp_path / "ur5.urdf")
    (tmp_path / "robot").mkdir()
    spec = tmp_path / "robot" / "ur5.yaml"
    spec.write_text(SPEC.format(file="../ur5.urdf", base="base_link"))
    from_spec = {k.name: k.function for k in kernels_for(load_system(str(spec)))}
    direct = {
        k.name: k.function for k in kernels_for(load_urdf_system(str(tmp_path / "ur5.urdf"), "tool0", "base_link"))
    }
    q = np.random.default_rng(0).uniform(-3, 3, 6)
    qd = np.random.default_rng(1).normal(size=6)
    for name in ("fk", "mass", "gravity"):
        np.testing.assert_array_equal(np.array(from_spec[name](q)), np.array(direct[name](q)))
    np.testing.assert_array_equal(np.array(from_spec["coriolis"](q, qd)), np.array(direct["coriolis"](q, qd)))


def test_missing_urdf_file_points_at_the_spec_field(tmp_path, capsys):
    spec = tmp_path / "r.yaml"
    spec.write_text(SPEC.format(file="absent.urdf", base="base_link"))
    assert main(["check", str(spec)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"{spec}:7:20: ") and "absent.urdf' not found" in err, err


def test_error_inside_the_urdf_points_into_the_urdf(tmp_path, capsys):
    shutil.copy(robots_dir() / UR5[0], tmp_path / "ur5.urdf")
    spec = tmp_path / "r.yaml"
    spec.write_text(SPEC.format(file="ur5.urdf", base="ee_link"))
    assert main(["build", str(spec), "-o", str(tmp_path / "out")]) == 1
    err = messages(capsys.readouterr().err)
    assert err.startswith(f"{tmp_path / 'ur5.urdf'}:"), err
    assert "tip link 'tool0' is not below base link 'ee_link'" in err, err
    assert not (tmp_path / "out").exists()


def test_urdf_leaf_notes_reach_the_spec_warnings(tmp_path, capsys):
    """The URDF reader's note about elements it ignores under <robot> reaches the spec's
    warnings (printed by the CLI); the module is named by the spec, so no module-name note."""
    text = (robots_dir() / UR5[0]).read_text()
    end = text.index(">", text.index("<robot ")) + 1
    line = text[:end].count("\n") + 2  # <ros2_control> goes on the line after <robot ...>
    text = text[:end] + '\n<ros2_control name="hw" type="system"><joint name="x"/></ros2_control>' + text[end:]
    (tmp_path / "ur5.urdf").write_text(text)
    spec = tmp_path / "ur5.yaml"
    spec.write_text(SPEC.format(file="ur5.urdf", base="base_link"))
    system = load_system(str(spec))
    assert system.warnings == (
        f"{tmp_path / 'ur5.urdf'}:{line}:1: note: ignored 1 element robotgen does not "
        f"use under <robot>: <ros2_control> (line {line})",
    ), system.warnings
    assert main(["check", str(spec)]) == 0
    assert capsys.readouterr().err.count("note: ignored 1 element") == 1
