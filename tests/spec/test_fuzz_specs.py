"""Random mutations of the example specs: whatever `robotgen check` is handed, it answers
with located errors (FILE:LINE:COL) or accepts the spec, never anything else.

A few hundred mutants run by default; ROBOTGEN_FUZZ_CASES=10000 runs more (same seed, so a
failure reproduces). The mutants are dumped back to YAML text, so the reader sees them as a
user's file."""
from __future__ import annotations

import io
import os
import random
import re
from pathlib import Path

import pytest
from ruamel.yaml import YAML

from robotgen.errors import UserErrors
from robotgen.frontend import load_system

SPECS = sorted((Path(__file__).resolve().parents[2] / "specs").glob("*.yaml"))
CASES = int(os.environ.get("ROBOTGEN_FUZZ_CASES", "400"))
VALUES = [None, True, False, 0, -1, 1, 2, 7, 1e308, -1e308, 1e-320, "nan", "inf", "-inf", "1/0", "10^400",
          "exp(1000)", "x", "", " ", "q1", "__import__('os')", "a.b", "[1]", "pi", "sqrt(-1)", [], {}, [1, 2, 3],
          [[1, 2], [3]], {"a": 1}, {"runtime": "x"}, "é", "ｍ2", "a" * 300, [None], [[None]], -0.0, 3.5]


def paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for key, value in node.items():
            yield from paths(value, prefix + (key,))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from paths(value, prefix + (i,))


def mutate(data, rng: random.Random):
    """One to three random edits: replace a value, delete a key or item, add an unknown key,
    duplicate or shorten a list, turn a value into a list of it."""
    for _ in range(rng.randint(1, 3)):
        targets = [p for p in paths(data) if p]
        if not targets:
            return data
        path = rng.choice(targets)
        parent = data
        for key in path[:-1]:
            parent = parent[key]
        key = path[-1]
        kind = rng.randrange(6)
        if kind == 0 or not isinstance(parent, (dict, list)):
            parent[key] = rng.choice(VALUES)
        elif kind == 1:
            del parent[key]
        elif kind == 2 and isinstance(parent, dict):
            parent[rng.choice(["extra", "law", "kp", "joints", "M", "root", "1"])] = rng.choice(VALUES)
        elif kind == 3 and isinstance(parent[key], list):
            parent[key] = parent[key] + parent[key][:1]
        elif kind == 4 and isinstance(parent[key], list):
            parent[key] = parent[key][:-1]
        else:
            parent[key] = [parent[key]]
    return data


def plain(node):
    if isinstance(node, dict):
        return {str(k): plain(v) for k, v in node.items()}
    if isinstance(node, list):
        return [plain(v) for v in node]
    return node


@pytest.mark.parametrize("seed", range(4))
def test_mutants_get_located_errors_or_pass(tmp_path, seed):
    rng = random.Random(seed)
    yaml = YAML(typ="safe", pure=True)
    sources = [plain(yaml.load(spec.read_text())) for spec in SPECS]
    failures = []
    for case in range(CASES // 4):
        data = mutate(plain(rng.choice(sources)), rng)
        text = io.StringIO()
        yaml.dump(data, text)
        path = tmp_path / f"m{case}.yaml"
        path.write_text(text.getvalue())
        try:
            load_system(str(path))
        except UserErrors as errors:
            located = re.compile(re.escape(str(path)) + r"(:\d+:\d+)?: \S")  # a file-level error has no line
            bad = [str(e) for e in errors.errors if not located.match(str(e))]
            if bad:
                failures.append((case, bad[0]))
        except Exception as error:  # noqa: BLE001 - what this test hunts
            failures.append((case, f"{type(error).__name__}: {error}", text.getvalue()[:2000]))
    assert not failures, failures[:3]
