"""Settings of law resolved_rate (Whitney 1972) from a spec: command frames, axes, weights,
redundancy (with joint weights), damping, rate limits, the horizon, the arrival and the
regulator, over a chain; over a composite robot only damping, rate limits, the horizon and
the arrival."""

from __future__ import annotations

import dataclasses

import numpy as np

from robotgen.documentation import hint
from robotgen.frontend.control.node import ControlReader
from robotgen.frontend.document import Path, format_path
from robotgen.frontend.schema_types import closed_object, number, vector3
from robotgen.model.chain import KinematicTree, mimic_joints
from robotgen.model.laws.resolved_rate import (
    COMPOSITE_KEYS,
    EXTENDED_JACOBIAN,
    FRAMES,
    GENERIC_AXES,
    HAND,
    JOINT_LIMITS,
    LINE_OF_SIGHT,
    OBJECTIVES,
    PSEUDO_INVERSE,
    REDUNDANCY_METHODS,
    SPHERICAL,
    TOOL,
    WEIGHTED_PSEUDO_INVERSE,
    Arrival,
    CommandFrame,
    CompositeRateSettings,
    Damping,
    LQRSettings,
    RateControlSettings,
    Redundancy,
)
from robotgen.model.signature import (
    Signature,
    angle_coordinates,
    robot_leaves,
)
from robotgen.model.system import (
    ControlNode,
    DefineNode,
    RobotSystem,
    under_controls,
)

SCHEMA = closed_object(
    "settings of law resolved_rate: resolved motion rate and position control of a chain "
    "(Whitney 1972), or of a composite robot in its own coordinates (then only damping, "
    "rate_limits, horizon and arrival apply)",
    {
        "frame": {
            "enum": list(FRAMES),
            "description": "command coordinates: base, hand (eq 7), tool (axes of a held "
            "tool), line_of_sight (eq 10), spherical; default hand",
        },
        "eye": vector3("line_of_sight: the eye point in base coordinates [m]"),
        "centre": vector3("spherical: the centre in base coordinates [m]"),
        "tool": {"$ref": "#/$defs/pose", "description": "tool: the tool frame in the hand frame"},
        "active": {
            "type": "array",
            "items": {"type": "string"},
            "uniqueItems": True,
            "description": "command axes that follow the command (default all); the others are held at rate zero",
        },
        "free": {
            "type": "array",
            "items": {"type": "string"},
            "uniqueItems": True,
            "description": "command axes left out of the task (neither commanded nor held)",
        },
        "weights": {
            "type": "array",
            "minItems": 6,
            "maxItems": 6,
            "items": {"$ref": "#/$defs/number"},
            "description": "proportion of each command axis, default 1",
        },
        "redundancy": closed_object(
            "joint rates of a redundant arm",
            {
                "method": {
                    "enum": list(REDUNDANCY_METHODS),
                    "description": "pseudo_inverse (default), weighted_pseudo_inverse or extended_jacobian",
                },
                "joint_weights": {
                    "type": ["number", "string", "array"],
                    "items": {"$ref": "#/$defs/number"},
                    "description": "weighted_pseudo_inverse: W = diag(joint_weights), a positive "
                    "number or one per joint; the rates minimise qdot^T W qdot",
                },
                "objective": {
                    "enum": list(OBJECTIVES),
                    "description": "secondary objective H to increase (default none)",
                },
                "gain": number("gain on grad H, > 0, default 1", exclusiveMinimum=0),
            },
        ),
        "damping": closed_object(
            "damped least squares near singularities",
            {
                "lambda_max": number("damping at a singularity, > 0", exclusiveMinimum=0),
                "threshold": number("manipulability below which damping rises, > 0", exclusiveMinimum=0),
            },
            ("lambda_max", "threshold"),
        ),
        "rate_limits": {
            "type": ["number", "string", "array"],
            "items": {"$ref": "#/$defs/number"},
            "description": "joint-rate bounds: a number or one per joint (of every leaf, "
            "in tree order, for a composite robot; default the joints' "
            "velocity limits); the whole rate vector is scaled",
        },
        "horizon": number("T of eqs 11-18: position control time constant [s], > 0, default 0.1", exclusiveMinimum=0),
        "arrival": closed_object(
            "adds arrival_step: position control with T of eq 11 the time remaining until arrival, "
            "passed at every call",
            {
                "minimum_remaining": number(
                    "remaining times below this count as this [s] (one control period), > 0, default 0.001",
                    exclusiveMinimum=0,
                )
            },
        ),
        "lqr": closed_object(
            "optimal regulator about a nominal posture from the linearised dynamics (eq 19)",
            {
                "nominal": {
                    "type": "array",
                    "minItems": 1,
                    "items": {"$ref": "#/$defs/number"},
                    "description": "nominal joint positions (rates zero)",
                },
                "q": {
                    "type": "array",
                    "minItems": 2,
                    "items": {"$ref": "#/$defs/number"},
                    "description": "state weights: [position, rate] or one per state (2n), default [100, 1]",
                },
                "r": {
                    "type": ["number", "string", "array"],
                    "items": {"$ref": "#/$defs/number"},
                    "description": "torque weights: a number or one per joint, default 1",
                },
                "servo": {
                    "type": "boolean",
                    "description": "also emit servo_step(q, qd, v): the optimal linear servo on these "
                    "gains, its feedforward v passed in (default false)",
                },
            },
            ("nominal",),
        ),
    },
)


