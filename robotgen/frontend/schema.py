"""JSON Schema (draft 2020-12) of spec format 1; docs/spec-format.md is the prose version.

The schema checks shape only (types, keys, ranges of plain numbers). A number that can
become a run-time parameter (a gain, a weight, the forgetting factor, a payload's mass) has
its range in its description only: robotgen.frontend checks it with the message the emitted
module gives for the same value at run time (robotgen.model.parameters). What needs the whole
document or arithmetic (root exists, inertia positive semi-definite, formula names,
constant expressions given as strings) is checked in robotgen.frontend.system.

A node holds exactly one primitive key; ``PRIMITIVES`` lists them, so a new primitive is
one more entry there and in ``$defs``. A control law's settings block is its own ``$defs``
entry, written beside its reader (its ``schema`` in robotgen.model.laws.registry), so the
schema is made from the registry when asked for (``spec_schema``).
"""

from __future__ import annotations

import json

from robotgen.frontend.schema_types import IDENTIFIER
from robotgen.frontend.schema_types import closed_object as _object
from robotgen.frontend.schema_types import exactly_one_of as _exactly_one_of
from robotgen.frontend.schema_types import expression_matrix as _expression_matrix
from robotgen.frontend.schema_types import expressions as _expressions
from robotgen.frontend.schema_types import names as _names
from robotgen.frontend.schema_types import number as _number
from robotgen.frontend.schema_types import numbers as _numbers
from robotgen.frontend.schema_types import parameter as _parameter
from robotgen.frontend.schema_types import vector2 as _vector2
from robotgen.frontend.schema_types import vector3 as _vector3
from robotgen.model.chain import ACCEPTABLE_DEVIATIONS, JOINT_TYPES
from robotgen.model.derivatives import DEFAULT_MAX_DOF, INTEGRATORS
from robotgen.model.dh import CONVENTIONS
from robotgen.model.laws.registry import LAWS
from robotgen.model.names import SPELLING
from robotgen.model.signature import UNITS
from robotgen.model.simulation import PLANTS
from robotgen.model.system import CHAIN_OUTPUTS, GAIN_MODES

MODULE_NAME = f"^{SPELLING}$"
PRIMITIVES = ("define", "attach", "control")


_EXPRESSION = {
    "type": ["string", "number"],
    "description": "expression: numbers, names, + - * / ** ^, unary -, "
    "sin cos tan asin acos atan atan2 exp log sqrt abs tanh sinh cosh sign min max",
}

_CHAIN = _object(
    "a serial chain of rigid links",
    {
        "convention": {
            "enum": list(CONVENTIONS),
            "description": "how joints are written: dh_standard, dh_modified (Craig) or joints (URDF-like); no default",
        },
        "gravity": _vector3("gravitational acceleration in the base frame [m/s^2], default 0 0 -9.81"),
        "base": {"$ref": "#/$defs/pose", "description": "base frame -> frame before joint 1"},
        "tool": {"$ref": "#/$defs/pose", "description": "last link frame -> tip frame"},
        "coulomb_smoothing": _number(
            "velocity scale of tanh in Coulomb friction, > 0, default 0.01", exclusiveMinimum=0
        ),
        "joints": {
            "type": "array",
            "minItems": 1,
            "items": {"$ref": "#/$defs/joint"},
            "description": "joints from the base to the tip",
        },
    },
    ("convention", "joints"),
)

_FRICTION = _number(
    "Coulomb friction coefficient between each fingertip and the payload, > 0, default 1; "
    "robotgen's grasp model holds the fingertips bilaterally and does not read it, the "
    "MuJoCo plant's contacts do (robotgen simulate --plant mujoco)",
    exclusiveMinimum=0,
)

