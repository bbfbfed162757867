"""Schema-valid spec document -> RobotSystem, with the checks the schema cannot express:
root exists, constant expressions, inertia physically valid, joint keys that fit the
convention, unique names, formula shapes and the names each formula may read; for robot
trees, that the nodes form one tree below the root, that every ATTACH and CONTROL fits the
dimensions of its children (robotgen.model.signature) and the gains' shapes.
Every problem is collected; nothing is returned unless there are none."""
from __future__ import annotations

import dataclasses
import keyword
import pathlib

import numpy as np

from robotgen.errors import Location, UserError, UserErrors
from robotgen.model.chain import TRIANGLE_INEQUALITY, Body, KinematicTree, Limits
from robotgen.model.dh import DH_MODIFIED, DH_STANDARD, JOINT_LIST, DHParameters, JointRow, canonical_chain, unit_axis
from robotgen.model.expression import CONSTANTS, FUNCTIONS, Expr, parse_constant, parse_expression
from robotgen.model.formula import FormulaRobot
from robotgen.model.rate_control import (
    COMPOSITE_KEYS,
    EXTENDED_JACOBIAN,
    GENERIC_AXES,
    HAND,
    JOINT_LIMITS,
    LINE_OF_SIGHT,
    PSEUDO_INVERSE,
    RESOLVED_RATE,
    SPHERICAL,
    TOOL,
    CommandFrame,
    CompositeRateSettings,
    Damping,
    LQRSettings,
    RateControlSettings,
    Redundancy,
)
from robotgen.model.simulation import SimulationSettings
from robotgen.model.signature import (
    Signature,
    SignatureError,
    angle_coordinates,
    kinematic_outputs,
    robot_leaves,
    signature,
)
from robotgen.model.system import (
    CONSTRAINT_FORMULAS,
    FEEDFORWARD,
    FRAME_CHANGE,
    PD,
    CONTACT_GRASPS,
    PAYLOAD_BODIES,
    PLANAR_CONTACTS,
    POINT_CONTACTS,
    AttachNode,
    Constraint,
    ControlNode,
    DefineNode,
    Node,
    PlanarBody,
    SpatialBody,
    RobotSystem,
)
from robotgen.model.transforms import xyz_rpy
from robotgen.spec.loader import Document, Path, format_path, sort_errors
from robotgen.spec.urdf import read_urdf

DEFAULT_GRAVITY = (0.0, 0.0, -9.81)
DEFAULT_PLANAR_GRAVITY = (0.0, 0.0)
DEFAULT_BODY_COORDINATES = ("x", "y", "psi")
DEFAULT_SPATIAL_COORDINATES = ("x", "y", "z", "roll", "pitch", "yaw")
DEFAULT_COULOMB_SMOOTHING = 1e-2
# keys a joint needs, and keys it must not have, by convention
_CONVENTION_KEYS = {
    DH_STANDARD: (("dh",), ("origin", "axis")),
    DH_MODIFIED: (("dh",), ("origin", "axis")),
    JOINT_LIST: (("axis",), ("dh",)),
}


