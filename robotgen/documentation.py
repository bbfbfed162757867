"""The documentation pages (the repository's docs/*.md), which a wheel installs as
robotgen/docs: what `robotgen docs [PAGE]` lists and prints, and what error messages point
to, so that a hint names what an installed user has rather than a path in a clone."""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent
# An installed robotgen has them as robotgen/docs; a source checkout keeps docs/ beside robotgen/.
_DIRS = (_PACKAGE / "docs", _PACKAGE.parent / "docs")


def directory() -> Path | None:
    """Where the pages are, or None (a broken installation)."""
    return next((d for d in _DIRS if (d / "cli.md").is_file()), None)


def pages() -> dict[str, tuple[Path, str]]:
    """Page name (the file's stem) -> (its file, its title), in name order."""
    where = directory()
    if where is None:
        return {}
    out = {}
    for path in sorted(where.glob("*.md")):
        first = path.read_text(encoding="utf-8").split("\n", 1)[0]
        out[path.stem] = (path, first.lstrip("# ").replace("`", ""))
    return out


def hint(page: str, section: str = "") -> str:
    """How a message points to a page: "`robotgen docs spec-format`", with the section's name."""
    return f"`robotgen docs {page}`" + (f', "{section}"' if section else "")
