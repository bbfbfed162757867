"""The floors of robotgen (docs/ARCHITECTURE.md): every import, at module level, inside a
function or under TYPE_CHECKING, goes to the same floor or one below. Read from the source
with ast, so an import that runs only sometimes is checked too."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "robotgen"

# lowest first; a module belongs to the longest prefix listed. The tree laws
# (symbolic.control) sit below the root laws, which build on the whole tree's graphs.
FLOORS = (
    (
        "robotgen",
        "robotgen.errors",
        "robotgen.numeric",
        "robotgen.progress",
        "robotgen.interrupts",
        "robotgen.documentation",
    ),
    ("robotgen.model",),
    ("robotgen.frontend", "robotgen.symbolic"),
    ("robotgen.symbolic.root_laws", "robotgen.symbolic.module", "robotgen.symbolic.__init__"),
    ("robotgen.output_files", "robotgen.emit"),
    ("robotgen.simulation",),
    ("robotgen.cli", "robotgen.__main__"),
)
# pairs on one floor that must not import each other either: (importer prefix, imported prefix)
APART = (("robotgen.frontend", "robotgen.symbolic"), ("robotgen.symbolic", "robotgen.frontend"))


def floor(module: str) -> int:
    best, found = -1, None
    for level, prefixes in enumerate(FLOORS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best:
                best, found = len(prefix), level
    assert found is not None, module
    return found


def module_name(path: Path) -> str:
    """robotgen.a.b for robotgen/a/b.py; robotgen.a.__init__ for a package's own file, which
    may gather what its modules offer (robotgen.symbolic's does)."""
    return ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts)


def imports(path: Path, here: str) -> list[tuple[int, str]]:
    """(line, module) of every import of robotgen in the file of module ``here``, wherever it
    is written."""
    package = here.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            # ``from robotgen.simulation import hand`` imports the module robotgen.simulation.hand
            out += [
                (
                    node.lineno,
                    f"{base}.{a.name}"
                    if (PACKAGE.parent / base.replace(".", "/") / a.name).exists()
                    or (PACKAGE.parent / f"{base.replace('.', '/')}/{a.name}.py").exists()
                    else base,
                )
                for a in node.names
            ]
    return [(line, name) for line, name in out if name == "robotgen" or name.startswith("robotgen.")]


def violations(files: dict[Path, str] | None = None) -> list[str]:
    """Every import up a floor (or across APART) in ``files`` (path: module name; default
    every module of robotgen)."""
    found = []
    files = files or {path: module_name(path) for path in sorted(PACKAGE.rglob("*.py"))}
    for path, here in files.items():
        for line, target in imports(path, here):
            upward = floor(target) > floor(here)
            sideways = any(
                here.startswith(a)
                and target.startswith(b)
                and not target.startswith(here)
                and floor(here) == floor(target)
                for a, b in APART
            )
            if upward or sideways:
                found.append(f"{path.name}:{line}: {here} imports {target}")
    return found


def test_no_import_goes_up_a_floor():
    assert violations() == []


def test_the_check_sees_imports_up_and_across(tmp_path):
    """Imports of the CLI inside a function, of the simulation under TYPE_CHECKING and of a
    root law, relative, from a tree law's module are found; one down is not."""
    probe = tmp_path / "probe.py"
    probe.write_text(
        "from typing import TYPE_CHECKING\n\nfrom robotgen.numeric import exact\n\n"
        "if TYPE_CHECKING:\n    from robotgen.simulation.tree import Result\n\n\n"
        "def f():\n    from robotgen import cli\n    return cli\n"
    )
    assert violations({probe: "robotgen.model.probe"}) == [
        "probe.py:6: robotgen.model.probe imports robotgen.simulation.tree",
        "probe.py:10: robotgen.model.probe imports robotgen.cli",
    ]
    probe.write_text("from ..root_laws import law\nfrom ...frontend.collector import Collector\n")
    assert violations({probe: "robotgen.symbolic.control.probe"}) == [
        "probe.py:1: robotgen.symbolic.control.probe imports robotgen.symbolic.root_laws.law",
        "probe.py:2: robotgen.symbolic.control.probe imports robotgen.frontend.collector",
    ]


def import_cycle(files: dict[Path, str]) -> list[str]:
    """One cycle of imports among the modules ``files`` (path: module name), TYPE_CHECKING and
    function-level imports included, as the modules around it (the first repeated at the end);
    [] when there is none. An import of a package names its __init__."""
    names = set(files.values())
    graph = {
        here: sorted({t if t in names else f"{t}.__init__" for _, t in imports(path, here)} & names - {here})
        for path, here in files.items()
    }
    state: dict[str, int] = {}  # 1 on the current path, 2 finished
    path: list[str] = []

    def visit(module: str) -> list[str]:
        state[module] = 1
        path.append(module)
        for target in graph[module]:
            if state.get(target) == 1:
                return path[path.index(target) :] + [target]
            if target not in state and (cycle := visit(target)):
                return cycle
        state[module] = 2
        path.pop()
        return []

    for module in sorted(graph):
        if module not in state and (cycle := visit(module)):
            return cycle
    return []


def test_emit_has_no_import_cycle():
    """No module of robotgen/emit imports one that imports it back, even only for types: the
    views several modules share sit in emit/views.py, below them all."""
    emit = PACKAGE / "emit"
    assert import_cycle({path: module_name(path) for path in sorted(emit.rglob("*.py"))}) == []


def test_the_cycle_check_sees_a_type_checking_cycle(tmp_path):
    """Two modules importing each other, one only under TYPE_CHECKING, make a cycle; a third
    importing one of them from outside does not join it."""
    (tmp_path / "a.py").write_text("from robotgen.emit.b import B\n")
    (tmp_path / "b.py").write_text(
        "from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n    from robotgen.emit.a import A\n"
    )
    (tmp_path / "c.py").write_text("from robotgen.emit.a import A\n")
    files = {tmp_path / f"{m}.py": f"robotgen.emit.{m}" for m in "abc"}
    assert import_cycle(files) == ["robotgen.emit.a", "robotgen.emit.b", "robotgen.emit.a"]
    (tmp_path / "b.py").write_text("B = 1\n")
    assert import_cycle(files) == []
