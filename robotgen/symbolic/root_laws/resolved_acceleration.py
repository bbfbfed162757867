"""Resolved acceleration control (Luh, Walker and Paul 1980), the hand-space computed torque
that Lee and Lee 1983 set beside their adaptive law: a root law on a 6-joint chain.

    e = (p_d - p, orientation error of R_d R^T),  e' = twist_d - J qd,
    xdd* = accel_d + Kv e' + Kp e,
    qdd  = J^-1 (xdd* - Jdot qd)          (eq 13 with the commanded hand acceleration),
    tau  = Newton-Euler(q, qd, qdd).

With an exact model the hand error obeys e'' + Kv e' + Kp e = 0 (to first order in the
orientation error). The module is the chain's functions plus resolved_acceleration_step."""

from __future__ import annotations

import casadi as ca

from robotgen.model.laws import RESOLVED_ACCELERATION
from robotgen.model.parameter_struct import runtime_parameters
from robotgen.model.system import ControlNode, RobotSystem
from robotgen.symbolic.kernel import Kernel, ParameterSymbols, make_kernel
from robotgen.symbolic.leaf_kernels import leaf_kernels
from robotgen.symbolic.root_laws.hand import Hand, hand_kernels, orientation_error, pose_rows, start_check
from robotgen.symbolic.root_laws.law import Controller, RootLaw

STEP = "resolved_acceleration_step"


def gains(node: ControlNode, parameters: ParameterSymbols) -> tuple[ca.SX, ca.SX]:
    """Kp and Kv (6,) of the node: run-time parameter symbols, or its folded constants."""
    s = node.acceleration
    if f"{node.name}_kp" in parameters.symbols:
        return parameters.symbols[f"{node.name}_kp"], parameters.symbols[f"{node.name}_kv"]
    return ca.SX(ca.DM(s.kp)), ca.SX(ca.DM(s.kv))


def kernels(system: RobotSystem) -> list[Kernel]:
    """The resolved acceleration control kernels (Luh, Walker, Paul 1980) of the root's 6-joint chain."""
    node = system.root_control
    tree = system.tree(node.robot)
    parameters = ParameterSymbols.of(runtime_parameters(system))
    hand = Hand(tree, node.hand_settings.tool)
    q, qd = ca.SX.sym("q", 6), ca.SX.sym("qd", 6)
    pose_d, twist_d, accel_d = ca.SX.sym("pose_d", 16), ca.SX.sym("twist_d", 6), ca.SX.sym("accel_d", 6)
    R_d, p_d = pose_rows(pose_d)
    R, p = hand.pose(q)
    J = hand.jacobian(q)
    Kp, Kv = gains(node, parameters)
    e = ca.vertcat(p_d - p, orientation_error(R_d, R))
    command = accel_d + Kv * (twist_d - J @ qd) + Kp * e
    qdd = hand.joint_accelerations(q, qd, command)  # NaN near a singular J: status 2
    tau = hand.torques(q, qd, qdd)
    step = make_kernel(
        STEP,
        "Resolved acceleration control (Luh, Walker, Paul 1980), one sampling period: joint torques "
        "for the desired hand pose (4x4, base frame), twist [v; omega] and its derivative, from the "
        "measured joint state: Newton-Euler at qdd = J^-1 (accel_d + Kv e' + Kp e - Jdot qd). Also the "
        "hand error e (position, then the orientation error's vector part).",
        [("q", q), ("qd", qd), ("pose_d", pose_d, (4, 4)), ("twist_d", twist_d), ("accel_d", accel_d)],
        [("tau", tau, (6, 1)), ("error", e, (6, 1))],
        parameters,
        guarded=True,
    )
    return leaf_kernels(tree, derivatives=system.derivatives.when_asked()) + hand_kernels(hand) + [step]


def report(system: RobotSystem) -> tuple[dict, dict]:
    """(info entries, module attributes) of a resolved acceleration spec: its gains, period and tool."""
    node = system.root_control
    s = node.acceleration
    info = {
        "controller": system.root,
        "robot": node.robot,
        "law": RESOLVED_ACCELERATION,
        "period": s.period,
        "kp": [float(v) for v in s.kp],
        "kv": [float(v) for v in s.kv],
        "tool": [[float(v) for v in row] for row in s.tool],
    }
    return {"hand_control": info}, {}


def controller(system: RobotSystem) -> Controller:
    """The module's ResolvedAccelerationController: its step kernel, period [s] and first step's check."""
    return Controller(
        "ResolvedAccelerationController", STEP, system.root_control.hand_settings.period, start=start_check()
    )


LAW = RootLaw(RESOLVED_ACCELERATION, kernels, report, controller)
