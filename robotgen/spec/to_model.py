"""Schema-valid spec document -> RobotSystem, with the checks the schema cannot express:
root exists, constant expressions, inertia physically valid, joint keys that fit the
convention, unique names, formula shapes and the names each formula may read.
Every problem is collected; nothing is returned unless there are none."""
from __future__ import annotations

import dataclasses
import keyword
import pathlib

import numpy as np

from robotgen.errors import Location, UserError, UserErrors
from robotgen.model.chain import Body, KinematicTree, Limits
from robotgen.model.dh import DH_MODIFIED, DH_STANDARD, JOINT_LIST, DHParameters, JointRow, canonical_chain, unit_axis
from robotgen.model.expression import CONSTANTS, FUNCTIONS, Expr, parse_constant, parse_expression
from robotgen.model.formula import FormulaRobot
from robotgen.model.system import DefineNode, RobotSystem
from robotgen.model.transforms import xyz_rpy
from robotgen.spec.loader import Document, Path, format_path, sort_errors
from robotgen.spec.urdf import read_urdf

DEFAULT_GRAVITY = (0.0, 0.0, -9.81)
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
            # carry such estimates, and M stays positive definite with them.
            self.warnings.append(f"{self.doc.source.key(path)}: warning: {format_path(self.doc.data, path)}: "
                                 f"principal moments {shown} violate the triangle inequality I1 + I2 >= I3 "
                                 "(no rigid body has this inertia)")
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
        self.check_names(path, entries)
        parameters = {p: self.constant(path + ("parameters", p), v) for p, v in raw_parameters.items()}
        in_q = set(coordinates) | set(parameters)
        in_q_qd = in_q | set(velocities)
        return FormulaRobot(
            name=name, coordinates=coordinates, velocities=velocities, parameters=parameters,
            mass=self.matrix(path + ("M",), spec["M"], nq, in_q),
            coriolis=self.matrix(path + ("C",), spec["C"], nq, in_q_qd) if "C" in spec else None,
            nonlinear=self.vector_of_expressions(path + ("N",), spec["N"], nq, in_q_qd) if "N" in spec else None,
            kinematics=self.vector_of_expressions(path + ("kinematics",), spec["kinematics"], None, in_q)
            if "kinematics" in spec else None,
        )

    def urdf(self, name: str, path: Path, spec: dict) -> KinematicTree | None:
        """A URDF leaf; its own errors point into the URDF file, a missing file at the spec."""
        file = pathlib.Path(self.doc.path).parent / spec["file"]
        if not file.is_file():
            self.at_value(path + ("file",), f"URDF file '{spec['file']}' not found (looked for {file})")
            return None
        try:
            chain = read_urdf(str(file), spec["tip"], spec.get("base"), name)
        except UserError as e:
            self.errors.append(e)
            return None
        self.warnings.extend(chain.ignored_attributes)
        gravity = self.vector(path + ("gravity",), spec.get("gravity"), DEFAULT_GRAVITY)
        return dataclasses.replace(chain.tree, gravity=gravity)

    # -- system ----------------------------------------------------------------------
    def node(self, name: str, node: dict) -> DefineNode:
        path: Path = ("nodes", name, "define")
        define = node["define"]
        if "chain" in define:
            return DefineNode(name, self.chain(name, path + ("chain",), define["chain"]))
        if "urdf" in define:
            return DefineNode(name, self.urdf(name, path + ("urdf",), define["urdf"]))
        return DefineNode(name, self.formulas(name, path + ("formulas",), define["formulas"]))

    def system(self) -> RobotSystem:
        data = self.doc.data
        nodes = {name: self.node(name, node) for name, node in data["nodes"].items()}
        if data["root"] not in nodes:
            self.at_value(("root",), f"'{data['root']}' is not a node (nodes: {', '.join(nodes)})")
        return RobotSystem(name=data["name"], source=self.doc.path, source_sha256=self.doc.sha256,
                           nodes=nodes, root=data["root"], warnings=tuple(self.warnings))


def to_system(doc: Document) -> RobotSystem:
    """The RobotSystem of a schema-valid document; raises UserErrors with every problem."""
    builder = _Builder(doc)
    system = builder.system()
    if builder.errors:
        raise UserErrors(sort_errors(builder.errors))
    return system
