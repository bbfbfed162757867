"""`make lint` is `ruff check .` under pyproject.toml's rules: D1 holds on robotgen/ (a public
function without a docstring fails), not on tests/, bench/ or examples/, and the tree passes;
then mypy on robotgen/ ([tool.mypy]), which the tree passes and which refuses reading a node's
fields through the DefineNode | AttachNode | ControlNode union without narrowing it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
UNDOCUMENTED = "def public(x):\n    return x\n\n\nclass Thing:\n    def method(self):\n        return 1\n"


def ruff(*args: str, source: str | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "ruff", "check", "--no-cache", *args],
        input=source,
        capture_output=True,
        text=True,
        cwd=ROOT,
    )


@pytest.mark.parametrize(
    "where, codes",
    [
        ("robotgen/emit/probe.py", {"D100", "D101", "D102", "D103"}),
        ("robotgen/symbolic/rigid_body/probe.py", {"D100", "D101", "D102", "D103"}),
        ("tests/cli/probe.py", set()),
        ("bench/probe.py", set()),
        ("examples/probe.py", set()),
    ],
)
def test_d1_holds_on_robotgen_alone(where, codes):
    found = ruff("--output-format", "concise", "--stdin-filename", where, "-", source=UNDOCUMENTED)
    reported = {line.split()[1] for line in found.stdout.splitlines() if line.startswith(where)}
    assert reported == codes, found.stdout
    assert found.returncode == (1 if codes else 0)


def test_the_tree_passes_lint():
    checked = ruff(".")
    assert checked.returncode == 0, checked.stdout[-3000:]


def mypy(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mypy", *args], capture_output=True, text=True, cwd=ROOT)


def test_the_tree_passes_mypy():
    checked = mypy()  # files = robotgen, from pyproject.toml
    assert checked.returncode == 0, checked.stdout[-3000:] + checked.stderr
    assert "no issues found" in checked.stdout and " 0 source files" not in checked.stdout, checked.stdout


@pytest.mark.parametrize(
    "body, error",
    [
        ("return system.root_node.robot", "union-attr"),  # a CONTROL node's field, read off the union
        ("return system.nodes[name].leaf", "union-attr"),  # a DEFINE node's
        ("return system.control(name).robot", None),  # narrowed by type: RobotSystem's typed accessors
        ("return system.leaf(name).nq", None),
        ("node = system.nodes[name]\n    return node.robot if isinstance(node, ControlNode) else name", None),
    ],
)
def test_mypy_holds_the_node_union_to_narrowing(body, error, tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text(
        "from robotgen.model.system import ControlNode, RobotSystem\n\n\n"
        f"def probe(system: RobotSystem, name: str) -> object:\n    {body}\n"
    )
    checked = mypy(str(probe))  # under pyproject.toml's settings, robotgen found from the repository root
    if error is None:
        assert checked.returncode == 0, checked.stdout
    else:
        assert checked.returncode == 1 and f"[{error}]" in checked.stdout, checked.stdout