class _Builder:
    """Builds model objects from ``doc.data`` while collecting located errors."""

    def __init__(self, doc: Document):
        self.doc = doc
        self.errors: list[UserError] = []
        self.warnings: list[str] = []
        self.dependencies: list[str] = []

    # -- reporting -------------------------------------------------------------------
    def error(self, location: Location, path: Path, message: str) -> None:
        self.errors.append(UserError(location, f"{format_path(self.doc.data, path)}: {message}"))

    def at_key(self, path: Path, message: str) -> None:
        self.error(self.doc.source.key(path), path, message)

    def at_value(self, path: Path, message: str) -> None:
        self.error(self.doc.source.value(path), path, message)

    def text_location(self, path: Path, value: object) -> tuple[Location, bool]:
        if isinstance(value, str):
            return self.doc.source.text_start(path, value)
        return self.doc.source.value(path), True

    # -- numbers ---------------------------------------------------------------------
    def constant(self, path: Path, value: object, *, minimum: float | None = None,
                 exclusive: bool = False) -> float:
        location, exact = self.text_location(path, value)
        try:
            number = parse_constant(value, location, exact_columns=exact)
        except UserError as error:
            self.error(error.location, path, error.message)
            return 0.0
        if minimum is not None and (number <= minimum if exclusive else number < minimum):
            shown = f"{value!r} = {number:g}" if isinstance(value, str) else f"{number!r}"
            relation = "less than or equal to" if exclusive else "less than"
            self.at_value(path, f"{shown} is {relation} the minimum of {minimum:g}")
        return number

    def optional(self, mapping: dict, path: Path, key: str, default: float, **bounds) -> float:
        if key not in mapping:
            return default
        return self.constant(path + (key,), mapping[key], **bounds)

    def vector(self, path: Path, values: list | None, default) -> np.ndarray:
        if values is None:
            return np.array(default, dtype=float)
        return np.array([self.constant(path + (i,), v) for i, v in enumerate(values)])

    def pose(self, path: Path, pose: dict | None) -> np.ndarray:
        pose = pose or {}
        return xyz_rpy(self.vector(path + ("xyz",), pose.get("xyz"), (0, 0, 0)),
                       self.vector(path + ("rpy",), pose.get("rpy"), (0, 0, 0)))

    # -- chain -----------------------------------------------------------------------
    def inertia(self, path: Path, tensor: dict) -> np.ndarray:
        ixx, iyy, izz = (self.constant(path + (k,), tensor[k]) for k in ("ixx", "iyy", "izz"))
        ixy, ixz, iyz = (self.optional(tensor, path, k, 0.0) for k in ("ixy", "ixz", "iyz"))
        inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        moments = np.linalg.eigvalsh(inertia)  # ascending
        tolerance = 1e-9 * max(1.0, float(np.abs(inertia).max()))
        shown = ", ".join(f"{m:.6g}" for m in moments)
        if moments[0] < -tolerance:
            self.at_key(path, f"inertia is not positive semi-definite (principal moments {shown})")
        elif moments[0] + moments[1] < moments[2] - tolerance:
            # A warning, not an error: published parameter sets (the PUMA 560's among them)
            # carry such estimates, and M stays positive definite with them. `accept` keeps
            # a known one quiet.
            if TRIANGLE_INEQUALITY not in tensor.get("accept", ()):
                self.warnings.append(f"{self.doc.source.key(path)}: warning: {format_path(self.doc.data, path)}: "
                                     f"principal moments {shown} violate the triangle inequality I1 + I2 >= I3 "
                                     "(no rigid body has this inertia; if the data are published as such, "
                                     "add 'accept: [triangle_inequality]' to this inertia)")
        elif TRIANGLE_INEQUALITY in tensor.get("accept", ()):
            self.warnings.append(f"{self.doc.source.key(path + ('accept',))}: warning: "
                                 f"{format_path(self.doc.data, path + ('accept',))}: the principal moments "
                                 f"{shown} satisfy the triangle inequality; 'triangle_inequality' is not needed")
        return inertia

    def body(self, path: Path, link: dict | None) -> Body:
        if link is None:
            return Body.zero()
        mass = self.constant(path + ("mass",), link["mass"], minimum=0.0)
        com = self.vector(path + ("com",), link.get("com"), (0, 0, 0))
        inertia = self.inertia(path + ("inertia",), link["inertia"]) if "inertia" in link else np.zeros((3, 3))
        return Body(mass, com, inertia)

    def limits(self, path: Path, limits: dict | None) -> Limits:
        limits = limits or {}
        values = {k: self.constant(path + (k,), limits[k], minimum=0.0 if k in ("velocity", "effort") else None)
                  for k in ("lower", "upper", "velocity", "effort") if k in limits}
        if "lower" in values and "upper" in values and values["lower"] > values["upper"]:
            self.at_value(path + ("upper",), f"upper limit {values['upper']:g} is below lower limit {values['lower']:g}")
        return Limits(**values)

    def check_convention_keys(self, path: Path, joint: dict, convention: str) -> None:
        needed, foreign = _CONVENTION_KEYS[convention]
        for key in foreign:
            if key in joint:
                self.at_key(path + (key,), f"not used with convention {convention} "
                                           f"(it needs {' and '.join(needed)})")
        for key in needed:
            if key not in joint:
                self.at_key(path, f"missing required key '{key}' (convention {convention})")

    def axis(self, path: Path, values: list | None) -> np.ndarray:
        try:
            return unit_axis(self.vector(path, values, (0, 0, 1)))
        except ValueError as error:
            self.at_value(path, str(error))
            return np.array([0.0, 0.0, 1.0])  # placeholder; the error stops the build

    def joint_row(self, path: Path, joint: dict, index: int, convention: str) -> JointRow:
        self.check_convention_keys(path, joint, convention)
        motor = joint.get("motor") or {}
        friction = joint.get("friction") or {}
        geometry = {}
        if convention == JOINT_LIST:
            geometry["origin"] = self.pose(path + ("origin",), joint.get("origin"))
            geometry["axis"] = self.axis(path + ("axis",), joint.get("axis"))
        else:
            dh = joint.get("dh") or {}
            geometry["dh"] = DHParameters(**{k: self.optional(dh, path + ("dh",), k, 0.0)
                                             for k in ("a", "alpha", "d", "theta")})
        return JointRow(
            name=joint.get("name", f"q{index + 1}"),
            type=joint["type"],
            body=self.body(path + ("link",), joint.get("link")),
            motor_inertia=self.optional(motor, path + ("motor",), "inertia", 0.0, minimum=0.0),
            gear_ratio=self.optional(motor, path + ("motor",), "gear_ratio", 1.0),
            viscous=self.optional(friction, path + ("friction",), "viscous", 0.0, minimum=0.0),
            coulomb=self.optional(friction, path + ("friction",), "coulomb", 0.0, minimum=0.0),
            limits=self.limits(path + ("limits",), joint.get("limits")),
            **geometry,
        )

    def chain(self, name: str, path: Path, chain: dict) -> KinematicTree:
        convention = chain["convention"]
        rows = [self.joint_row(path + ("joints", i), joint, i, convention)
                for i, joint in enumerate(chain["joints"])]
        seen: set[str] = set()
        for i, row in enumerate(rows):
            if row.name in seen:
                self.at_key(path + ("joints", i, "name"), f"joint name '{row.name}' is used twice")
            seen.add(row.name)
        base = self.pose(path + ("base",), chain.get("base"))
        tool = self.pose(path + ("tool",), chain.get("tool"))
        joints, tool = canonical_chain(convention, rows, base, tool)
        return KinematicTree(
            name=name, joints=joints, tip=len(joints) - 1, tool=tool,
            gravity=self.vector(path + ("gravity",), chain.get("gravity"), DEFAULT_GRAVITY),
            coulomb_smoothing=self.optional(chain, path, "coulomb_smoothing", DEFAULT_COULOMB_SMOOTHING,
                                            minimum=0.0, exclusive=True),
            base_link="base", tip_link="tool",
        )

    # -- formulas --------------------------------------------------------------------
    def expression(self, path: Path, value: object, names: set[str]) -> Expr | None:
        location, exact = self.text_location(path, value)
        try:
            return parse_expression(value, location, names, exact_columns=exact)
        except UserError as error:
            self.error(error.location, path, error.message)
            return None

    def check_names(self, path: Path, entries: list[tuple[str, Path, str]]) -> None:
        """Names of coordinates, velocities and parameters: distinct, not reserved."""
        owner: dict[str, str] = {}
        for name, where, kind in entries:
            if name in FUNCTIONS or name in CONSTANTS:
                self.at_key(where, f"{kind} '{name}' shadows the {'function' if name in FUNCTIONS else 'constant'} "
                                   f"'{name}'")
            elif keyword.iskeyword(name):
                self.at_key(where, f"{kind} '{name}' is a reserved word")
            elif name in owner:
                self.at_key(where, f"{kind} '{name}' is already a {owner[name]} name")
            owner.setdefault(name, kind)

    def matrix(self, path: Path, rows: list, nq: int, names: set[str]) -> tuple[tuple[Expr, ...], ...]:
        if len(rows) != nq:
            self.at_key(path, f"expected {nq} x {nq} (nq = {nq}), got {len(rows)} rows")
        for i, row in enumerate(rows):
            if len(row) != nq:
                self.at_value(path + (i,), f"expected {nq} entries in each row, got {len(row)}")
        return tuple(self.vector_of_expressions(path + (i,), row, None, names) for i, row in enumerate(rows))

    def vector_of_expressions(self, path: Path, values: list, length: int | None,
                              names: set[str]) -> tuple[Expr, ...]:
        if length is not None and len(values) != length:
            self.at_key(path, f"expected {length} entries (nq = {length}), got {len(values)}")
        return tuple(self.expression(path + (i,), v, names) for i, v in enumerate(values))

    def formulas(self, name: str, path: Path, spec: dict) -> FormulaRobot:
        coordinates = tuple(spec["coordinates"])
        nq = len(coordinates)
        entries = [(c, path + ("coordinates", i), "coordinate") for i, c in enumerate(coordinates)]
        if "velocities" in spec:
            velocities = tuple(spec["velocities"])
            entries += [(v, path + ("velocities", i), "velocity") for i, v in enumerate(velocities)]
            if len(velocities) != nq:
                self.at_key(path + ("velocities",), f"expected {nq} names (one per coordinate), got {len(velocities)}")
        else:
            velocities = tuple("d" + c for c in coordinates)
            entries += [(v, path + ("coordinates", i), "velocity") for i, v in enumerate(velocities)]
        raw_parameters = spec.get("parameters", {})
        entries += [(p, path + ("parameters", p), "parameter") for p in raw_parameters]
        outputs = self.outputs(name, path, spec)
        if "outputs" in spec:
            entries += [(o, path + ("outputs", i), "output") for i, o in enumerate(outputs)]
        else:
            entries += [(o, path + ("kinematics", i), "output") for i, o in enumerate(outputs)]
        self.check_names(path, entries)
        parameters = {p: self.constant(path + ("parameters", p), v) for p, v in raw_parameters.items()}
        in_q = set(coordinates) | set(parameters)
        in_q_qd = in_q | set(velocities)
        inverse = None
        if "inverse_kinematics" in spec:
            if "kinematics" not in spec:
                self.at_key(path + ("inverse_kinematics",), "needs kinematics (it inverts them)")
            inverse = self.vector_of_expressions(path + ("inverse_kinematics",), spec["inverse_kinematics"],
                                                 nq, set(outputs) | set(parameters))
        units = spec.get("units", {})
        for key in units:
            if key not in coordinates and key not in outputs:
                self.at_key(path + ("units", key), f"'{key}' is not a coordinate or output of '{name}' "
                                                   f"(coordinates: {', '.join(coordinates)}"
                                                   f"{'; outputs: ' + ', '.join(outputs) if outputs else ''})")
        return FormulaRobot(
            name=name, coordinates=coordinates, velocities=velocities, parameters=parameters, units=dict(units),
            mass=self.matrix(path + ("M",), spec["M"], nq, in_q),
            coriolis=self.matrix(path + ("C",), spec["C"], nq, in_q_qd) if "C" in spec else None,
            nonlinear=self.vector_of_expressions(path + ("N",), spec["N"], nq, in_q_qd) if "N" in spec else None,
            kinematics=self.vector_of_expressions(path + ("kinematics",), spec["kinematics"], None, in_q)
            if "kinematics" in spec else None,
            outputs=outputs, inverse_kinematics=inverse,
        )

    def outputs(self, name: str, path: Path, spec: dict) -> tuple[str, ...]:
        """Names of the kinematics outputs: given, or <node>_x1, <node>_x2, ..."""
        n = len(spec.get("kinematics", ()))
        if "outputs" not in spec:
            return tuple(f"{name}_x{i + 1}" for i in range(n))
        outputs = tuple(spec["outputs"])
        if "kinematics" not in spec:
            self.at_key(path + ("outputs",), "needs kinematics (outputs name the kinematics' entries)")
        elif len(outputs) != n:
            self.at_key(path + ("outputs",), f"expected {n} names (one per kinematics entry), got {len(outputs)}")
        return outputs

    def rigid_body(self, name: str, path: Path, spec: dict) -> PlanarBody | SpatialBody:
        spatial = "spatial" in spec
        default = DEFAULT_SPATIAL_COORDINATES if spatial else DEFAULT_BODY_COORDINATES
        coordinates = tuple(spec.get("coordinates", default))
        if len(coordinates) != len(default):
            self.at_value(path + ("coordinates",), f"a {'spatial' if spatial else 'planar'} body has "
                                                   f"{len(default)} coordinates, got {len(coordinates)}")
        self.check_names(path, [(c, path + ("coordinates", i) if "coordinates" in spec else path, "coordinate")
                                for i, c in enumerate(coordinates)])
        gravity_default = DEFAULT_GRAVITY if spatial else DEFAULT_PLANAR_GRAVITY
        gravity = self.vector(path + ("gravity",), spec.get("gravity"), gravity_default)
        if len(gravity) != len(gravity_default):
            self.at_value(path + ("gravity",), f"a {'spatial' if spatial else 'planar'} body takes "
                                               f"{len(gravity_default)} gravity components, got {len(gravity)}")
        if spatial:
            body = spec["spatial"]
            return SpatialBody(
                name=name, coordinates=coordinates,
                mass=self.constant(path + ("spatial", "mass"), body["mass"], minimum=0.0),
                inertia=self.inertia(path + ("spatial", "inertia"), body["inertia"]), gravity=gravity)
        planar = spec["planar"]
        return PlanarBody(
            name=name, coordinates=coordinates,
            mass=self.constant(path + ("planar", "mass"), planar["mass"], minimum=0.0),
            inertia=self.constant(path + ("planar", "inertia"), planar["inertia"], minimum=0.0),
            gravity=gravity,
        )

    def urdf(self, name: str, path: Path, spec: dict) -> KinematicTree | None:
        """A URDF leaf; its own errors point into the URDF file, a missing file at the spec."""
        file = pathlib.Path(self.doc.path).parent / spec["file"]
        if not file.is_file():
            self.at_value(path + ("file",), f"URDF file '{spec['file']}' not found (looked for {file})")
            return None
        self.dependencies.append(str(file))
        try:
            chain = read_urdf(str(file), spec["tip"], spec.get("base"), name)
        except UserError as e:
            self.errors.append(e)
            return None
        self.warnings.extend(chain.notes)
        gravity = self.vector(path + ("gravity",), spec.get("gravity"), DEFAULT_GRAVITY)
        return dataclasses.replace(chain.tree, gravity=gravity)

    # -- nodes -----------------------------------------------------------------------
    def node(self, name: str, node: dict) -> Node:
        if "attach" in node:
            return self.attach(name, ("nodes", name, "attach"), node["attach"])
        if "control" in node:
            return self.control(name, ("nodes", name, "control"), node["control"])
        path: Path = ("nodes", name, "define")
        define = node["define"]
        if "chain" in define:
            return DefineNode(name, self.chain(name, path + ("chain",), define["chain"]))
        if "urdf" in define:
            return DefineNode(name, self.urdf(name, path + ("urdf",), define["urdf"]))
        if "rigid_body" in define:
            return DefineNode(name, self.rigid_body(name, path + ("rigid_body",), define["rigid_body"]))
        return DefineNode(name, self.formulas(name, path + ("formulas",), define["formulas"]))

    def attach(self, name: str, path: Path, spec: dict) -> AttachNode:
        """The node with its constraint's structure; a formulas constraint's expressions are
        parsed once the robots' coordinate names are known (``constraint_formulas``)."""
        raw = spec["constraint"]
        where = path + ("constraint",)
        if "frame_change" in raw:
            constraint = Constraint(FRAME_CHANGE, output=raw["frame_change"].get("output", "position"))
        elif "planar_contacts" in raw:
            points = raw["planar_contacts"]["points"]
            at = where + ("planar_contacts", "points")
            contacts = np.array([[self.constant(at + (i, k), v) for k, v in enumerate(point)]
                                 for i, point in enumerate(points)])
            constraint = Constraint(PLANAR_CONTACTS, contacts=contacts)
        elif "point_contacts" in raw:
            points = raw["point_contacts"]["points"]
            at = where + ("point_contacts", "points")
            contacts = np.array([[self.constant(at + (i, k), v) for k, v in enumerate(point)]
                                 for i, point in enumerate(points)])
            if np.linalg.norm(np.cross(contacts[1] - contacts[0], contacts[2] - contacts[0])) < 1e-9:
                self.at_key(at, "the first three contact points are collinear: they cannot fix the "
                                "payload's orientation")
            constraint = Constraint(POINT_CONTACTS, contacts=contacts)
        else:
            formulas = raw["formulas"]
            at = where + ("formulas",)
            coordinates = tuple(formulas["coordinates"])
            raw_parameters = formulas.get("parameters", {})
            self.check_names(at, [(c, at + ("coordinates", i), "coordinate") for i, c in enumerate(coordinates)]
                             + [(p, at + ("parameters", p), "parameter") for p in raw_parameters])
            parameters = {p: self.constant(at + ("parameters", p), v) for p, v in raw_parameters.items()}
            # J's rows fix the node's signature; its entries are parsed later
            rows = tuple(() for _ in formulas["J"]) if "J" in formulas else None
            constraint = Constraint(CONSTRAINT_FORMULAS, coordinates=coordinates, parameters=parameters, J=rows)
        return AttachNode(name, tuple(spec["robots"]), spec.get("payload"), constraint)

    def control(self, name: str, path: Path, spec: dict) -> ControlNode:
        """The node without its gains (they need the robot's dimension: ``control_gains``)."""
        forces = spec.get("internal_forces")
        return ControlNode(
            name=name, robot=spec["robot"], law=spec["law"], kp=None, kv=None,
            kv_internal=self.optional(spec, path, "kv_internal", 0.0, minimum=0.0),
            internal_forces=None if forces is None else
            np.array([self.constant(path + ("internal_forces", i), f) for i, f in enumerate(forces)]),
            resolve_internal_motion=bool(spec.get("resolve_internal_motion", False)),
        )

    # -- the tree --------------------------------------------------------------------
    def references(self, name: str, node: Node) -> list[tuple[str, Path, str]]:
        """(child, path of the reference, role) of a node, in file order."""
        if isinstance(node, AttachNode):
            path: Path = ("nodes", name, "attach")
            refs = [(r, path + ("robots", i), "robot") for i, r in enumerate(node.robots)]
            if node.payload is not None:
                refs.append((node.payload, path + ("payload",), "payload"))
            return refs
        if isinstance(node, ControlNode):
            return [(node.robot, ("nodes", name, "control", "robot"), "controlled robot")]
        return []

    def check_tree(self, nodes: dict[str, Node], root: str) -> set[str]:
        """Every reference names a node, each node is used at most once, the root is used by
        none, there are no cycles and the root reaches every node. Returns the nodes whose
        subtrees are whole (every node below exists, no cycle): their signatures can be
        worked out."""
        refs = {name: self.references(name, node) for name, node in nodes.items()}
        used_by: dict[str, Path] = {}
        reported: set[str] = set()  # nodes whose misuse is reported: not also "unreachable"
        for name, node_refs in refs.items():
            for child, path, role in node_refs:
                if child not in nodes:
                    self.at_value(path, f"'{child}' is not a node (nodes: {', '.join(nodes)})")
                elif child == root:
                    self.at_value(path, f"'{child}' is the root; the root cannot be used by another node")
                    reported.add(name)
                elif child in used_by:
                    self.at_value(path, f"'{child}' is already used by {format_path(self.doc.data, used_by[child])}; "
                                        "each node is used at most once")
                else:
                    used_by[child] = path

        whole: dict[str, bool] = {}
        stack: list[str] = []

        def visit(name: str) -> bool:
            if name in whole:
                return whole[name]
            stack.append(name)
            ok = True
            for child, path, _ in refs[name]:
                if child not in nodes:
                    ok = False
                elif child in stack:
                    ok = False
                    if child != root:  # a use of the root is reported above
                        loop = stack[stack.index(child):]
                        reported.update(loop)
                        self.at_value(path, f"'{child}' makes a cycle: {' -> '.join(loop + [child])}")
                elif not visit(child):
                    ok = False
            stack.pop()
            whole[name] = ok
            return ok

        for name in [root] + list(nodes) if root in nodes else nodes:
            visit(name)
        dangling = any(child not in nodes for node_refs in refs.values() for child, _, _ in node_refs)
        if root in nodes and not dangling:  # a misspelt reference would make its node look unused
            reached = {root} | reported
            frontier = list(reached)
            while frontier:
                for child, _, _ in refs[frontier.pop()]:
                    if child in nodes and child not in reached:
                        reached.add(child)
                        frontier.append(child)
            for name in nodes:
                if name not in reached:
                    self.at_key(("nodes", name), f"node '{name}' is not reachable from the root '{root}' "
                                                 "(every node but the root is used as a robot, payload or "
                                                 "controlled robot)")
        return {name for name, ok in whole.items() if ok}

    def leaf_below(self, nodes: dict[str, Node], name: str) -> Node:
        """The node itself, or what a chain of control nodes controls."""
        node = nodes[name]
        while isinstance(node, ControlNode):
            node = nodes[node.robot]
        return node

    def signatures(self, nodes: dict[str, Node], root: str, whole: set[str]) -> dict[str, Node]:
        """Checks every attach and control node against its children's signatures, children
        first, and completes them (constraint formulas, gains). Returns the final nodes."""
        system = RobotSystem(name=self.doc.data["name"], source=self.doc.path, source_sha256=self.doc.sha256,
                             nodes=nodes, root=root)
        known: dict[str, Signature | None] = {}

        def sig(name: str) -> Signature | None:
            if name in known:
                return known[name]
            known[name] = None
            if name not in whole:
                return None
            node = nodes[name]
            if any(sig(child) is None for child in node.children):
                return None
            if isinstance(node, DefineNode):
                if node.leaf is None:  # a URDF that failed to load
                    return None
                result = signature(system, name)
            else:
                before = len(self.errors)
                if isinstance(node, AttachNode):
                    nodes[name] = node = self.check_attach(system, node, [sig(r) for r in node.robots])
                else:
                    nodes[name] = node = self.check_control(system, node, sig(node.robot))
                if len(self.errors) > before:
                    return None
                try:
                    result = signature(system, name)
                except SignatureError as error:
                    self.at_key(("nodes", name, node.primitive), str(error))
                    return None
            known[name] = result
            return result

        for name in list(nodes):
            sig(name)
        return nodes

    def check_attach(self, system: RobotSystem, node: AttachNode, robots: list[Signature]) -> AttachNode:
        nodes = system.nodes
        path: Path = ("nodes", node.name, "attach")
        for i, r in enumerate(node.robots):
            leaf = getattr(nodes[r], "leaf", None)
            if isinstance(leaf, PAYLOAD_BODIES):
                self.at_value(path + ("robots", i), f"'{r}' is a rigid_body, a payload without actuators; "
                                                    "it cannot be a robot (give it as payload)")
        payload = None
        if node.payload is not None:
            payload = getattr(nodes[node.payload], "leaf", None)
            if not isinstance(payload, (*PAYLOAD_BODIES, FormulaRobot)):
                kind = (f"a {nodes[node.payload].primitive} node" if not isinstance(nodes[node.payload], DefineNode)
                        else "a chain")
                self.at_value(path + ("payload",), f"payload '{node.payload}' must be a define node with "
                                                   f"rigid_body or formulas (it is {kind})")
                payload = None
        m = sum(s.n_external for s in robots)
        c = node.constraint
        kind_path = path + ("constraint", c.kind)
        if c.kind == FRAME_CHANGE:
            if node.payload is not None:
                self.at_key(path + ("payload",), "frame_change takes no payload (nil payload, G = I); "
                                                 "use planar_contacts or formulas to hold one")
            owner: dict[str, str] = {}
            for i, r in enumerate(node.robots):
                below = self.leaf_below(nodes, r)
                leaf = getattr(below, "leaf", None)
                if isinstance(leaf, PAYLOAD_BODIES):
                    continue  # reported above
                if not isinstance(leaf, (KinematicTree, FormulaRobot)):
                    what = (f"an {below.primitive} node" if below is nodes[r]
                            else f"a control of {below.primitive} node '{below.name}'")
                    self.at_value(path + ("robots", i), f"'{r}' is {what}; frame_change needs a chain or a formulas "
                                                        "leaf with kinematics (possibly under control nodes)")
                    continue
                if isinstance(leaf, FormulaRobot) and not leaf.kinematics:
                    self.at_value(path + ("robots", i), f"robot '{r}' ({below.name}) has no kinematics; "
                                                        "frame_change needs a formulas leaf's kinematics")
                    continue
                self.check_unique(owner, kinematic_outputs(system, r) or (), r, path + ("robots", i), "output",
                                  "rename its outputs")
        elif c.kind in CONTACT_GRASPS:
            grasp = CONTACT_GRASPS[c.kind]
            if node.payload is None:
                self.at_key(kind_path, f"{c.kind} needs a payload: {grasp.payload}")
            elif payload is not None and len(leaf_names(payload)) != grasp.pose_dim:
                self.at_value(path + ("payload",), f"payload '{node.payload}' has {len(leaf_names(payload))} "
                                                   f"coordinates; {c.kind} needs {grasp.payload}")
            k = len(c.contacts)
            if m != grasp.tip_dim * k:
                self.at_key(kind_path + ("points",), f"{k} contact points need {grasp.tip_dim * k} robot "
                                                     f"coordinates (fingertip {grasp.axes} each); robots "
                                                     f"{', '.join(node.robots)} have {m}")
        else:
            if payload is not None and len(leaf_names(payload)) != len(c.coordinates):
                self.at_value(path + ("payload",), f"payload '{node.payload}' has {len(leaf_names(payload))} "
                                                   f"coordinates, the constraint {len(c.coordinates)}; the "
                                                   "payload's coordinates are the node's")
            node = dataclasses.replace(node, constraint=self.constraint_formulas(node, robots, m))
        return node

    def check_unique(self, owner: dict[str, str], names, robot: str, path: Path, kind: str, fix: str) -> None:
        for n in names:
            if n in owner and owner[n] != robot:
                self.at_value(path, f"{kind} '{n}' of '{robot}' is also one of '{owner[n]}'; "
                                    f"names must be unique across the robots: {fix}")
                return
        for n in names:
            owner.setdefault(n, robot)

    def constraint_formulas(self, node: AttachNode, robots: list[Signature], m: int) -> Constraint:
        """Parses h, h_inverse, J, G of a formulas constraint with the names each may read."""
        path: Path = ("nodes", node.name, "attach")
        at: Path = path + ("constraint", "formulas")
        spec = self.doc.data["nodes"][node.name]["attach"]["constraint"]["formulas"]
        c = node.constraint
        owner: dict[str, str] = {}
        for i, (r, s) in enumerate(zip(node.robots, robots)):
            self.check_unique(owner, s.external, r, path + ("robots", i), "coordinate",
                              "the formulas constraint reads robot coordinates by name; rename one")
        for i, name in enumerate(c.coordinates):
            if name in owner:
                self.at_key(at + ("coordinates", i), f"coordinate '{name}' is also a coordinate of robot "
                                                     f"'{owner[name]}'; rename one")
        for name in c.parameters:
            if name in owner:
                self.at_key(at + ("parameters", name), f"parameter '{name}' is also a coordinate of robot "
                                                       f"'{owner[name]}'; rename one")
        y, x, p = set(owner), set(c.coordinates), set(c.parameters)
        n = len(c.coordinates)
        h = self.vector_of_expressions(at + ("h",), spec["h"], None, y | p)
        if len(h) != n:
            self.at_key(at + ("h",), f"expected {n} entries (one per node coordinate), got {len(h)}")
        h_inverse = None
        if "h_inverse" in spec:
            h_inverse = self.vector_of_expressions(at + ("h_inverse",), spec["h_inverse"], None, x | p)
            if len(h_inverse) != m:
                self.at_key(at + ("h_inverse",), f"expected {m} entries (one per robot coordinate), "
                                                 f"got {len(h_inverse)}")
        J = None
        rows = m
        if "J" in spec:
            J = self.rectangle(at + ("J",), spec["J"], None, m, y | p, "robot coordinate")
            rows = len(J)
        G = self.rectangle(at + ("G",), spec["G"], n, rows, x | y | p,
                           "row of J" if "J" in spec else "robot coordinate, as J = I")
        return dataclasses.replace(c, h=h, h_inverse=h_inverse, J=J, G=G)

    def rectangle(self, path: Path, rows: list, n_rows: int | None, n_cols: int, names: set[str],
                  columns: str) -> tuple[tuple[Expr, ...], ...]:
        if n_rows is not None and len(rows) != n_rows:
            self.at_key(path, f"expected {n_rows} rows (one per node coordinate), got {len(rows)}")
        for i, row in enumerate(rows):
            if len(row) != n_cols:
                self.at_value(path + (i,), f"expected {n_cols} entries in each row (one per {columns}), "
                                           f"got {len(row)}")
        return tuple(self.vector_of_expressions(path + (i,), row, None, names) for i, row in enumerate(rows))

    def check_control(self, system: RobotSystem, node: ControlNode, robot: Signature) -> ControlNode:
        path: Path = ("nodes", node.name, "control")
        spec = self.doc.data["nodes"][node.name]["control"]
        if node.law == RESOLVED_RATE:
            return self.check_rate_control(system, node, spec, robot)
        if "resolved_rate" in spec:
            self.at_key(path + ("resolved_rate",), f"settings of law resolved_rate; this node's law is {node.law}")
        target = system.nodes[node.robot]
        if isinstance(getattr(target, "leaf", None), PAYLOAD_BODIES):
            self.at_value(path + ("robot",), f"'{node.robot}' is a rigid_body, a payload without actuators; "
                                             "it cannot be controlled")
        n = robot.n_external
        gains = {}
        for key in ("kp", "kv"):
            if node.law == FEEDFORWARD:
                if key in spec:
                    self.at_key(path + (key,), f"law feedforward takes no {key} (it is computed torque with "
                                               "Kp = Kv = 0)")
                gains[key] = np.zeros((n, n))
            elif key not in spec:
                self.at_key(path, f"missing required key '{key}' (law {node.law})")
                gains[key] = np.zeros((n, n))
            else:
                gains[key] = self.gain(path + (key,), spec[key], robot, node.robot)
        if node.internal_forces is not None:
            have = robot.n_internal_forces
            if node.law == PD:
                self.at_key(path + ("internal_forces",), "law pd cannot resolve internal forces (it passes the "
                                                         "robot's attributes up unchanged)")
            elif len(node.internal_forces) != have:
                listed = f" ({', '.join(robot.internal_forces)})" if have else ""
                self.at_key(path + ("internal_forces",), f"expected {have} values, one per internal force of "
                                                         f"'{node.robot}'{listed}, got {len(node.internal_forces)}")
        if node.resolve_internal_motion:
            if node.law == PD:
                self.at_key(path + ("resolve_internal_motion",), "law pd cannot resolve internal motion (it passes "
                                                                 "the robot's attributes up unchanged)")
            elif not robot.internal_motions:
                self.at_key(path + ("resolve_internal_motion",), f"robot '{node.robot}' has no internal motions "
                                                                 "to resolve")
        return dataclasses.replace(node, kp=gains["kp"], kv=gains["kv"])

    # -- resolved motion rate control (Whitney 1972) ------------------------------------
    def check_rate_control(self, system: RobotSystem, node: ControlNode, spec: dict, robot: Signature) -> ControlNode:
        """A resolved_rate controller: the root, over a chain or urdf leaf or over a composite
        robot (an attach node, possibly under control nodes)."""
        path: Path = ("nodes", node.name, "control")
        for key in ("kp", "kv", "kv_internal", "internal_forces", "resolve_internal_motion"):
            if key in spec:
                self.at_key(path + (key,), f"law resolved_rate takes no {key} (it outputs joint rates; "
                                           "its settings go under resolved_rate)")
        target = system.nodes[node.robot]
        chain = getattr(target, "leaf", None)
        below = self.leaf_below(system.nodes, node.robot)
        composite = isinstance(below, AttachNode)
        if not isinstance(chain, KinematicTree) and not composite:
            leaf = type(getattr(below, "leaf", None)).__name__
            what = (f"a {leaf} leaf" if below is target else f"a control node over the {leaf} leaf '{below.name}'")
            self.at_value(path + ("robot",), f"law resolved_rate controls a chain or urdf leaf, or a composite robot "
                                             f"(an attach node, possibly under control nodes); '{node.robot}' is {what}")
            return node
        if node.name != system.root:
            self.at_key(("nodes", node.name), f"a resolved_rate controller must be the root (it outputs joint "
                                              f"rates, which no node above can use); the root is '{system.root}'")
            return node
        settings = spec.get("resolved_rate", {})
        if composite:
            rate = self.composite_rate_settings(path + ("resolved_rate",), settings, system, node.robot, robot)
        else:
            rate = self.rate_settings(path + ("resolved_rate",), settings, chain)
        n = robot.n_external
        return dataclasses.replace(node, kp=np.zeros((n, n)), kv=np.zeros((n, n)), rate=rate)

    def composite_rate_settings(self, path: Path, spec: dict, system: RobotSystem, name: str,
                                robot: Signature) -> CompositeRateSettings:
        """Over a composite robot the command coordinates are the robot's own: only damping,
        rate limits (one per sensed leaf coordinate) and the horizon apply."""
        for key in spec:
            if key not in COMPOSITE_KEYS:
                self.at_key(path + (key,), f"'{key}' applies to a chain leaf; over the composite robot '{name}' the "
                                           f"command is its velocity in its own coordinates "
                                           f"({', '.join(robot.velocity_names)}) and the leaves' rates come from the "
                                           f"tree's velocity map (settings here: {', '.join(COMPOSITE_KEYS)})")
        leaves = [system.nodes[leaf].leaf for leaf in robot_leaves(system, name)]
        n = sum(leaf.nq for leaf in leaves)
        if "rate_limits" in spec:
            rate_limits = self.per_joint(path + ("rate_limits",), spec["rate_limits"], n, "rate limit", positive=True)
        else:
            # the joints' velocity limits, when every leaf is a chain and every joint has one
            chains = all(isinstance(leaf, KinematicTree) for leaf in leaves)
            velocities = [j.limits.velocity for leaf in leaves for j in leaf.joints] if chains else []
            limited = chains and all(v is not None and v > 0 for v in velocities)
            rate_limits = np.array(velocities, dtype=float) if limited else None
        return CompositeRateSettings(
            robot_names=robot.velocity_names, n_external=robot.n_external,
            angles=angle_coordinates(system, name), damping=self.damping(path, spec), rate_limits=rate_limits,
            horizon=self.optional(spec, path, "horizon", 0.1, minimum=0.0, exclusive=True))

    def damping(self, path: Path, spec: dict) -> Damping | None:
        if "damping" not in spec:
            return None
        d = spec["damping"]
        dpath = path + ("damping",)
        return Damping(self.constant(dpath + ("lambda_max",), d["lambda_max"], minimum=0.0, exclusive=True),
                       self.constant(dpath + ("threshold",), d["threshold"], minimum=0.0, exclusive=True))

    def rate_settings(self, path: Path, spec: dict, chain: KinematicTree) -> RateControlSettings:
        n = chain.nq
        kind = spec.get("frame", HAND)
        needs = {LINE_OF_SIGHT: "eye", SPHERICAL: "centre", TOOL: "tool"}
        for key in ("eye", "centre", "tool"):
            if key in spec and needs.get(kind) != key:
                self.at_key(path + (key,), f"'{key}' belongs to frame {next(f for f, k in needs.items() if k == key)}, "
                                           f"not {kind}")
        if kind in needs and needs[kind] not in spec:
            self.at_key(path, f"frame {kind} needs '{needs[kind]}'")
        point = tool = None
        if kind in (LINE_OF_SIGHT, SPHERICAL) and needs[kind] in spec:
            point = self.vector(path + (needs[kind],), spec[needs[kind]], (0, 0, 0))
        if kind == TOOL:
            tool = self.pose(path + ("tool",), spec.get("tool"))
        frame = CommandFrame(kind, point, tool)
        names = frame.axis_names

        def axes(key: str) -> tuple[bool, ...]:
            chosen = [False] * 6
            for i, name in enumerate(spec.get(key, ())):
                if name in names:
                    chosen[names.index(name)] = True
                elif name in GENERIC_AXES:
                    chosen[GENERIC_AXES.index(name)] = True
                else:
                    self.at_value(path + (key, i), f"'{name}' is not a command axis of frame {kind} "
                                                   f"({', '.join(names)}; or {', '.join(GENERIC_AXES)})")
            return tuple(chosen)

        active = axes("active") if "active" in spec else (True,) * 6
        free = axes("free")
        for i, name in enumerate(spec.get("free", ())):
            k = names.index(name) if name in names else GENERIC_AXES.index(name) if name in GENERIC_AXES else -1
            if k >= 0 and "active" in spec and active[k]:
                self.at_value(path + ("free", i), f"axis '{names[k]}' is both active and free")
        if "active" not in spec:
            active = tuple(not f for f in free)
        m = 6 - sum(free)
        if m == 0:
            self.at_key(path + ("free",), "every command axis is free: there is no task")
        elif m > n:
            self.at_key(path, f"the task has {m} command axes but '{chain.name}' has {n} joints; free "
                              f"{m - n} of them (key 'free')")
        weights = self.vector(path + ("weights",), spec.get("weights"), (1.0,) * 6)

        raw = spec.get("redundancy", {})
        rpath = path + ("redundancy",)
        objective = raw.get("objective", "none")
        redundancy = Redundancy(raw.get("method", PSEUDO_INVERSE), None if objective == "none" else objective,
                                self.optional(raw, rpath, "gain", 1.0, minimum=0.0, exclusive=True))
        if redundancy.method == EXTENDED_JACOBIAN:
            if n != m + 1:
                self.at_value(rpath + ("method",), f"extended_jacobian needs exactly one degree of redundancy: "
                                                   f"{n} joints, {m} task axes")
            if redundancy.objective != JOINT_LIMITS:
                self.at_key(rpath, "extended_jacobian needs objective joint_limits (the optimality condition "
                                   "z^T grad H = 0 is differentiated once more)")
        elif redundancy.objective is not None and n == m:
            self.warnings.append(f"{self.doc.source.key(rpath)}: warning: {format_path(self.doc.data, rpath)}: "
                                 f"'{chain.name}' has no redundancy ({n} joints, {m} task axes); the objective "
                                 "has no effect")
        if redundancy.objective == JOINT_LIMITS:
            if not any(j.limits.lower is not None and j.limits.upper is not None and j.limits.upper > j.limits.lower
                       for j in chain.joints):
                self.at_value(rpath + ("objective",), f"objective joint_limits needs position limits; no joint of "
                                                      f"'{chain.name}' has both lower and upper")

        damping = self.damping(path, spec)
        rate_limits = self.rate_limits(path + ("rate_limits",), spec, chain)
        horizon = self.optional(spec, path, "horizon", 0.1, minimum=0.0, exclusive=True)
        lqr = self.lqr_settings(path + ("lqr",), spec["lqr"], n) if "lqr" in spec else None
        return RateControlSettings(frame=frame, active=active, free=free, weights=weights, redundancy=redundancy,
                                   damping=damping, rate_limits=rate_limits, horizon=horizon, lqr=lqr)

    def per_joint(self, path: Path, value: object, n: int, what: str, *, positive: bool) -> np.ndarray:
        """A number (the same for every joint) or a list of n numbers."""
        if not isinstance(value, list):
            values = np.full(n, self.constant(path, value))
            if positive and values[0] <= 0:
                self.at_value(path, f"{what} {values[0]:g} must be positive")
            return values
        if len(value) != n:
            self.at_key(path, f"expected {n} entries (one per joint), got {len(value)}")
            return np.ones(n)
        values = np.array([self.constant(path + (i,), v) for i, v in enumerate(value)])
        for i, v in enumerate(values):
            if positive and v <= 0:
                self.at_value(path + (i,), f"{what} {v:g} must be positive")
        return values

    def rate_limits(self, path: Path, spec: dict, chain: KinematicTree) -> np.ndarray | None:
        if "rate_limits" in spec:
            return self.per_joint(path, spec["rate_limits"], chain.nq, "rate limit", positive=True)
        velocities = [j.limits.velocity for j in chain.joints]
        if all(v is not None and v > 0 for v in velocities):
            return np.array(velocities, dtype=float)
        return None

    def lqr_settings(self, path: Path, spec: dict, n: int) -> LQRSettings:
        nominal = spec["nominal"]
        if len(nominal) != n:
            self.at_key(path + ("nominal",), f"expected {n} joint positions, got {len(nominal)}")
        nominal = np.array([self.constant(path + ("nominal", i), v) for i, v in enumerate(nominal)])
        q = spec.get("q", [100, 1])
        if len(q) not in (2, 2 * n):
            self.at_key(path + ("q",), f"expected 2 entries (position, rate) or {2 * n} (one per state), "
                                       f"got {len(q)}")
        weights = np.array([self.constant(path + ("q", i), v) for i, v in enumerate(q)])
        for i, w in enumerate(weights):
            if w <= 0:
                self.at_value(path + ("q", i), f"weight {w:g} must be positive")
        if len(weights) == 2:
            weights = np.repeat(weights, n)
        r = self.per_joint(path + ("r",), spec.get("r", 1), n, "weight", positive=True)
        if len(nominal) != n or len(weights) != 2 * n:
            nominal, weights = np.zeros(n), np.ones(2 * n)
        return LQRSettings(nominal, weights, r)

    def gain(self, path: Path, value: object, robot: Signature, name: str) -> np.ndarray:
        """A scalar (times I), a per-axis list (diagonal) or a symmetric positive definite
        matrix, on the robot's n external coordinates."""
        n = robot.n_external
        axes = f"'{name}' has {n} external coordinate{'' if n == 1 else 's'}: {', '.join(robot.external)}"
        if not isinstance(value, list):
            s = self.constant(path, value)
            if s <= 0:
                self.at_value(path, f"gain {s:g} must be positive (the gain matrix must be positive definite)")
            return s * np.eye(n)
        if all(not isinstance(v, list) for v in value):
            if len(value) != n:
                self.at_key(path, f"expected {n} entries ({axes}), got {len(value)}")
            diagonal = [self.constant(path + (i,), v) for i, v in enumerate(value)]
            for i, d in enumerate(diagonal):
                if d <= 0:
                    self.at_value(path + (i,), f"gain {d:g} must be positive (the gain matrix must be "
                                               "positive definite)")
            return np.diag(diagonal) if len(diagonal) == n else np.zeros((n, n))
        if not all(isinstance(v, list) for v in value):
            self.at_value(path, "mixes numbers and rows: give a number, a list of numbers or a matrix")
            return np.zeros((n, n))
        if len(value) != n or any(len(row) != n for row in value):
            self.at_key(path, f"expected a {n} x {n} matrix ({axes}), got "
                              f"{len(value)} rows of {', '.join(sorted({str(len(r)) for r in value}))}")
            return np.zeros((n, n))
        matrix = np.array([[self.constant(path + (i, k), v) for k, v in enumerate(row)]
                           for i, row in enumerate(value)])
        scale = max(1.0, float(np.abs(matrix).max()))
        if not np.allclose(matrix, matrix.T, rtol=0, atol=1e-12 * scale):
            self.at_key(path, "gain matrix is not symmetric")
        elif np.linalg.eigvalsh(matrix)[0] <= 1e-12 * scale:
            shown = ", ".join(f"{e:.6g}" for e in np.linalg.eigvalsh(matrix))
            self.at_key(path, f"gain matrix is not positive definite (eigenvalues {shown})")
        return matrix

    # -- system ----------------------------------------------------------------------
    def system(self) -> RobotSystem:
        data = self.doc.data
        nodes = {name: self.node(name, node) for name, node in data["nodes"].items()}
        root = data["root"]
        if root not in nodes:
            self.at_value(("root",), f"'{root}' is not a node (nodes: {', '.join(nodes)})")
        whole = self.check_tree(nodes, root)
        nodes = self.signatures(nodes, root, whole)
        simulation = self.simulation(data["simulation"], nodes, root) if "simulation" in data else None
        return RobotSystem(name=data["name"], source=self.doc.path, source_sha256=self.doc.sha256,
                           nodes=nodes, root=root, warnings=tuple(self.warnings), simulation=simulation,
                           dependencies=tuple(self.dependencies),
                           node_locations={name: self.doc.source.key(("nodes", name)) for name in nodes})

    def simulation(self, spec: dict, nodes: dict[str, Node], root: str) -> SimulationSettings:
        """The settings, each list checked against the dimensions it must have: the root's
        coordinates (start, initial_error, amplitude, frequency), the leaves' joints (theta0),
        the root's unresolved internal forces (internal_forces)."""
        path: Path = ("simulation",)
        values = {k: self.constant(path + (k,), spec[k]) for k in ("duration", "dt") if k in spec}
        for k in ("start", "theta0", "initial_error", "amplitude", "frequency", "internal_forces"):
            if k in spec:
                values[k] = tuple(self.constant(path + (k, i), v) for i, v in enumerate(spec[k]))
        if "initial_error" in spec and "theta0" in spec:
            self.at_key(path + ("initial_error",), "initial_error offsets the plant from start through inverse "
                                                   "kinematics; with theta0 the plant starts at theta0 (give the "
                                                   "perturbed joint positions there, or drop theta0)")
        if "initial_error" in spec and "start" not in spec and "theta0" not in spec:
            self.at_key(path + ("initial_error",), "initial_error offsets the plant from start: give start too")
        system = RobotSystem(name=self.doc.data["name"], source=self.doc.path, source_sha256=self.doc.sha256,
                             nodes=nodes, root=root)
        try:
            sig = signature(system, root)
            leaves = [nodes[leaf].leaf for leaf in robot_leaves(system)]
        except (SignatureError, KeyError, AttributeError):
            sig = None  # the tree has errors of its own, reported elsewhere
        if sig is not None and all(leaf is not None for leaf in leaves):
            n_theta = sum(leaf.nq for leaf in leaves)
            coords = ", ".join(sig.external)
            expected = {
                "start": (sig.n_external, f"one per root coordinate of '{root}': {coords}"),
                "initial_error": (sig.n_external, f"one per root coordinate of '{root}': {coords}"),
                "amplitude": (sig.n_external, f"one per root coordinate of '{root}': {coords}"),
                "frequency": (sig.n_external, f"one per root coordinate of '{root}': {coords}"),
                "theta0": (n_theta, "one per joint of the leaves "
                                    f"({', '.join(robot_leaves(system))}), in tree order"),
                "internal_forces": (sig.n_internal_forces,
                                    f"one per internal force the root leaves unresolved: "
                                    f"{', '.join(sig.internal_forces) or 'none'}"),
            }
            for key, (n, what) in expected.items():
                if key in spec and len(spec[key]) != n:
                    self.at_key(path + (key,), f"expected {n} entries ({what}), got {len(spec[key])}")
        locations = {k: self.doc.source.key(path + (k,)) for k in spec}
        return SimulationSettings(**values, locations=locations)


def leaf_names(leaf) -> tuple[str, ...]:
    return tuple(j.name for j in leaf.joints) if isinstance(leaf, KinematicTree) else tuple(leaf.coordinates)


def to_system(doc: Document) -> RobotSystem:
    """The RobotSystem of a schema-valid document; raises UserErrors with every problem."""
    builder = _Builder(doc)
    system = builder.system()
    if builder.errors:
        raise UserErrors(sort_errors(builder.errors))
    return system