_DEFS = {
    "number": _number('a number, or a constant expression such as "pi/2" (names: pi, e)'),
    "expression": _EXPRESSION,
    "parameter": _parameter("a number or constant expression"),
    "pose": _object(
        "rigid transform: translation xyz [m], then fixed-axis roll-pitch-yaw [rad], R = Rz(yaw) Ry(pitch) Rx(roll)",
        {"xyz": _vector3("translation [m], default 0 0 0"), "rpy": _vector3("roll pitch yaw [rad], default 0 0 0")},
    ),
    "dh": _object(
        "DH row (missing parameters are 0); the joint variable adds to theta (revolute) or d (prismatic)",
        {
            "a": _number("link length [m] (dh_modified: a_{i-1})"),
            "alpha": _number("link twist [rad] (dh_modified: alpha_{i-1})"),
            "d": _number("link offset [m]"),
            "theta": _number("joint angle offset [rad]"),
        },
    ),
    "inertia": _object(
        "inertia tensor about the COM in the link frame [kg m^2]; positive "
        "semi-definite, principal moments satisfy the triangle inequalities",
        {
            "ixx": _number("I_xx"),
            "iyy": _number("I_yy"),
            "izz": _number("I_zz"),
            "ixy": _number("I_xy, default 0"),
            "ixz": _number("I_xz, default 0"),
            "iyz": _number("I_yz, default 0"),
            "accept": {
                "type": "array",
                "uniqueItems": True,
                "items": {"enum": list(ACCEPTABLE_DEVIATIONS)},
                "description": "known deviations of published data to keep without a "
                "warning: triangle_inequality (principal moments "
                "I1 + I2 < I3)",
            },
        },
        ("ixx", "iyy", "izz"),
    ),
    "link": _object(
        "the body this joint moves (default: massless)",
        {
            "mass": _number("mass [kg], >= 0", minimum=0),
            "com": _vector3("centre of mass in the link frame [m], default 0 0 0"),
            "inertia": {"$ref": "#/$defs/inertia"},
        },
        ("mass",),
    ),
    "motor": _object(
        "motor on the joint: armature inertia * gear_ratio^2 is added to M's diagonal",
        {
            "inertia": _number("rotor inertia [kg m^2], >= 0", minimum=0),
            "gear_ratio": _number("gear ratio (motor/joint), default 1"),
        },
        ("inertia",),
    ),
    "friction": _object(
        "joint-side friction: viscous * qd + coulomb * tanh(qd / coulomb_smoothing)",
        {
            "viscous": _number("viscous coefficient, >= 0, default 0", minimum=0),
            "coulomb": _number("Coulomb friction force/torque, >= 0, default 0", minimum=0),
        },
    ),
    "limits": _object(
        "joint limits (all optional)",
        {
            "lower": _number("lower position limit"),
            "upper": _number("upper position limit"),
            "velocity": _number("velocity limit, >= 0", minimum=0),
            "effort": _number("effort limit, >= 0", minimum=0),
        },
    ),
    "joint": _object(
        "one joint and the link it moves; dh for dh_standard/dh_modified, origin and axis for joints",
        {
            "name": {"type": "string", "pattern": IDENTIFIER, "description": "joint name, default q1, q2, ..."},
            "type": {"enum": list(JOINT_TYPES), "description": "revolute or prismatic"},
            "dh": {"$ref": "#/$defs/dh"},
            "origin": {"$ref": "#/$defs/pose", "description": "parent link frame -> joint frame at q = 0"},
            "axis": _vector3("joint axis in the joint frame (normalised)"),
            "link": {"$ref": "#/$defs/link"},
            "motor": {"$ref": "#/$defs/motor"},
            "friction": {"$ref": "#/$defs/friction"},
            "limits": {"$ref": "#/$defs/limits"},
        },
        ("type",),
    ),
    "chain": _CHAIN,
    "formulas": _object(
        "a leaf robot given by M(q), C(q, qd), N(q, qd) as expressions (Deno et al. 1990, eq 3.1)",
        {
            "coordinates": {
                "type": "array",
                "minItems": 1,
                "items": {"type": "string", "pattern": IDENTIFIER},
                "description": "names of the joint coordinates q",
            },
            "velocities": {
                "type": "array",
                "minItems": 1,
                "items": {"type": "string", "pattern": IDENTIFIER},
                "description": 'names of qd, default "d" + coordinate name',
            },
            "parameters": {
                "type": "object",
                "propertyNames": {"pattern": IDENTIFIER},
                "additionalProperties": {"$ref": "#/$defs/parameter"},
                "description": "named constants usable in every expression",
            },
            "M": {
                "type": "array",
                "items": {"type": "array", "items": {"$ref": "#/$defs/expression"}},
                "description": "nq x nq inertia matrix in coordinates and parameters",
            },
            "C": {
                "type": "array",
                "items": {"type": "array", "items": {"$ref": "#/$defs/expression"}},
                "description": "nq x nq Coriolis matrix in q, qd, parameters; default: from M by Christoffel symbols",
            },
            "N": {
                "type": "array",
                "items": {"$ref": "#/$defs/expression"},
                "description": "nq vector N(q, qd): gravity, friction; default zero",
            },
            "kinematics": {
                "type": "array",
                "minItems": 1,
                "items": {"$ref": "#/$defs/expression"},
                "description": "output map x = f(q) in coordinates and parameters",
            },
            "outputs": _names("names of the kinematics outputs, default <node>_x1, <node>_x2, ...", minItems=1),
            "inverse_kinematics": _expressions("q = f^-1(x): nq expressions in the outputs and parameters", minItems=1),
            "units": {
                "type": "object",
                "propertyNames": {"pattern": IDENTIFIER},
                "additionalProperties": {"enum": list(UNITS)},
                "description": "unit of coordinates and outputs by name (m or rad), for plots "
                "and reports; forces are in N on m, torques in N m on rad",
            },
            "mechanism": {"$ref": "#/$defs/mechanism"},
        },
        ("coordinates", "M"),
    ),
    "mechanism": {
        **_CHAIN,
        "description": "the rigid bodies behind a formulas leaf, for an independent "
        "simulator (robotgen simulate --plant mujoco): a chain, with the "
        "leaf's coordinates as affine expressions of its joint positions; its "
        "tip frame is the leaf's fingertip",
        "properties": {
            **_CHAIN["properties"],
            "coordinates": _expressions(
                "the leaf's coordinates in the chain's joint names "
                "(and the leaf's parameters), affine: theta = T q + "
                "offset with T invertible",
                minItems=1,
            ),
        },
        "required": [*_CHAIN["required"], "coordinates"],
    },
    "rigid_body": {
        **_object(
            "a rigid payload body (never actuated), planar or spatial",
            {
                "planar": _object(
                    "a body moving in a plane, coordinates (x, y, psi): M = diag(m, m, I), C = 0, N = -m (gx, gy, 0)",
                    {
                        "mass": _parameter("mass [kg], >= 0"),
                        "inertia": _number("moment of inertia about the centre of mass [kg m^2], >= 0", minimum=0),
                    },
                    ("mass", "inertia"),
                ),
                "spatial": _object(
                    "a body in space, coordinates (x, y, z, roll, pitch, yaw) of its frame at "
                    "the centre of mass (R = Rz(yaw) Ry(pitch) Rx(roll))",
                    {"mass": _parameter("mass [kg], >= 0"), "inertia": {"$ref": "#/$defs/inertia"}},
                    ("mass", "inertia"),
                ),
                "gravity": {
                    "type": "array",
                    "minItems": 2,
                    "maxItems": 3,
                    "items": {"$ref": "#/$defs/number"},
                    "description": "gravitational acceleration [m/s^2]: 2 numbers for a planar body "
                    "(default 0 0), 3 for a spatial one (default 0 0 -9.81)",
                },
                "coordinates": _names(
                    "names of the body's coordinates, default x, y, psi (planar) or "
                    "x, y, z, roll, pitch, yaw (spatial)",
                    minItems=3,
                    maxItems=6,
                ),
            },
        ),
        "oneOf": _exactly_one_of(("planar", "spatial")),
    },
    "frame_change": _object(
        "nil payload, G = I: the node's coordinates are the robots' kinematic outputs",
        {
            "output": {
                "enum": list(CHAIN_OUTPUTS),
                "description": "a chain's output: tip position x y z (default) or planar x y",
            }
        },
    ),
    "planar_contacts": _object(
        "fingertips (robot coordinates x, y per contact) held at body-frame points of a planar payload",
        {
            "points": {
                "type": "array",
                "minItems": 2,
                "items": _vector2("contact point [x, y] in the payload's frame [m]"),
                "description": "contact points in the payload's frame, one per fingertip",
            },
            "friction": _FRICTION,
        },
        ("points",),
    ),
    "point_contacts": _object(
        "fingertips (robot coordinates x, y, z per contact) held at body-frame points of a spatial payload",
        {
            "points": {
                "type": "array",
                "minItems": 3,
                "items": _vector3("contact point [x, y, z] in the payload's frame [m]"),
                "description": "contact points in the payload's frame, one per fingertip; the first "
                "three must not be collinear",
            },
            "friction": _FRICTION,
        },
        ("points",),
    ),
    "constraint_formulas": _object(
        "a constraint J(y) ydot = G(x)^T xdot given by expressions",
        {
            "coordinates": _names("names of the node's coordinates x", minItems=1),
            "parameters": {
                "type": "object",
                "propertyNames": {"pattern": IDENTIFIER},
                "additionalProperties": {"$ref": "#/$defs/number"},
                "description": "named constants usable in every expression",
            },
            "h": _expressions(
                "x = h(y): one expression per node coordinate, in the robots' coordinates and parameters", minItems=1
            ),
            "h_inverse": _expressions(
                "y = h^-1(x): one expression per robot coordinate, in the node's coordinates and parameters", minItems=1
            ),
            "J": _expression_matrix(
                "constraint rows x robot coordinates, in the robots' coordinates and parameters; default identity"
            ),
            "G": _expression_matrix(
                "grasp map: node coordinates x constraint rows, in the node's and robots' coordinates and parameters"
            ),
        },
        ("coordinates", "h", "G"),
    ),
    "constraint": {
        **_object(
            "ATTACH's constraint: exactly one of frame_change, planar_contacts, point_contacts, formulas",
            {
                "frame_change": {"$ref": "#/$defs/frame_change"},
                "planar_contacts": {"$ref": "#/$defs/planar_contacts"},
                "point_contacts": {"$ref": "#/$defs/point_contacts"},
                "formulas": {"$ref": "#/$defs/constraint_formulas"},
            },
        ),
        "oneOf": _exactly_one_of(("frame_change", "planar_contacts", "point_contacts", "formulas")),
    },
    "attach": _object(
        "ATTACH: robots joined to an optional payload through a constraint (Deno et al. 1990, 3.3)",
        {
            "robots": {
                "type": "array",
                "minItems": 1,
                "items": {"type": "string", "pattern": IDENTIFIER},
                "description": "child robot nodes, in order; their coordinates are stacked",
            },
            "payload": {
                "type": "string",
                "pattern": IDENTIFIER,
                "description": "a define node (rigid_body or formulas); default nil",
            },
            "constraint": {"$ref": "#/$defs/constraint"},
        },
        ("robots", "constraint"),
    ),
    "gain": {
        "type": ["number", "string", "array"],
        "description": "scalar (times I), per-axis list (diagonal) or matrix (symmetric "
        "positive definite), on the robot's external coordinates",
        "minItems": 1,
        "items": {"type": ["number", "string", "array"], "minItems": 1, "items": {"$ref": "#/$defs/number"}},
    },
    "control": _object(
        "CONTROL: a controller on a robot (Deno et al. 1990, 3.4)",
        {
            "robot": {"type": "string", "pattern": IDENTIFIER, "description": "the controlled node"},
            "law": {"enum": list(LAWS), "description": "control law"},
            "kp": {"$ref": "#/$defs/gain"},
            "kv": {"$ref": "#/$defs/gain"},
            "kv_internal": _number("damping of internal motion rates, >= 0, default 0"),
            "kf_internal": _number(
                "gain on the internal forces the robot senses (its rd force term): write "
                "f_d + kf_internal (f_d - f_sensed); the servo step then takes tau_sensed, "
                "0 <= kf_internal < 1, default none (open loop)"
            ),
            "ki_internal": _number(
                "gain on the integral of that error [1/s]: write f_d + kf_internal e + "
                "ki_internal z, z the integral of e = f_d - f_sensed (controller state), "
                ">= 0, with ki_internal dt < 2 (1 - kf_internal); default none"
            ),
            "anchor": {
                "type": ["number", "string", "boolean"],
                "description": "computed_torque and feedforward: the time constant [s] over which the "
                "expected trajectory (x_e, xd_e) it integrates relaxes to the sensed state, > 0, "
                "default 1; false: the open-loop integral as printed (Deno et al. 1990, 3.4), "
                "which drifts in directions no controller above observes, such as a grasp's squeeze",
            },
            "internal_forces": {
                "type": "array",
                "minItems": 1,
                "items": {"$ref": "#/$defs/number"},
                "description": "resolve all of the robot's internal forces to these values",
            },
            "gains": {
                "enum": list(GAIN_MODES),
                "description": "runtime (default): kp, kv, kv_internal, kf_internal, ki_internal and a force "
                "law's settings are inputs of the emitted code "
                "(a parameter struct in C, keyword arguments in Python) with the spec's "
                "values as defaults; folded: compiled in as constants (faster, retuning "
                "needs a rebuild)",
            },
            "resolve_internal_motion": {
                "type": "boolean",
                "description": "drive internal motion rates to zero and mask them",
            },
            "period": _number(
                "sampling period of this controller [s], > 0; default its nearest controller "
                "ancestor's, the topmost ones simulation.dt (else 0.001). Controllers of one period "
                "form a rate group with a step function of its own: every period an integer "
                "multiple of the fastest, a controller at least as fast as the one above it, and "
                "every period dividing the slowest",
                exclusiveMinimum=0,
            ),
        },
        ("robot", "law"),
    ),
    "urdf": _object(
        "a serial chain read from a URDF file, from a base link to a tip link",
        {
            "file": {"type": "string", "minLength": 1, "description": "URDF path, relative to the spec"},
            "tip": {"type": "string", "minLength": 1, "description": "tip link"},
            "base": {"type": "string", "minLength": 1, "description": "base link, default the root link"},
            "gravity": _vector3("gravitational acceleration in the base frame [m/s^2], default 0 0 -9.81"),
        },
        ("file", "tip"),
    ),
    "define": {
        **_object(
            "DEFINE: a leaf robot, by exactly one of chain, urdf, formulas or rigid_body",
            {
                "chain": {"$ref": "#/$defs/chain"},
                "urdf": {"$ref": "#/$defs/urdf"},
                "formulas": {"$ref": "#/$defs/formulas"},
                "rigid_body": {"$ref": "#/$defs/rigid_body"},
            },
        ),
        "oneOf": _exactly_one_of(("chain", "urdf", "formulas", "rigid_body")),
    },
    "simulation": _object(
        "how `robotgen simulate` runs the closed loop",
        {
            "duration": _number("simulated time [s], default 2", exclusiveMinimum=0),
            "dt": _number("servo period and RK4 step [s], default 0.001", exclusiveMinimum=0),
            "start": _numbers("root positions at t = 0 (needs inverse kinematics in every attach)"),
            "theta0": _numbers("or the leaf joint positions at t = 0"),
            "initial_error": _numbers("the plant starts at start + initial_error"),
            "amplitude": _numbers("x_d(t) = start + amplitude sin(2 pi frequency t)"),
            "frequency": _numbers("[Hz] per root coordinate"),
            "internal_forces": _numbers("internal forces commanded at the root"),
            "plant": {
                "enum": list(PLANTS),
                "description": "what the loop is closed around: robotgen (its own model, default), mujoco "
                "(an independent MuJoCo model of the same system, with real contacts; needs "
                "pip install 'robotgen[mujoco]') or both side by side; --plant overrides",
            },
            "force": {
                "type": "array",
                "items": {"$ref": "#/$defs/number"},
                "description": "f_e written at the root, one per root velocity coordinate (default zeros): "
                "the force a hybrid law's force-controlled coordinates exert",
            },
            "payload_change": {
                "description": "from time at on the plant's payload has another mass, which the controller is not "
                "told about (a hand controller's hand holds a point mass; a robot tree's rigid_body "
                "payload, its mass a run-time parameter, takes mass); one change or a list of them "
                "in time order",
                "anyOf": [
                    {"$ref": "#/$defs/payload_change"},
                    {"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/payload_change"}},
                ],
            },
            "wall": {"$ref": "#/$defs/wall"},
        },
    ),
    "payload_change": _object(
        "from time at on, the plant's hand holds mass at com (a robot tree: its payload has mass)",
        {
            "at": _number("time of the change [s], >= 0", minimum=0),
            "mass": _number("the payload's mass [kg], >= 0 (0 drops it)", minimum=0),
            "com": _vector3(
                "the payload's centre of mass in the hand frame [m], "
                "default the hand's origin (a hand controller's run)"
            ),
            "payload": {
                "type": "string",
                "pattern": IDENTIFIER,
                "description": "a robot tree's rigid_body node whose mass changes (default: the tree's one rigid_body)",
            },
        },
        ("at", "mass"),
    ),
    "wall": _object(
        "a flat frictionless wall in the plant, touched by the point a node's coordinates are",
        {
            "node": {
                "type": "string",
                "pattern": IDENTIFIER,
                "description": "a node whose 2 or 3 coordinates are a point in metres (a frame change's tip)",
            },
            "point": _numbers("a point of the wall's face, in the node's coordinates [m]"),
            "normal": _numbers("the face's outward normal (any length): the wall fills (x - point) . normal < 0"),
            "stiffness": _number("robotgen's plant: the wall's spring [N/m], > 0, default 1e5", exclusiveMinimum=0),
            "damping": _number("robotgen's plant: its damper [N s/m], >= 0, default 300", minimum=0),
        },
        ("node", "point", "normal"),
    ),
    "derivatives": _object(
        "the derivative functions of a module whose root is a define leaf (or a hand or "
        "resolved-rate law on a chain): inverse_dynamics_derivatives, "
        "forward_dynamics_derivatives, mass_inverse, discrete_dynamics, "
        "discrete_dynamics_derivatives and, for a chain, jacobian_derivative; of a robot "
        "tree's module: plant_dynamics_derivatives",
        {
            "include": {
                "type": "boolean",
                "description": f"emit them; default true for a define leaf of at most {DEFAULT_MAX_DOF} "
                "coordinates, false otherwise (they grow build time)",
            },
            "integrator": {
                "enum": list(INTEGRATORS),
                "description": "the discrete model's step, tau held over it: semi_implicit_euler "
                "(qd+ = qd + dt qdd, q+ = q + dt qd+; default) or rk4",
            },
        },
    ),
    "node": {
        **_object(
            "a node of the robot tree: exactly one primitive key",
            {key: {"$ref": f"#/$defs/{key}"} for key in PRIMITIVES},
        ),
        "oneOf": _exactly_one_of(PRIMITIVES),
    },
}

