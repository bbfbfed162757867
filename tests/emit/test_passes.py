"""The passes chosen before a straight-line program is printed (robotgen.emit.passes): a block
bound by its longest chain is list-scheduled, any other block pressure-ordered, a block's
angles paired for the sin and cos routine in double precision only, a loop body left as read;
and each choice applies the pass it names."""

from __future__ import annotations

import casadi as ca

from robotgen.emit import issue_order, sincos
from robotgen.emit.passes import Order, Passes, Use, choose
from robotgen.emit.sx_program import read_program
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
