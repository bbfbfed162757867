"""The passes chosen before a straight-line program is printed (robotgen.emit.passes): a block
bound by its longest chain is list-scheduled, any other block pressure-ordered, a block's
angles paired for the sin and cos routine in double precision only, a loop body left as read;
and each choice applies the pass it names."""

from __future__ import annotations

import casadi as ca

from robotgen.emit import issue_order, sincos
from robotgen.emit.passes import Order, Passes, Use, choose
from robotgen.emit.sx_program import defining_steps, read_program
from robotgen.symbolic.kernel import Kernel, Port


def _program(name: str, outputs):
    x = ca.SX.sym("x", 6)
    function = ca.Function(name, [x], [ca.vertcat(*outputs(x))])
    return read_program(Kernel(name, "", (Port("x", 6),), (Port("y", function.size1_out(0)),), function))


def _chain():
    """One long chain of dependent sines: a few operations per cycle of it."""

    def outputs(x):
        y = x[0]
        for _ in range(12):
            y = ca.sin(y) * x[1]
        return [y]

    return _program("chain", outputs)


def _wide():
    """Many independent products and sums: many operations per cycle of the longest chain."""
    return _program("wide", lambda x: [x[i] * x[j] + x[j] for i in range(6) for j in range(6)])


def test_the_order_follows_the_longest_chain():
    chain, wide = _chain(), _wide()
    assert issue_order.latency_bound(chain) and not issue_order.latency_bound(wide)
    assert choose(chain, Use.BLOCK) == Passes(Order.LIST, pair_angles=True)
    assert choose(wide, Use.BLOCK) == Passes(Order.PRESSURE, pair_angles=True)


def test_angles_are_paired_in_blocks_and_loop_bodies_are_left_as_read():
    for program in (_chain(), _wide()):
        assert choose(program, Use.BLOCK).pair_angles
        assert choose(program, Use.LOOP_BODY) == Passes(Order.AS_READ, pair_angles=False)


def test_each_choice_applies_its_pass():
    wide = _wide()
    assert Passes(Order.AS_READ, pair_angles=False).apply(wide) is wide
    listed = Passes(Order.LIST, pair_angles=False).apply(wide)
    assert listed.instructions == issue_order.list_scheduled(wide).instructions
    pressure = Passes(Order.PRESSURE, pair_angles=False).apply(wide)
    assert pressure.instructions == issue_order.pressure_scheduled(wide).instructions
    assert listed.instructions != pressure.instructions  # the two orders differ on this program
    chain = _chain()
    paired = Passes(Order.AS_READ, pair_angles=True).apply(chain)
    assert paired.instructions == sincos.pair_angles(chain).instructions
    assert sincos.SINCOS in [s.op for s in paired.instructions] and sincos.SINCOS not in [
        s.op for s in chain.instructions
    ]


def test_a_value_is_divided_into_once():
    """A value divided by more than once, counting a reciprocal the program forms (1/x0 and
    x1/x0), gets one OP_INV and multiplications by it, the program's own reciprocal a copy of
    it; a value divided by once (x2/x3, 1/x4) keeps its division."""
    program = _program("divisions", lambda x: [1 / x[0], x[1] / x[0], x[2] / x[3], 1 / x[4]])
    steps = program.instructions
    defs = defining_steps(steps)

    def element(k: int, operand: int) -> int:  # the input element step k's operand reads (-1: not an input)
        writer = steps[defs[k][operand]]
        return writer.element if writer.op == ca.OP_INPUT else -1

    inverses = [k for k, s in enumerate(steps) if s.op == ca.OP_INV]
    assert sorted(element(k, 0) for k in inverses) == [0, 4]
    shared = next(k for k in inverses if element(k, 0) == 0)
    readers = [steps[k].op for k in range(len(steps)) if shared in defs[k]]
    assert sorted(readers) == sorted([ca.OP_MUL, ca.OP_ASSIGN])
    divisions = [k for k, s in enumerate(steps) if s.op == ca.OP_DIV]
    assert [(element(k, 0), element(k, 1)) for k in divisions] == [(2, 3)]
