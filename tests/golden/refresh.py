"""Refresh tests/golden/ from specs/ (`make golden`): every spec's manifest.json, which pins
each emitted file by its sha256, and the whole output of the small specs in FULL, for
reading in review. tests/test_golden.py checks that a fresh build matches both."""
from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

GOLDEN = Path(__file__).resolve().parent
ROOT = GOLDEN.parent.parent
FULL = ("two_link", "styx_finger")  # kept whole: a chain and a formulas leaf, small enough to read
COMPILED = (".so", ".pyd", ".o", ".a")
STAMP = ".robotgen-build"


def emitted(directory: Path) -> dict[str, bytes]:
    """The emitted files of a build directory (not compiled objects, not the cache stamp)."""
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())
            if p.is_file() and not p.name.endswith(COMPILED) and p.name != STAMP}


def golden_files(name: str, build: Path) -> dict[str, bytes]:
    files = emitted(build)
    return files if name in FULL else {"manifest.json": files["manifest.json"]}


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from robotgen.cli import main as robotgen

    specs = sorted((ROOT / "specs").glob("*.yaml"))
    with tempfile.TemporaryDirectory() as tmp:
        for spec in specs:
            out = Path(tmp) / spec.stem
            if robotgen(["build", str(spec), "-o", str(out), "--no-compile", "-q"]) != 0:
                return 1
            name = next(out.glob("*.h")).stem
            target = GOLDEN / name
            shutil.rmtree(target, ignore_errors=True)
            target.mkdir()
            for file, data in golden_files(name, out).items():
                (target / file).write_bytes(data)
            print(f"golden: {target.relative_to(ROOT)} ({len(list(target.iterdir()))} file(s))")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
