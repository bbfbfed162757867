"""The passes a straight-line SX program goes through before it is printed as C, chosen from the
program and where it is printed (its ``Use``), so that robotgen.emit.c_kernel only prints.

A block of its own (a kernel without a schedule, a schedule's stage helper or prologue) is
printed in an issue order (robotgen.emit.issue_order: the list schedule when it is bound by its
longest chain, else the order that holds few values live) and, in double precision, with its
angles paired for robotgen.emit.sincos's routine. A schedule's loop body goes through none:
it keeps CasADi's order with its reads before its writes (robotgen.emit.sx_program.reads_first,
applied when it is read: a body may read and write the same array) and libm's sin and cos."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from robotgen.emit import issue_order, sincos
from robotgen.emit.sx_program import Program


class Use(Enum):
    """Where a straight-line program is printed."""

    BLOCK = "block"  # a kernel's body, a stage helper, a schedule's prologue
    LOOP_BODY = "loop body"  # the body of one of a schedule's loops


class Order(Enum):
    """The order a program's statements are printed in (robotgen.emit.issue_order)."""

    AS_READ = "as read"  # the program's own order
    LIST = "list"  # issue_order.list_scheduled
    PRESSURE = "pressure"  # issue_order.pressure_scheduled


@dataclass(frozen=True)
class Passes:
    """The passes chosen for one program: its print order and whether its angles go through the sin and cos routine."""

    order: Order
    pair_angles: bool

    def apply(self, program: Program) -> Program:
        """``program`` after these passes: the same values bit for bit, in another order, sin and cos paired."""
        if self.order is Order.LIST:
            program = issue_order.list_scheduled(program)
        elif self.order is Order.PRESSURE:
            program = issue_order.pressure_scheduled(program)
        return sincos.pair_angles(program) if self.pair_angles else program


def choose(program: Program, use: Use) -> Passes:
    """The passes for ``program`` printed as ``use`` (in either precision: each has its rg_sincos2)."""
    if use is Use.LOOP_BODY:
        return Passes(Order.AS_READ, pair_angles=False)
    order = Order.LIST if issue_order.latency_bound(program) else Order.PRESSURE
    return Passes(order, pair_angles=True)
