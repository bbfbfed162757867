"""What the URDF reader does with each element inside <link>, <joint> and <inertial>: read
it, accept it unread, skip it with a note, or refuse it.

- Read: <inertial> in a link; <origin>, <parent>, <child>, <axis>, <limit>, <dynamics> and
  <mimic> in a joint; <origin>, <mass> and <inertia> in <inertial>. A second copy of one
  of them is refused unless it says the same as the first.
- Accepted unread: URDF's own elements without dynamic meaning (visual, collision, ...).
- Refused, located, because misreading them would change the dynamics:
  - <mass> or <inertia> directly in a link or joint, <inertial> in a joint (inertia in the
    wrong place);
  - elements named like joint dynamics (<damping>, <friction>, <spring>, <stiffness>,
    <armature>, <rotor_inertia>, ...): URDF keeps damping and friction as <dynamics>
    attributes and has no springs or rotor inertia;
  - xacro macros left unexpanded (they may expand to any of these);
  - four that are harmless only with their default content: Gazebo's <gravity> (1) and
    <kinematic> (0) in a link, the pre-1.0 <joint_properties> (damping and friction 0) in
    a joint, and a pybullet <contact> holding <inertia_scaling> other than 1 (pybullet
    scales the link's inertia by it).
- Anything else inside <link> or <joint> (pybullet's <contact>, <self_filter>,
  <collision_checking>, <surface>, an <origin> directly in a link, a vendor's tags) has no
  rigid-body meaning for robotgen: it is skipped with its children, and one located note per
  element name says so, at its first occurrence. Inside <inertial> every element is read, so
  anything else there is refused.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from robotgen.errors import Location, UserError
from robotgen.frontend.urdf_xml import Element

# URDF's elements without dynamic meaning, accepted unread wherever they stand
KNOWN_UNREAD = {
    "visual",
    "collision",
    "material",
    "transmission",
    "gazebo",
    "calibration",
    "safety_controller",
    "sensor",
}
READ = {
    "link": {"inertial"},
    "joint": {"origin", "parent", "child", "axis", "limit", "dynamics", "mimic"},
    "inertial": {"origin", "mass", "inertia"},
}
_MISPLACED_INERTIA = {
    "link": {"mass", "inertia"},
    "joint": {"mass", "inertia", "inertial"},
}
# joint dynamics URDF does not have (or keeps in <dynamics> attributes), by local name
_JOINT_DYNAMICS = {
    "damping",
    "friction",
    "spring",
    "stiffness",
    "spring_stiffness",
    "spring_reference",
    "springref",
    "armature",
    "rotor_inertia",
    "reflected_inertia",
    "gear_ratio",
}
# why a skipped element has no rigid-body meaning, for the note
_SKIPPED_BECAUSE = {
    ("link", "contact"): "a simulator's contact parameters",
    ("link", "self_filter"): "collision filtering",
    ("link", "collision_checking"): "collision settings",
    ("link", "surface"): "contact surface settings",
    ("link", "gravity"): "Gazebo's flag, at its default 1",
    ("link", "kinematic"): "Gazebo's flag, at its default 0",
    ("link", "origin"): "not URDF: a link's frame is where its joint puts it",
    ("joint", "joint_properties"): "the pre-1.0 form of <dynamics>, with damping and friction 0",
}


def _local(tag: str) -> str:
    return tag.rpartition(":")[2]


def _content(el: Element) -> tuple:
    """What an element says: its tag, attributes and children (a copy that says the same
    is harmless)."""
    return el.tag, sorted(el.attrib.items()), el.text.strip(), [_content(c) for c in el.children]


def _is_number(text: str, value: float) -> bool:
    try:
        return float(text) == value
    except ValueError:
        return False


def _default_content_problem(parent: str, el: Element) -> str | None:
    """Why an element that is harmless only with its default content would change the
    dynamics as written (None when it is at its default)."""
    text = el.text.strip().lower()
    if (parent, el.tag) == ("link", "gravity") and text not in ("1", "true"):
        return (
            f"<gravity>{el.text.strip()}</gravity> takes the link out of gravity in Gazebo; robotgen applies "
            "gravity to every link (remove the element to do the same)"
        )
    if (parent, el.tag) == ("link", "kinematic") and text not in ("0", "false"):
        return (
            f"<kinematic>{el.text.strip()}</kinematic> makes the link kinematic (moved, not pushed) in "
            "Gazebo; robotgen has no such links"
        )
    if (parent, el.tag) == ("joint", "joint_properties"):
        named = {k: v for k, v in el.attrib.items() if k in ("damping", "friction") and not _is_number(v, 0.0)}
        if named:
            listed = " ".join(f'{k}="{v}"' for k, v in named.items())
            return f"<joint_properties {listed}> is the pre-1.0 form of <dynamics>; write <dynamics {listed}/>"
    if (parent, el.tag) == ("link", "contact"):
        for scaling in (c for c in el.children if c.tag == "inertia_scaling"):
            value = scaling.attrib.get("value", "")
            if not _is_number(value, 1.0):
                return (
                    f'<inertia_scaling value="{value}"> inside it scales the link\'s inertia in pybullet; '
                    "scale <inertia> itself instead"
                )
    return None


@dataclass
class ElementCheck:
    """Walks every <link> and <joint> of one file, raising on what it refuses and noting
    what it skips (``notes``: one per (parent, element name), in the order first met)."""

    path: str
    skipped: dict[tuple[str, str], list[Element]] = field(default_factory=dict)

    def fail(self, el: Element, message: str) -> UserError:
        """A UserError located at ``el``."""
        return UserError(Location(self.path, el.line, el.col), message)

    def check(self, el: Element) -> None:
        """Check one <link> or <joint> (or an element in it): children read, refused, or skipped and noted."""
        read = READ[el.tag]
        seen: dict[str, Element] = {}
        for child in el.children:
            tag = child.tag
            if tag in read:
                if tag in seen and _content(seen[tag]) != _content(child):
                    raise self.fail(
                        child,
                        f"<{el.tag}> has a second <{tag}> that differs from the first (line "
                        f"{seen[tag].line}); robotgen reads one",
                    )
                seen.setdefault(tag, child)
                if tag == "inertial":
                    self.check(child)
            elif tag in KNOWN_UNREAD and el.tag != "inertial":
                continue
            else:
                problem = self.refusal(el.tag, child)
                if problem is not None:
                    raise self.fail(child, f"<{tag}> is not supported inside <{el.tag}>: {problem}")
                self.skipped.setdefault((el.tag, tag), []).append(child)

    def refusal(self, parent: str, el: Element) -> str | None:
        """Why a child ``el`` of <parent> is refused (it would change the dynamics if skipped), or None."""
        local = _local(el.tag)
        if parent == "inertial":
            return "<inertial> holds <origin>, <mass> and <inertia>"
        if el.tag.startswith("xacro:"):
            return "the file holds xacro macros, which may expand to inertia or joint data; expand it with xacro first"
        if local in _MISPLACED_INERTIA.get(parent, ()):
            return "inertia belongs inside a link's <inertial>; robotgen refuses it here rather than lose it"
        if parent == "joint" and local in _JOINT_DYNAMICS:
            return "it would change the joint's dynamics, which URDF gives as <dynamics damping=... friction=...> only"
        return _default_content_problem(parent, el)

    @property
    def notes(self) -> tuple[str, ...]:
        """One located note per (parent, element name) skipped, in the order first met."""
        notes = []
        for (parent, tag), elements in self.skipped.items():
            first = elements[0]
            why = _SKIPPED_BECAUSE.get((parent, tag), "not a URDF element")
            what = f"{len(elements)} <{tag}> elements" if len(elements) > 1 else f"<{tag}>"
            notes.append(
                f"{Location(self.path, first.line, first.col)}: note: skipped {what} inside <{parent}> "
                f"({why}): no rigid-body meaning for robotgen"
            )
        return tuple(notes)
