"""Specs built to hurt the reader: nesting deep enough to exhaust a recursive parser, aliases
that stand for exponentially many values, files too large to be a spec. Each gets a located
error and exit status 1 in bounded time, and nothing is built."""

from __future__ import annotations

import os
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
    "flow lists 5000 deep": (
        HEAD + "nodes: " + "[" * 5000 + "]" * 5000 + "\n",
        4,
        7 + MAX_DEPTH + 1,
        f"nested deeper than the {MAX_DEPTH} levels",
    ),
    "flow maps 20000 deep": (
        HEAD + "nodes: " + "{a: " * 20000 + "1" + "}" * 20000 + "\n",
        4,
        8 + 4 * MAX_DEPTH,
        f"nested deeper than the {MAX_DEPTH} levels",
    ),
    "block maps 300 deep": (
        HEAD + "nodes:\n" + "".join("  " * (i + 1) + f"k{i}:\n" for i in range(300)),
        5 + 4 * MAX_DEPTH // 2,
        1,
        "indented 258 columns",
    ),
    "billion laughs": (laughs(9), 4, None, f"more than {MAX_VALUES} values"),
    "a flat list of too many values": (
        HEAD
        + "nodes: {a: {define: {formulas: {coordinates: [q], M: [[1]], N: ["
        + ", ".join(["0"] * (MAX_VALUES + 10))
        + "]}}}}\n",
        4,
        None,
        f"more than {MAX_VALUES}",
    ),
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
    result = subprocess.run(
        [sys.executable, "-m", "robotgen", "build", str(path), "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 1
    assert result.stderr.startswith(f"{path}:4:") and "Traceback" not in result.stderr
    assert not out.exists()


def test_specs_of_the_repository_are_far_inside_the_bounds():
    for spec in sorted((Path(__file__).resolve().parents[2] / "specs").glob("*.yaml")):
        load_system(str(spec))  # raises if a bound were too tight for a real spec


def _check(path: Path, *options: str) -> subprocess.CompletedProcess:
    """`robotgen check` in a process of its own, bounded: a FIFO used to block it forever and
    /dev/zero to fill its memory."""
    return subprocess.run(
        [sys.executable, "-m", "robotgen", "check", str(path), *options], capture_output=True, text=True, timeout=60
    )


@pytest.mark.parametrize("suffix, options, what", [(".yaml", (), "spec"), (".urdf", ("--tip", "l1"), "URDF file")])
@pytest.mark.parametrize("kind", ["/dev/zero", "/dev/urandom", "fifo", "directory"])
def test_special_files_are_refused_before_they_are_read(tmp_path, suffix, options, what, kind):
    path = tmp_path / f"robot{suffix}"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "directory":
        path.mkdir()
    else:
        path.symlink_to(kind)  # the suffix chooses the reader
    start = time.perf_counter()
    result = _check(path, *options)
    assert time.perf_counter() - start < 30
    named = {"fifo": "a FIFO (named pipe)", "directory": "a directory"}.get(kind, "a character device")
    assert (result.returncode, result.stderr) == (
        1,
        f"{path}:1:1: {what} is {named}; robotgen reads regular files only\n",
    )


def test_the_bound_is_checked_on_what_is_read(tmp_path):
    """The size stat gives is checked first, and the bytes read as well: a file whose size
    says 0 (a /proc file, one that grows while it is read) is cut off one byte past the bound."""
    from robotgen.errors import UserError
    from robotgen.frontend.input_file import read_input

    path = tmp_path / "spec.yaml"
    path.write_bytes(b"x" * 101)
    with pytest.raises(UserError, match="spec is 101 bytes; robotgen reads at most 100$"):
        read_input(str(path), 100, "spec")
    assert read_input(str(path), 101, "spec") == b"x" * 101
    if Path("/proc/self/maps").exists():
        assert os.stat("/proc/self/maps").st_size == 0
        with pytest.raises(UserError, match="is more than 100 bytes; robotgen reads at most 100$"):
            read_input("/proc/self/maps", 100, "spec")


@pytest.mark.parametrize(
    "value, column, words",
    [
        ("1" + "0" * 5000, 56, "an integer of 5001 digits; robotgen reads integers of at most 4300 digits"),
        ("-0x" + "f" * 6000, 56, "the integer (about 10^7224) is out of range"),  # base 16 has no digit limit
        ("1" + "0" * 400, 56, "the integer (about 10^400) is out of range"),
        ("2001-13-45", 56, "'2001-13-45' cannot be read: month must be in 1..12"),
    ],
)
def test_numbers_the_yaml_library_cannot_convert_are_located(tmp_path, value, column, words):
    path = tmp_path / "spec.yaml"
    path.write_text(HEAD + "nodes: {a: {define: {formulas: {coordinates: [q], M: [[" + value + "]]}}}}\n")
    with pytest.raises(UserErrors) as caught:
        load_system(str(path))
    (error,) = caught.value.errors
    assert (error.location.line, error.location.col) == (4, column), str(error)
    assert words in error.message, error.message


def flat(n: int) -> str:
    return HEAD + "nodes: {a: {define: {formulas: {coordinates: [q], M: [[1]], N: [" + ",".join(["1"] * n) + "]}}}}\n"


@pytest.mark.parametrize(
    "name, text, line",
    [
        ("a 0.96 MB flow list of 480,000 numbers", flat(480_000), 4),
        ("a block list of 400,000 empty items", HEAD + "nodes:\n" + "-\n" * 400_000, MAX_VALUES + 1),
        (
            "110,000 block mapping keys",
            HEAD + "nodes:\n" + "".join(f" {i:x}:\n" for i in range(110_000)),
            MAX_VALUES + 1,
        ),
    ],
)
def test_too_many_values_are_refused_while_the_text_is_read(tmp_path, name, text, line):
    """Before the YAML parser runs: it took 49-159 s and 0.7 GB to refuse the flow list."""
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    assert len(text) < MAX_BYTES
    start = time.perf_counter()
    with pytest.raises(UserErrors) as caught:
        load_system(str(path))
    assert time.perf_counter() - start < 1.0, name  # 0.1 s here; the parser would need over 2 s
    (error,) = caught.value.errors
    assert error.location.line == line and f"more than {MAX_VALUES} values" in error.message, str(error)


TRICKY = [
    HEAD + "doc: |\n" + "  - a: [1, 2]\n" * 50 + "nodes: {a: [1, 2, {b: c}], d: 'x, y: z'}  # e, f: g\n",
    HEAD + "nodes:\n  - - a: 1\n    - [1, 2,]\n  -\n  - 'x: - y'\n  - >-\n    - folded: [1, 2]\n  - {a: 1, b: [3]}\n",
    HEAD + 'nodes: {a: &x [1, 2, 3], b: *x, c: "q: 1, 2"}\nk: 12:30\nurl: http://x.org/a,b\n',
]


@pytest.mark.parametrize(
    "text", TRICKY + [s.read_text() for s in sorted((Path(__file__).resolve().parents[2] / "specs").glob("*.yaml"))]
)
def test_the_counted_entries_never_exceed_the_values(text):
    """The count that refuses a spec before parsing is a lower bound of the values the parser
    makes (the nodes of PyYAML's composed document that are not mapping keys, an alias's as often
    as it is used),
    so it never refuses a spec that holds at most MAX_VALUES values."""
    import yaml

    from robotgen.frontend.document import _check_bounds

    def values(node) -> int:
        if isinstance(node, yaml.MappingNode):
            return 1 + sum(values(v) for _, v in node.value)
        if isinstance(node, yaml.SequenceNode):
            return 1 + sum(values(v) for v in node.value)
        return 1

    counted = _check_bounds("x.yaml", text)
    assert 0 < counted <= values(yaml.compose(text)) - 1  # the root is not an entry
