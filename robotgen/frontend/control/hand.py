"""Settings of the hand laws resolved_acceleration and resolved_adaptive (Lee and Lee 1983)
from a spec: the root controller of one 6-joint chain (a chain or urdf leaf)."""
from __future__ import annotations

import dataclasses

import numpy as np

from robotgen.frontend.collector import Collector
from robotgen.frontend.document import Path
from robotgen.model.chain import KinematicTree
from robotgen.model.laws import RESOLVED_ACCELERATION
from robotgen.model.laws.hand import HAND_DOF, AdaptiveSettings, ResolvedAccelerationSettings
from robotgen.model.signature import Signature
from robotgen.model.system import RUNTIME_GAINS, ControlNode, RobotSystem

# defaults (docs/spec-format.md): a 1 kHz servo; Kp, Kv critically damped at 20 rad/s
DEFAULT_PERIOD = 1e-3
DEFAULT_KP, DEFAULT_KV = 400.0, 40.0
# eq 38 on (p, Phi, v, Omega) and on the torques, and eq 37's forgetting factor: chosen on the
# PUMA 560 at 1 kHz (docs/spec-format.md says how they act)
DEFAULT_Q = (1e6, 1e6, 1e4, 1e4)
DEFAULT_R = 1e-5
DEFAULT_FORGETTING = 0.97
DEFAULT_INITIAL_COVARIANCE = 100.0
DEFAULT_COVARIANCE_LIMIT = 1e6
DEFAULT_IK_ITERATIONS = 2


class HandLawReader(Collector):
    """Laws resolved_acceleration and resolved_adaptive."""

    def check_hand_control(self, system: RobotSystem, node: ControlNode, spec: dict, robot: Signature) -> ControlNode:
        path: Path = ("nodes", node.name, "control")
        law = node.law
        for key in ("kp", "kv", "kv_internal", "internal_forces", "resolve_internal_motion", "gains"):
            if key in spec:
                self.at_key(path + (key,), f"law {law} takes no {key} here (its settings go under {law})")
        chain = getattr(system.nodes[node.robot], "leaf", None)
        if not isinstance(chain, KinematicTree):
            self.at_value(path + ("robot",), f"law {law} controls a chain or urdf leaf; '{node.robot}' is a "
                                             f"{system.nodes[node.robot].primitive} node")
            return node
        if chain.nq != HAND_DOF:
            self.at_value(path + ("robot",), f"law {law} resolves hand motion through a square Jacobian: it needs "
                                             f"{HAND_DOF} joints, '{node.robot}' has {chain.nq}")
            return node
        if node.name != system.root:
            self.at_key(("nodes", node.name), f"a {law} controller must be the root (it makes the module's "
                                              f"controller); the root is '{system.root}'")
            return node
        where = path + (law,)
        settings = spec.get(law, {})
        period = self.optional(settings, where, "period", DEFAULT_PERIOD, minimum=0.0, exclusive=True)
        tool = self.pose(where + ("tool",), settings.get("tool"))
        runtime = settings.get("gains", RUNTIME_GAINS) == RUNTIME_GAINS
        if law == RESOLVED_ACCELERATION:
            hand = ResolvedAccelerationSettings(
                period, tool, self.weights(where + ("kp",), settings.get("kp", DEFAULT_KP), HAND_DOF, "gain"),
                self.weights(where + ("kv",), settings.get("kv", DEFAULT_KV), HAND_DOF, "gain"), runtime)
        else:
            q = settings.get("q", list(DEFAULT_Q))
            if isinstance(q, list) and len(q) == 4:
                q_values = np.repeat(self.weights(where + ("q",), q, 4, "weight"), 3)
            else:
                q_values = self.weights(where + ("q",), q, 12, "weight", counts="4 (position, orientation, "
                                        "velocity, angular velocity) or 12 (one per state)")
            forgetting = self.optional(settings, where, "forgetting", DEFAULT_FORGETTING, minimum=0.0, exclusive=True)
            if forgetting > 1:
                self.at_value(where + ("forgetting",), f"forgetting factor {forgetting:g} must be at most 1 (eq 37)")
            p0 = self.optional(settings, where, "initial_covariance", DEFAULT_INITIAL_COVARIANCE, minimum=0.0,
                               exclusive=True)
            limit = self.optional(settings, where, "covariance_limit", DEFAULT_COVARIANCE_LIMIT, minimum=0.0,
                                  exclusive=True)
            if limit < p0 * 3 * HAND_DOF:
                self.at_value(where + ("covariance_limit",), f"covariance_limit {limit:g} is below trace(P_0) = "
                                                             f"{p0 * 3 * HAND_DOF:g} (18 x initial_covariance)")
            iterations = settings.get("ik_iterations", DEFAULT_IK_ITERATIONS)  # the schema: an integer >= 1
            hand = AdaptiveSettings(period, tool, q_values,
                                    self.weights(where + ("r",), settings.get("r", DEFAULT_R), HAND_DOF, "weight"),
                                    forgetting, p0, limit, int(iterations), runtime)
        n = robot.n_external
        return dataclasses.replace(node, kp=np.zeros((n, n)), kv=np.zeros((n, n)), hand=hand)

    def weights(self, path: Path, value: object, n: int, kind: str, *, counts: str | None = None) -> np.ndarray:
        """A positive number (the same on every axis) or a list of n positive numbers."""
        if not isinstance(value, list):
            v = self.constant(path, value)
            if v <= 0:
                self.at_value(path, f"{kind} {v:g} must be positive")
            return np.full(n, v)
        if len(value) != n:
            self.at_key(path, f"expected a number or {counts or n} entries, got {len(value)}")
            return np.ones(n)
        values = np.array([self.constant(path + (i,), v) for i, v in enumerate(value)])
        for i, v in enumerate(values):
            if v <= 0:
                self.at_value(path + (i,), f"{kind} {v:g} must be positive")
        return values
