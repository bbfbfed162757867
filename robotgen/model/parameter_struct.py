"""The module's parameter struct: every run-time parameter of a robot system, in walk order
(robotgen.model.parameters says what a run-time parameter is)."""

from __future__ import annotations

from robotgen.model.formula import FormulaRobot
from robotgen.model.laws.registry import LAWS
from robotgen.model.parameters import MATRIX_GAIN, Bounds, RuntimeParameter, written_shape
from robotgen.model.signature import signature
from robotgen.model.system import (
    DAMPING,
    GAIN,
    GAIN_MATRIX,
    PAYLOAD_BODIES,
    PAYLOAD_MASS,
    ControlNode,
    DefineNode,
    RobotSystem,
)

# the internal-force loop's gains (robotgen.symbolic.servo: its poles); ki_internal dt < 2 (1 -
# kf_internal) as well, checked against the simulation's dt (robotgen.frontend.simulation)
KF_INTERNAL = Bounds(
    "gain kf_internal",
    minimum=0.0,
    maximum=1.0,
    exclusive_maximum=True,
    note="sensed a period late, the loop's pole is at -kf_internal",
)
KI_INTERNAL = Bounds("gain ki_internal", minimum=0.0, note="[1/s]; stable for ki_internal dt < 2 (1 - kf_internal)")


def runtime_parameters(system: RobotSystem) -> list[RuntimeParameter]:
    """The module's parameter struct, in walk order (children before parents)."""
    out: list[RuntimeParameter] = []
    for node in system.walk():
        if isinstance(node, ControlNode) and not LAWS[node.law].is_root and node.runtime_gains:
            out += _gains(system, node)
        elif isinstance(node, ControlNode) and node.hand is not None:
            out += node.hand.parameters(node.name)
        elif isinstance(node, DefineNode):
            leaf = node.leaf
            if isinstance(leaf, FormulaRobot):
                out += [
                    RuntimeParameter(
                        f"{node.name}_{p}",
                        (),
                        (float(leaf.parameters[p]),),
                        f"parameter {p} of formulas leaf '{node.name}'",
                    )
                    for p in leaf.parameters
                    if p in leaf.runtime
                ]
            elif isinstance(leaf, PAYLOAD_BODIES) and "mass" in leaf.runtime:
                out.append(
                    RuntimeParameter(
                        f"{node.name}_mass",
                        (),
                        (float(leaf.mass),),
                        f"mass of payload '{node.name}' [kg]",
                        PAYLOAD_MASS,
                    )
                )
    return out


def gain_parameter_name(node: ControlNode, key: str) -> str:
    """The parameter name of gain ``key`` of a CONTROL node: <node>_<key>."""
    return f"{node.name}_{key}"


def _gains(system: RobotSystem, node: ControlNode) -> list[RuntimeParameter]:
    out = []
    robot = signature(system, node.robot)
    n = robot.n_external
    for key, form, K in (("kp", node.gain_forms[0], node.kp), ("kv", node.gain_forms[1], node.kv)):
        if not LAWS[node.law].gains:
            continue  # the law reads no kp, kv (feedforward: both zero; an impedance has its own matrices)
        shape, values = written_shape(form, K)
        out.append(
            RuntimeParameter(
                gain_parameter_name(node, key),
                shape,
                values,
                f"{'position' if key == 'kp' else 'velocity'} gain {key} of controller "
                f"'{node.name}' on {', '.join(robot.external)}",
                GAIN_MATRIX if form == MATRIX_GAIN else GAIN,
            )
        )
    if robot.n_velocity > n:  # internal motions below: their damping (eq 5.13)
        out.append(
            RuntimeParameter(
                gain_parameter_name(node, "kv_internal"),
                (),
                (float(node.kv_internal),),
                f"damping kv_internal of controller '{node.name}' on internal motions",
                DAMPING,
            )
        )
    if node.kf_internal is not None:  # the loop on sensed internal forces
        out.append(
            RuntimeParameter(
                gain_parameter_name(node, "kf_internal"),
                (),
                (float(node.kf_internal),),
                f"gain kf_internal of controller '{node.name}' on the sensed internal forces",
                KF_INTERNAL,
            )
        )
    if node.ki_internal is not None:
        out.append(
            RuntimeParameter(
                gain_parameter_name(node, "ki_internal"),
                (),
                (float(node.ki_internal),),
                f"gain ki_internal of controller '{node.name}' on the integral of the sensed "
                "internal forces' error [1/s]",
                KI_INTERNAL,
            )
        )
    if node.force is not None:  # an impedance's or a hybrid law's own
        out += node.force.parameters(node.name, ", ".join(robot.external))
    return out
