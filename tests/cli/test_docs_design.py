"""docs/ARCHITECTURE.md is the design: every module named, each rule's threshold the one the
code uses, and no measurement (those go to docs/performance-log.md, dated)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from robotgen.emit.c_kernel import FILL_RUN
from robotgen.emit.context import COMPILE_PARTS, COMPILE_PARTS_ABOVE, LOOP_STATEMENT_COST
from robotgen.emit.issue_order import ISSUE_WIDTH
from robotgen.model.snap import SNAP_ULPS
from robotgen.symbolic.dynamics_derivatives import DERIVATIVE_LOOPS_ABOVE_OPS, RECURSION_LOOPS_WITHIN
from robotgen.symbolic.rigid_body.chain import AD_CORIOLIS_MAX_DOF
from robotgen.symbolic.rigid_body.chain_loops import CORIOLIS_LOOPS_ABOVE_OPS, LOOPS_ABOVE_DOF, LOOPS_ABOVE_OPS

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"


def flat(text: str) -> str:
    return " ".join(text.split())


# what a measurement looks like: a time, a benchmark's vocabulary, a before -> after
MEASUREMENT = [
    r"\b\d[\d.,-]*\s*(ns|us|ms|s)\b",
    r"\bZen\b",
    r"A/B",
    r"alternating",
    r"\b[Mm]easured\b",
    r"\d\s*->\s*\d",
    r"\bfrom \d[\d.]* to \d",
    r"\d[\d.]* against \d",
    r"\d+(\.\d+)? times (faster|slower)",
]


def test_architecture_quotes_no_measurement():
    text = flat((DOCS / "ARCHITECTURE.md").read_text())
    found = [m.group(0) for pattern in MEASUREMENT for m in re.finditer(pattern, text)]
    assert not found, f"measurements belong in docs/performance-log.md: {found}"


def test_performance_log_entries_are_dated():
    """Each entry ("**topic** (date, commit ...)") says when it was recorded."""
    log = flat((DOCS / "performance-log.md").read_text())
    entries = re.findall(r"\*\*[^*]+\*\* \(([^)]*)\)", log)
    assert len(entries) >= 20, entries
    undated = [e for e in entries if not re.match(r"20\d\d-\d\d-\d\d, [0-9a-f]{7}\b", e)]
    assert not undated, undated


@pytest.mark.parametrize(
    "said",
    [
        f"past {LOOPS_ABOVE_DOF} joints: M, C",
        f"past {LOOPS_ABOVE_OPS} operations: loops",
        f"The Coriolis matrix past {CORIOLIS_LOOPS_ABOVE_OPS} operations: loops",
        f"d tau/dqd past {DERIVATIVE_LOOPS_ABOVE_OPS} operations: the recursion's loops",
        f"Forward dynamics' derivatives past {DERIVATIVE_LOOPS_ABOVE_OPS} operations",
        f"at most {round(100 * (RECURSION_LOOPS_WITHIN - 1))} % more operations than the sweeps",
        f"`AD_CORIOLIS_MAX_DOF` = {AD_CORIOLIS_MAX_DOF} joints",
        f"within {SNAP_ULPS} units in the last place",
        f"fewer than {ISSUE_WIDTH} operations per modelled cycle",
        f"up to {ISSUE_WIDTH} ready steps",
        f"past {COMPILE_PARTS_ABOVE:,} characters is compiled in {COMPILE_PARTS} parts".replace(",", " "),
        f"those in loop bodies counted {LOOP_STATEMENT_COST} times",
        f"A run of {FILL_RUN} or more stores of one value",
    ],
)
def test_architecture_states_the_thresholds_the_code_uses(said):
    assert said in flat((DOCS / "ARCHITECTURE.md").read_text())


def test_architecture_names_every_module():
    text = (DOCS / "ARCHITECTURE.md").read_text()
    table = text[text.index("## Every module") :].split("\n## ")[0]
    named = set(re.findall(r"`(?:[\w/]+/)?(\w+\.py)`", table))
    modules = {p.name for p in (ROOT / "robotgen").rglob("*.py") if p.name != "__init__.py"}
    assert not modules - named, f"modules missing from ARCHITECTURE.md's table: {sorted(modules - named)}"
