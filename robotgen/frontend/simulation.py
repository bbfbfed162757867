"""A spec's `simulation` section, each list checked against the dimension it must have."""

from __future__ import annotations

import math
from typing import Any

from robotgen.frontend.collector import Collector
from robotgen.frontend.document import Path
from robotgen.model.laws.hand import HAND_AXES, HAND_DOF
from robotgen.model.laws.registry import LAWS
from robotgen.model.rate_groups import controller_periods
from robotgen.model.signature import (
    METRE,
    SignatureError,
    coordinate_units,
    robot_leaves,
    signature,
)
from robotgen.model.simulation import WALL_DAMPING, WALL_STIFFNESS, PayloadChange, SimulationSettings, Wall
from robotgen.model.system import (
    PAYLOAD_BODIES,
    ControlNode,
    DefineNode,
    Node,
    RobotSystem,
    leaf_of,
)


class SimulationReader(Collector):
    """The simulation section."""

    def simulation(self, spec: dict, nodes: dict[str, Node], root: str) -> SimulationSettings:
        """The settings, each list checked against the dimensions it must have: the root's
        coordinates (start, initial_error, amplitude, frequency), the leaves' joints (theta0),
        the root's unresolved internal forces (internal_forces)."""
        path: Path = ("simulation",)
        # SimulationSettings' fields by name: floats, tuples, the plant's name, payload changes, a wall
        values: dict[str, Any] = {k: self.constant(path + (k,), spec[k]) for k in ("duration", "dt") if k in spec}
        if "plant" in spec:
            values["plant"] = spec["plant"]  # the schema holds it to PLANTS
        for k in ("start", "theta0", "initial_error", "amplitude", "frequency", "internal_forces", "force"):
            if k in spec:
                values[k] = tuple(self.constant(path + (k, i), v) for i, v in enumerate(spec[k]))
        if "initial_error" in spec and "theta0" in spec:
            self.at_key(
                path + ("initial_error",),
                "initial_error offsets the plant from start through inverse "
                "kinematics; with theta0 the plant starts at theta0 (give the "
                "perturbed joint positions there, or drop theta0)",
            )
        if "initial_error" in spec and "start" not in spec and "theta0" not in spec:
            self.at_key(path + ("initial_error",), "initial_error offsets the plant from start: give start too")
        if "payload_change" in spec:
            values["payload_changes"] = self.payload_changes(path + ("payload_change",), spec["payload_change"])
        root_node = nodes.get(root)
        if isinstance(root_node, ControlNode) and LAWS[root_node.law].hand_frame:
            return self.hand_simulation(spec, values, nodes, root_node)
        system = RobotSystem(
            name=self.doc.data["name"], source=self.doc.path, source_sha256=self.doc.sha256, nodes=nodes, root=root
        )
        if system.is_rate_controlled:
            for key in ("force", "wall", "payload_change"):
                if key in spec:
                    self.at_key(
                        path + (key,),
                        f"'{key}' applies to robot trees of torque controllers; a resolved_rate "
                        "root is simulated through its regulator from theta0",
                    )
                    spec = {k: v for k, v in spec.items() if k != key}
                    values.pop({"payload_change": "payload_changes"}.get(key, key), None)
        if "payload_change" in spec:
            values["payload_changes"] = self.tree_payload_changes(
                path + ("payload_change",), spec["payload_change"], values["payload_changes"], system
            )
        if "wall" in spec:
            values["wall"] = self.wall(path + ("wall",), spec["wall"], system)
        self.internal_force_periods(system, values.get("dt", SimulationSettings.dt))
        try:
            sig = signature(system, root)
            leaves = [system.leaf(leaf) for leaf in robot_leaves(system)]
        except (SignatureError, KeyError, AttributeError, TypeError):
            sig = None  # the tree has errors of its own, reported elsewhere
        if sig is not None and all(leaf is not None for leaf in leaves):
            n_theta = sum(leaf.nq for leaf in leaves)
            coords = ", ".join(sig.external)
            expected = {
                "start": (sig.n_external, f"one per root coordinate of '{root}': {coords}"),
                "initial_error": (sig.n_external, f"one per root coordinate of '{root}': {coords}"),
                "amplitude": (sig.n_external, f"one per root coordinate of '{root}': {coords}"),
                "frequency": (sig.n_external, f"one per root coordinate of '{root}': {coords}"),
                "theta0": (n_theta, f"one per joint of the leaves ({', '.join(robot_leaves(system))}), in tree order"),
                "internal_forces": (
                    sig.n_internal_forces,
                    f"one per internal force the root leaves unresolved: {', '.join(sig.internal_forces) or 'none'}",
                ),
                "force": (sig.n_velocity, f"one per velocity coordinate of '{root}': {', '.join(sig.velocity_names)}"),
            }
            for key, (n, what) in expected.items():
                if key in spec and len(spec[key]) != n:
                    self.at_key(path + (key,), f"expected {n} entries ({what}), got {len(spec[key])}")
        locations = {k: self.doc.source.key(path + (k,)) for k in spec}
        return SimulationSettings(**values, locations=locations)

    def payload_changes(self, path: Path, spec: dict | list) -> tuple[PayloadChange, ...]:
        """One change (a mapping) or several (a list of them, in time order)."""
        entries = [(path, spec)] if isinstance(spec, dict) else [(path + (k,), c) for k, c in enumerate(spec)]
        changes = []
        for at, change in entries:
            x, y, z = (self.constant(at + ("com", i), v) for i, v in enumerate(change.get("com", (0, 0, 0))))
            com = (x, y, z)  # the schema holds com to three numbers
            changes.append(
                PayloadChange(
                    self.constant(at + ("at",), change["at"], minimum=0.0),
                    self.constant(at + ("mass",), change["mass"], minimum=0.0),
                    com,
                )
            )
        for (at, _), before, after in zip(entries[1:], changes, changes[1:]):
            if after.at <= before.at:
                self.at_value(
                    at + ("at",), f"payload changes must be in time order: {after.at:g} s comes after {before.at:g} s"
                )
        return tuple(changes)

    def tree_payload_changes(
        self, path: Path, spec: dict | list, changes: tuple[PayloadChange, ...], system: RobotSystem
    ) -> tuple[PayloadChange, ...]:
        """A robot tree's payload changes: each names a rigid_body payload (``payload``, which
        may be left out when the tree has one) whose mass is a run-time parameter, so that
        robotgen's plant can take another mass than the controller's; no ``com``."""
        entries = [path] if isinstance(spec, dict) else [path + (k,) for k in range(len(spec))]
        raw = [spec] if isinstance(spec, dict) else spec
        bodies = [
            n.name for n in system.nodes.values() if isinstance(n, DefineNode) and isinstance(n.leaf, PAYLOAD_BODIES)
        ]
        out = []
        for at, entry, change in zip(entries, raw, changes):
            if "com" in entry:
                self.at_key(
                    at + ("com",),
                    "a robot tree's payload change sets the mass of a rigid_body payload; "
                    "com applies to a hand controller's",
                )
            name = entry.get("payload")
            if name is None:
                if len(bodies) != 1:
                    self.at_key(
                        at,
                        f"name the payload whose mass changes: payload: one of {', '.join(bodies)}"
                        if bodies
                        else "the tree has no rigid_body payload whose mass could change",
                    )
                    continue
                name = bodies[0]
            elif name not in bodies:
                self.at_value(
                    at + ("payload",),
                    f"'{name}' is not a rigid_body payload of the tree" + (f" ({', '.join(bodies)})" if bodies else ""),
                )
                continue
            body = system.leaf(name)  # one of bodies
            if isinstance(body, PAYLOAD_BODIES) and "mass" not in body.runtime:
                where = self.doc.source.key(("nodes", name))
                self.at_key(
                    at,
                    f"payload '{name}''s mass must be a run-time parameter (mass: {{runtime: "
                    f"{body.mass:g}}} at {where}), so that robotgen's plant "
                    "can take another mass than the controller's",
                )
            out.append(PayloadChange(change.at, change.mass, payload=name))
        return tuple(out)

    def wall(self, path: Path, spec: dict, system: RobotSystem) -> Wall | None:
        """A wall on the point that node ``node``'s coordinates are (metres, 2 or 3 of them)."""
        name = spec["node"]
        if name not in system.nodes:
            self.at_value(path + ("node",), f"'{name}' is not a node (nodes: {', '.join(system.nodes)})")
            return None
        if isinstance(system.nodes[name], DefineNode) and name not in robot_leaves(system):
            self.at_value(
                path + ("node",), f"'{name}' is a payload; a wall touches a robot's point (a frame change's tip)"
            )
            return None
        try:
            sig = signature(system, name)
            units = coordinate_units(system, name)[: sig.n_external]
        except (SignatureError, KeyError, AttributeError):
            return None  # the tree has errors of its own, reported elsewhere
        if sig.n_external not in (2, 3) or any(u != METRE for u in units):
            self.at_value(
                path + ("node",),
                f"a wall touches a point: node '{name}' must have 2 or 3 coordinates in "
                f"metres (a frame change's tip), it has {', '.join(sig.external)}"
                f" [{', '.join(u or '?' for u in units)}]",
            )
            return None
        point, normal = (
            tuple(self.constant(path + (k, i), v) for i, v in enumerate(spec[k])) for k in ("point", "normal")
        )
        for key, vector in (("point", point), ("normal", normal)):
            if len(vector) != sig.n_external:
                self.at_key(
                    path + (key,),
                    f"expected {sig.n_external} entries, one per coordinate of '{name}': "
                    f"{', '.join(sig.external)}; got {len(vector)}",
                )
                return None
        length = math.sqrt(sum(v * v for v in normal))
        if not length > 0:
            self.at_value(path + ("normal",), "the wall's normal must not be zero")
            return None
        stiffness = self.optional(spec, path, "stiffness", WALL_STIFFNESS, minimum=0.0, exclusive=True)
        damping = self.optional(spec, path, "damping", WALL_DAMPING, minimum=0.0)
        return Wall(name, point, tuple(v / length for v in normal), stiffness, damping)

    def internal_force_periods(self, system: RobotSystem, dt: float) -> None:
        """Each internal-force PI loop is stable at the period its controller runs at (its own,
        an ancestor's, else the simulation's dt): ki_internal dt < 2 (1 - kf_internal)
        (robotgen.symbolic.servo)."""
        try:
            periods = controller_periods(system, dt)
        except (KeyError, AttributeError):
            periods = {}  # the tree has errors of its own, reported elsewhere
        for node in system.nodes.values():
            period = periods.get(node.name, dt)
            problem = node.internal_force_loop_problem(period) if isinstance(node, ControlNode) else None
            if problem:
                self.at_value(("nodes", node.name, "control", "ki_internal"), problem)

    def hand_simulation(
        self, spec: dict, values: dict, nodes: dict[str, Node], root: ControlNode
    ) -> SimulationSettings:
        """A hand controller's run: theta0 (the chain's joints), amplitude and frequency on the
        hand's x, y, z, roll, pitch, yaw about its start pose, payload_change."""
        path: Path = ("simulation",)
        if "dt" in spec:
            self.at_key(
                path + ("dt",),
                "a hand controller runs at its own period (its settings' period); the simulation steps with it",
            )
        for key in ("start", "initial_error", "internal_forces", "force", "wall"):
            if key in spec:
                self.at_key(
                    path + (key,),
                    f"'{key}' applies to robot trees; a hand controller starts at theta0 "
                    "and follows its start pose plus amplitude sin(2 pi frequency t)",
                )
        changes = spec.get("payload_change", [])
        for k, change in enumerate([changes] if isinstance(changes, dict) else changes):
            if "payload" in change:
                at = path + ("payload_change",) + (() if isinstance(changes, dict) else (k,))
                self.at_key(
                    at + ("payload",),
                    "a hand controller's payload is a point mass in its hand (mass, com); "
                    "payload names a robot tree's rigid_body",
                )
        chain = leaf_of(nodes.get(root.robot))
        expected = {
            "theta0": (chain.nq if chain is not None else HAND_DOF, f"one per joint of '{root.robot}'"),
            "amplitude": (HAND_DOF, f"one per hand axis: {', '.join(HAND_AXES)}"),
            "frequency": (HAND_DOF, f"one per hand axis: {', '.join(HAND_AXES)}"),
        }
        for key, (n, what) in expected.items():
            if key in spec and len(spec[key]) != n:
                self.at_key(path + (key,), f"expected {n} entries ({what}), got {len(spec[key])}")
        locations = {k: self.doc.source.key(path + (k,)) for k in spec}
        return SimulationSettings(**values, locations=locations)
