"""Settings of the hand laws resolved_acceleration and resolved_adaptive (Lee and Lee 1983)
from a spec: the root controller of one 6-joint chain (a chain or urdf leaf)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from robotgen.documentation import hint
from robotgen.frontend.control.node import ControlReader
from robotgen.frontend.document import Path
from robotgen.frontend.schema_types import closed_object, number, weight_matrix, weights
from robotgen.model.chain import KinematicTree, mimic_joints
from robotgen.model.laws.hand import (
    COVARIANCE_BLOCKS,
    FORGETTING,
    GAIN,
    HAND_DOF,
    Q_MATRIX,
    R_MATRIX,
    TORQUE_WEIGHT,
    WEIGHT,
    AdaptiveSettings,
    ResolvedAccelerationSettings,
)
from robotgen.model.parameters import Bounds
from robotgen.model.signature import Signature
from robotgen.model.system import (
    GAIN_MODES,
    RUNTIME_GAINS,
    ControlNode,
    RobotSystem,
    leaf_of,
)

# defaults (docs/spec-format.md): a 1 kHz servo; Kp, Kv critically damped at 20 rad/s
DEFAULT_PERIOD = 1e-3
DEFAULT_KP, DEFAULT_KV = 400.0, 40.0
# the weight rule of eq 38 (docs/spec-format.md): positions and orientations decay at 20 rad/s
# (a 50 ms time constant), and R = B^T Q B removes half the predicted rate error per period
DEFAULT_BANDWIDTH = 20.0
DEFAULT_TORQUE_WEIGHT = 1.0
# eq 37: the directional forgetting factor and P_0 on the regressor blocks (A's, B's, c's):
# A and B start at the linearised model and are trusted (closed-loop data do not tell them
# apart), the offset c is not (docs/spec-format.md gives the measurements behind them)
DEFAULT_FORGETTING = 0.99
DEFAULT_INITIAL_COVARIANCE = {"A": 1.0, "B": 1e-8, "c": 1e-2}
DEFAULT_COVARIANCE_LIMIT = 1e6
DEFAULT_IK_ITERATIONS = 2


RESOLVED_ACCELERATION_SCHEMA = closed_object(
    "settings of law resolved_acceleration (Luh, Walker, Paul 1980) on a 6-joint chain: "
    "xdd* = xdd_d + Kv (xd_d - xd) + Kp e, qdd = J^-1 (xdd* - Jdot qd), Newton-Euler torques",
    {
        "period": number("sampling period T [s], > 0, default 0.001", exclusiveMinimum=0),
        "tool": {"$ref": "#/$defs/pose", "description": "the hand frame in the tip frame, default identity"},
        "kp": weights("hand position gains on x, y, z, roll, pitch, yaw: a number or 6, default 400"),
        "kv": weights("hand velocity gains: a number or 6, default 40"),
        "gains": {"enum": list(GAIN_MODES), "description": "runtime (default) or folded kp, kv"},
    },
)

RESOLVED_ADAPTIVE_SCHEMA = closed_object(
    "settings of law resolved_adaptive (Lee and Lee 1983) on a 6-joint chain: Newton-Euler "
    "feedforward and the one-step optimal control (eq 39) of an RLS-identified perturbation model",
    {
        "period": number("sampling period T [s], > 0, default 0.001", exclusiveMinimum=0),
        "tool": {"$ref": "#/$defs/pose", "description": "the hand frame in the tip frame, default identity"},
        "bandwidth": number(
            "the weight rule: positions and orientations decay at this rate [rad/s], "
            "> 0, default 20 (Q = diag(2 bandwidth / period on p and Phi, 1 on v and Omega))",
            exclusiveMinimum=0,
        ),
        "q": weight_matrix(
            "Q of eq 38 instead of the rule: a number, 4 numbers (position, orientation, velocity, "
            "angular velocity), 12 (the diagonal) or 12 rows of 12 (symmetric positive definite)"
        ),
        "torque_weight": number("the weight rule: R = torque_weight B^T Q B, > 0, default 1"),
        "r": weight_matrix(
            "R of eq 38 instead of the rule: a number, 6 (the diagonal) or 6 rows of 6 (symmetric positive definite)"
        ),
        "forgetting": number("forgetting factor mu of eq 37, 0 < mu <= 1, default 0.99"),
        "directional": {
            "type": "boolean",
            "description": "forget along the regressor only (default true); false is eq 37 as printed, P divided by mu",
        },
        "initial_covariance": {
            "type": ["number", "string", "object"],
            "description": "P_0 of eq 37: one number, or per regressor block {A: 1, B: 1e-8, c: 1e-2} (the defaults)",
            "properties": {k: {"$ref": "#/$defs/number"} for k in ("A", "B", "c")},
            "additionalProperties": False,
        },
        "covariance_limit": number("largest trace of P, default 1e6", exclusiveMinimum=0),
        "affine": {"type": "boolean", "description": "identify and cancel the model's constant term c (default true)"},
        "ik_iterations": {
            "type": "integer",
            "minimum": 1,
            "maximum": 10,
            "description": "Newton steps of the inverse kinematics per cycle, for arms without a "
            "closed form (a spherical wrist), default 2",
        },
        "gains": {
            "enum": list(GAIN_MODES),
            "description": "runtime (default) or folded q, r or torque_weight, forgetting",
        },
    },
)


class HandLawReader(ControlReader):
    """Laws resolved_acceleration and resolved_adaptive."""

    def check_acceleration_control(
        self, system: RobotSystem, node: ControlNode, spec: dict, robot: Signature
    ) -> ControlNode:
        """Law resolved_acceleration's node and settings."""
        return self.check_hand_control(system, node, spec, robot, self.acceleration_settings)

    def check_adaptive_control(
        self, system: RobotSystem, node: ControlNode, spec: dict, robot: Signature
    ) -> ControlNode:
        """Law resolved_adaptive's node and settings."""
        return self.check_hand_control(system, node, spec, robot, self.adaptive_settings)

    def check_hand_control(
        self,
        system: RobotSystem,
        node: ControlNode,
        spec: dict,
        robot: Signature,
        read: Callable[[Path, dict, float, np.ndarray, bool], ResolvedAccelerationSettings | AdaptiveSettings],
    ) -> ControlNode:
        """A hand law's node: the root, over a 6-joint chain without mimic joints; its period,
        tool and gain mode, then ``read`` (the block's path, the block, those three) for the
        rest of its settings."""
        path: Path = ("nodes", node.name, "control")
        law = node.law
        chain = leaf_of(system.nodes[node.robot])
        if not isinstance(chain, KinematicTree):
            self.at_value(
                path + ("robot",),
                f"law {law} controls a chain or urdf leaf; '{node.robot}' is a "
                f"{system.nodes[node.robot].primitive} node",
            )
            return node
        if chain.coupling is not None:
            self.at_value(
                path + ("robot",),
                f"law {law} resolves a chain's own joints; '{node.robot}' has mimic "
                f"joints ({mimic_joints(chain)}): a tip above them leaves them out "
                f"({hint('spec-format', 'Mimic joints')})",
            )
            return node
        if chain.nq != HAND_DOF:
            self.at_value(
                path + ("robot",),
                f"law {law} resolves hand motion through a square Jacobian: it needs "
                f"{HAND_DOF} joints, '{node.robot}' has {chain.nq}",
            )
            return node
        if not self.must_be_root(system, node):
            return node
        where = path + (law,)
        settings = spec.get(law, {})
        period = self.optional(settings, where, "period", DEFAULT_PERIOD, minimum=0.0, exclusive=True)
        tool = self.pose(where + ("tool",), settings.get("tool"))
        runtime = settings.get("gains", RUNTIME_GAINS) == RUNTIME_GAINS
        hand = read(where, settings, period, tool, runtime)
        n = robot.n_external
        return dataclasses.replace(node, kp=np.zeros((n, n)), kv=np.zeros((n, n)), hand=hand)

    def acceleration_settings(
        self, where: Path, settings: dict, period: float, tool: np.ndarray, runtime: bool
    ) -> ResolvedAccelerationSettings:
        """resolved_acceleration: Kp and Kv on x, y, z, roll, pitch, yaw."""
        return ResolvedAccelerationSettings(
            period,
            tool,
            self.weights(where + ("kp",), settings.get("kp", DEFAULT_KP), HAND_DOF, GAIN),
            self.weights(where + ("kv",), settings.get("kv", DEFAULT_KV), HAND_DOF, GAIN),
            runtime,
        )

    def adaptive_settings(
        self, where: Path, settings: dict, period: float, tool: np.ndarray, runtime: bool
    ) -> AdaptiveSettings:
        """resolved_adaptive: Q by the weight rule from ``bandwidth`` or given, R by the rule
        from ``torque_weight`` or given, and the identification's settings."""
        for given, rule in (("q", "bandwidth"), ("r", "torque_weight")):
            if given in settings and rule in settings:
                self.at_key(
                    where + (rule,),
                    f"give {given} or {rule}, not both: {rule} sets {given.upper()} by the "
                    f"weight rule ({hint('spec-format', 'The weight rule')})",
                )
        bandwidth = self.optional(settings, where, "bandwidth", DEFAULT_BANDWIDTH, minimum=0.0, exclusive=True)
        if "q" in settings:
            q = self.weight_matrix(where + ("q",), settings["q"], 12, Q_MATRIX, groups=4)
            bandwidth_used = None
        else:
            if bandwidth * period >= 2:
                self.at_value(
                    where + ("bandwidth",),
                    f"bandwidth {bandwidth:g} rad/s is at or past 2 / period "
                    f"({2 / period:g} rad/s): the rule's discrete pole "
                    "(2 - bandwidth T) / (2 + bandwidth T) would not be in (0, 1)",
                )
            q = np.repeat([2 * bandwidth / period, 1.0], 6)
            bandwidth_used = bandwidth
        torque_weight = self.setting(settings, where, "torque_weight", DEFAULT_TORQUE_WEIGHT, TORQUE_WEIGHT)
        r = self.weight_matrix(where + ("r",), settings["r"], HAND_DOF, R_MATRIX) if "r" in settings else None
        forgetting = self.setting(settings, where, "forgetting", DEFAULT_FORGETTING, FORGETTING)
        p0 = self.initial_covariance(where + ("initial_covariance",), settings.get("initial_covariance"))
        affine = bool(settings.get("affine", True))  # the schema: booleans
        directional = bool(settings.get("directional", True))
        limit = self.optional(
            settings, where, "covariance_limit", DEFAULT_COVARIANCE_LIMIT, minimum=0.0, exclusive=True
        )
        trace0 = 12 * p0[0] + HAND_DOF * p0[1] + (p0[2] if affine else 0.0)
        if limit < trace0:
            self.at_value(where + ("covariance_limit",), f"covariance_limit {limit:g} is below trace(P_0) = {trace0:g}")
        iterations = settings.get("ik_iterations", DEFAULT_IK_ITERATIONS)  # the schema: an integer >= 1
        return AdaptiveSettings(
            period,
            tool,
            q,
            r,
            torque_weight,
            bandwidth_used,
            forgetting,
            p0,
            limit,
            int(iterations),
            affine,
            directional,
            runtime,
        )

    def setting(self, settings: dict, where: Path, key: str, default: float, bounds: Bounds) -> float:
        """A number of the law's settings, within the bounds of the run-time parameter it
        becomes (robotgen.model.laws.hand), or its default."""
        return self.bounded(where + (key,), settings[key], bounds) if key in settings else default

    def initial_covariance(self, path: Path, value: object) -> tuple[float, float, float]:
        """P_0's blocks on A's, B's and c's regressors: one positive number for all, or a
        mapping with any of A, B, c (the others keep their defaults)."""
        if not isinstance(value, dict) and value is not None:
            v = self.constant(path, value, minimum=0.0, exclusive=True)
            return (v, v, v)
        given = value or {}
        a, b, c = (
            self.constant(path + (k,), given[k], minimum=0.0, exclusive=True)
            if k in given
            else DEFAULT_INITIAL_COVARIANCE[k]
            for k in COVARIANCE_BLOCKS
        )
        return (a, b, c)

    def weight_matrix(self, path: Path, value: object, n: int, bounds: Bounds, groups: int | None = None) -> np.ndarray:
        """A weight of eq 38: a number (n equal diagonal entries), ``groups`` numbers (each
        repeated n / groups times), n numbers (the diagonal), or an n x n symmetric positive
        definite matrix (rows as lists; ``bounds`` names it). A diagonal is returned as (n,), a
        matrix as (n, n)."""
        if isinstance(value, list) and value and all(isinstance(row, list) for row in value):
            if len(value) != n or any(len(row) != n for row in value):
                self.at_key(
                    path,
                    f"{bounds.what} as a matrix must be {n} x {n}, got {len(value)} rows of "
                    f"{sorted({len(row) for row in value})} entries",
                )
                return np.ones(n)
            M = np.array([[self.constant(path + (i, j), v) for j, v in enumerate(row)] for i, row in enumerate(value)])
            return M if self.within(path, M, bounds, lambda index: index or None) else np.ones(n)
        if isinstance(value, list) and groups and len(value) == groups:
            return np.repeat(self.weights(path, value, groups, WEIGHT), n // groups)
        counts = (
            f"{groups} ({', '.join(('position', 'orientation', 'velocity', 'angular velocity'))}), "
            f"{n} (the diagonal) or {n} rows of {n}"
            if groups
            else f"{n} (the diagonal) or {n} rows of {n}"
        )
        return self.weights(path, value, n, WEIGHT, counts=counts)

    def weights(self, path: Path, value: object, n: int, bounds: Bounds, *, counts: str | None = None) -> np.ndarray:
        """A number within ``bounds`` (the same on every axis) or a list of n such numbers."""
        if not isinstance(value, list):
            return np.full(n, self.bounded(path, value, bounds))
        if len(value) != n:
            self.at_key(path, f"expected a number or {counts or n} entries, got {len(value)}")
            return np.ones(n)
        return np.array([self.bounded(path + (i,), v, bounds) for i, v in enumerate(value)])
