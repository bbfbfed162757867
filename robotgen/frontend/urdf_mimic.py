"""URDF <mimic>: a joint that follows another, q = multiplier q_leader + offset (URDF's defaults
1 and 0), read as reduced coordinates (robotgen.model.coupling): the mimic joint stays a joint
of the tree and moves with its leader's coordinate; a mimic of a mimic follows the joint at
the end of the line.

Refused, located at the <mimic>: no 'joint' attribute; a leader that is not a joint of the
file (the nearest names suggested), a fixed joint, or a joint not below the base; a multiplier
of 0 (the joint would be held: a fixed joint says so); numbers that are not finite; mimic
joints that follow each other round a cycle.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import Protocol

from robotgen.errors import Location, UserError
from robotgen.frontend.urdf_xml import Element
from robotgen.model.coupling import Coupling, Mimic, affine, couple


class Reader(Protocol):
    """What the mimic reader needs of the URDF reader: locations, failures, attributes and numbers of elements."""

    def loc(self, el: Element) -> Location:
        """Where ``el`` is written in the file."""

    def fail(self, el: Element, message: str) -> UserError:
        """A UserError located at ``el``."""

    def attr(self, el: Element, name: str, default: str | None = None) -> str:
        """The attribute ``name`` of ``el`` (``default`` when absent, else an error)."""

    def number(self, el: Element, name: str, default: str | None = None, finite: bool = True) -> float:
        """The attribute ``name`` of ``el`` as a number, finite unless told otherwise."""


@dataclass(frozen=True, eq=False)
class MimicElement:
    """Joint ``name`` (its <joint> ``joint``, its <mimic> ``element``) follows ``leader``."""

    joint: Element
    element: Element
    name: str
    leader: str
    multiplier: float
    offset: float


def read_mimics(r: Reader, joints: dict[str, Element], below: list[Element], base: str) -> dict[str, MimicElement]:
    """The <mimic> of each movable joint ``below`` the base that has one, by joint name;
    ``joints``: every joint of the file by name."""
    movable = {j.attrib["name"] for j in below}
    out: dict[str, MimicElement] = {}
    for j in below:
        el = j.find("mimic")
        if el is None:
            continue
        name, leader = j.attrib["name"], r.attr(el, "joint")
        if leader not in joints:
            near = difflib.get_close_matches(leader, joints, n=3, cutoff=0.6)
            hint = f"; nearest: {', '.join(repr(n) for n in near)}" if near else ""
            raise r.fail(el, f"joint '{name}' mimics '{leader}', which is not a joint of the URDF{hint}")
        if joints[leader].attrib["type"] == "fixed":
            raise r.fail(el, f"joint '{name}' mimics '{leader}', a fixed joint: make '{name}' fixed too")
        if leader not in movable:
            raise r.fail(el, f"joint '{name}' mimics '{leader}', which is not below base link '{base}'")
        multiplier, offset = r.number(el, "multiplier", "1"), r.number(el, "offset", "0")
        if multiplier == 0:
            raise r.fail(
                el,
                f"joint '{name}' mimics '{leader}' with multiplier 0, which holds it at its offset: "
                "a fixed joint says so",
            )
        out[name] = MimicElement(j, el, name, leader, multiplier, offset)
    return out


def independent_joints(r: Reader, mimics: dict[str, MimicElement]) -> dict[str, str]:
    """The joint at the end of each mimic joint's line of leaders, by mimic joint name; a line
    that returns to a joint is an error at the <mimic> of the cycle's first joint in the file."""
    found: dict[str, str] = {}
    for name in mimics:
        line = [name]
        while line[-1] in mimics and line[-1] not in found:
            leader = mimics[line[-1]].leader
            if leader in line:
                cycle = line[line.index(leader) :]
                first = min(cycle, key=lambda n: (mimics[n].element.line, mimics[n].element.col))
                at = cycle.index(first)
                listed = " -> ".join(f"'{n}'" for n in cycle[at:] + cycle[:at] + [first])
                raise r.fail(mimics[first].element, f"mimic joints follow each other in a cycle: {listed}")
            line.append(leader)
        end = found.get(line[-1], line[-1])
        for n in line[:-1] if line[-1] not in found else line:
            found[n] = end
    return found


def coupling_of(kept: list[str], mimics: dict[str, MimicElement]) -> Coupling | None:
    """The coupling of the kept joints (by name, in the tree's order) of which ``mimics``
    follow others; each kept mimic joint's leader is kept."""
    index = {name: k for k, name in enumerate(kept)}
    return couple(
        len(kept),
        [Mimic(index[m.name], index[m.leader], m.multiplier, m.offset) for m in mimics.values() if m.name in index],
    )


def coupled_note(r: Reader, mimics: list[MimicElement]) -> tuple[str, ...]:
    """One note naming the mimic joints kept as followers, in file order, at the first <mimic>."""
    if not mimics:
        return ()
    mimics = sorted(mimics, key=lambda m: (m.element.line, m.element.col))
    listed = ", ".join(f"'{m.name}' = {affine(m.multiplier, repr(m.leader), m.offset)}" for m in mimics)
    n = len(mimics)
    which = (
        "a mimic joint moves with the coordinate of the joint it follows (no coordinate of its own)"
        if n == 1
        else f"{n} mimic joints move with the coordinates of the joints they follow (no coordinates of their own)"
    )
    return (f"{r.loc(mimics[0].element)}: note: {which}: {listed}",)
