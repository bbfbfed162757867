"""A tree law's gains as CasADi matrices: folded constants, or the module's run-time
parameters (robotgen.model.parameters) shaped as the spec wrote them: a number times I,
a diagonal, or a full matrix (row-major)."""
from __future__ import annotations

import casadi as ca

from robotgen.model.parameter_struct import gain_parameter_name
from robotgen.model.system import DIAGONAL_GAIN, SCALAR_GAIN, ControlNode
from robotgen.symbolic.kernel import ParameterSymbols


def gain(node: ControlNode, key: str, parameters: ParameterSymbols) -> ca.SX | ca.DM:
    """kp or kv (n x n) of ``node``."""
    K = node.kp if key == "kp" else node.kv
    p = parameters.symbols.get(gain_parameter_name(node, key))
    if p is None:
        return ca.DM(K)
    n = K.shape[0]
    form = node.gain_forms[0 if key == "kp" else 1]
    if form == SCALAR_GAIN:
        return p * ca.SX.eye(n)
    if form == DIAGONAL_GAIN:
        return ca.diag(p)
    return ca.reshape(p, n, n).T  # the parameter holds the matrix row by row


def kv_internal(node: ControlNode, parameters: ParameterSymbols) -> ca.SX | float:
    """The damping of internal motions (eq 5.13)."""
    return parameters.symbols.get(gain_parameter_name(node, "kv_internal"), node.kv_internal)


def kf_internal(node: ControlNode, parameters: ParameterSymbols) -> ca.SX | float:
    """The gain on the sensed internal-force error (None in the node: no loop)."""
    return parameters.symbols.get(gain_parameter_name(node, "kf_internal"), node.kf_internal)
