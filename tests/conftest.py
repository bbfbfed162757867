"""Shared fixtures: build a spec once per test session and import its generated module."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent
SPECS = ROOT / "specs"
ALL_SPECS = sorted(SPECS.glob("*.yaml"))


def _is_single_leaf(spec: Path) -> bool:
    with open(spec) as f:
        data = yaml.safe_load(f)
    return "define" in data["nodes"][data["root"]]


def _is_rate_controlled(spec: Path) -> bool:
    with open(spec) as f:
        data = yaml.safe_load(f)
    return data["nodes"][data["root"]].get("control", {}).get("law") == "resolved_rate"


# Specs whose root is one leaf robot: their module has the chain or formulas API (docs/python-api.md).
EXAMPLE_SPECS = [s for s in ALL_SPECS if _is_single_leaf(s)]
# Resolved-rate controllers of a chain (Whitney 1972): the chain's API plus rate_step etc.
RATE_SPECS = [s for s in ALL_SPECS if _is_rate_controlled(s)]
# Robot trees (ATTACH / CONTROL): per-node functions, servo_step, plant_*.
TREE_SPECS = [s for s in ALL_SPECS if not _is_single_leaf(s) and s not in RATE_SPECS]

# Make `import robotgen` and `import reference` work however pytest is started.
for p in (str(ROOT), str(Path(__file__).resolve().parent)):
    if p not in sys.path:
        sys.path.insert(0, p)


class ModuleBuilder:
    """Builds each spec once (cached by resolved path) into its own directory under the
    session's temporary directory and imports the module named by the spec's `name`."""

    def __init__(self, base: Path):
        self.base = base
        self.cache: dict[Path, object] = {}

    def __call__(self, spec_path) -> object:
        spec = Path(spec_path).resolve()
        if spec in self.cache:
            return self.cache[spec]
        from robotgen.cli import main

        with open(spec) as f:
            name = yaml.safe_load(f)["name"]
        out = self.base / f"{name}-{len(self.cache)}"
        status = main(["build", str(spec), "-o", str(out)])
        assert status == 0, f"robotgen build {spec} -o {out} exited with {status}"
        if name in sys.modules:
            # Two specs with one module name cannot both be imported in one process.
            loaded = Path(getattr(sys.modules[name], "__file__", "") or "")
            raise AssertionError(f"module {name!r} already imported from {loaded}; give the spec a unique name")
        sys.path.insert(0, str(out))
        try:
            importlib.invalidate_caches()
            module = importlib.import_module(name)
        finally:
            sys.path.remove(str(out))
        assert Path(module.__file__).resolve().is_relative_to(out.resolve()), module.__file__
        self.cache[spec] = module
        return module


@pytest.fixture(scope="session")
def build_module(tmp_path_factory) -> ModuleBuilder:
    """build_module(spec_path) -> the imported generated module (built once per session)."""
    return ModuleBuilder(tmp_path_factory.mktemp("robotgen-build"))
