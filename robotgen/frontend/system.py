"""A schema-valid spec document -> RobotSystem: the nodes (robotgen.frontend.leaves, attach,
control), that they form one tree below the root, that every ATTACH and CONTROL fits the
dimensions of its children (robotgen.model.signature), and the simulation section.
Every problem is collected; nothing is returned unless there are none."""

from __future__ import annotations

from robotgen.errors import UserErrors
from robotgen.frontend.attach import AttachReader
from robotgen.frontend.control.force import ForceLawReader
from robotgen.frontend.control.hand import HandLawReader
from robotgen.frontend.control.node import ControlReader
from robotgen.frontend.control.resolved_rate import ResolvedRateReader
from robotgen.frontend.document import Document, Path, format_path, sort_errors
from robotgen.frontend.leaves import LeafReader
from robotgen.frontend.rates import RateReader
from robotgen.frontend.simulation import SimulationReader
from robotgen.model.derivatives import SEMI_IMPLICIT_EULER, DerivativeSettings
from robotgen.model.names import name_problem
from robotgen.model.signature import (
    Signature,
    SignatureError,
    signature,
)
from robotgen.model.system import (
    AttachNode,
    ControlNode,
    DefineNode,
    Node,
    RobotSystem,
)


class SpecReader(
    LeafReader,
    AttachReader,
    ForceLawReader,
    ResolvedRateReader,
    HandLawReader,
    ControlReader,
    SimulationReader,
    RateReader,
):
    """The whole spec: every part's reader over one collector."""

    def node(self, name: str, node: dict) -> Node:
        """One entry of the spec's nodes as a DefineNode, AttachNode or ControlNode."""
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
            for child, path, _ in node_refs:
                if child not in nodes:
                    self.at_value(path, f"'{child}' is not a node (nodes: {', '.join(nodes)})")
                elif child == root:
                    self.at_value(path, f"'{child}' is the root; the root cannot be used by another node")
                    reported.add(name)
                elif child in used_by:
                    self.at_value(
                        path,
                        f"'{child}' is already used by {format_path(self.doc.data, used_by[child])}; "
                        "each node is used at most once",
                    )
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
                        loop = stack[stack.index(child) :]
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
                    self.at_key(
                        ("nodes", name),
                        f"node '{name}' is not reachable from the root '{root}' "
                        "(every node but the root is used as a robot, payload or "
                        "controlled robot)",
                    )
        return {name for name, ok in whole.items() if ok}

    def signatures(self, nodes: dict[str, Node], root: str, whole: set[str]) -> dict[str, Node]:
        """Checks every attach and control node against its children's signatures, children
        first, and completes them (constraint formulas, gains). Returns the final nodes."""
        system = RobotSystem(
            name=self.doc.data["name"], source=self.doc.path, source_sha256=self.doc.sha256, nodes=nodes, root=root
        )
        known: dict[str, Signature | None] = {}

        def sig(name: str) -> Signature | None:
            if name in known:
                return known[name]
            known[name] = None
            if name not in whole:
                return None
            node = nodes[name]
            below = {child: sig(child) for child in node.children}
            checked = {child: s for child, s in below.items() if s is not None}
            if len(checked) < len(below):
                return None
            if isinstance(node, DefineNode):
                if node.leaf is None:  # a URDF that failed to load
                    return None
                result = signature(system, name)
            else:
                before = len(self.errors)
                if isinstance(node, AttachNode):
                    nodes[name] = node = self.check_attach(system, node, [checked[r] for r in node.robots])
                else:
                    nodes[name] = node = self.check_control(system, node, checked[node.robot])
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

    def derivatives(self, spec: dict) -> DerivativeSettings:
        """The `derivatives` section (a robot tree's module gets the plant's derivatives only
        when it asks, robotgen.symbolic.system_kernels)."""
        return DerivativeSettings(spec.get("include"), spec.get("integrator", SEMI_IMPLICIT_EULER))

    def system(self) -> RobotSystem:
        """The whole spec as a RobotSystem: name, nodes, root, the tree below it, simulation and derivatives
        sections."""
        data = self.doc.data
        problem = name_problem(data["name"])
        if problem:
            shown = data["name"] if len(data["name"]) <= 40 else data["name"][:40] + "..."
            self.at_value(("name",), f"{shown!r} {problem}")
        nodes = {name: self.node(name, node) for name, node in data["nodes"].items()}
        root = data["root"]
        if root not in nodes:
            self.at_value(("root",), f"'{root}' is not a node (nodes: {', '.join(nodes)})")
        whole = self.check_tree(nodes, root)
        nodes = self.signatures(nodes, root, whole)
        simulation = self.simulation(data["simulation"], nodes, root) if "simulation" in data else None
        self.check_periods(nodes, root, simulation)
        derivatives = self.derivatives(data.get("derivatives", {}))
        return RobotSystem(
            name=data["name"],
            source=self.doc.path,
            source_sha256=self.doc.sha256,
            nodes=nodes,
            root=root,
            warnings=tuple(self.warnings),
            simulation=simulation,
            derivatives=derivatives,
            dependencies=tuple(self.dependencies),
            node_locations={name: self.doc.source.key(("nodes", name)) for name in nodes},
        )


def to_system(doc: Document) -> RobotSystem:
    """The RobotSystem of a schema-valid document; raises UserErrors with every problem."""
    reader = SpecReader(doc)
    system = reader.system()
    if reader.errors:
        raise UserErrors(sort_errors(reader.errors))
    return system
