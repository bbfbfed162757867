"""Settings of the force laws from a spec (robotgen.model.laws.force): an impedance's stiffness,
damping and inertia, a hybrid law's selection and force gains, each under a block named after
the law, on the controlled robot's external coordinates."""
from __future__ import annotations

import dataclasses

import numpy as np

from robotgen.frontend.collector import Collector
from robotgen.frontend.control.node import gain_form
from robotgen.frontend.document import Path
from robotgen.model.laws import IMPEDANCE
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
from robotgen.model.system import ControlNode


class ForceLawReader(Collector):
    """Laws impedance and hybrid."""

    def check_force_law(self, node: ControlNode, spec: dict, robot: Signature) -> ControlNode:
        """Check a force law's node (impedance or hybrid) against its robot's signature; return it with its settings
        read."""
        path: Path = ("nodes", node.name, "control")
        law = node.law
        if robot.internal_motions:
            self.at_value(path + ("robot",), f"law {law} acts on all of its robot's coordinates and needs their "
                                             f"positions; '{node.robot}' has internal motions "
                                             f"({', '.join(robot.internal_motions)}): resolve them below "
                                             "(resolve_internal_motion on a controller of that robot)")
            return node
        if law not in spec:
            self.at_key(path, f"missing required key '{law}' (the settings of law {law})")
            return node
        settings = spec[law]
        here = path + (law,)
        runtime = node.runtime_gains
        if law == IMPEDANCE:
            def matrix(key: str, bounds) -> WrittenMatrix:
                value = settings[key]
                form = gain_form(value)
                return WrittenMatrix(self.gain(here + (key,), value, robot, node.robot, bounds), form)

            for key in ("stiffness", "damping"):
                if key not in settings:
                    self.at_key(here, f"missing required key '{key}'")
                    return node
            force = ImpedanceSettings(matrix("stiffness", STIFFNESS), matrix("damping", DAMPING),
                                      matrix("inertia", INERTIA) if "inertia" in settings else None, runtime)
        else:
            if "selection" not in settings:
                self.at_key(here, "missing required key 'selection'")
                return node
            n = robot.n_external
            values = settings["selection"]
            if len(values) != n:
                self.at_key(here + ("selection",), f"expected {n} entries, one per coordinate of '{node.robot}' "
                                                   f"({', '.join(robot.external)}): 1 position-controlled, 0 "
                                                   f"force-controlled; got {len(values)}")
                return node
            selection = np.array([self.bounded(here + ("selection", i), v, SELECTION) for i, v in enumerate(values)])
            kf = self.bounded(here + ("kf",), settings["kf"], FORCE_GAIN) if "kf" in settings else 0.0
            ki = self.bounded(here + ("ki",), settings["ki"], FORCE_INTEGRAL_GAIN) if "ki" in settings else 0.0
            force = HybridSettings(selection, kf, ki, runtime)
        return dataclasses.replace(node, force=force)
