"""The module's parameter struct: every run-time parameter of a robot system, in walk order
(robotgen.model.parameters says what a run-time parameter is)."""
from __future__ import annotations

import numpy as np

from robotgen.model.formula import FormulaRobot
from robotgen.model.laws import FEEDFORWARD, TREE_LAWS
from robotgen.model.parameters import Bounds, RuntimeParameter
from robotgen.model.signature import signature
from robotgen.model.system import (
    DAMPING,
    DIAGONAL_GAIN,
    GAIN,
    GAIN_MATRIX,
    MATRIX_GAIN,
    PAYLOAD_BODIES,
    PAYLOAD_MASS,
    SCALAR_GAIN,
    ControlNode,
    DefineNode,
    RobotSystem,
)


def runtime_parameters(system: RobotSystem) -> list[RuntimeParameter]:
    """The module's parameter struct, in walk order (children before parents)."""
    out: list[RuntimeParameter] = []
    for node in system.walk():
        if isinstance(node, ControlNode) and node.law in TREE_LAWS and node.runtime_gains:
            out += _gains(system, node)
        elif isinstance(node, ControlNode) and node.hand is not None:
            out += node.hand.parameters(node.name)
        elif isinstance(node, DefineNode):
            leaf = node.leaf
            if isinstance(leaf, FormulaRobot):
                out += [RuntimeParameter(f"{node.name}_{p}", (), (float(leaf.parameters[p]),),
                                         f"parameter {p} of formulas leaf '{node.name}'")
                        for p in leaf.parameters if p in leaf.runtime]
            elif isinstance(leaf, PAYLOAD_BODIES) and "mass" in leaf.runtime:
                out.append(RuntimeParameter(f"{node.name}_mass", (), (float(leaf.mass),),
                                            f"mass of payload '{node.name}' [kg]", PAYLOAD_MASS))
    return out


def gain_parameter_name(node: ControlNode, key: str) -> str:
    return f"{node.name}_{key}"


def _gains(system: RobotSystem, node: ControlNode) -> list[RuntimeParameter]:
    out = []
    robot = signature(system, node.robot)
    n = robot.n_external
    for key, form, K in (("kp", node.gain_forms[0], node.kp), ("kv", node.gain_forms[1], node.kv)):
        if node.law == FEEDFORWARD and key == "kp":
            continue  # feedforward reads no position error
        if node.law == FEEDFORWARD and not np.any(K):
            continue  # zero velocity gain: nothing to tune
        K = np.asarray(K, dtype=float)
        shape, values = {SCALAR_GAIN: ((), (K[0, 0],)), DIAGONAL_GAIN: ((n,), tuple(np.diag(K))),
                         MATRIX_GAIN: ((n, n), tuple(K.ravel()))}[form]
        out.append(RuntimeParameter(gain_parameter_name(node, key), shape, tuple(map(float, values)),
                                    f"{'position' if key == 'kp' else 'velocity'} gain {key} of controller "
                                    f"'{node.name}' on {', '.join(robot.external)}",
                                    GAIN_MATRIX if form == MATRIX_GAIN else GAIN))
    if robot.n_velocity > n:  # internal motions below: their damping (eq 5.13)
        out.append(RuntimeParameter(gain_parameter_name(node, "kv_internal"), (), (float(node.kv_internal),),
                                    f"damping kv_internal of controller '{node.name}' on internal motions", DAMPING))
    if node.kf_internal is not None:  # the loop on sensed internal forces
        out.append(RuntimeParameter(gain_parameter_name(node, "kf_internal"), (), (float(node.kf_internal),),
                                    f"gain kf_internal of controller '{node.name}' on the sensed internal forces",
                                    Bounds("gain kf_internal", minimum=0.0, maximum=1.0, exclusive_maximum=True,
                                           note="sensed a period late, the loop's pole is at -kf_internal")))
    return out
