"""Settings of the force laws from a spec (robotgen.model.laws.force): an impedance's stiffness,
damping and inertia, a hybrid law's selection and force gains, each under a block named after
the law, on the controlled robot's external coordinates."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from robotgen.frontend.control.node import ControlReader, gain_form
from robotgen.frontend.document import Path
from robotgen.frontend.schema_types import closed_object, number
from robotgen.model.laws.force import (
    DAMPING,
    FORCE_GAIN,
    FORCE_INTEGRAL_GAIN,
    INERTIA,
    SELECTION,
    STIFFNESS,
    HybridSettings,
    ImpedanceSettings,
    WrittenMatrix,
)
from robotgen.model.signature import Signature
from robotgen.model.system import ControlNode, RobotSystem

IMPEDANCE_SCHEMA = closed_object(
    "settings of law impedance (Hogan 1985) on the robot's coordinates x: the target "
    "M_d (xdd - xdd_d) + D (xd - xd_d) + K (x - x_d) = F_ext + f_e, F_ext the sensed force of what it touches",
    {
        "stiffness": {
            "$ref": "#/$defs/gain",
            "description": "K [N/m or N m/rad]: a number (times I), a list "
            "(the diagonal, >= 0) or a matrix (symmetric "
            "positive definite)",
        },
        "damping": {"$ref": "#/$defs/gain", "description": "D [N s/m or N m s/rad], > 0, as K"},
        "inertia": {
            "$ref": "#/$defs/gain",
            "description": "M_d [kg or kg m^2], > 0, as K; optional: with it the "
            "law reads the sensed force (the servo step takes "
            "tau_sensed), without it M_d is the robot's own M",
        },
    },
    ("stiffness", "damping"),
)

HYBRID_SCHEMA = closed_object(
    "settings of law hybrid, hybrid force/position control (Raibert and Craig 1981): coordinates with "
    "selection 1 follow x_d (kp, kv), those with 0 exert the force f_e written at the node, with a PI "
    "loop on the sensed force",
    {
        "selection": {
            "type": "array",
            "minItems": 1,
            "items": {"$ref": "#/$defs/number"},
            "description": "S, one entry per coordinate in [0, 1]: 1 position-controlled, 0 force-controlled",
        },
        "kf": number("gain on the force error f_e - F_s, >= 0, default 0"),
        "ki": number("gain on the force error's integral [1/s], >= 0, default 0"),
    },
    ("selection",),
)


class ForceLawReader(ControlReader):
    """Laws impedance and hybrid."""

    def check_impedance(self, system: RobotSystem, node: ControlNode, spec: dict, robot: Signature) -> ControlNode:
        """Law impedance's settings block."""
        return self.check_force_law(node, spec, robot, self.impedance_settings)

    def check_hybrid(self, system: RobotSystem, node: ControlNode, spec: dict, robot: Signature) -> ControlNode:
        """Law hybrid's settings block."""
        return self.check_force_law(node, spec, robot, self.hybrid_settings)

    def check_force_law(
        self,
        node: ControlNode,
        spec: dict,
        robot: Signature,
        read: Callable[[Path, dict, ControlNode, Signature], ImpedanceSettings | HybridSettings | None],
    ) -> ControlNode:
        """A force law's node: its robot without internal motions, its block present, then
        ``read`` (the block's path, the block, the node, the robot) for the settings (None
        where they are wrong)."""
        path: Path = ("nodes", node.name, "control")
        law = node.law
        if robot.internal_motions:
            self.at_value(
                path + ("robot",),
                f"law {law} acts on all of its robot's coordinates and needs their "
                f"positions; '{node.robot}' has internal motions "
                f"({', '.join(robot.internal_motions)}): resolve them below "
                "(resolve_internal_motion on a controller of that robot)",
            )
            return node
        if law not in spec:
            self.at_key(path, f"missing required key '{law}' (the settings of law {law})")
            return node
        force = read(path + (law,), spec[law], node, robot)
        return node if force is None else dataclasses.replace(node, force=force)

    def impedance_settings(
        self, here: Path, settings: dict, node: ControlNode, robot: Signature
    ) -> ImpedanceSettings | None:
        """K, D and, if given, M_d."""

        def matrix(key: str, bounds) -> WrittenMatrix:
            value = settings[key]
            form = gain_form(value)
            return WrittenMatrix(self.gain(here + (key,), value, robot, node.robot, bounds), form)

        for key in ("stiffness", "damping"):
            if key not in settings:
                self.at_key(here, f"missing required key '{key}'")
                return None
        return ImpedanceSettings(
            matrix("stiffness", STIFFNESS),
            matrix("damping", DAMPING),
            matrix("inertia", INERTIA) if "inertia" in settings else None,
            node.runtime_gains,
        )

    def hybrid_settings(self, here: Path, settings: dict, node: ControlNode, robot: Signature) -> HybridSettings | None:
        """The selection S and the force gains kf, ki."""
        if "selection" not in settings:
            self.at_key(here, "missing required key 'selection'")
            return None
        n = robot.n_external
        values = settings["selection"]
        if len(values) != n:
            self.at_key(
                here + ("selection",),
                f"expected {n} entries, one per coordinate of '{node.robot}' "
                f"({', '.join(robot.external)}): 1 position-controlled, 0 "
                f"force-controlled; got {len(values)}",
            )
            return None
        selection = np.array([self.bounded(here + ("selection", i), v, SELECTION) for i, v in enumerate(values)])
        kf = self.bounded(here + ("kf",), settings["kf"], FORCE_GAIN) if "kf" in settings else 0.0
        ki = self.bounded(here + ("ki",), settings["ki"], FORCE_INTEGRAL_GAIN) if "ki" in settings else 0.0
        return HybridSettings(selection, kf, ki, node.runtime_gains)
