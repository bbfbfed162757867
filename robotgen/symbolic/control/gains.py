"""A tree law's gains as CasADi matrices: folded constants, or the module's run-time
parameters (robotgen.model.parameters) shaped as the spec wrote them: a number times I,
a diagonal, or a full matrix (row-major)."""

from __future__ import annotations

import casadi as ca

from robotgen.model.parameter_struct import gain_parameter_name
from robotgen.model.parameters import DIAGONAL_GAIN, SCALAR_GAIN
from robotgen.model.system import ControlNode
from robotgen.symbolic.kernel import ParameterSymbols


def gain(node: ControlNode, key: str, parameters: ParameterSymbols) -> ca.SX | ca.DM:
    """kp or kv (n x n) of ``node``."""
    K = node.kp if key == "kp" else node.kv
    return written_matrix(
        parameters.symbols.get(gain_parameter_name(node, key)), K, node.gain_forms[0 if key == "kp" else 1]
    )


def written_matrix(p: ca.SX | None, K, form: str) -> ca.SX | ca.DM:
    """Matrix ``K`` (n x n) as written in ``form``: its run-time parameter ``p`` (a number times
    I, a diagonal or the rows), or the constant K when it is folded (p None)."""
    if p is None:
        return ca.DM(K)
    n = K.shape[0]
    if form == SCALAR_GAIN:
        return p * ca.SX.eye(n)
    if form == DIAGONAL_GAIN:
        return ca.diag(p)
    return ca.reshape(p, n, n).T  # the parameter holds the matrix row by row


def kv_internal(node: ControlNode, parameters: ParameterSymbols) -> ca.SX | float:
    """The damping of internal motions (eq 5.13)."""
    return parameters.symbols.get(gain_parameter_name(node, "kv_internal"), node.kv_internal)


def internal_force_gain(node: ControlNode, key: str, parameters: ParameterSymbols) -> ca.SX | float | None:
    """kf_internal or ki_internal: the proportional or integral gain on the sensed
    internal-force error (None in the node: that term is absent)."""
    return parameters.symbols.get(gain_parameter_name(node, key), getattr(node, key))
