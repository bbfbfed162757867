"""A spec's `simulation` section, each list checked against the dimension it must have."""
from __future__ import annotations

from robotgen.frontend.collector import Collector
from robotgen.frontend.document import Path
from robotgen.model.laws import HAND_LAWS
from robotgen.model.laws.hand import HAND_AXES, HAND_DOF
from robotgen.model.signature import (
    SignatureError,
    robot_leaves,
    signature,
)
from robotgen.model.simulation import PayloadChange, SimulationSettings
from robotgen.model.system import ControlNode, Node, RobotSystem


class SimulationReader(Collector):
    """The simulation section."""

    def simulation(self, spec: dict, nodes: dict[str, Node], root: str) -> SimulationSettings:
        """The settings, each list checked against the dimensions it must have: the root's
        coordinates (start, initial_error, amplitude, frequency), the leaves' joints (theta0),
        the root's unresolved internal forces (internal_forces)."""
        path: Path = ("simulation",)
        values = {k: self.constant(path + (k,), spec[k]) for k in ("duration", "dt") if k in spec}
        if "plant" in spec:
            values["plant"] = spec["plant"]  # the schema holds it to PLANTS
        for k in ("start", "theta0", "initial_error", "amplitude", "frequency", "internal_forces"):
            if k in spec:
                values[k] = tuple(self.constant(path + (k, i), v) for i, v in enumerate(spec[k]))
        if "initial_error" in spec and "theta0" in spec:
            self.at_key(path + ("initial_error",), "initial_error offsets the plant from start through inverse "
                                                   "kinematics; with theta0 the plant starts at theta0 (give the "
                                                   "perturbed joint positions there, or drop theta0)")
        if "initial_error" in spec and "start" not in spec and "theta0" not in spec:
            self.at_key(path + ("initial_error",), "initial_error offsets the plant from start: give start too")
        if "payload_change" in spec:
            values["payload_changes"] = self.payload_changes(path + ("payload_change",), spec["payload_change"])
        root_node = nodes.get(root)
        if isinstance(root_node, ControlNode) and root_node.law in HAND_LAWS:
            return self.hand_simulation(spec, values, nodes, root_node)
        if "payload_change" in spec:
            self.at_key(path + ("payload_change",), "payload_change applies to a hand controller's simulation "
                                                    "(law resolved_acceleration or resolved_adaptive at the root)")
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


    def payload_changes(self, path: Path, spec: dict | list) -> tuple[PayloadChange, ...]:
        """One change (a mapping) or several (a list of them, in time order)."""
        entries = [(path, spec)] if isinstance(spec, dict) else [(path + (k,), c) for k, c in enumerate(spec)]
        changes = []
        for at, change in entries:
            com = tuple(self.constant(at + ("com", i), v) for i, v in enumerate(change.get("com", (0, 0, 0))))
            changes.append(PayloadChange(self.constant(at + ("at",), change["at"], minimum=0.0),
                                         self.constant(at + ("mass",), change["mass"], minimum=0.0), com))
        for (at, _), before, after in zip(entries[1:], changes, changes[1:]):
            if after.at <= before.at:
                self.at_value(at + ("at",), f"payload changes must be in time order: {after.at:g} s comes after "
                                            f"{before.at:g} s")
        return tuple(changes)

    def hand_simulation(self, spec: dict, values: dict, nodes: dict[str, Node],
                        root: ControlNode) -> SimulationSettings:
        """A hand controller's run: theta0 (the chain's joints), amplitude and frequency on the
        hand's x, y, z, roll, pitch, yaw about its start pose, payload_change."""
        path: Path = ("simulation",)
        if "dt" in spec:
            self.at_key(path + ("dt",), "a hand controller runs at its own period (its settings' period); "
                                        "the simulation steps with it")
        for key in ("start", "initial_error", "internal_forces"):
            if key in spec:
                self.at_key(path + (key,), f"'{key}' applies to robot trees; a hand controller starts at theta0 "
                                           "and follows its start pose plus amplitude sin(2 pi frequency t)")
        chain = getattr(nodes.get(root.robot), "leaf", None)
        expected = {"theta0": (getattr(chain, "nq", HAND_DOF), f"one per joint of '{root.robot}'"),
                    "amplitude": (HAND_DOF, f"one per hand axis: {', '.join(HAND_AXES)}"),
                    "frequency": (HAND_DOF, f"one per hand axis: {', '.join(HAND_AXES)}")}
        for key, (n, what) in expected.items():
            if key in spec and len(spec[key]) != n:
                self.at_key(path + (key,), f"expected {n} entries ({what}), got {len(spec[key])}")
        locations = {k: self.doc.source.key(path + (k,)) for k in spec}
        return SimulationSettings(**values, locations=locations)
