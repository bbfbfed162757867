"""Specs built to hurt the reader: nesting deep enough to exhaust a recursive parser, aliases
that stand for exponentially many values, files too large to be a spec. Each gets a located
error and exit status 1 in bounded time, and nothing is built."""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from robotgen.errors import UserErrors
from robotgen.frontend import load_system
from robotgen.frontend.document import MAX_BYTES, MAX_DEPTH, MAX_VALUES

HEAD = "robotgen: 1\nname: x\nroot: a\n"


def laughs(levels: int) -> str:
    lines = [HEAD.rstrip("\n"), "a0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]"]
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]")
    lines.append(f"nodes: {{a: {{define: {{chain: {{convention: joints, joints: *a{levels - 1}}}}}}}}}")
    return "\n".join(lines) + "\n"


CASES = {
    # name: (text, line, column, words the message must contain)
    "flow lists 5000 deep": (HEAD + "nodes: " + "[" * 5000 + "]" * 5000 + "\n", 4, 7 + MAX_DEPTH + 1,
                             f"nested deeper than the {MAX_DEPTH} levels"),
    "flow maps 20000 deep": (HEAD + "nodes: " + "{a: " * 20000 + "1" + "}" * 20000 + "\n", 4, 8 + 4 * MAX_DEPTH,
                             f"nested deeper than the {MAX_DEPTH} levels"),
    "block maps 300 deep": (HEAD + "nodes:\n" + "".join("  " * (i + 1) + f"k{i}:\n" for i in range(300)),
                             5 + 4 * MAX_DEPTH // 2, 1, "indented 258 columns"),
    "billion laughs": (laughs(9), 4, None, f"more than {MAX_VALUES} values"),
    "a flat list of too many values": (HEAD + "nodes: {a: {define: {formulas: {coordinates: [q], M: [[1]], N: ["
                                       + ", ".join(["0"] * (MAX_VALUES + 10)) + "]}}}}\n", 4, None, f"more than {MAX_VALUES}"),
}


@pytest.mark.parametrize("name", list(CASES))
def test_hostile_yaml_gets_a_located_error_in_bounded_time(tmp_path, name):
    text, line, column, words = CASES[name]
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    start = time.perf_counter()
    with pytest.raises(UserErrors) as caught:
        load_system(str(path))
    assert time.perf_counter() - start < 30  # a bound, not a speed test: the unbounded cases ran for minutes
    (error,) = caught.value.errors
    assert error.location.line == line and (column is None or error.location.col == column), str(error)
    assert words in error.message


def test_a_file_too_large_to_be_a_spec(tmp_path):
    path = tmp_path / "big.yaml"
    path.write_text(HEAD + "# " + "x" * MAX_BYTES + "\n")
    with pytest.raises(UserErrors, match=f"at most {MAX_BYTES}"):
        load_system(str(path))


def test_the_cli_answers_with_exit_1_and_writes_nothing(tmp_path):
    path = tmp_path / "spec.yaml"
    path.write_text(CASES["flow lists 5000 deep"][0])
    out = tmp_path / "out"
    result = subprocess.run([sys.executable, "-m", "robotgen", "build", str(path), "-o", str(out)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 1
    assert result.stderr.startswith(f"{path}:4:") and "Traceback" not in result.stderr
    assert not out.exists()


def test_specs_of_the_repository_are_far_inside_the_bounds():
    for spec in sorted((Path(__file__).resolve().parents[2] / "specs").glob("*.yaml")):
        load_system(str(spec))  # raises if a bound were too tight for a real spec