class ResolvedRateReader(ControlReader):
    """Law resolved_rate's settings."""

    def check_rate_control(self, system: RobotSystem, node: ControlNode, spec: dict, robot: Signature) -> ControlNode:
        """A resolved_rate controller: the root, over a chain or urdf leaf or over a composite
        robot (an attach node, possibly under control nodes)."""
        path: Path = ("nodes", node.name, "control")
        target = system.nodes[node.robot]
        chain = target.leaf if isinstance(target, DefineNode) else None
        below = under_controls(system.nodes, node.robot)
        if not isinstance(chain, KinematicTree) and isinstance(below, DefineNode):
            leaf = type(below.leaf).__name__
            what = f"a {leaf} leaf" if below is target else f"a control node over the {leaf} leaf '{below.name}'"
            self.at_value(
                path + ("robot",),
                f"law resolved_rate controls a chain or urdf leaf, or a composite "
                f"robot (an attach node, possibly under control nodes); "
                f"'{node.robot}' is {what}",
            )
            return node
        if isinstance(chain, KinematicTree) and chain.coupling is not None:
            self.at_value(
                path + ("robot",),
                f"law resolved_rate resolves a chain's own joints; '{node.robot}' has "
                f"mimic joints ({mimic_joints(chain)}): a tip above them leaves them out "
                f"({hint('spec-format', 'Mimic joints')})",
            )
            return node
        if not self.must_be_root(system, node):
            return node
        settings = spec.get(node.law, {})
        rate: RateControlSettings | CompositeRateSettings
        if isinstance(chain, KinematicTree):  # (then the robot is no composite)
            rate = self.rate_settings(path + (node.law,), settings, chain)
        else:
            rate = self.composite_rate_settings(path + (node.law,), settings, system, node.robot, robot)
        n = robot.n_external
        return dataclasses.replace(node, kp=np.zeros((n, n)), kv=np.zeros((n, n)), rate=rate)

    def composite_rate_settings(
        self, path: Path, spec: dict, system: RobotSystem, name: str, robot: Signature
    ) -> CompositeRateSettings:
        """Over a composite robot the command coordinates are the robot's own: only damping,
        rate limits (one per sensed leaf coordinate), the horizon and the arrival apply."""
        for key in spec:
            if key not in COMPOSITE_KEYS:
                self.at_key(
                    path + (key,),
                    f"'{key}' applies to a chain leaf; over the composite robot '{name}' the "
                    f"command is its velocity in its own coordinates "
                    f"({', '.join(robot.velocity_names)}) and the leaves' rates come from the "
                    f"tree's velocity map (settings here: {', '.join(COMPOSITE_KEYS)})",
                )
        leaves = [system.leaf(leaf) for leaf in robot_leaves(system, name)]
        n = sum(leaf.nq for leaf in leaves)
        rate_limits: np.ndarray | None
        if "rate_limits" in spec:
            rate_limits = self.per_joint(path + ("rate_limits",), spec["rate_limits"], n, "rate limit", positive=True)
        else:
            # the joints' velocity limits, when every leaf is a chain and every joint has one
            chains = all(isinstance(leaf, KinematicTree) for leaf in leaves)
            velocities = (
                [
                    j.limits.velocity
                    for leaf in leaves
                    if isinstance(leaf, KinematicTree)
                    for j in leaf.coordinate_joints
                ]
                if chains
                else []
            )
            limited = chains and all(v is not None and v > 0 for v in velocities)
            rate_limits = np.array(velocities, dtype=float) if limited else None
        return CompositeRateSettings(
            robot_names=robot.velocity_names,
            n_external=robot.n_external,
            angles=angle_coordinates(system, name),
            damping=self.damping(path, spec),
            rate_limits=rate_limits,
            horizon=self.optional(spec, path, "horizon", 0.1, minimum=0.0, exclusive=True),
            arrival=self.arrival(path, spec),
        )

    def arrival(self, path: Path, spec: dict) -> Arrival | None:
        """``arrival: {minimum_remaining: s}``: an arrival_step with the remaining time of eq 11."""
        if "arrival" not in spec:
            return None
        raw = spec["arrival"] or {}
        return Arrival(
            self.optional(
                raw, path + ("arrival",), "minimum_remaining", Arrival.minimum_remaining, minimum=0.0, exclusive=True
            )
        )

    def damping(self, path: Path, spec: dict) -> Damping | None:
        """The damped least-squares settings (lambda_max, threshold > 0), or None when the spec has none."""
        if "damping" not in spec:
            return None
        d = spec["damping"]
        dpath = path + ("damping",)
        return Damping(
            self.constant(dpath + ("lambda_max",), d["lambda_max"], minimum=0.0, exclusive=True),
            self.constant(dpath + ("threshold",), d["threshold"], minimum=0.0, exclusive=True),
        )

    def rate_settings(self, path: Path, spec: dict, chain: KinematicTree) -> RateControlSettings:
        """The resolved-rate settings of a chain: its command frame, gains, rate limits, damping and lqr."""
        n = chain.nq
        kind = spec.get("frame", HAND)
        needs = {LINE_OF_SIGHT: "eye", SPHERICAL: "centre", TOOL: "tool"}
        for key in ("eye", "centre", "tool"):
            if key in spec and needs.get(kind) != key:
                self.at_key(
                    path + (key,),
                    f"'{key}' belongs to frame {next(f for f, k in needs.items() if k == key)}, not {kind}",
                )
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
                    self.at_value(
                        path + (key, i),
                        f"'{name}' is not a command axis of frame {kind} "
                        f"({', '.join(names)}; or {', '.join(GENERIC_AXES)})",
                    )
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
            self.at_key(
                path,
                f"the task has {m} command axes but '{chain.name}' has {n} joints; free {m - n} of them (key 'free')",
            )
        weights = self.vector(path + ("weights",), spec.get("weights"), (1.0,) * 6)

        raw = spec.get("redundancy", {})
        rpath = path + ("redundancy",)
        objective = raw.get("objective", "none")
        method = raw.get("method", PSEUDO_INVERSE)
        joint_weights = None
        if method == WEIGHTED_PSEUDO_INVERSE:
            if "joint_weights" in raw:
                joint_weights = tuple(
                    float(w)
                    for w in self.per_joint(
                        rpath + ("joint_weights",), raw["joint_weights"], n, "joint weight", positive=True
                    )
                )
            else:
                self.at_key(
                    rpath,
                    f"method weighted_pseudo_inverse needs joint_weights: a positive number per "
                    f"joint of '{chain.name}' ({n}), the diagonal of W in qdot^T W qdot",
                )
        elif "joint_weights" in raw:
            self.at_key(
                rpath + ("joint_weights",), f"joint_weights belong to method weighted_pseudo_inverse, not {method}"
            )
        redundancy = Redundancy(
            method,
            None if objective == "none" else objective,
            self.optional(raw, rpath, "gain", 1.0, minimum=0.0, exclusive=True),
            joint_weights,
        )
        if redundancy.method == EXTENDED_JACOBIAN:
            if n != m + 1:
                self.at_value(
                    rpath + ("method",),
                    f"extended_jacobian needs exactly one degree of redundancy: {n} joints, {m} task axes",
                )
            if redundancy.objective != JOINT_LIMITS:
                self.at_key(
                    rpath,
                    "extended_jacobian needs objective joint_limits (the optimality condition "
                    "z^T grad H = 0 is differentiated once more)",
                )
        elif redundancy.objective is not None and n == m:
            self.warnings.append(
                f"{self.doc.source.key(rpath)}: warning: {format_path(self.doc.data, rpath)}: "
                f"'{chain.name}' has no redundancy ({n} joints, {m} task axes); the objective "
                "has no effect"
            )
        if joint_weights is not None and n == m:
            self.warnings.append(
                f"{self.doc.source.key(rpath)}: warning: {format_path(self.doc.data, rpath)}: "
                f"'{chain.name}' has no redundancy ({n} joints, {m} task axes); the weighted "
                "pseudo-inverse is J^-1 whatever the weights (they act only where damping does)"
            )
        if redundancy.objective == JOINT_LIMITS:
            if not any(
                j.limits.lower is not None and j.limits.upper is not None and j.limits.upper > j.limits.lower
                for j in chain.joints
            ):
                self.at_value(
                    rpath + ("objective",),
                    f"objective joint_limits needs position limits; no joint of "
                    f"'{chain.name}' has both lower and upper",
                )

        damping = self.damping(path, spec)
        rate_limits = self.rate_limits(path + ("rate_limits",), spec, chain)
        horizon = self.optional(spec, path, "horizon", 0.1, minimum=0.0, exclusive=True)
        lqr = self.lqr_settings(path + ("lqr",), spec["lqr"], n) if "lqr" in spec else None
        return RateControlSettings(
            frame=frame,
            active=active,
            free=free,
            weights=weights,
            redundancy=redundancy,
            damping=damping,
            rate_limits=rate_limits,
            horizon=horizon,
            lqr=lqr,
            arrival=self.arrival(path, spec),
        )

    def rate_limits(self, path: Path, spec: dict, chain: KinematicTree) -> np.ndarray | None:
        """(nq,) joint rate limits [rad/s or m/s]: the spec's, else the chain's velocity limits, else None."""
        if "rate_limits" in spec:
            return self.per_joint(path, spec["rate_limits"], chain.nq, "rate limit", positive=True)
        velocities = [j.limits.velocity for j in chain.coordinate_joints]
        if all(v is not None and v > 0 for v in velocities):
            return np.array(velocities, dtype=float)
        return None

    def lqr_settings(self, path: Path, spec: dict, n: int) -> LQRSettings:
        """The lqr settings: nominal (n,) joint positions, state weights (2n,) (two entries repeated per joint), r
        (n,), all positive."""
        nominal = spec["nominal"]
        if len(nominal) != n:
            self.at_key(path + ("nominal",), f"expected {n} joint positions, got {len(nominal)}")
        nominal = np.array([self.constant(path + ("nominal", i), v) for i, v in enumerate(nominal)])
        q = spec.get("q", [100, 1])
        if len(q) not in (2, 2 * n):
            self.at_key(path + ("q",), f"expected 2 entries (position, rate) or {2 * n} (one per state), got {len(q)}")
        weights = np.array([self.constant(path + ("q", i), v) for i, v in enumerate(q)])
        for i, w in enumerate(weights):
            if w <= 0:
                self.at_value(path + ("q", i), f"weight {w:g} must be positive")
        if len(weights) == 2:
            weights = np.repeat(weights, n)
        r = self.per_joint(path + ("r",), spec.get("r", 1), n, "weight", positive=True)
        if len(nominal) != n or len(weights) != 2 * n:
            nominal, weights = np.zeros(n), np.ones(2 * n)
        return LQRSettings(nominal, weights, r, bool(spec.get("servo", False)))
