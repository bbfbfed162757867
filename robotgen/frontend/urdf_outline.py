"""`robotgen info ROBOT.urdf` without --tip: the file's links as a tree, each with the joint
that carries it and that joint's type, so that a user can choose a tip (or a base)."""

from __future__ import annotations

from pathlib import Path

from robotgen.frontend.urdf import UrdfFile

_MOVABLE = ("revolute", "continuous", "prismatic")


def outline(f: UrdfFile, base: str | None = None) -> str:
    """The links below ``base`` (default: the root link), depth first in file order, two
    spaces per level; beside each, its joint's name and type (a mimic joint names the joint
    it follows)."""
    start = f.known_link("base", base) if base is not None else f.root_link
    rows: list[tuple[str, str, str]] = []
    stack = [(start, 0)]
    while stack:
        link, depth = stack.pop()
        j = f.joints.get(link) if link != start else None
        if j is None:
            rows.append(("  " * depth + link, "", ""))
        else:
            mimic = j.find("mimic")
            kind = j.attrib["type"] + (f", mimics {mimic.attrib.get('joint', '?')}" if mimic is not None else "")
            rows.append(("  " * depth + link, j.attrib["name"], kind))
        stack.extend((child, depth + 1) for child in reversed(f.children_of.get(link, [])))
    below = [f.joints[r[0].strip()] for r in rows[1:]]
    movable = sum(j.attrib["type"] in _MOVABLE for j in below)
    name = f.root.attrib.get("name", Path(f.r.path).stem)
    head = (
        f"{name} ({Path(f.r.path).name}): {len(rows)} links, {len(below)} joints below '{start}', {movable} of "
        f"them movable; each link with the joint that carries it"
    )
    width = max(len(r[0]) for r in rows) + 2
    joint_width = max(len(r[1]) for r in rows) + 2
    lines = [head] + [f"{r[0]:{width}}{r[1]:{joint_width}}{r[2]}".rstrip() for r in rows]
    coupled = " and the joints <mimic> couples to them" if any(j.find("mimic") is not None for j in below) else ""
    lines.append(
        f"a chain: --tip LINK (the movable joints from '{start}' to LINK{coupled}; the others locked at "
        "q = 0); every movable joint: --tree"
    )
    return "\n".join(lines)
