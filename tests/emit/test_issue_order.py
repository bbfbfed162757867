"""The printing order of straight-line kernels (robotgen.emit.issue_order): a list schedule
for latency-bound kernels, an order holding few values live for the others. Each computes
what CasADi's order computes, bit for bit, and reads every value after it is written; the list
schedule keeps the longest chain and is chosen for the kernels bound by it and only for them;
the other order holds fewer values live than CasADi's."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from robots import PANDA, UR5, robots_dir

from robotgen.emit import issue_order
from robotgen.emit.sx_program import read_program
from robotgen.frontend.urdf import load_urdf_system
from robotgen.symbolic import kernels_for

_BINARY = {
    ca.OP_ADD: lambda a, b: a + b,
    ca.OP_SUB: lambda a, b: a - b,
    ca.OP_MUL: lambda a, b: a * b,
    ca.OP_DIV: lambda a, b: a / b,
    ca.OP_LT: lambda a, b: float(a < b),
    ca.OP_LE: lambda a, b: float(a <= b),
    ca.OP_AND: lambda a, b: float(bool(a) and bool(b)),
    ca.OP_OR: lambda a, b: float(bool(a) or bool(b)),
    ca.OP_IF_ELSE_ZERO: lambda c, x: x if c else 0.0,
}
_UNARY = {
    ca.OP_NEG: lambda a: -a,
    ca.OP_SQ: lambda a: a * a,
    ca.OP_TWICE: lambda a: 2 * a,
    ca.OP_INV: lambda a: 1 / a,
    ca.OP_SQRT: math.sqrt,
    ca.OP_SIN: math.sin,
    ca.OP_COS: math.cos,
    ca.OP_NOT: lambda a: float(not a),
    ca.OP_FABS: abs,
    ca.OP_ASSIGN: lambda a: a,
}


def run(program, inputs: list[np.ndarray]) -> dict[tuple[int, int], float]:
    """The program step by step in IEEE double (Python floats): output (port, element) -> value."""
    registers: dict[int, float] = {}
    out = {}
    for step in program.instructions:
        if step.op == ca.OP_INPUT:
            registers[step.target] = float(inputs[step.port][step.element])
        elif step.op == ca.OP_CONST:
            registers[step.target] = step.constant
        elif step.op == ca.OP_OUTPUT:
            out[(step.port, step.element)] = registers[step.args[0]]
        elif step.op in _BINARY:
            registers[step.target] = _BINARY[step.op](*(registers[r] for r in step.args))
        else:
            registers[step.target] = _UNARY[step.op](registers[step.args[0]])
    return out


@pytest.fixture(scope="module")
def kernels():
    return {
        name: {k.name: k for k in kernels_for(load_urdf_system(str(robots_dir() / urdf), tip))}
        for name, (urdf, tip) in (("ur5", UR5), ("panda", PANDA))
    }


@pytest.mark.parametrize(
    "robot, kernel",
    [
        ("panda", "mass"),
        ("panda", "jacobian"),
        ("panda", "gravity"),
        ("ur5", "inverse_dynamics"),
        ("ur5", "forward_dynamics"),
        ("panda", "mass_inverse"),
    ],
)
def test_the_schedule_computes_the_same_bits_in_a_valid_order(kernels, robot, kernel):
    program = read_program(kernels[robot][kernel])
    scheduled = issue_order.list_scheduled(program)
    assert_same_bits_in_a_valid_order(kernels[robot][kernel], program, scheduled)
    assert issue_order.critical_path(scheduled) == issue_order.critical_path(program)


def assert_same_bits_in_a_valid_order(kernel, program, scheduled):
    written: set[int] = set()
    for step in scheduled.instructions:
        assert set(step.args) <= written, f"{step.op_name} reads a register before it is written"
        if step.target >= 0:
            assert step.target not in written  # one write per register
            written.add(step.target)
    assert sorted(s.op for s in scheduled.instructions) == sorted(s.op for s in program.instructions)
    # step k of the original writes register k: the order changed where the registers are not ascending
    targets = [s.target for s in scheduled.instructions if s.target >= 0]
    assert targets != sorted(targets)
    rng = np.random.default_rng(7)
    n = kernel.inputs[0].size
    for _ in range(5):
        inputs = [
            rng.uniform(-np.pi, np.pi, p.size) if p.name == "q" else rng.uniform(-2, 2, p.size) for p in kernel.inputs
        ]
        expected, got = run(program, inputs), run(scheduled, inputs)
        assert got.keys() == expected.keys() and len(got) >= n
        assert all(got[k] == expected[k] or (math.isnan(got[k]) and math.isnan(expected[k])) for k in got)


def test_it_is_chosen_for_the_kernels_bound_by_their_longest_chain(kernels):
    """A mass matrix (few operations per cycle of its chain) is; the fused servo terms and the
    derivative kernels (many) are not."""
    panda, ur5 = kernels["panda"], kernels["ur5"]
    for k in (panda["mass"], panda["jacobian"], ur5["mass"], ur5["gravity"]):
        assert issue_order.latency_bound(read_program(k))
    for k in (panda["servo_terms"], ur5["servo_terms"], ur5["inverse_dynamics_derivatives"]):
        assert not issue_order.latency_bound(read_program(k))


def test_the_order_is_deterministic(kernels):
    program = read_program(kernels["panda"]["mass"])
    assert issue_order.list_scheduled(program) == issue_order.list_scheduled(program)


@pytest.mark.parametrize(
    "robot, kernel",
    [
        ("panda", "servo_terms"),
        ("ur5", "servo_terms"),
        ("panda", "forward_dynamics"),
        ("ur5", "coriolis"),
        ("ur5", "inverse_dynamics_derivatives"),
    ],
)
def test_the_pressure_order_computes_the_same_bits_with_constants_read_at_once(kernels, robot, kernel):
    """The order of every other straight-line kernel: the same bits, each value written before
    it is read, and each constant and input printed just before the step that first reads it
    (with that step's other constants and inputs), so none of them is held live."""
    program = read_program(kernels[robot][kernel])
    ordered = issue_order.pressure_scheduled(program)
    assert_same_bits_in_a_valid_order(kernels[robot][kernel], program, ordered)
    steps = ordered.instructions
    for k, step in enumerate(steps):
        if step.op in (ca.OP_CONST, ca.OP_INPUT):
            reader = next(j for j in range(k + 1, len(steps)) if steps[j].op not in (ca.OP_CONST, ca.OP_INPUT))
            assert step.target in steps[reader].args, f"step {k} is not read by the next operation"
    assert ordered == issue_order.pressure_scheduled(program)  # deterministic
