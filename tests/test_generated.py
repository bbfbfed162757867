"""generated/ is what robotgen emits for specs/, byte for byte: a fresh build of every
example spec equals the committed tree (so it never goes stale), and two builds are equal."""
from __future__ import annotations

from pathlib import Path

import pytest

from robotgen.cli import main

ROOT = Path(__file__).resolve().parent.parent
SPECS = sorted((ROOT / "specs").glob("*.yaml"))
COMPILED_SUFFIXES = (".so", ".pyd", ".o", ".a")
BUILD_STAMP = ".robotgen-build"  # the content-hash cache's key, not an emitted file


def emitted_files(directory: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())
            if p.is_file() and not p.name.endswith(COMPILED_SUFFIXES) and p.name != BUILD_STAMP}


@pytest.mark.parametrize("spec", SPECS, ids=[s.stem for s in SPECS])
def test_committed_output_equals_a_fresh_build(spec, tmp_path):
    first, second = tmp_path / "first", tmp_path / "second"
    assert main(["build", str(spec), "-o", str(first), "--no-compile"]) == 0
    assert main(["build", str(spec), "-o", str(second), "--no-compile"]) == 0
    fresh = emitted_files(first)
    assert fresh == emitted_files(second), "two builds of one spec differ"
    name = next(first.glob("*.h")).stem
    committed = ROOT / "generated" / name
    assert committed.is_dir(), f"generated/{name} is missing: run `make generated`"
    stored = emitted_files(committed)
    assert sorted(stored) == sorted(fresh), "file sets differ: run `make generated`"
    stale = [f for f in fresh if fresh[f] != stored[f]]
    assert not stale, f"generated/{name}: {stale} differ from a fresh build: run `make generated`"
