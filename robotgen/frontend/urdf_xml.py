"""A URDF file as plain elements with their lines and columns, read by the standard library's
expat (which keeps positions).

XML allows nothing before its declaration (`<?xml version="1.0"?>`), but files are found
with blank lines or a comment in front of it (pybullet_data's biped2d and diff_ring), and
other URDF readers take them. Such a declaration is read as if it came first, with a note;
what follows it keeps its line and column. Entities are refused: no URDF needs one, and
expanding them is how a small file becomes gigabytes."""

from __future__ import annotations

import re
import xml.parsers.expat
from dataclasses import dataclass, field

from robotgen.errors import Location, UserError

_BOM = b"\xef\xbb\xbf"
# whitespace and comments, then the declaration (no '?' inside it, as XML's grammar has it)
_LATE_DECLARATION = re.compile(rb"((?:\s|<!--.*?-->)+)(<\?xml\s[^?]*\?>)", re.DOTALL)


@dataclass
class Element:
    """A URDF element with its file position (line, column), attributes, children and text."""

    tag: str
    attrib: dict[str, str]
    line: int
    col: int
    children: list[Element] = field(default_factory=list)
    text: str = ""  # character data directly inside the element (e.g. <gravity>1</gravity>)

    def find(self, tag: str) -> Element | None:
        """The first child with tag ``tag``, or None."""
        return next((c for c in self.children if c.tag == tag), None)


def declaration_first(path: str, data: bytes) -> tuple[bytes, tuple[str, ...]]:
    """The file's bytes with an XML declaration that follows whitespace or comments moved to
    the start (its old place blanked, newlines kept, so every later line and column stays),
    and the note saying so; the bytes unchanged and no note otherwise."""
    bom = _BOM if data.startswith(_BOM) else b""
    m = _LATE_DECLARATION.match(data, len(bom))
    if m is None:
        return data, ()
    prefix, declaration = m.group(1), m.group(2)
    blank = re.sub(rb"[^\n]", b" ", declaration)
    one_line = re.sub(rb"\s+", b" ", declaration)  # the moved copy adds no line
    line = prefix.count(b"\n") + 1
    col = len(prefix) - (prefix.rfind(b"\n") + 1) + 1
    before = "a comment" if b"<!--" in prefix else "whitespace"
    note = (
        f"{Location(path, line, col)}: note: the XML declaration comes after {before}, which XML does not "
        "allow; read as if it were at the start of the file"
    )
    return bom + one_line + prefix + blank + data[m.end() :], (note,)


def parse_xml(path: str, data: bytes) -> Element:
    """The root <robot> element of ``data``; malformed XML, an entity or another root is a
    located error."""
    parser = xml.parsers.expat.ParserCreate()
    stack: list[Element] = []
    root: list[Element] = []

    def start(tag, attrib):
        el = Element(tag, dict(attrib), parser.CurrentLineNumber, parser.CurrentColumnNumber + 1)
        (stack[-1].children if stack else root).append(el)
        stack.append(el)

    def text(data):
        if stack:
            stack[-1].text += data

    def entity(name, *_):
        # the expat in use may predate its amplification limit
        raise UserError(
            Location(path, parser.CurrentLineNumber, parser.CurrentColumnNumber + 1),
            f"the URDF declares an XML entity ('{name}'); robotgen reads URDFs without entities",
        )

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda tag: stack.pop()
    parser.CharacterDataHandler = text
    parser.EntityDeclHandler = entity
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as e:
        raise UserError(
            Location(path, e.lineno, e.offset + 1), f"not well-formed XML: {xml.parsers.expat.ErrorString(e.code)}"
        ) from None
    except LookupError as e:  # the XML declaration names an encoding Python does not know
        first = data.split(b"\n", 1)[0]
        col = first.find(b"encoding") + 1 if b"encoding" in first else 1
        raise UserError(
            Location(path, 1, col),
            f"the XML declaration names an encoding Python does not know ({e}); save the URDF as UTF-8",
        ) from None
    if not root or root[0].tag != "robot":
        raise UserError(Location(path, 1, 1), "a URDF file must have a <robot> root element")
    return root[0]
