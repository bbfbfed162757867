"""Malformed URDF numbers and structure: each is a located error (exit 1), never a module that
returns NaN, never an internal error in the manifest writer."""

from __future__ import annotations

from pathlib import Path

import pytest

from robotgen.cli import main

JOINT = (
    '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
    '<origin xyz="{origin}"/><axis xyz="{axis}"/>'
    '<limit lower="{lower}" upper="{upper}" effort="10" velocity="{velocity}"/>'
    '<dynamics damping="{damping}"/></joint>'
)
LINK = (
    '<link name="l1"><inertial><mass value="{mass}"/><origin xyz="0 0 0.1"/>'
    '<inertia ixx="{ixx}" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
)
GOOD = dict(origin="0 0 0.1", axis="0 0 1", lower="-1", upper="1", velocity="2", damping="0.1", mass="1", ixx="0.01")


def urdf(**changes) -> str:
    v = {**GOOD, **changes}
    return f'<robot name="r"><link name="base"/>{LINK.format(**v)}{JOINT.format(**v)}</robot>\n'


@pytest.mark.parametrize(
    "changes, words",
    [
        (dict(mass="nan"), "finite numbers"),
        (dict(mass="inf"), "finite numbers"),
        (dict(mass="1e999"), "finite"),
        (dict(ixx="nan"), "finite numbers"),
        (dict(origin="0 nan 0"), "finite numbers"),
        (dict(axis="0 0 inf"), "finite"),
        (dict(velocity="nan"), "finite numbers"),
        (dict(lower="nan"), "finite numbers"),
        (dict(lower="2", upper="-2"), "lower 2 is above upper -2"),
        (dict(velocity="-2"), "velocity must be >= 0"),
        (dict(damping="-0.1"), "damping and friction must be >= 0"),
        (dict(origin="0 0 1e300"), "larger than 1e+15"),
    ],
)
def test_bad_numbers_are_located_errors(tmp_path, capsys, changes, words):
    path = tmp_path / "r.urdf"
    path.write_text(urdf(**changes))
    out = tmp_path / "out"
    assert main(["build", str(path), "--tip", "l1", "-o", str(out), "--no-compile"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"{path}:1:") and words in err and "internal error" not in err, err
    assert not out.exists()


def test_duplicate_joint_names(tmp_path, capsys):
    text = urdf().replace(
        "</robot>",
        '<link name="l2"/><joint name="j1" type="fixed"><parent link="l1"/><child link="l2"/></joint></robot>',
    )
    path = tmp_path / "r.urdf"
    path.write_text(text)
    assert main(["check", str(path), "--tip", "l1"]) == 1
    assert "duplicate joint 'j1'" in capsys.readouterr().err


def test_the_good_one_builds(tmp_path):
    path = tmp_path / "r.urdf"
    path.write_text(urdf())
    assert main(["build", str(path), "--tip", "l1", "-o", str(tmp_path / "out"), "--no-compile"]) == 0


def test_a_joint_that_moves_no_mass_is_warned_about(tmp_path, capsys):
    """A massless tip link (and nothing after it) makes M singular: the build still runs, but
    the user hears why forward dynamics will have no finite answer, at the joint."""
    text = urdf().replace(
        "</robot>",
        '<link name="l2"/><joint name="j2" type="revolute"><parent link="l1"/>'
        '<child link="l2"/><axis xyz="0 0 1"/></joint></robot>',
    )
    path = tmp_path / "r.urdf"
    path.write_text(text)
    assert main(["check", str(path), "--tip", "l2"]) == 0
    err = capsys.readouterr().err
    column = text.index('<joint name="j2"') + 1
    assert f"{path}:1:{column}: warning: joint 'j2' moves no mass" in err, err
    assert main(["check", str(path), "--tip", "l1"]) == 0
    assert "moves no mass" not in capsys.readouterr().err


def test_a_massless_last_link_of_a_spec_chain_is_warned_about(tmp_path, capsys):
    spec = Path(__file__).resolve().parents[2] / "specs" / "two_link.yaml"
    text = spec.read_text()
    start = text.index("          - name: elbow")
    text = text[:start] + text[start:].replace("mass: 0.9", "mass: 0").replace(
        "inertia: {ixx: 0.0005, iyy: 0.03, izz: 0.03, ixy: 0, ixz: 0, iyz: 0}", "inertia: {ixx: 0, iyy: 0, izz: 0}"
    )
    path = tmp_path / "arm.yaml"
    path.write_text(text)
    assert main(["check", str(path)]) == 0
    line = text[:start].count("\n") + 1
    assert f"{path}:{line}:13: warning: arm: joint 'elbow' moves no mass" in capsys.readouterr().err


LAUGHS = (
    '<?xml version="1.0"?>\n<!DOCTYPE robot [\n<!ENTITY a "'
    + "a" * 40
    + '">\n'
    + "".join(f'<!ENTITY {b} "{("&" + a + ";") * 16}">\n' for a, b in zip("abcdef", "bcdefg"))
    + ']>\n<robot name="&g;"><link name="base"/></robot>\n'
)


@pytest.mark.parametrize(
    "name, text, where, words",
    [
        ("laughs", LAUGHS, ":3:", "declares an XML entity ('a')"),
        (
            "external",
            '<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY x SYSTEM "file:///etc/passwd">]>\n'
            '<robot name="&x;"><link name="base"/></robot>\n',
            ":2:",
            "declares an XML entity ('x')",
        ),
        ("no_links", "<robot name='r'>" + "<a>" * 10000 + "</a>" * 10000 + "</robot>", ":1:1:", "no <link> elements"),
        ("no_robot", "<model/>", ":1:1:", "must have a <robot> root element"),
        (
            "many_links",
            "<robot name='r'>" + "".join(f"<link name='l{i}'/>" for i in range(1002)) + "</robot>",
            ":1:",
            "more than 1000 links",
        ),
    ],
)
def test_hostile_xml_is_refused_quickly_and_located(tmp_path, capsys, name, text, where, words):
    path = tmp_path / f"{name}.urdf"
    path.write_text(text)
    assert main(["check", str(path), "--tip", "l1"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"{path}{where}") and words in err, err


def test_a_file_past_the_size_bound_is_not_read(tmp_path, capsys):
    path = tmp_path / "huge.urdf"
    with open(path, "wb") as f:  # sparse: 17 MB that cost no disk
        f.truncate(17_000_000)
    assert main(["check", str(path), "--tip", "l1"]) == 1
    assert f"{path}:1:1: URDF file is 17000000 bytes; robotgen reads at most 16000000" in capsys.readouterr().err


def test_links_without_inertial_are_massless_and_warned_about(tmp_path, capsys):
    path = tmp_path / "r.urdf"
    path.write_text(urdf().replace(LINK.format(**GOOD), '<link name="l1"/>'))
    assert main(["check", str(path), "--tip", "l1"]) == 0
    assert "warning: joint 'j1' moves no mass" in capsys.readouterr().err


@pytest.mark.parametrize(
    "declaration, column",
    [('<?xml version="1.0" encoding="klingon"?>', 21), ("<?xml version='1.0' encoding='x-unknown-8'?>", 21)],
)
def test_an_encoding_python_does_not_know_is_located(tmp_path, capsys, declaration, column):
    path = tmp_path / "r.urdf"
    path.write_text(declaration + "\n" + urdf())
    assert main(["check", str(path), "--tip", "l1"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"{path}:1:{column}: the XML declaration names an encoding Python does not know"), err
    path.write_text(declaration.replace("klingon", "utf-8").replace("x-unknown-8", "latin-1") + "\n" + urdf())
    assert main(["check", str(path), "--tip", "l1"]) == 0
