"""MJCF files that MuJoCo refuses, or that robotgen cannot represent: exit status 1, MuJoCo's
message or one naming the element, located in the file, no traceback and no output
directory."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from robotgen.cli import main

SUITE = Path(importlib.util.find_spec("dm_control").submodule_search_locations[0]) / "suite"


def messages(err: str) -> str:
    return "".join(l for l in err.splitlines(True) if not l.startswith("robotgen: ["))


def model(*bodies: str, extra: str = "") -> str:
    return '<mujoco model="m">\n  <worldbody>\n' + "\n".join(bodies) + "\n  </worldbody>\n" + extra + "</mujoco>\n"


ARM = """    <body name="upper">
      <joint name="shoulder" type="hinge" axis="0 1 0"{0}/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/>
      <body name="lower" pos="0.5 0 0">
        <joint name="elbow" type="{1}"/>
        <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/>
        <site name="tip" pos="0.5 0 0"/>
      </body>
    </body>"""
FREE = """    <body name="torso" pos="0 0 1">
      <freejoint name="root"/>
      <geom type="sphere" size="0.1"/>
      <body name="leg">
        <joint name="hip" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.05"/>
      </body>
    </body>"""
WELDED = """    <body name="plate">
      <geom type="box" size="0.1 0.1 0.01"/>
      <body name="knob" pos="0 0 0.02">
        <geom type="sphere" size="0.01"/>
      </body>
    </body>"""

# name: (file text or a suite file, argv after the path, (line, col) or None for the file's start, message)
CASES = {
    "mismatched_tag": (
        model(ARM.format("", "hinge").replace("</body>\n    </body>", "</bod>\n    </body>")),
        ["--tip", "tip"],
        None,
        "MuJoCo cannot compile this file: XML parse error",
    ),
    "unknown_attribute": (
        model(ARM.format(' spring="1"', "hinge")),
        ["--tip", "tip"],
        (4, 7),
        "MuJoCo cannot compile this file: XML Error: Schema violation: unrecognized attribute: "
        "'spring'; Element 'joint', line 4",
    ),
    "missing_include": (
        model(ARM.format("", "hinge"), extra='  <include file="hand.xml"/>\n'),
        ["--tip", "tip"],
        (13, 3),
        "Error opening file",
    ),
    "unknown_tip": (
        model(ARM.format("", "hinge")),
        ["--tip", "hand"],
        (1, 1),
        "tip body or site 'hand' is not in the model",
    ),
    "fused_tip": (
        model(WELDED).replace("<worldbody>", '<compiler fusestatic="true"/>\n  <worldbody>'),
        ["--tip", "knob"],
        (1, 1),
        "tip body or site 'knob' is not in the model (MuJoCo's compiler fused "
        'it into its parent: <compiler fusestatic="true">; name a site on it '
        "or its parent)",
    ),
    "unknown_base": (
        model(ARM.format("", "hinge")),
        ["--tip", "tip", "--base", "pelvis"],
        (1, 1),
        "base body 'pelvis' is not in the model",
    ),
    "ball_on_chain": (
        model(ARM.format("", "ball")),
        ["--tip", "tip"],
        (7, 9),
        "joint 'elbow' is a ball joint (on the chain from 'world' to 'tip'), which robotgen does not support",
    ),
    "ball_in_tree": (
        model(ARM.format("", "ball")),
        ["--tree"],
        (7, 9),
        "joint 'elbow' is a ball joint (below the base body 'world'), which robotgen does not support",
    ),
    "free_on_chain": (
        model(FREE),
        ["--tip", "leg"],
        (4, 7),
        "joint 'root' is a free joint (on the chain from 'world' to 'leg'), which robotgen does not "
        "support; read the tree below it with --base torso",
    ),
    "free_in_tree": (
        model(FREE),
        ["--tree"],
        (4, 7),
        "joint 'root' is a free joint (below the base body 'world'), which robotgen does not support; "
        "read the tree below it with --base torso",
    ),
    "tip_not_below_base": (
        model(ARM.format("", "hinge")),
        ["--tip", "upper", "--base", "lower"],
        (3, 5),
        "tip 'upper' is not below base body 'lower'",
    ),
    "no_joint_between": (
        model(WELDED),
        ["--tip", "knob", "--base", "plate"],
        (5, 7),
        "no joint between 'plate' and 'knob'",
    ),
    "weld_on_the_chain": (
        model(ARM.format("", "hinge"), extra='  <equality>\n    <weld body1="lower"/>\n  </equality>\n'),
        ["--tip", "tip"],
        (14, 5),
        "equality constraint 'equality 0' acts on the joints robotgen keeps, and robotgen has no "
        "constraints inside a chain or tree",
    ),
    "quadruped_legs": (
        "quadruped.xml",
        ["--tree", "--base", "torso"],
        (272, 5),
        "equality constraint 'coupling_front_left' acts on the joints robotgen keeps",
    ),
    "flex": (
        model(
            ARM.format("", "hinge"),
            '    <flexcomp name="cloth" type="grid" count="3 3 1" spacing=".1 .1 .1" dim="2" pos="0 0 1"/>',
        ),
        ["--tip", "tip"],
        (12, 5),
        "flex 'cloth': deformable bodies are not part of robotgen's model",
    ),
    "negative_damping": (
        model(ARM.format(' damping="-1"', "hinge")),
        ["--tip", "tip"],
        (4, 7),
        "joint 'shoulder': damping -1 is negative",
    ),
    "huge_number": (
        model(ARM.format("", "hinge").replace('pos="0.5 0 0">', 'pos="1e300 0 0">')),
        ["--tip", "tip"],
        (6, 7),
        "body 'lower': MuJoCo's compiled body_pos holds 1e+300 0 0; robotgen reads finite numbers "
        "up to 1e+15 in magnitude",
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_refused_with_a_located_message(case, tmp_path, capsys):
    text, args, where, expected = CASES[case]
    if text.endswith(".xml"):
        path = SUITE / text
    else:
        path = tmp_path / "robot.xml"
        path.write_text(text)
    out = tmp_path / "out"
    assert main(["build", str(path), *args, "-o", str(out), "-q"]) == 1
    err = messages(capsys.readouterr().err)
    assert expected in err, err
    assert "Traceback" not in err
    if where is not None:
        assert err.startswith(f"{path}:{where[0]}:{where[1]}: "), err
    else:
        assert err.startswith(f"{path}:"), err
    assert not out.exists()


def test_a_file_that_is_not_there(tmp_path, capsys):
    path = tmp_path / "none.xml"
    assert main(["build", str(path), "--tip", "a", "-o", str(tmp_path / "out")]) == 1
    assert messages(capsys.readouterr().err) == f"{path}:1:1: cannot read MJCF file: No such file or directory\n"


def test_an_mjcf_file_needs_a_tip_or_the_tree(tmp_path, capsys):
    path = tmp_path / "robot.xml"
    path.write_text(model(ARM.format("", "hinge")))
    assert main(["build", str(path)]) == 2
    assert "an MJCF file needs --tip BODY (or --tree for every joint below the base)" in capsys.readouterr().err


def test_without_mujoco_the_message_says_what_to_install(tmp_path, capsys, monkeypatch):
    path = tmp_path / "robot.xml"
    path.write_text(model(ARM.format("", "hinge")))
    monkeypatch.setitem(sys.modules, "mujoco", None)  # import mujoco raises ImportError
    out = tmp_path / "out"
    assert main(["build", str(path), "--tip", "tip", "-o", str(out)]) == 1
    err = messages(capsys.readouterr().err)
    assert err == "robotgen: error: reading an MJCF file needs MuJoCo: pip install 'robotgen[mujoco]'\n"
    assert not out.exists()
