"""The figures the docs quote that a quick command prints: each test runs what the docs show
(a console block's command, a Python snippet, the C program of c-api.md) and compares its
output with the docs' text, so that a change that moves a figure fails here rather than
leaving the docs stale. (The README's adaptive-PUMA figures: tests/control/test_hand_control.py.)"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from robotgen.cli import main
from robotgen.frontend import load_system
from robotgen.frontend.mjcf import load_mjcf_system, load_mjcf_tree_system
from robotgen.frontend.urdf import load_urdf_system, load_urdf_tree_system
from robotgen.symbolic import kernels_for

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
SPECS = {yaml.safe_load(p.read_text())["name"]: p for p in (ROOT / "specs").glob("*.yaml")}

# docs/cli.md's arm2.urdf, as far as the figures need it: two arm joints, a fixed flange `tool`,
# two fingers, the second mimicking the first
ARM2 = """<?xml version="1.0"?>
<robot name="Arm-2">
  <link name="base"/>
  <link name="upper"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="fore"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tool"/>
  <link name="finger_a"><inertial><mass value="0.1"/><inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="finger_b"><inertial><mass value="0.1"/><inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0.5 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
  <joint name="flange" type="fixed"><parent link="fore"/><child link="tool"/><origin xyz="0.5 0 0"/></joint>
  <joint name="finger_a_joint" type="prismatic"><parent link="tool"/><child link="finger_a"/><axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="10" velocity="1"/></joint>
  <joint name="finger_b_joint" type="prismatic"><parent link="tool"/><child link="finger_b"/><axis xyz="0 -1 0"/><limit lower="0" upper="0.04" effort="10" velocity="1"/><mimic joint="finger_a_joint"/></joint>
</robot>
"""


def doc(name: str) -> str:
    return (DOCS / name).read_text()


def block_after(text: str, marker: str, fence: str = "```") -> str:
    """The body of the first fenced block that starts after ``marker``."""
    rest = text[text.index(marker) :]
    start = rest.index(fence)
    body = rest[rest.index("\n", start) + 1 :]
    return body[: body.index("```")]


def block_with(text: str, inside: str, fence: str = "```python") -> tuple[str, str]:
    """The fenced block of ``fence`` that contains ``inside``, and the text after it."""
    for part in text.split(fence + "\n")[1:]:
        body, _, after = part.partition("```")
        if inside in body:
            return body, after
    raise AssertionError(f"no {fence} block holds {inside!r}")


def run(code: str) -> tuple[str, dict]:
    """``code`` run here (its imports find the modules the fixtures built): its stdout and
    its variables."""
    out, names = io.StringIO(), {"__name__": "docs"}
    with contextlib.redirect_stdout(out):
        exec(compile(code, "<docs>", "exec"), names)
    return out.getvalue(), names


def numbers(text: str) -> list[float]:
    return [float(v) for v in re.findall(r"-?\d+\.?\d*(?:e[-+]?\d+)?", text)]


@pytest.fixture(scope="module")
def modules(build_module) -> dict:
    """The modules the docs' snippets import, built (and imported) once."""
    return {name: build_module(SPECS[name]) for name in ("puma560", "puma560_rmrc", "styx_high_ct", "puma560_rmac")}


def dm_control_suite() -> Path:
    """dm_control's suite of MJCF models (a test dependency), as cli.md's MJCF example uses it."""
    return Path(importlib.util.find_spec("dm_control").submodule_search_locations[0]) / "suite"


def test_function_counts_are_what_build_prints(tmp_path):
    """Every "robotgen: built NAME (N functions)" the docs show: N is the number of functions
    robotgen build prints for that spec (or for cli.md's arm2.urdf)."""
    (tmp_path / "arm2.urdf").write_text(ARM2)
    urdf = str(tmp_path / "arm2.urdf")
    systems = {
        "arm_2": lambda: load_urdf_system(urdf, tip="tool"),
        "arm2_tree": lambda: load_urdf_tree_system(urdf, name="arm2_tree"),
        "planar_manipulator": lambda: load_mjcf_system(str(dm_control_suite() / "manipulator.xml"), tip="grasp"),
        "cheetah_legs": lambda: load_mjcf_tree_system(
            str(dm_control_suite() / "cheetah.xml"), base="torso", name="cheetah_legs"
        ),
    }
    quoted = [
        (page.name, name, int(n))
        for page in sorted(DOCS.glob("*.md"))
        for name, n in re.findall(r"robotgen: built (\w+) \((\d+) functions\)", page.read_text())
    ]
    assert len(quoted) >= 6, quoted
    counts = {}
    for page, name, n in quoted:
        if name not in counts:
            counts[name] = len(kernels_for(systems[name]() if name in systems else load_system(str(SPECS[name]))))
        assert n == counts[name], f"docs/{page}: built {name} ({n} functions), a build prints {counts[name]}"
    progress = re.search(r"printing (\d+) C functions\n.*\((\d+)/(\d+)\)", doc("cli.md"))
    assert int(progress.group(1)) == int(progress.group(3)) == counts["styx_high_ct"]


def test_cli_info_and_simulate_print_what_cli_md_shows(tmp_path, capsys):
    cli = doc("cli.md")
    assert main(["info", str(SPECS["puma560"])]) == 0
    shown = block_after(cli, "$ robotgen info specs/puma560.yaml", "")
    assert capsys.readouterr().out == shown
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    simulated = subprocess.run(
        [sys.executable, "-m", "robotgen", "simulate", str(SPECS["styx_high_ct"]), "-o", str(tmp_path), "-q"],
        capture_output=True,
        text=True,
        env=env,
    )  # its own process:
    assert simulated.returncode == 0, simulated.stderr  # it imports a styx_high_ct of its own
    printed = simulated.stdout.splitlines()
    shown = block_after(cli, "$ robotgen simulate specs/styx_high_ct.yaml -o sim", "").splitlines()
    assert printed[:-1] == shown[:-1]
    assert printed[-1] == shown[-1].replace("sim/", f"{tmp_path}/")
    rows = (tmp_path / "styx_high_ct.csv").read_text().splitlines()[:2]
    assert rows == block_after(cli, "Its columns are `t`, then").splitlines()