_HEAD: dict = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "$id": "https://robotgen.dev/schema/spec-1.json",
    "title": "robotgen spec, format 1",
    **_object(
        "a robot system: named nodes and the root whose functions the module exposes",
        {
            "robotgen": {"const": 1, "description": "spec format version, must be 1"},
            "name": {
                "type": "string",
                "pattern": MODULE_NAME,
                "description": "module name and C prefix: [a-z_][a-z0-9_]*",
            },
            "root": {"type": "string", "description": "name of the root node"},
            "nodes": {
                "type": "object",
                "minProperties": 1,
                "propertyNames": {"pattern": IDENTIFIER},
                "additionalProperties": {"$ref": "#/$defs/node"},
                "description": "the nodes by name (C identifiers)",
            },
            "simulation": {"$ref": "#/$defs/simulation"},
            "derivatives": {"$ref": "#/$defs/derivatives"},
        },
        ("robotgen", "name", "root", "nodes"),
    ),
}


def spec_schema() -> dict:
    """The schema, every law of the registry in it: its name among the laws a control node may
    carry, and its settings block under its name."""
    blocks = {name: law.part("schema") for name, law in LAWS.items() if law.schema is not None}
    control = _DEFS["control"]
    control = {
        **control,
        "properties": {
            **control["properties"],
            "law": {**control["properties"]["law"], "enum": list(LAWS)},
            **{name: {"$ref": f"#/$defs/{name}"} for name in blocks},
        },
    }
    return {**_HEAD, "$defs": {**_DEFS, **blocks, "control": control}}


def schema_json() -> str:
    """The schema as deterministic JSON (sorted keys, indent 2)."""
    return json.dumps(spec_schema(), sort_keys=True, indent=2) + "\n"
