"""Error hints point to what an installed user has: `robotgen docs PAGE` (the pages a wheel
installs as robotgen/docs) or `robotgen --help`, never to docs/ or examples/ paths that only
a clone of the repository has."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
import yaml

from robotgen import documentation
from robotgen.cli import main

ROOT = Path(__file__).resolve().parents[2]
CLONE_ONLY = re.compile(r"\b(docs|examples)/")


def strings_outside_docstrings(path: Path) -> list[tuple[int, str]]:
    """Every string constant of a module (f-strings' parts included) that is not a docstring."""
    tree = ast.parse(path.read_text())
    docstrings = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                docstrings.add(id(first.value))
    return [
        (node.lineno, node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings
    ]


def test_no_message_names_a_path_of_the_clone():
    found = [
        f"{path.relative_to(ROOT)}:{line}: {text!r}"
        for path in sorted((ROOT / "robotgen").rglob("*.py"))
        for line, text in strings_outside_docstrings(path)
        if CLONE_ONLY.search(text)
    ]
    found += [
        f"{path.relative_to(ROOT)}: {line.strip()}"
        for path in sorted((ROOT / "templates").glob("*.jinja"))
        for line in path.read_text().splitlines()
        if CLONE_ONLY.search(line)
    ]
    assert found == []


def test_every_page_a_hint_names_exists():
    pages = documentation.pages()
    named = {
        m.group(1)
        for path in (ROOT / "robotgen").rglob("*.py")
        for m in re.finditer(r"hint\(['\"]([\w-]+)['\"]", path.read_text())
    }
    assert named and named <= set(pages), named - set(pages)
    assert {"cli", "spec-format", "python-api", "c-api"} <= set(pages)


def test_robotgen_docs_lists_and_prints_the_pages(capsys):
    assert main(["docs"]) == 0
    listed = capsys.readouterr().out
    assert "  spec-format          robotgen spec format, version 1\n" in listed
    shown = (ROOT / "docs" / "cli.md").read_text().split("$ robotgen docs\n")[1].split("$ ")[0]
    assert shown.splitlines()[1:] == listed.splitlines()[1:]  # cli.md shows what it prints (but the path)
    assert main(["docs", "python-api"]) == 0
    assert capsys.readouterr().out == (ROOT / "docs" / "python-api.md").read_text()
    assert main(["docs", "nope"]) == 2
    assert "no page 'nope'; the pages are ARCHITECTURE, c-api, cli" in capsys.readouterr().err
    assert main(["--help"]) == 0
    assert "Documentation: robotgen docs" in " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize(
    "spec, says",
    [
        ("puma560", 'a chain\'s module closes a loop in a few lines of Python: `robotgen docs python-api`, "A chain"'),
        (
            "puma560_rmrc_no_lqr",
            'integrate its rate_step / position_step (`robotgen docs python-api`, "Resolved-rate controllers"',
        ),
    ],
)
def test_simulate_points_to_the_installed_docs(capsys, tmp_path, spec, says):
    path = ROOT / "specs" / f"{spec}.yaml"
    if spec == "puma560_rmrc_no_lqr":  # a resolved-rate controller without a regulator to simulate
        data = yaml.safe_load((ROOT / "specs" / "puma560_rmrc.yaml").read_text())
        del data["nodes"]["rmrc"]["control"]["resolved_rate"]["lqr"]
        data.pop("simulation", None)
        path = tmp_path / "rmrc.yaml"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
    assert main(["simulate", str(path)]) == 2
    assert says in capsys.readouterr().err
