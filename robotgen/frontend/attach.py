"""ATTACH nodes from a spec (Deno et al. 1990, §3.3): the constraint's structure first, then,
once the robots' signatures are known, the checks that need them (payload kinds, contact
counts, unique outputs) and a formulas constraint's h, h^-1, J and G."""

from __future__ import annotations

import dataclasses

import numpy as np

from robotgen.frontend.collector import Collector
from robotgen.frontend.document import Path
from robotgen.model.chain import KinematicTree
from robotgen.model.formula import FormulaRobot
from robotgen.model.signature import (
    Signature,
    kinematic_outputs,
    leaf_coordinates,
)
from robotgen.model.system import (
    CONSTRAINT_FORMULAS,
    CONTACT_GRASPS,
    DEFAULT_CONTACT_FRICTION,
    FRAME_CHANGE,
    PAYLOAD_BODIES,
    PLANAR_CONTACTS,
    POINT_CONTACTS,
    POSITION_OUTPUT,
    AttachNode,
    Constraint,
    DefineNode,
    RobotSystem,
    leaf_of,
    under_controls,
)


class AttachReader(Collector):
    """ATTACH nodes."""

    def attach(self, name: str, path: Path, spec: dict) -> AttachNode:
        """The node with its constraint's structure; a formulas constraint's expressions are
        parsed once the robots' coordinate names are known (``constraint_formulas``)."""
        raw = spec["constraint"]
        where = path + ("constraint",)
        if "frame_change" in raw:
            constraint = Constraint(FRAME_CHANGE, output=raw["frame_change"].get("output", POSITION_OUTPUT))
        elif "planar_contacts" in raw:
            points = raw["planar_contacts"]["points"]
            at = where + ("planar_contacts", "points")
            contacts = np.array(
                [[self.constant(at + (i, k), v) for k, v in enumerate(point)] for i, point in enumerate(points)]
            )
            friction = self.contact_friction(where + ("planar_contacts",), raw["planar_contacts"])
            constraint = Constraint(PLANAR_CONTACTS, contacts=contacts, friction=friction)
        elif "point_contacts" in raw:
            points = raw["point_contacts"]["points"]
            at = where + ("point_contacts", "points")
            contacts = np.array(
                [[self.constant(at + (i, k), v) for k, v in enumerate(point)] for i, point in enumerate(points)]
            )
            if np.linalg.norm(np.cross(contacts[1] - contacts[0], contacts[2] - contacts[0])) < 1e-9:
                self.at_key(
                    at, "the first three contact points are collinear: they cannot fix the payload's orientation"
                )
            friction = self.contact_friction(where + ("point_contacts",), raw["point_contacts"])
            constraint = Constraint(POINT_CONTACTS, contacts=contacts, friction=friction)
        else:
            formulas = raw["formulas"]
            at = where + ("formulas",)
            coordinates = tuple(formulas["coordinates"])
            raw_parameters = formulas.get("parameters", {})
            self.check_names(
                at,
                [(c, at + ("coordinates", i), "coordinate") for i, c in enumerate(coordinates)]
                + [(p, at + ("parameters", p), "parameter") for p in raw_parameters],
            )
            parameters = {p: self.constant(at + ("parameters", p), v) for p, v in raw_parameters.items()}
            # J's rows fix the node's signature; its entries are parsed later
            rows = tuple(() for _ in formulas["J"]) if "J" in formulas else None
            constraint = Constraint(CONSTRAINT_FORMULAS, coordinates=coordinates, parameters=parameters, J=rows)
        return AttachNode(name, tuple(spec["robots"]), spec.get("payload"), constraint)

    def contact_friction(self, path: Path, spec: dict) -> float:
        """The fingertips' Coulomb friction coefficient on the payload (> 0, default 1): read
        by an independent plant with unilateral contacts (robotgen.simulation.mujoco), not by
        robotgen's bilateral grasp model."""
        return self.optional(spec, path, "friction", DEFAULT_CONTACT_FRICTION, minimum=0.0, exclusive=True)

    def check_attach(self, system: RobotSystem, node: AttachNode, robots: list[Signature]) -> AttachNode:
        """Check an ATTACH node against its robots' signatures (robots, payload, constraint); return it with its
        constraint read."""
        nodes = system.nodes
        path: Path = ("nodes", node.name, "attach")
        for i, r in enumerate(node.robots):
            leaf = leaf_of(nodes[r])
            if isinstance(leaf, PAYLOAD_BODIES):
                self.at_value(
                    path + ("robots", i),
                    f"'{r}' is a rigid_body, a payload without actuators; it cannot be a robot (give it as payload)",
                )
        payload = None
        if node.payload is not None:
            payload = leaf_of(nodes[node.payload])
            if not isinstance(payload, (*PAYLOAD_BODIES, FormulaRobot)):
                kind = (
                    f"a {nodes[node.payload].primitive} node"
                    if not isinstance(nodes[node.payload], DefineNode)
                    else "a chain"
                )
                self.at_value(
                    path + ("payload",),
                    f"payload '{node.payload}' must be a define node with rigid_body or formulas (it is {kind})",
                )
                payload = None
        m = sum(s.n_external for s in robots)
        c = node.constraint
        kind_path = path + ("constraint", c.kind)
        if c.kind == FRAME_CHANGE:
            if node.payload is not None:
                self.at_key(
                    path + ("payload",),
                    "frame_change takes no payload (nil payload, G = I); use planar_contacts or formulas to hold one",
                )
            owner: dict[str, str] = {}
            for i, r in enumerate(node.robots):
                below = under_controls(nodes, r)
                leaf = leaf_of(below)
                if isinstance(leaf, PAYLOAD_BODIES):
                    continue  # reported above
                if not isinstance(leaf, (KinematicTree, FormulaRobot)):
                    what = (
                        f"an {below.primitive} node"
                        if below is nodes[r]
                        else f"a control of {below.primitive} node '{below.name}'"
                    )
                    self.at_value(
                        path + ("robots", i),
                        f"'{r}' is {what}; frame_change needs a chain or a formulas "
                        "leaf with kinematics (possibly under control nodes)",
                    )
                    continue
                if isinstance(leaf, FormulaRobot) and not leaf.kinematics:
                    self.at_value(
                        path + ("robots", i),
                        f"robot '{r}' ({below.name}) has no kinematics; "
                        "frame_change needs a formulas leaf's kinematics",
                    )
                    continue
                self.check_unique(
                    owner, kinematic_outputs(system, r) or (), r, path + ("robots", i), "output", "rename its outputs"
                )
        elif c.kind in CONTACT_GRASPS:
            grasp = CONTACT_GRASPS[c.kind]
            if node.payload is None:
                self.at_key(kind_path, f"{c.kind} needs a payload: {grasp.payload}")
            elif payload is not None and len(leaf_coordinates(payload)) != grasp.pose_dim:
                self.at_value(
                    path + ("payload",),
                    f"payload '{node.payload}' has {len(leaf_coordinates(payload))} "
                    f"coordinates; {c.kind} needs {grasp.payload}",
                )
            k = 0 if c.contacts is None else len(c.contacts)
            if m != grasp.tip_dim * k:
                self.at_key(
                    kind_path + ("points",),
                    f"{k} contact points need {grasp.tip_dim * k} robot "
                    f"coordinates (fingertip {grasp.axes} each); robots "
                    f"{', '.join(node.robots)} have {m}",
                )
        else:
            if payload is not None and len(leaf_coordinates(payload)) != len(c.coordinates):
                self.at_value(
                    path + ("payload",),
                    f"payload '{node.payload}' has {len(leaf_coordinates(payload))} "
                    f"coordinates, the constraint {len(c.coordinates)}; the "
                    "payload's coordinates are the node's",
                )
            node = dataclasses.replace(node, constraint=self.constraint_formulas(node, robots, m))
        return node

    def constraint_formulas(self, node: AttachNode, robots: list[Signature], m: int) -> Constraint:
        """Parses h, h_inverse, J, G of a formulas constraint with the names each may read."""
        path: Path = ("nodes", node.name, "attach")
        at: Path = path + ("constraint", "formulas")
        spec = self.doc.data["nodes"][node.name]["attach"]["constraint"]["formulas"]
        c = node.constraint
        owner: dict[str, str] = {}
        for i, (r, s) in enumerate(zip(node.robots, robots)):
            self.check_unique(
                owner,
                s.external,
                r,
                path + ("robots", i),
                "coordinate",
                "the formulas constraint reads robot coordinates by name; rename one",
            )
        for i, name in enumerate(c.coordinates):
            if name in owner:
                self.at_key(
                    at + ("coordinates", i),
                    f"coordinate '{name}' is also a coordinate of robot '{owner[name]}'; rename one",
                )
        for name in c.parameters:
            if name in owner:
                self.at_key(
                    at + ("parameters", name),
                    f"parameter '{name}' is also a coordinate of robot '{owner[name]}'; rename one",
                )
        y, x, p = set(owner), set(c.coordinates), set(c.parameters)
        n = len(c.coordinates)
        h = self.vector_of_expressions(at + ("h",), spec["h"], None, y | p)
        if len(h) != n:
            self.at_key(at + ("h",), f"expected {n} entries (one per node coordinate), got {len(h)}")
        h_inverse = None
        if "h_inverse" in spec:
            h_inverse = self.vector_of_expressions(at + ("h_inverse",), spec["h_inverse"], None, x | p)
            if len(h_inverse) != m:
                self.at_key(
                    at + ("h_inverse",), f"expected {m} entries (one per robot coordinate), got {len(h_inverse)}"
                )
        J = None
        rows = m
        if "J" in spec:
            J = self.rectangle(at + ("J",), spec["J"], None, m, y | p, "robot coordinate")
            rows = len(J)
        G = self.rectangle(
            at + ("G",), spec["G"], n, rows, x | y | p, "row of J" if "J" in spec else "robot coordinate, as J = I"
        )
        return dataclasses.replace(c, h=h, h_inverse=h_inverse, J=J, G=G)
