"""Arithmetic operations of a graph, by kind, as its emitted C performs them (CasADi's SX
instruction list after common-subexpression elimination): the counts set beside Lee and
Lee's Table 1 and used to choose between equivalent forms."""

from __future__ import annotations

import casadi as ca

_KINDS = {
    "mul": {ca.OP_MUL, ca.OP_SQ},
    "add": {ca.OP_ADD, ca.OP_SUB, ca.OP_TWICE},
    "trig": {getattr(ca, op) for op in ("OP_SIN", "OP_COS", "OP_TAN", "OP_ASIN", "OP_ACOS", "OP_ATAN", "OP_ATAN2")},
}
_NOT_COUNTED = {ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST, ca.OP_ASSIGN}


def count_operations(inputs: list[ca.SX], outputs: list[ca.SX]) -> dict[str, int]:
    """{mul, add, trig, other, total} of the outputs as functions of the inputs; "other" is
    divisions, square roots, comparisons, selections, negations and the rest."""
    f = ca.Function("count", inputs, [ca.densify(o) for o in outputs], {"cse": True})
    counts = {"mul": 0, "add": 0, "trig": 0, "other": 0}
    for k in range(f.n_instructions()):
        op = f.instruction_id(k)
        if op in _NOT_COUNTED:
            continue
        kind = next((name for name, ops in _KINDS.items() if op in ops), "other")
        counts[kind] += 1
    counts["total"] = sum(counts.values())
    return counts
