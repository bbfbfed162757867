"""JSON Schema (draft 2020-12) of spec format 1; docs/spec-format.md is the prose version.

The schema checks shape only (types, keys, ranges of plain numbers). What needs the whole
document or arithmetic (root exists, inertia positive semi-definite, formula names,
constant expressions given as strings) is checked in robotgen.spec.to_model.

A node holds exactly one primitive key; ``PRIMITIVES`` lists them, so a new primitive is
one more entry there and in ``$defs``.
"""
from __future__ import annotations

import json

IDENTIFIER = "^[A-Za-z_][A-Za-z0-9_]*$"
MODULE_NAME = "^[a-z_][a-z0-9_]*$"
PRIMITIVES = ("define",)


def _number(description: str, **bounds: float) -> dict:
    """A YAML number or a string holding a constant expression; bounds apply to numbers."""
    return {"type": ["number", "string"], "description": description, **bounds}


def _vector3(description: str) -> dict:
    return {"type": "array", "description": description, "minItems": 3, "maxItems": 3,
            "items": {"$ref": "#/$defs/number"}}


def _object(description: str, properties: dict, required: tuple[str, ...] = ()) -> dict:
    schema = {"type": "object", "description": description, "additionalProperties": False,
              "properties": properties}
    if required:
        schema["required"] = list(required)
    return schema


def _exactly_one_of(keys: tuple[str, ...]) -> list[dict]:
    return [{"required": [key]} for key in keys]


_EXPRESSION = {"type": ["string", "number"],
               "description": "expression: numbers, names, + - * / ** ^, unary -, "
                              "sin cos tan asin acos atan atan2 exp log sqrt abs tanh sinh cosh sign min max"}

