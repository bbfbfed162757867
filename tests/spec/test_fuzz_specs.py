"""Mutations of the example specs, drawn by Hypothesis: whatever `robotgen check` or `robotgen
build` is handed, it answers exit 0, or exit 1 with located errors (FILE:LINE:COL) and nothing
written; never a traceback, never an internal error.

400 mutants run in `make test`: 300 checked, and 100 of the chain specs, built too where check
accepts them; `pytest -m slow` runs 10^4 (derandomised, so a failure reproduces; Hypothesis
shrinks it to the smallest mutant that fails). The mutants are
dumped back to YAML text, so the reader sees them as a user's file."""

from __future__ import annotations

import contextlib
import copy
import io
import re
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from ruamel.yaml import YAML

from robotgen.cli import main

SPECS = sorted((Path(__file__).resolve().parents[2] / "specs").glob("*.yaml"))
# values that broke robotgen once (overflow, injection, look-alikes, shapes), then anything
VALUES = st.one_of(
    st.sampled_from(
        [
            None,
            True,
            False,
            0,
            -1,
            1,
            2,
            7,
            1e308,
            -1e308,
            1e-320,
            "nan",
            "inf",
            "-inf",
            "1/0",
            "10^400",
            "exp(1000)",
            "x",
            "",
            " ",
            "q1",
            "__import__('os')",
            "a.b",
            "[1]",
            "pi",
            "sqrt(-1)",
            [],
            {},
            [1, 2, 3],
            [[1, 2], [3]],
            {"a": 1},
            {"runtime": "x"},
            "é",
            "ｍ2",
            "a" * 300,
            [None],
            [[None]],
            -0.0,
            3.5,
            "int",
            "math",
            "import",
            "x\n",
            "(" * 200 + "1" + ")" * 200,
            "2^2^2^2^2",
            "lambda: 1",
            "[x for x in q]",
            "q1.real",
        ]
    ),
    st.floats(),
    st.integers(),
    st.text(max_size=12),
    st.lists(st.floats(-10, 10), max_size=4),
)
KEYS = st.sampled_from(["extra", "law", "kp", "kd", "joints", "M", "root", "1", "name", "runtime", "tip"])


def _plain(node):
    if isinstance(node, dict):
        return {str(k): _plain(v) for k, v in node.items()}
    if isinstance(node, list):
        return [_plain(v) for v in node]
    return node


_yaml = YAML(typ="safe", pure=True)
SOURCES = [_plain(_yaml.load(spec.read_text())) for spec in SPECS]
# the specs whose graphs build in well under a second (the chains), for the build fuzzer
CHAINS = [s for spec, s in zip(SPECS, SOURCES) if not spec.stem.startswith(("styx", "tripod"))]


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _paths(value, prefix + (key,))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from _paths(value, prefix + (i,))


@st.composite
def mutants(draw, sources=SOURCES) -> str:
    """One to three edits of an example spec: replace a value, delete a key or item, add a
    key, duplicate or shorten a list, wrap a value in a list; the YAML text of the result."""
    data = copy.deepcopy(draw(st.sampled_from(sources)))
    for _ in range(draw(st.integers(1, 3))):
        targets = [p for p in _paths(data) if p]
        if not targets:
            break
        path = draw(st.sampled_from(targets))
        parent = data
        for key in path[:-1]:
            parent = parent[key]
        key = path[-1]
        kind = draw(st.integers(0, 5))
        if kind == 1:
            del parent[key]
        elif kind == 2 and isinstance(parent, dict):
            parent[draw(KEYS)] = copy.deepcopy(draw(VALUES))
        elif kind == 3 and isinstance(parent[key], list):
            parent[key] = parent[key] + parent[key][:1]
        elif kind == 4 and isinstance(parent[key], list):
            parent[key] = parent[key][:-1]
        elif kind == 5:
            parent[key] = [parent[key]]
        else:
            parent[key] = copy.deepcopy(draw(VALUES))  # the edits below must not change VALUES
    text = io.StringIO()
    _yaml.dump(data, text)
    return text.getvalue()


def answer(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        status = main(argv)
    return status, err.getvalue()


def assert_a_users_answer(text: str, build: bool) -> None:
    """exit 0, or exit 1 with every message located in the mutant's file and nothing written."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "mutant.yaml"
        path.write_text(text)
        argv = (
            ["build", str(path), "-o", str(Path(tmp) / "out"), "--no-compile", "-q"] if build else ["check", str(path)]
        )
        status, err = answer(argv)
        located = re.compile(re.escape(str(path)) + r"(:\d+:\d+)?: \S")  # a file-level error has no line
        assert status in (0, 1) and "Traceback" not in err and "internal error" not in err, (status, err)
        if status == 1:
            lines = [line for line in err.splitlines() if line.strip()]
            assert lines and all(located.match(line) or line.startswith(" ") for line in lines), err
            assert not (Path(tmp) / "out").exists()


FUZZ = dict(deadline=None, database=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])


@settings(max_examples=300, **FUZZ)
@given(mutants())
def test_mutants_get_located_errors_or_pass(text):
    assert_a_users_answer(text, build=False)


@pytest.mark.slow
@settings(max_examples=10_000, **FUZZ)
@given(mutants())
def test_ten_thousand_mutants(text):
    assert_a_users_answer(text, build=False)


@settings(max_examples=100, **FUZZ)
@given(mutants(CHAINS))
def test_mutants_that_check_accepts_also_build(text):
    """`check` and `build` read a spec the same way: a mutant check accepts builds, one it
    refuses is refused by build with nothing written."""
    assert_a_users_answer(text, build=True)
