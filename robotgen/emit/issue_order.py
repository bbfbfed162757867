"""The order in which a small straight-line kernel's statements are printed.

CasADi lists a program's steps in the order its expression graph was built: one recursion
after the other. A kernel with few operations per step of its longest chain of dependent
operations (a mass matrix, a Jacobian, gravity) is bound by that chain,
and the processor overlaps the independent chains only as far as its window reaches. For
such a kernel the statements are printed in the order of a list schedule instead: cycle by
cycle, up to ISSUE_WIDTH ready operations, the one heading the longest remaining chain
first. The values, and so the results, are the same bit for bit; only the order differs.
Kernels with many operations per chain step (fused, derivative kernels) are bound by the
processor's throughput, and a list schedule holds too many values live for them (it made
fused servo terms slower). Those without loops are printed
in an order that frees values early instead (pressure_scheduled): a constant or an input
just before the step that reads it, and of the steps ready, the one reading the most values
for the last time. gcc at -O2 on x86-64 does not reorder before allocating registers, so
the printed order is the one it spills by (the timings behind both orders:
docs/performance-log.md).

The latencies are a model (cycles of a current x86-64 core), used only to rank; the order
is computed from them alone, so it is the same on every machine.
"""

from __future__ import annotations

import heapq

import casadi as ca

from robotgen.emit.sx_program import Instruction, Program, defining_steps

ISSUE_WIDTH = 4  # floating-point operations a core starts per cycle
_FREE = frozenset({ca.OP_INPUT, ca.OP_CONST, ca.OP_OUTPUT, ca.OP_ASSIGN})
_LATENCY = {
    ca.OP_NEG: 1,
    ca.OP_FABS: 1,
    ca.OP_DIV: 13,
    ca.OP_INV: 13,
    ca.OP_SQRT: 15,
    ca.OP_SIN: 25,
    ca.OP_COS: 25,
    ca.OP_TAN: 30,
    ca.OP_ATAN2: 40,
    ca.OP_EXP: 20,
    ca.OP_LOG: 20,
}
_DEFAULT_LATENCY = 3  # add, subtract, multiply, compare, select


def latency(op: int) -> int:
    """Modelled latency of an operation in cycles of a current x86-64 core (0 for inputs, constants, outputs,
    copies)."""
    return 0 if op in _FREE else _LATENCY.get(op, _DEFAULT_LATENCY)


def _single_assignment(program: Program) -> list[Instruction]:
    """The steps with step k writing register k (CasADi reuses registers; a moved step must
    not read a register that something else wrote in the meantime)."""
    defs = defining_steps(program.instructions)
    return [
        Instruction(step.op, k if step.target >= 0 else -1, defs[k], step.port, step.element, step.constant)
        for k, step in enumerate(program.instructions)
    ]


def critical_path(program: Program) -> tuple[int, int]:
    """(operations, cycles of the longest chain of dependent operations) in the model."""
    ready: dict[int, int] = {}
    longest = operations = 0
    for step in program.instructions:
        start = max((ready.get(r, 0) for r in step.args), default=0)
        if step.target >= 0:
            ready[step.target] = start + latency(step.op)
        operations += step.op not in _FREE
        longest = max(longest, start + latency(step.op))
    return operations, longest


def latency_bound(program: Program) -> bool:
    """Whether the program has fewer operations per cycle of its longest chain than a core
    can start (so the chain, not the operations, sets its time)."""
    operations, longest = critical_path(program)
    return operations < ISSUE_WIDTH * longest


def list_scheduled(program: Program) -> Program:
    """``program`` in list-schedule order (registers renamed: step k of the original writes
    register k). Ties go to the step listed first, so the order is deterministic."""
    steps = _single_assignment(program)
    n = len(steps)
    users: list[list[int]] = [[] for _ in range(n)]
    waiting = [0] * n
    for k, step in enumerate(steps):
        for r in set(step.args):
            users[r].append(k)
        waiting[k] = len(set(step.args))
    height = [0] * n  # cycles from the start of step k to the end of the program
    for k in reversed(range(n)):
        height[k] = latency(steps[k].op) + max((height[u] for u in users[k]), default=0)
    available = [0] * n
    ready = [(-height[k], k) for k in range(n) if waiting[k] == 0]
    heapq.heapify(ready)
    later: list[tuple[int, int]] = []  # (cycle its operands are done, step)
    order: list[int] = []
    cycle = 0
    while ready or later:
        while later and later[0][0] <= cycle:
            heapq.heappush(ready, (-height[later[0][1]], heapq.heappop(later)[1]))
        for _ in range(ISSUE_WIDTH):
            if not ready:
                break
            k = heapq.heappop(ready)[1]
            order.append(k)
            for u in users[k]:
                available[u] = max(available[u], cycle + latency(steps[k].op))
                waiting[u] -= 1
                if waiting[u] == 0:
                    heapq.heappush(later, (available[u], u))
        cycle += 1
    return Program(tuple(steps[k] for k in order), program.unwritten_outputs)


def pressure_scheduled(program: Program) -> Program:
    """``program`` in an order that holds few values live at once (registers renamed as in
    list_scheduled). Greedily, of the steps whose computed operands are all done, the one that
    frees the most values: the operands it reads for the last time, less the value it defines
    and the constants and inputs it needs first (each printed right before its first reader).
    Ties go to the step listed first, so the order is deterministic."""
    steps = _single_assignment(program)
    n = len(steps)
    lazy = [step.op in (ca.OP_CONST, ca.OP_INPUT) for step in steps]
    operands = [sorted(set(step.args)) for step in steps]
    users: list[list[int]] = [[] for _ in range(n)]
    for k in range(n):
        for r in operands[k]:
            users[r].append(k)
    remaining = [len(u) for u in users]  # readers not yet printed
    blocked = [sum(not lazy[r] for r in operands[k]) for k in range(n)]  # computed operands not done
    done = [False] * n
    score = [0] * n
    heap: list[tuple[int, int]] = []

    def rescore(k: int) -> None:
        if done[k] or lazy[k] or blocked[k]:
            return
        s = (
            sum(remaining[r] == 1 for r in operands[k])
            - sum(lazy[r] and not done[r] for r in operands[k])
            - (1 if steps[k].target >= 0 and users[k] else 0)
        )
        score[k] = s
        heapq.heappush(heap, (-s, k))

    order: list[int] = []

    def emit(k: int) -> None:
        done[k] = True
        order.append(k)
        for r in operands[k]:
            remaining[r] -= 1
            if remaining[r] == 1:  # its last reader now frees it
                for u in users[r]:
                    rescore(u)
        for u in users[k]:
            if lazy[k]:
                rescore(u)  # one constant or input fewer to print first
            else:
                blocked[u] -= 1
                rescore(u)

    for k in range(n):
        rescore(k)
    while heap:
        s, k = heapq.heappop(heap)
        if done[k] or -s != score[k]:
            continue
        for r in operands[k]:
            if not done[r]:
                emit(r)
        emit(k)
    order += [k for k in range(n) if not done[k]]  # constants and inputs nothing reads
    return Program(tuple(steps[k] for k in order), program.unwritten_outputs)
