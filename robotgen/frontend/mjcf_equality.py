"""MJCF joint equality constraints read as mimic joints (robotgen.model.coupling).

``<equality><joint joint1="A" joint2="B" polycoef="a0 a1 a2 a3 a4"/>`` holds, in MuJoCo's
terms (mj_instantiateEquality),

    qpos_A - qpos0_A = a0 + a1 (qpos_B - qpos0_B) + a2 (qpos_B - qpos0_B)^2 + ... ,

so with a2 = a3 = a4 = 0 joint A follows joint B, and in robotgen's q = qpos

    q_A = a1 q_B + (qpos0_A + a0 - a1 qpos0_B)

(the offset exact, rounded once). robotgen reads it as exact; MuJoCo enforces it as a soft
constraint (solref, solimp), so MuJoCo's own motion of such a model drifts from robotgen's by
that constraint's give.

Refused, located at the constraint, when it touches a kept joint: no joint B (A held at a
constant), a joint B that is not a hinge or slide joint below the base, a polynomial past
degree 1, a1 = 0, a second constraint on one joint A, and joints that follow each other round
a cycle. Inactive constraints are not read (``mjcf`` notes them).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, Protocol

from robotgen.errors import Location, UserError
from robotgen.model.coupling import Coupling, Mimic, affine, couple

JOINT_EQUALITY = 2  # mjtEq's mjEQ_JOINT


class Compiled(Protocol):
    """What the equality readers need of a compiled MJCF model: the mjModel, joint names, names and locations."""

    m: Any  # a mujoco.MjModel (mujoco has no type stubs)
    joint_names: list[str]

    def name(self, kind: str, i: int) -> str:
        """The MJCF name of element i of ``kind`` (joint, body, equality)."""

    def loc(self, kind: str, i: int) -> Location:
        """Where element i of ``kind`` is written in the file."""

    def fail(self, kind: str, i: int, message: str) -> UserError:
        """A UserError located at element i of ``kind``."""


@dataclass(frozen=True)
class JointEquality:
    """Constraint ``equality``: joint ``joint`` follows ``leader``, q = multiplier q_leader +
    offset; or ``problem``, why robotgen cannot read it (an error when it touches a kept joint)."""

    equality: int
    joint: int
    leader: int
    multiplier: float = 0.0
    offset: float = 0.0
    problem: str | None = None


def joint_equalities(mj: Compiled, joints: set[int], base: str) -> list[JointEquality]:
    """The active joint equality constraints whose joint1 is one of ``joints`` (the hinge and
    slide joints below the base), each read or with its problem (the module docstring's)."""
    m = mj.m
    out: list[JointEquality] = []
    read: dict[int, int] = {}  # joint1 -> the constraint read for it
    for e in range(m.neq):
        if int(m.eq_type[e]) != JOINT_EQUALITY or not m.eq_active0[e] or int(m.eq_obj1id[e]) not in joints:
            continue
        a, b = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
        what = f"equality constraint '{mj.name('equality', e)}'"
        coefficients = [float(v) for v in m.eq_data[e, :5]]
        problem = None
        if b < 0:
            problem = (
                f"{what} holds joint '{mj.joint_names[a]}' at a constant (no joint2), which robotgen does "
                "not model: a body without that joint says so"
            )
        elif b not in joints:
            problem = (
                f"{what} couples joint '{mj.joint_names[a]}' to '{mj.joint_names[b]}', which is not a hinge "
                f"or slide joint below the base body '{base}'"
            )
        elif any(coefficients[2:]):
            degree = max(k for k in range(5) if coefficients[k])
            problem = (
                f"{what} is a polynomial of degree {degree} in joint '{mj.joint_names[b]}' (polycoef=\""
                f'{" ".join(f"{c:g}" for c in coefficients)}"); robotgen couples joints linearly, '
                'polycoef="a0 a1 0 0 0"'
            )
        elif coefficients[1] == 0:
            problem = (
                f"{what} holds joint '{mj.joint_names[a]}' at a constant (its polycoef's a1 is 0), which "
                "robotgen does not model"
            )
        elif a in read:
            problem = (
                f"{what} couples joint '{mj.joint_names[a]}', which equality constraint "
                f"'{mj.name('equality', read[a])}' couples already"
            )
        if problem is not None:
            out.append(JointEquality(e, a, b, problem=problem))
            continue
        read[a] = e
        ref_a, ref_b = (Fraction(float(m.qpos0[m.jnt_qposadr[j]])) for j in (a, b))
        offset = ref_a + Fraction(coefficients[0]) - Fraction(coefficients[1]) * ref_b
        out.append(JointEquality(e, a, b, coefficients[1], float(offset)))
    return out


def refuse_touching(mj: Compiled, equalities: Sequence[JointEquality], kept: set[int]) -> None:
    """The first constraint robotgen cannot read that touches a kept joint, as an error."""
    for q in equalities:
        if q.problem is not None and (q.joint in kept or q.leader in kept):
            raise mj.fail("equality", q.equality, q.problem)


def leading_joints(mj: Compiled, read: Sequence[JointEquality]) -> dict[int, int]:
    """The joint at the end of each coupled joint's line of leaders (the constraints read); a
    line that returns to a joint is an error at the cycle's first constraint."""
    equalities = {q.joint: q for q in read if q.problem is None}
    found: dict[int, int] = {}
    for joint in equalities:
        line = [joint]
        while line[-1] in equalities and line[-1] not in found:
            leader = equalities[line[-1]].leader
            if leader in line:
                cycle = line[line.index(leader) :]
                first = min(cycle, key=lambda j: equalities[j].equality)
                at = cycle.index(first)
                listed = " -> ".join(f"'{mj.joint_names[j]}'" for j in cycle[at:] + cycle[:at] + [first])
                raise mj.fail(
                    "equality",
                    equalities[first].equality,
                    f"joint equality constraints couple joints round a cycle: {listed}",
                )
            line.append(leader)
        end = found.get(line[-1], line[-1])
        for j in line[:-1] if line[-1] not in found else line:
            found[j] = end
    return found


def coupling_of(kept: list[int], read: Sequence[JointEquality]) -> Coupling | None:
    """The coupling of the kept joints (MuJoCo ids, in the tree's order) by the constraints
    read; each kept coupled joint's leader is kept."""
    index = {j: k for k, j in enumerate(kept)}
    return couple(
        len(kept),
        [
            Mimic(index[q.joint], index[q.leader], q.multiplier, q.offset)
            for q in read
            if q.problem is None and q.joint in index
        ],
    )


def coupled_note(mj: Compiled, read: list[JointEquality]) -> tuple[str, ...]:
    """One note on the constraints read as couplings, at the first of them."""
    if not read:
        return ()
    read = sorted(read, key=lambda q: q.equality)
    listed = ", ".join(
        f"'{mj.joint_names[q.joint]}' = {affine(q.multiplier, repr(mj.joint_names[q.leader]), q.offset)}" for q in read
    )
    many = len(read) != 1
    return (
        f"{mj.loc('equality', read[0].equality)}: note: read {len(read)} joint equality constraint"
        f"{'s' if many else ''} as exact coupling{'s' if many else ''} (MuJoCo enforces "
        f"{'them' if many else 'it'} softly): the coupled joint{'s have' if many else ' has'} no coordinate of "
        f"{'their' if many else 'its'} own, q = a1 q_joint2 + offset: {listed}",
    )
