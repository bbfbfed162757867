"""`make lint` is `ruff check .` under pyproject.toml's rules: D1 holds on robotgen/ (a public
function without a docstring fails), not on tests/, bench/ or examples/, and the tree passes."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
UNDOCUMENTED = "def public(x):\n    return x\n\n\nclass Thing:\n    def method(self):\n        return 1\n"


def ruff(*args: str, source: str | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", *args], input=source,
                          capture_output=True, text=True, cwd=ROOT)


@pytest.mark.parametrize("where, codes", [
    ("robotgen/emit/probe.py", {"D100", "D101", "D102", "D103"}),
    ("robotgen/symbolic/rigid_body/probe.py", {"D100", "D101", "D102", "D103"}),
    ("tests/cli/probe.py", set()),
    ("bench/probe.py", set()),
    ("examples/probe.py", set()),
])
def test_d1_holds_on_robotgen_alone(where, codes):
    found = ruff("--output-format", "concise", "--stdin-filename", where, "-", source=UNDOCUMENTED)
    reported = {line.split()[1] for line in found.stdout.splitlines() if line.startswith(where)}
    assert reported == codes, found.stdout
    assert found.returncode == (1 if codes else 0)


def test_the_tree_passes_lint():
    checked = ruff(".")
    assert checked.returncode == 0, checked.stdout[-3000:]