_DEFS = {
    "number": _number("a number, or a constant expression such as \"pi/2\" (names: pi, e)"),
    "expression": _EXPRESSION,
    "pose": _object("rigid transform: translation xyz [m], then fixed-axis roll-pitch-yaw [rad], "
                    "R = Rz(yaw) Ry(pitch) Rx(roll)",
                    {"xyz": _vector3("translation [m], default 0 0 0"),
                     "rpy": _vector3("roll pitch yaw [rad], default 0 0 0")}),
    "dh": _object("DH row (missing parameters are 0); the joint variable adds to theta "
                  "(revolute) or d (prismatic)",
                  {"a": _number("link length [m] (dh_modified: a_{i-1})"),
                   "alpha": _number("link twist [rad] (dh_modified: alpha_{i-1})"),
                   "d": _number("link offset [m]"),
                   "theta": _number("joint angle offset [rad]")}),
    "inertia": _object("inertia tensor about the COM in the link frame [kg m^2]; positive "
                       "semi-definite, principal moments satisfy the triangle inequalities",
                       {"ixx": _number("I_xx"), "iyy": _number("I_yy"), "izz": _number("I_zz"),
                        "ixy": _number("I_xy, default 0"), "ixz": _number("I_xz, default 0"),
                        "iyz": _number("I_yz, default 0")},
                       ("ixx", "iyy", "izz")),
    "link": _object("the body this joint moves (default: massless)",
                    {"mass": _number("mass [kg], >= 0", minimum=0),
                     "com": _vector3("centre of mass in the link frame [m], default 0 0 0"),
                     "inertia": {"$ref": "#/$defs/inertia"}},
                    ("mass",)),
    "motor": _object("motor on the joint: armature inertia * gear_ratio^2 is added to M's diagonal",
                     {"inertia": _number("rotor inertia [kg m^2], >= 0", minimum=0),
                      "gear_ratio": _number("gear ratio (motor/joint), default 1")},
                     ("inertia",)),
    "friction": _object("joint-side friction: viscous * qd + coulomb * tanh(qd / coulomb_smoothing)",
                        {"viscous": _number("viscous coefficient, >= 0, default 0", minimum=0),
                         "coulomb": _number("Coulomb friction force/torque, >= 0, default 0", minimum=0)}),
    "limits": _object("joint limits (all optional)",
                      {"lower": _number("lower position limit"), "upper": _number("upper position limit"),
                       "velocity": _number("velocity limit, >= 0", minimum=0),
                       "effort": _number("effort limit, >= 0", minimum=0)}),
    "joint": _object(
        "one joint and the link it moves; dh for dh_standard/dh_modified, origin and axis for joints",
        {"name": {"type": "string", "pattern": IDENTIFIER, "description": "joint name, default q1, q2, ..."},
         "type": {"enum": ["revolute", "prismatic"], "description": "revolute or prismatic"},
         "dh": {"$ref": "#/$defs/dh"},
         "origin": {"$ref": "#/$defs/pose", "description": "parent link frame -> joint frame at q = 0"},
         "axis": _vector3("joint axis in the joint frame (normalised)"),
         "link": {"$ref": "#/$defs/link"},
         "motor": {"$ref": "#/$defs/motor"},
         "friction": {"$ref": "#/$defs/friction"},
         "limits": {"$ref": "#/$defs/limits"}},
        ("type",)),
    "chain": _object(
        "a serial chain of rigid links",
        {"convention": {"enum": ["dh_standard", "dh_modified", "joints"],
                        "description": "how joints are written: dh_standard, dh_modified (Craig) "
                                       "or joints (URDF-like); no default"},
         "gravity": _vector3("gravitational acceleration in the base frame [m/s^2], default 0 0 -9.81"),
         "base": {"$ref": "#/$defs/pose", "description": "base frame -> frame before joint 1"},
         "tool": {"$ref": "#/$defs/pose", "description": "last link frame -> tip frame"},
         "coulomb_smoothing": _number("velocity scale of tanh in Coulomb friction, > 0, default 0.01",
                                      exclusiveMinimum=0),
         "joints": {"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/joint"},
                    "description": "joints from the base to the tip"}},
        ("convention", "joints")),
    "formulas": _object(
        "a leaf robot given by M(q), C(q, qd), N(q, qd) as expressions (Deno et al. 1990, eq 3.1)",
        {"coordinates": {"type": "array", "minItems": 1,
                         "items": {"type": "string", "pattern": IDENTIFIER},
                         "description": "names of the joint coordinates q"},
         "velocities": {"type": "array", "minItems": 1,
                        "items": {"type": "string", "pattern": IDENTIFIER},
                        "description": "names of qd, default \"d\" + coordinate name"},
         "parameters": {"type": "object", "propertyNames": {"pattern": IDENTIFIER},
                        "additionalProperties": {"$ref": "#/$defs/number"},
                        "description": "named constants usable in every expression"},
         "M": {"type": "array", "items": {"type": "array", "items": {"$ref": "#/$defs/expression"}},
               "description": "nq x nq inertia matrix in coordinates and parameters"},
         "C": {"type": "array", "items": {"type": "array", "items": {"$ref": "#/$defs/expression"}},
               "description": "nq x nq Coriolis matrix in q, qd, parameters; default: from M by "
                              "Christoffel symbols"},
         "N": {"type": "array", "items": {"$ref": "#/$defs/expression"},
               "description": "nq vector N(q, qd): gravity, friction; default zero"},
         "kinematics": {"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/expression"},
                        "description": "output map x = f(q) in coordinates and parameters"}},
        ("coordinates", "M")),
    "urdf": _object(
        "a serial chain read from a URDF file, from a base link to a tip link",
        {"file": {"type": "string", "minLength": 1, "description": "URDF path, relative to the spec"},
         "tip": {"type": "string", "minLength": 1, "description": "tip link"},
         "base": {"type": "string", "minLength": 1, "description": "base link, default the root link"},
         "gravity": _vector3("gravitational acceleration in the base frame [m/s^2], default 0 0 -9.81")},
        ("file", "tip")),
    "define": {**_object("DEFINE: a leaf robot, by exactly one of chain, urdf or formulas",
                         {"chain": {"$ref": "#/$defs/chain"}, "urdf": {"$ref": "#/$defs/urdf"},
                          "formulas": {"$ref": "#/$defs/formulas"}}),
               "oneOf": _exactly_one_of(("chain", "urdf", "formulas"))},
    "node": {**_object("a node of the robot tree: exactly one primitive key",
                       {key: {"$ref": f"#/$defs/{key}"} for key in PRIMITIVES}),
             "oneOf": _exactly_one_of(PRIMITIVES)},
}

SCHEMA: dict = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "$id": "https://robotgen.dev/schema/spec-1.json",
    "title": "robotgen spec, format 1",
    **_object("a robot system: named nodes and the root whose functions the module exposes",
              {"robotgen": {"const": 1, "description": "spec format version, must be 1"},
               "name": {"type": "string", "pattern": MODULE_NAME,
                        "description": "module name and C prefix: [a-z_][a-z0-9_]*"},
               "root": {"type": "string", "description": "name of the root node"},
               "nodes": {"type": "object", "minProperties": 1, "propertyNames": {"pattern": IDENTIFIER},
                         "additionalProperties": {"$ref": "#/$defs/node"},
                         "description": "the nodes by name (C identifiers)"}},
              ("robotgen", "name", "root", "nodes")),
    "$defs": _DEFS,
}


def schema_json() -> str:
    """The schema as deterministic JSON (sorted keys, indent 2)."""
    return json.dumps(SCHEMA, sort_keys=True, indent=2) + "\n"
