"""A kernel's CasADi SX instruction list, read once into plain data and checked.

CasADi evaluates an SX Function as a straight-line program over work registers; this module
turns that program into ``Instruction`` records whose input and output references are dense
element indices of the kernel's ports, so printers and counters never touch CasADi again.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from robotgen.symbolic.kernel import Kernel

OP_NAMES: dict[int, str] = {getattr(ca, attr): attr for attr in sorted(dir(ca)) if attr.startswith("OP_")}


class KernelError(RuntimeError):
    """A kernel handed to the emitters breaks the ``Kernel`` contract: a robotgen bug."""


@dataclass(frozen=True)
class Instruction:
    """One step. ``target`` is the register written (-1 for OP_OUTPUT); ``args`` the
    registers read. OP_INPUT/OP_OUTPUT carry ``port`` and ``element`` (dense index into
    the port's flattened array); OP_CONST carries ``constant``."""

    op: int
    target: int
    args: tuple[int, ...] = ()
    port: int = -1
    element: int = -1
    constant: float = 0.0

    @property
    def op_name(self) -> str:
        """The CasADi operation's name (e.g. OP_MUL), for messages."""
        return OP_NAMES.get(self.op, f"op {self.op}")


@dataclass(frozen=True)
class Program:
    """A kernel's CasADi SX algorithm as a list of instructions, with the output elements it never writes."""

    instructions: tuple[Instruction, ...]
    unwritten_outputs: tuple[tuple[int, tuple[int, ...]], ...]
    """Per output port with structural zeros: (port index, dense elements never written)."""


def read_program(kernel: Kernel) -> Program:
    """The SX instruction list of ``kernel.function``, without writes that nothing reads."""
    f = kernel.function
    _check_signature(kernel)
    in_elements = [_dense_elements(f.sparsity_in(i)) for i in range(f.n_in())]
    out_elements = [_dense_elements(f.sparsity_out(j)) for j in range(f.n_out())]
    steps = []
    for k in range(f.n_instructions()):
        op = f.instruction_id(k)
        ins, outs = f.instruction_input(k), f.instruction_output(k)
        if op == ca.OP_INPUT:
            steps.append(Instruction(op, outs[0], port=ins[0], element=in_elements[ins[0]][ins[1]]))
        elif op == ca.OP_OUTPUT:
            steps.append(Instruction(op, -1, (ins[0],), port=outs[0], element=out_elements[outs[0]][outs[1]]))
        elif op == ca.OP_CONST:
            steps.append(Instruction(op, outs[0], constant=float(f.instruction_constant(k))))
        else:
            if len(outs) != 1:
                raise KernelError(
                    f"kernel {kernel.name!r}: {OP_NAMES.get(op, op)} has "
                    f"{len(outs)} results; only scalar operations can be printed"
                )
            steps.append(Instruction(op, outs[0], tuple(ins)))
    unwritten = tuple(
        (j, tuple(sorted(set(range(port.size)) - set(out_elements[j]))))
        for j, port in enumerate(kernel.outputs)
        if len(out_elements[j]) < port.size
    )
    return Program(_shared_reciprocals(_drop_dead_writes(steps)), unwritten)


def _check_signature(kernel: Kernel) -> None:
    f = kernel.function
    if not isinstance(f, ca.Function) or not f.is_a("SXFunction"):
        raise KernelError(f"kernel {kernel.name!r}: function must be a CasADi SX Function")
    if f.has_free():
        raise KernelError(f"kernel {kernel.name!r}: function has free symbols {f.get_free()}")
    for kind, ports, count, sparsity in (
        ("input", kernel.inputs, f.n_in(), f.sparsity_in),
        ("output", kernel.outputs, f.n_out(), f.sparsity_out),
    ):
        if count != len(ports):
            raise KernelError(f"kernel {kernel.name!r}: function has {count} {kind}s, ports name {len(ports)}")
        for i, port in enumerate(ports):
            rows, cols = sparsity(i).size()
            if rows * cols != port.size or min(rows, cols) > 1:
                raise KernelError(
                    f"kernel {kernel.name!r}: {kind} {port.name!r} is {rows}x{cols}, expected "
                    f"a column of {port.size} ({port.rows}x{port.cols} flattened row-major)"
                )


def _dense_elements(sparsity: ca.Sparsity) -> list[int]:
    """Dense index of each structural nonzero of a column or row vector."""
    return [int(i) for i in sparsity.find()]


def _drop_dead_writes(steps: list[Instruction]) -> tuple[Instruction, ...]:
    """Removes register writes whose register is never read (until none is left), so the
    printed C has no set-but-unused variables. Instructions have no side effects."""
    while True:
        read = {r for step in steps for r in step.args}
        kept = [s for s in steps if s.op == ca.OP_OUTPUT or s.target in read]
        if len(kept) == len(steps):
            return tuple(steps)
        steps = kept


def defining_steps(steps: tuple[Instruction, ...] | list[Instruction]) -> list[tuple[int, ...]]:
    """For each step, the index of the step that last wrote each register it reads (-1: none
    before it). CasADi reuses registers, so a value is a register together with its writer."""
    writer: dict[int, int] = {}  # register -> step that last wrote it
    defs = []
    for k, step in enumerate(steps):
        defs.append(tuple(writer.get(r, -1) for r in step.args))
        if step.target >= 0:
            writer[step.target] = k
    return defs


def _shared_reciprocals(steps: tuple[Instruction, ...]) -> tuple[Instruction, ...]:
    """Divisions by one value (a register between two writes) that occurs more than once
    become multiplications by its reciprocal, formed once right after the value: a triangular
    solve with many right-hand sides (M^-1 B) would otherwise divide by L's diagonal in every
    column, and a division costs several multiplications. A reciprocal the program already
    forms (OP_INV) counts as one such division and becomes a copy of the shared one, so that
    no value is divided into 1 twice. New registers are numbered above CasADi's, each written
    once."""
    defs = defining_steps(steps)
    divisors = [_divisor(step, defs[k]) for k, step in enumerate(steps)]
    uses: dict[tuple[int, int], int] = {}
    for key in filter(None, divisors):
        uses[key] = uses.get(key, 0) + 1
    shared = {key for key, count in uses.items() if count > 1}
    if not shared:
        return steps
    fresh = max((s.target for s in steps), default=-1) + 1
    reciprocal: dict[tuple[int, int], int] = {}
    out: list[Instruction] = []

    def add_reciprocal(register: int, defined_at: int) -> None:
        nonlocal fresh
        reciprocal[(register, defined_at)] = fresh
        out.append(Instruction(ca.OP_INV, fresh, (register,)))
        fresh += 1

    for register, defined_at in sorted(key for key in shared if key[1] < 0):  # registers never written here
        add_reciprocal(register, defined_at)
    for k, step in enumerate(steps):
        divisor = divisors[k]
        if divisor is not None and divisor in reciprocal:
            if step.op == ca.OP_INV:
                step = Instruction(ca.OP_ASSIGN, step.target, (reciprocal[divisor],))
            else:
                step = Instruction(ca.OP_MUL, step.target, (step.args[0], reciprocal[divisor]))
        out.append(step)
        if (step.target, k) in shared:
            add_reciprocal(step.target, k)
    return tuple(out)


def _divisor(step: Instruction, defined_at: tuple[int, ...]) -> tuple[int, int] | None:
    """The value (register, the step that wrote it) a division divides by or a reciprocal
    (OP_INV) inverts; None for any other step."""
    if step.op == ca.OP_DIV:
        return step.args[1], defined_at[1]
    if step.op == ca.OP_INV:
        return step.args[0], defined_at[0]
    return None


def reads_first(program: Program) -> Program:
    """The same program with every input read at its start and every output written at its end
    (through registers numbered above the program's): a loop body whose output slice overlaps
    its input slices then computes what it would as a function, all reads before any write."""
    fresh = max((s.target for s in program.instructions), default=-1) + 1
    loaded: dict[tuple[int, int], int] = {}
    head: list[Instruction] = []
    middle: list[Instruction] = []
    tail: list[Instruction] = []
    for step in program.instructions:
        if step.op == ca.OP_INPUT:
            key = (step.port, step.element)
            if key not in loaded:
                loaded[key] = fresh
                head.append(Instruction(ca.OP_INPUT, fresh, port=step.port, element=step.element))
                fresh += 1
            middle.append(Instruction(ca.OP_ASSIGN, step.target, (loaded[key],)))
        elif step.op == ca.OP_OUTPUT:
            middle.append(Instruction(ca.OP_ASSIGN, fresh, step.args))
            tail.append(Instruction(ca.OP_OUTPUT, -1, (fresh,), port=step.port, element=step.element))
            fresh += 1
        else:
            middle.append(step)
    return Program((*head, *middle, *tail), program.unwritten_outputs)