def test_python_api_snippets_print_what_they_say(modules):
    api = doc("python-api.md")
    first, _ = block_with(api, "puma560.inverse_dynamics(q, qd, qdd=np.zeros(6))")
    q, qd = np.array([0.0, 0.5, -0.3, 0.0, 0.4, 0.0]), np.full(6, 0.1)
    assert "q = np.array([0.0, 0.5, -0.3, 0.0, 0.4, 0.0])" in first and "qd = np.full(6, 0.1)" in first
    tau = modules["puma560"].inverse_dynamics(q, qd, qdd=np.zeros(6))
    assert numbers(first.split("# array(")[1]) == [float(f"{v:.8f}") for v in tau]

    loop, _ = block_with(api, "kp, kv, dt = 400.0, 40.0, 1e-3")
    said = loop.split("\n# ")[-1].strip()
    assert run(loop)[0].strip() == said

    rates, after = block_with(api, "qd, error, w, cond = arm.position_step(q, target)")
    assert run(rates)[0] == after[after.index("```\n") + 4 :].split("```")[0]

    step, _ = block_with(api, "hand.servo_step(theta, theta_dot")
    names = run(step)[1]
    hand, theta, v, tau, v_dot = (names[k] for k in ("hand", "theta", "v", "tau", "v_dot"))
    residual, forces = hand.constraint_residual(theta).max(), hand.plant_internal_forces(theta, v, tau)
    said = step.split("# tau = [")[1]
    assert numbers(said.split("]")[0]) == [float(f"{v:.5f}") for v in tau]
    assert f"hand.constraint_residual(theta).max() = {residual:.1e}" in said
    assert np.allclose(v_dot, [1, 0, 0], atol=1e-12) and "v_dot = [1, 0, 0]" in said
    assert f"hand.plant_internal_forces(theta, v, tau) = {np.array2string(forces)}" in said

    adaptive, _ = block_with(api, "c = arm.AdaptiveController(rmac_forgetting=0.99)")
    names = run(adaptive.replace("c.reset()", "tau_0, size = tau.copy(), c.state.size; c.reset()"))[1]
    tau, size = names["tau_0"], names["size"]
    said = numbers(adaptive.split("# tau = [")[1].split("]")[0])
    assert said == [float(f"{v:.4g}") if abs(v) > 1e-12 else 0.0 for v in tau]
    assert f"a copy of the whole raw state ({size} numbers" in " ".join(api.split())


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_c_api_program_prints_what_c_api_md_shows(modules, tmp_path):
    """app.c of c-api.md, compiled against the emitted C; the Python figure beside it; and
    what the link says without -lm."""
    api = doc("c-api.md")
    source = block_after(api, "`app.c` computes")
    (tmp_path / "app.c").write_text(source)
    out = Path(modules["puma560"].__file__).parent
    common = [
        "gcc",
        "-std=c99",
        f"-I{out}",
        str(tmp_path / "app.c"),
        str(out / "puma560.c"),
        "-o",
        str(tmp_path / "app"),
    ]
    subprocess.run([*common, "-lm"], check=True, capture_output=True)
    printed = subprocess.run([str(tmp_path / "app")], capture_output=True, text=True, check=True).stdout
    shown = block_after(api, "**Straight from the output directory**", "```console").splitlines()[1:]
    assert printed.splitlines() == shown
    q = np.array([0.0, 0.5, -0.3, 0.0, 0.4, 0.0])
    assert f"`puma560.mass(q)[1, 2]` is\n`{float(modules['puma560'].mass(q)[1, 2])!r}`" in api
    unlinked = subprocess.run(common, capture_output=True, text=True)
    missing = sorted(set(re.findall(r"undefined reference to `(\w+)'", unlinked.stderr)))
    said = re.search(r"Without `-lm`, the link fails with `undefined reference to '(\w+)'` \(and (.*)\)\.", api)
    assert [said.group(1), *re.findall(r"`(\w+)`", said.group(2))] == sorted(missing, key=said.group(0).index)


def test_spec_format_quotes_what_info_prints(capsys):
    """The weight rule's closed loop and stages 2 and 3 of Table 1, as `robotgen info` prints them."""
    assert main(["info", str(SPECS["puma560_rmac"])]) == 0
    printed = capsys.readouterr().out
    text = " ".join(doc("spec-format.md").split())
    loop = re.search(r"spectral radius (\S+) .*slowest time constant (\S+) ms", printed)
    assert f"radius {loop.group(1)}, a slowest time constant of {loop.group(2)} ms" in text
    feedforward = printed.split("    feedforward\n")[1].split("    feedback\n")[0]
    rows = {
        m.group(1): m.groups()[1:]
        for m in re.finditer(r"^\s+(\d) .*?\s(\d+)\s+(\d+)\s+(\d+)\s+(\d+)\s+\d+\s+\d+", feedforward, re.M)
    }
    stage2, stage3 = rows["2"], rows["3"]
    assert (
        f"stage 2 costs {stage2[2]} multiplications and {stage2[3]} additions (the paper {stage2[0]} and {stage2[1]};"
    ) in text
    assert f"stage 3 adds {stage3[2]} and {stage3[3]} (the paper {stage3[0]} and {stage3[1]}," in text
