"""CONTROL nodes from a spec (Deno et al. 1990, §3.4): the node, its gains (scalar, per axis or
symmetric positive definite on the robot's external coordinates) and what it resolves; a
law's own settings are read by its module in this package."""

from __future__ import annotations

import dataclasses

import numpy as np

from robotgen.frontend.collector import Collector
from robotgen.frontend.document import Path
from robotgen.model.laws.registry import LAWS
from robotgen.model.parameters import DIAGONAL_GAIN, MATRIX_GAIN, SCALAR_GAIN, Bounds
from robotgen.model.signature import Signature
from robotgen.model.system import (
    ANCHOR,
    DAMPING,
    GAIN,
    GAIN_MATRIX,
    PAYLOAD_BODIES,
    RUNTIME_GAINS,
    ControlNode,
    DefineNode,
    RobotSystem,
)

# the node's own keys, which a root law takes none of (its settings go under its name)
NODE_KEYS = (
    "kp",
    "kv",
    "kv_internal",
    "kf_internal",
    "ki_internal",
    "internal_forces",
    "resolve_internal_motion",
    "gains",
    "period",
    "anchor",
)


class ControlReader(Collector):
    """CONTROL nodes and their gains."""

    def control(self, name: str, path: Path, spec: dict) -> ControlNode:
        """The node without its gains (they need the robot's dimension: ``control_gains``)."""
        forces = spec.get("internal_forces")
        return ControlNode(
            name=name,
            robot=spec["robot"],
            law=spec["law"],
            kp=np.zeros((0, 0)),
            kv=np.zeros((0, 0)),  # read later
            kv_internal=self.bounded(path + ("kv_internal",), spec["kv_internal"], DAMPING)
            if "kv_internal" in spec
            else 0.0,
            internal_forces=None
            if forces is None
            else np.array([self.constant(path + ("internal_forces", i), f) for i, f in enumerate(forces)]),
            kf_internal=self.optional(spec, path, "kf_internal", None, minimum=0.0),
            ki_internal=self.optional(spec, path, "ki_internal", None, minimum=0.0),
            resolve_internal_motion=bool(spec.get("resolve_internal_motion", False)),
            runtime_gains=spec.get("gains", RUNTIME_GAINS) == RUNTIME_GAINS,
            period=self.optional(spec, path, "period", None, minimum=0.0, exclusive=True),
            anchor=self._anchor(path, spec),
        )

    def _anchor(self, path: Path, spec: dict) -> float | None:
        """The expected trajectory's time constant: ANCHOR if absent, None for ``false``."""
        value = spec.get("anchor", ANCHOR)
        if value is False:
            return None
        if value is True:
            self.at_value(path + ("anchor",), "anchor takes a time constant [s] > 0, or false")
            return ANCHOR
        return self.constant(path + ("anchor",), value, minimum=0.0, exclusive=True)

    def check_control(self, system: RobotSystem, node: ControlNode, robot: Signature) -> ControlNode:
        """The node checked against its law (robotgen.model.laws.registry): a root law takes
        none of the node's own keys and reads its settings block; a tree law's gains, what it
        resolves, then its settings block if it has one."""
        path: Path = ("nodes", node.name, "control")
        spec = self.doc.data["nodes"][node.name]["control"]
        law = LAWS[node.law]
        for other in LAWS.values():
            if other.settings is not None and other.name != law.name and other.name in spec:
                self.at_key(path + (other.name,), f"settings of law {other.name}; this node's law is {law.name}")
        if not law.expected:  # (a root law's `anchor` is refused below, as its other node keys)
            if "anchor" in spec and not law.is_root:
                self.at_key(path + ("anchor",), f"law {law.name} integrates no expected trajectory to anchor")
            node = dataclasses.replace(node, anchor=None)
        if law.is_root:
            for key in NODE_KEYS:
                if key in spec:
                    self.at_key(path + (key,), f"law {law.name} takes no {key} here (its settings go under {law.name})")
            return law.part("settings")(self, system, node, spec, robot)
        target = system.nodes[node.robot]
        if isinstance(target, DefineNode) and isinstance(target.leaf, PAYLOAD_BODIES):
            self.at_value(
                path + ("robot",),
                f"'{node.robot}' is a rigid_body, a payload without actuators; it cannot be controlled",
            )
        n = robot.n_external
        gains = {}
        for key in ("kp", "kv"):
            if not law.gains:
                if key in spec:
                    self.at_key(path + (key,), f"law {law.name} takes no {key} ({law.no_gains})")
                gains[key] = np.zeros((n, n))
            elif key not in spec:
                self.at_key(path, f"missing required key '{key}' (law {node.law})")
                gains[key] = np.zeros((n, n))
            else:
                gains[key] = self.gain(path + (key,), spec[key], robot, node.robot)
        if node.internal_forces is not None:
            have = robot.n_internal_forces
            if not law.internal_forces:
                self.at_key(
                    path + ("internal_forces",),
                    f"law {law.name} cannot resolve internal forces (it passes the robot's attributes up unchanged)",
                )
            elif len(node.internal_forces) != have:
                listed = f" ({', '.join(robot.internal_forces)})" if have else ""
                self.at_key(
                    path + ("internal_forces",),
                    f"expected {have} values, one per internal force of "
                    f"'{node.robot}'{listed}, got {len(node.internal_forces)}",
                )
        for key in ("kf_internal", "ki_internal"):
            if getattr(node, key) is None:
                continue
            if not law.internal_forces:
                self.at_key(
                    path + (key,),
                    f"law {law.name} passes internal forces up unresolved; close the "
                    "internal-force loop at the controller that commands them",
                )
            elif not robot.n_internal_forces:
                self.at_key(path + (key,), f"robot '{node.robot}' has no internal forces to close a loop on")
        if node.kf_internal is not None and law.internal_forces and robot.n_internal_forces:
            if node.kf_internal >= 1:
                self.at_value(
                    path + ("kf_internal",),
                    f"kf_internal {node.kf_internal:g} must be below 1: the force "
                    "is sensed a period late and a grasp carries a commanded "
                    "internal force at once, so f(k) = f_d + kf (f_d - f(k-1)) "
                    "has its pole at -kf",
                )
        if node.resolve_internal_motion:
            if not law.internal_forces:
                self.at_key(
                    path + ("resolve_internal_motion",),
                    f"law {law.name} cannot resolve internal motion (it passes the robot's attributes up unchanged)",
                )
            elif not robot.internal_motions:
                self.at_key(
                    path + ("resolve_internal_motion",), f"robot '{node.robot}' has no internal motions to resolve"
                )
        forms = (gain_form(spec.get("kp", 0)), gain_form(spec.get("kv", 0)))
        node = dataclasses.replace(node, kp=gains["kp"], kv=gains["kv"], gain_forms=forms)
        if law.settings is not None:
            return law.part("settings")(self, system, node, spec, robot)
        return node

    def must_be_root(self, system: RobotSystem, node: ControlNode) -> bool:
        """Whether a root law's node is the root of its spec (said where it is not)."""
        if node.name != system.root:
            self.at_key(
                ("nodes", node.name),
                f"a {node.law} controller must be the root ({LAWS[node.law].root}); the root is '{system.root}'",
            )
        return node.name == system.root

    def gain(
        self,
        path: Path,
        value: object,
        robot: Signature,
        name: str,
        bounds: tuple[Bounds, Bounds] = (GAIN, GAIN_MATRIX),
    ) -> np.ndarray:
        """A scalar (times I), a per-axis list (diagonal) or a symmetric positive definite
        matrix, on the robot's n external coordinates; ``bounds``: those of an entry of a
        number or a diagonal, and those of a matrix."""
        n = robot.n_external
        axes = f"'{name}' has {n} external coordinate{'' if n == 1 else 's'}: {', '.join(robot.external)}"
        if not isinstance(value, list):
            return self.bounded(path, value, bounds[0]) * np.eye(n)
        if all(not isinstance(v, list) for v in value):
            if len(value) != n:
                self.at_key(path, f"expected {n} entries ({axes}), got {len(value)}")
            diagonal = [self.bounded(path + (i,), v, bounds[0]) for i, v in enumerate(value)]
            return np.diag(diagonal) if len(diagonal) == n else np.zeros((n, n))
        if not all(isinstance(v, list) for v in value):
            self.at_value(path, "mixes numbers and rows: give a number, a list of numbers or a matrix")
            return np.zeros((n, n))
        if len(value) != n or any(len(row) != n for row in value):
            self.at_key(
                path,
                f"expected a {n} x {n} matrix ({axes}), got "
                f"{len(value)} rows of {', '.join(sorted({str(len(r)) for r in value}))}",
            )
            return np.zeros((n, n))
        matrix = np.array([[self.constant(path + (i, k), v) for k, v in enumerate(row)] for i, row in enumerate(value)])
        self.within(path, matrix, bounds[1], lambda index: index or None)
        return matrix


def gain_form(value: object) -> str:
    """How a gain is written: a number (times I), a list (the diagonal) or a matrix."""
    if not isinstance(value, list):
        return SCALAR_GAIN
    return MATRIX_GAIN if value and all(isinstance(v, list) for v in value) else DIAGONAL_GAIN
