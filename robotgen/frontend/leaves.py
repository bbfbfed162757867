"""DEFINE's leaves from a spec (Deno et al. 1990, §3.2): chains (DH standard, DH modified,
URDF-like joint lists), URDF leaves, formulas (M, C, N as expressions) and rigid payload
bodies, with the checks the schema cannot express (inertia physically valid, joint keys
that fit the convention, unique names, formula shapes and the names each may read)."""

from __future__ import annotations

import dataclasses
import pathlib

import numpy as np

from robotgen.errors import UserError
from robotgen.frontend.collector import Collector
from robotgen.frontend.document import Path, format_path
from robotgen.frontend.urdf import read_urdf
from robotgen.model.chain import TRIANGLE_INEQUALITY, Body, KinematicTree, Limits, joints_without_inertia
from robotgen.model.dh import DH_MODIFIED, DH_STANDARD, JOINT_LIST, DHParameters, JointRow, canonical_chain, unit_axis
from robotgen.model.expression import MATH_LIB, Expr, evaluate
from robotgen.model.formula import FormulaRobot, Mechanism
from robotgen.model.system import (
    PAYLOAD_MASS,
    PlanarBody,
    SpatialBody,
)

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


class LeafReader(Collector):
    """DEFINE leaves."""

    def inertia(self, path: Path, tensor: dict) -> np.ndarray:
        """A (3, 3) inertia tensor [kg m^2] about the centre of mass: an error unless positive semi-definite, a
        warning off the triangle inequality."""
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
                self.warnings.append(
                    f"{self.doc.source.key(path)}: warning: {format_path(self.doc.data, path)}: "
                    f"principal moments {shown} violate the triangle inequality I1 + I2 >= I3 "
                    "(no rigid body has this inertia; if the data are published as such, "
                    "add 'accept: [triangle_inequality]' to this inertia)"
                )
        elif TRIANGLE_INEQUALITY in tensor.get("accept", ()):
            self.warnings.append(
                f"{self.doc.source.key(path + ('accept',))}: warning: "
                f"{format_path(self.doc.data, path + ('accept',))}: the principal moments "
                f"{shown} satisfy the triangle inequality; 'triangle_inequality' is not needed"
            )
        return inertia

    def body(self, path: Path, link: dict | None) -> Body:
        """A link's Body: mass [kg], centre of mass (3,) [m], inertia (3, 3) [kg m^2]; a massless body without the
        link."""
        if link is None:
            return Body.zero()
        mass = self.constant(path + ("mass",), link["mass"], minimum=0.0)
        com = self.vector(path + ("com",), link.get("com"), (0, 0, 0))
        inertia = self.inertia(path + ("inertia",), link["inertia"]) if "inertia" in link else np.zeros((3, 3))
        return Body(mass, com, inertia)

    def limits(self, path: Path, limits: dict | None) -> Limits:
        """A joint's Limits (lower, upper, velocity, effort), upper not below lower."""
        limits = limits or {}
        values = {
            k: self.constant(path + (k,), limits[k], minimum=0.0 if k in ("velocity", "effort") else None)
            for k in ("lower", "upper", "velocity", "effort")
            if k in limits
        }
        if "lower" in values and "upper" in values and values["lower"] > values["upper"]:
            self.at_value(
                path + ("upper",), f"upper limit {values['upper']:g} is below lower limit {values['lower']:g}"
            )
        return Limits(**values)

    def check_convention_keys(self, path: Path, joint: dict, convention: str) -> None:
        """Check a joint's keys against its convention: none of another convention's, all of its own."""
        needed, foreign = _CONVENTION_KEYS[convention]
        for key in foreign:
            if key in joint:
                self.at_key(path + (key,), f"not used with convention {convention} (it needs {' and '.join(needed)})")
        for key in needed:
            if key not in joint:
                self.at_key(path, f"missing required key '{key}' (convention {convention})")

    def axis(self, path: Path, values: list | None) -> np.ndarray:
        """A joint axis (3,) as a unit vector (default z); a zero axis is a located error."""
        try:
            return unit_axis(self.vector(path, values, (0, 0, 1)))
        except ValueError as error:
            self.at_value(path, str(error))
            return np.array([0.0, 0.0, 1.0])  # placeholder; the error stops the build

    def joint_row(self, path: Path, joint: dict, index: int, convention: str) -> JointRow:
        """One joint of a chain spec as a JointRow: its geometry in the chain's convention, type, body, limits,
        motor, friction."""
        self.check_convention_keys(path, joint, convention)
        motor = joint.get("motor") or {}
        friction = joint.get("friction") or {}
        origin = axis = dh_row = None
        if convention == JOINT_LIST:
            origin = self.pose(path + ("origin",), joint.get("origin"))
            axis = self.axis(path + ("axis",), joint.get("axis"))
        else:
            dh = joint.get("dh") or {}
            dh_row = DHParameters(
                **{k: self.optional(dh, path + ("dh",), k, 0.0) for k in ("a", "alpha", "d", "theta")}
            )
        return JointRow(
            name=joint.get("name", f"q{index + 1}"),
            type=joint["type"],
            body=self.body(path + ("link",), joint.get("link")),
            motor_inertia=self.optional(motor, path + ("motor",), "inertia", 0.0, minimum=0.0),
            gear_ratio=self.optional(motor, path + ("motor",), "gear_ratio", 1.0),
            viscous=self.optional(friction, path + ("friction",), "viscous", 0.0, minimum=0.0),
            coulomb=self.optional(friction, path + ("friction",), "coulomb", 0.0, minimum=0.0),
            limits=self.limits(path + ("limits",), joint.get("limits")),
            dh=dh_row,
            origin=origin,
            axis=axis,
        )

    def chain(self, name: str, path: Path, chain: dict) -> KinematicTree:
        """A chain leaf as a KinematicTree: its joints in its convention (DH or joint list), base and tool, names
        unique."""
        convention = chain["convention"]
        rows = [self.joint_row(path + ("joints", i), joint, i, convention) for i, joint in enumerate(chain["joints"])]
        seen: set[str] = set()
        for i, row in enumerate(rows):
            if row.name in seen:
                self.at_key(path + ("joints", i, "name"), f"joint name '{row.name}' is used twice")
            seen.add(row.name)
        base = self.pose(path + ("base",), chain.get("base"))
        tool = self.pose(path + ("tool",), chain.get("tool"))
        joints, tool = canonical_chain(convention, rows, base, tool)
        for i in joints_without_inertia(KinematicTree(name, joints, len(joints) - 1, tool, np.array(DEFAULT_GRAVITY))):
            self.warnings.append(
                f"{self.doc.source.key(path + ('joints', i))}: warning: {name}: joint "
                f"'{joints[i].name}' moves no mass, inertia or motor inertia: M is singular and "
                "forward dynamics returns no finite answer (give its link a mass)"
            )
        return KinematicTree(
            name=name,
            joints=joints,
            tip=len(joints) - 1,
            tool=tool,
            gravity=self.vector(path + ("gravity",), chain.get("gravity"), DEFAULT_GRAVITY),
            coulomb_smoothing=self.optional(
                chain, path, "coulomb_smoothing", DEFAULT_COULOMB_SMOOTHING, minimum=0.0, exclusive=True
            ),
            base_link="base",
            tip_link="tool",
        )

    def matrix(self, path: Path, rows: list, nq: int, names: set[str]) -> tuple[tuple[Expr, ...], ...]:
        """An nq x nq matrix of formula expressions (a formulas leaf's M), its shape checked."""
        if len(rows) != nq:
            self.at_key(path, f"expected {nq} x {nq} (nq = {nq}), got {len(rows)} rows")
        for i, row in enumerate(rows):
            if len(row) != nq:
                self.at_value(path + (i,), f"expected {nq} entries in each row, got {len(row)}")
        return tuple(self.vector_of_expressions(path + (i,), row, None, names) for i, row in enumerate(rows))

    def formulas(self, name: str, path: Path, spec: dict) -> FormulaRobot:
        """A formulas leaf as a FormulaRobot: its coordinates and velocities, M, C, N and kinematics as checked
        expressions."""
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
        read = {p: self.parameter(path + ("parameters", p), v) for p, v in raw_parameters.items()}
        parameters = {p: value for p, (value, _) in read.items()}
        runtime = frozenset(p for p, (_, is_runtime) in read.items() if is_runtime)
        in_q = set(coordinates) | set(parameters)
        in_q_qd = in_q | set(velocities)
        inverse = None
        if "inverse_kinematics" in spec:
            if "kinematics" not in spec:
                self.at_key(path + ("inverse_kinematics",), "needs kinematics (it inverts them)")
            inverse = self.vector_of_expressions(
                path + ("inverse_kinematics",), spec["inverse_kinematics"], nq, set(outputs) | set(parameters)
            )
        units = spec.get("units", {})
        for key in units:
            if key not in coordinates and key not in outputs:
                self.at_key(
                    path + ("units", key),
                    f"'{key}' is not a coordinate or output of '{name}' "
                    f"(coordinates: {', '.join(coordinates)}"
                    f"{'; outputs: ' + ', '.join(outputs) if outputs else ''})",
                )
        before = len(self.errors)
        mass = self.matrix(path + ("M",), spec["M"], nq, in_q)
        if len(self.errors) == before:
            self.check_mass_matrix(path + ("M",), mass, coordinates, parameters)
        return FormulaRobot(
            name=name,
            coordinates=coordinates,
            velocities=velocities,
            parameters=parameters,
            units=dict(units),
            runtime=runtime,
            mass=mass,
            coriolis=self.matrix(path + ("C",), spec["C"], nq, in_q_qd) if "C" in spec else None,
            nonlinear=self.vector_of_expressions(path + ("N",), spec["N"], nq, in_q_qd) if "N" in spec else None,
            kinematics=self.vector_of_expressions(path + ("kinematics",), spec["kinematics"], None, in_q)
            if "kinematics" in spec
            else None,
            outputs=outputs,
            inverse_kinematics=inverse,
            mechanism=self.mechanism(name, path + ("mechanism",), spec["mechanism"], coordinates, parameters)
            if "mechanism" in spec
            else None,
        )

    def mechanism(
        self, name: str, path: Path, spec: dict, coordinates: tuple[str, ...], parameters: dict[str, float]
    ) -> Mechanism | None:
        """A formulas leaf's bodies: a chain (every key of `chain`) and the leaf's coordinates
        as affine expressions of the chain's joint positions, theta = T q + offset, T
        invertible (checked at the unit vectors and at random q)."""
        tree = self.chain(name, path, {k: v for k, v in spec.items() if k != "coordinates"})
        joints = tuple(j.name for j in tree.joints)
        if len(joints) != len(coordinates):
            self.at_key(
                path + ("joints",),
                f"the mechanism has {len(joints)} joints; '{name}' has {len(coordinates)} "
                f"coordinates ({', '.join(coordinates)}), one per joint",
            )
            return None
        self.check_names(
            path,
            [(j, path + ("joints", i), "joint") for i, j in enumerate(joints)]
            + [(p, path + ("coordinates",), "parameter") for p in parameters],
        )
        at = path + ("coordinates",)
        before = len(self.errors)
        exprs = self.vector_of_expressions(at, spec["coordinates"], len(coordinates), set(joints) | set(parameters))
        if len(self.errors) > before:
            return None
        n = len(joints)

        def theta(q: np.ndarray) -> np.ndarray:
            env = {**parameters, **dict(zip(joints, (float(v) for v in q)))}
            return np.array([float(evaluate(e, env, MATH_LIB)) for e in exprs])

        try:
            offset = theta(np.zeros(n))
            T = np.column_stack([theta(np.eye(n)[j]) - offset for j in range(n)])
            samples = np.random.default_rng(0).uniform(-np.pi, np.pi, size=(4, n))
            worst = max(float(np.abs(theta(q) - T @ q - offset).max()) for q in samples)
        except (ArithmeticError, ValueError):
            self.at_key(
                at,
                "cannot be evaluated at q = 0 and the unit vectors (they must be affine in the "
                f"joint positions {', '.join(joints)})",
            )
            return None
        scale = 1.0 + float(np.abs(T).max()) * np.pi + float(np.abs(offset).max())
        if worst > 1e-9 * scale:
            self.at_key(
                at,
                f"must be affine in the joint positions {', '.join(joints)} (theta = T q + offset, "
                f"as absolute link angles are of relative joints); off by {worst:.3g} at random q",
            )
            return None
        if abs(np.linalg.det(T)) < 1e-12 * max(1.0, float(np.abs(T).max())) ** n:
            self.at_key(
                at,
                f"T = d({', '.join(coordinates)})/d({', '.join(joints)}) is singular: every coordinate "
                "of the leaf must come from the joints one to one",
            )
            return None
        return Mechanism(tree, exprs, T, offset, self.doc.source.key(path))

    def check_mass_matrix(
        self, path: Path, mass: tuple[tuple[Expr, ...], ...], coordinates: tuple[str, ...], parameters: dict[str, float]
    ) -> None:
        """M must be symmetric and positive definite: checked at q = 0 and at 16 random
        configurations in [-pi, pi] (a fixed seed; run-time parameters at their defaults).
        Forward dynamics factorises M (L D L^T), which reads one triangle only and fails
        where M is not positive definite."""
        n = len(coordinates)
        rng = np.random.default_rng(0)
        for q in [np.zeros(n), *rng.uniform(-np.pi, np.pi, size=(16, n))]:
            env = {**parameters, **dict(zip(coordinates, (float(v) for v in q)))}
            try:
                M = np.array([[float(evaluate(e, env, MATH_LIB)) for e in row] for row in mass])
            except (ArithmeticError, ValueError):
                continue  # M undefined at this sample (a division by a coordinate, say)
            if not np.all(np.isfinite(M)):
                continue
            at = ", ".join(f"{c} = {v:.3g}" for c, v in zip(coordinates, q))
            scale = max(np.abs(M).max(), 1e-300)
            for i in range(n):
                for j in range(i):
                    if abs(M[i, j] - M[j, i]) > 1e-12 * scale:
                        self.at_value(
                            path + (i, j),
                            f"M is not symmetric: M[{i}][{j}] = {M[i, j]:.6g} but M[{j}][{i}] = {M[j, i]:.6g} at {at}",
                        )
                        return
            smallest = float(np.linalg.eigvalsh(M).min())
            if smallest <= 1e-12 * scale:
                self.at_key(
                    path,
                    f"M is not positive definite at {at} (smallest eigenvalue {smallest:.3g}); an "
                    "inertia matrix is, at every configuration",
                )
                return

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
        """A rigid_body leaf (a payload): planar (x, y, angle) or spatial (6 coordinates), with its mass and inertia."""
        spatial = "spatial" in spec
        default = DEFAULT_SPATIAL_COORDINATES if spatial else DEFAULT_BODY_COORDINATES
        coordinates = tuple(spec.get("coordinates", default))
        if len(coordinates) != len(default):
            self.at_value(
                path + ("coordinates",),
                f"a {'spatial' if spatial else 'planar'} body has {len(default)} coordinates, got {len(coordinates)}",
            )
        self.check_names(
            path,
            [
                (c, path + ("coordinates", i) if "coordinates" in spec else path, "coordinate")
                for i, c in enumerate(coordinates)
            ],
        )
        gravity_default = DEFAULT_GRAVITY if spatial else DEFAULT_PLANAR_GRAVITY
        gravity = self.vector(path + ("gravity",), spec.get("gravity"), gravity_default)
        if len(gravity) != len(gravity_default):
            self.at_value(
                path + ("gravity",),
                f"a {'spatial' if spatial else 'planar'} body takes "
                f"{len(gravity_default)} gravity components, got {len(gravity)}",
            )
        kind = "spatial" if spatial else "planar"
        mass, is_runtime = self.parameter(path + (kind, "mass"), spec[kind]["mass"], PAYLOAD_MASS)
        runtime = frozenset({"mass"} if is_runtime else ())
        if spatial:
            body = spec["spatial"]
            return SpatialBody(
                name=name,
                coordinates=coordinates,
                mass=mass,
                runtime=runtime,
                inertia=self.inertia(path + ("spatial", "inertia"), body["inertia"]),
                gravity=gravity,
            )
        planar = spec["planar"]
        return PlanarBody(
            name=name,
            coordinates=coordinates,
            mass=mass,
            runtime=runtime,
            inertia=self.constant(path + ("planar", "inertia"), planar["inertia"], minimum=0.0),
            gravity=gravity,
        )

    def urdf(self, name: str, path: Path, spec: dict) -> KinematicTree | None:
        """A URDF leaf; its own errors point into the URDF file, a missing file at the spec."""
        file = pathlib.Path(self.doc.path).parent / spec["file"]
        if not file.exists():  # a FIFO or a device is refused by the reader, named as such
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
