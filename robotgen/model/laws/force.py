"""Settings of the force laws, tree laws that read the force their robot senses (its rd force
term, Deno et al. 1990 eq 3.7) on its external coordinates x:

- impedance control (Hogan 1985): the robot made to behave as
  M_d (xdd - xdd_d) + D (xd - xd_d) + K (x - x_d) = F_ext + F_d, F_ext = -F_s the force of
  what it touches (F_s: what it exerts, as sensed);
- hybrid force/position control (Raibert and Craig 1981): a selection matrix S (1 on a
  position-controlled coordinate, 0 on a force-controlled one) splits the coordinates; the
  position ones follow x_d, the force ones exert the force F_d written at the node.

Every matrix is on the robot's n external coordinates, written as a number (times I), a list
(the diagonal) or n rows (symmetric positive definite), like kp and kv; each is a run-time
parameter unless the node's gains are folded."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robotgen.model.parameters import MATRIX_GAIN, Bounds, RuntimeParameter, written_shape

# The values the settings may take, in the spec and at run time (robotgen.model.parameters):
# (per entry of a number or a diagonal, of a matrix)
STIFFNESS = (
    Bounds("stiffness", minimum=0.0, note="K of the target impedance"),
    Bounds.definite("stiffness", "K of the target impedance"),
)
DAMPING = (
    Bounds.positive("damping", "D of the target impedance"),
    Bounds.definite("damping", "D of the target impedance"),
)
INERTIA = (
    Bounds.positive("inertia", "M_d of the target impedance"),
    Bounds.definite("inertia", "M_d of the target impedance"),
)
SELECTION = Bounds("selection", minimum=0.0, maximum=1.0, note="1 position-controlled, 0 force-controlled")
FORCE_GAIN = Bounds("force gain kf", minimum=0.0)
FORCE_INTEGRAL_GAIN = Bounds("force gain ki", minimum=0.0, note="[1/s]")


@dataclass(frozen=True, eq=False)
class WrittenMatrix:
    """A matrix as the spec wrote it: its value (n, n) and its form (robotgen.model.parameters:
    a number, a diagonal or the rows), which shapes its run-time parameter."""

    value: np.ndarray
    form: str

    def parameter(self, name: str, doc: str, bounds: tuple[Bounds, Bounds]) -> RuntimeParameter:
        """This matrix as a run-time parameter, bounded as a gain (number, diagonal) or a definite matrix (rows)."""
        shape, values = written_shape(self.form, self.value)
        return RuntimeParameter(name, shape, values, doc, bounds[1] if self.form == MATRIX_GAIN else bounds[0])


@dataclass(frozen=True, eq=False)
class ImpedanceSettings:
    """Hogan's target impedance on the robot's external coordinates. With ``inertia`` the law
    reads the sensed force and reshapes the robot's inertia to M_d; without it the robot
    keeps its own (M_d = M) and the law needs no force sensing."""

    stiffness: WrittenMatrix
    damping: WrittenMatrix
    inertia: WrittenMatrix | None = None
    runtime: bool = True  # read at run time (the node's gains: folded compiles them in)

    def parameters(self, node: str, axes: str) -> list[RuntimeParameter]:
        """The run-time parameters of an impedance node: stiffness K, damping D and, when set, inertia M_d."""
        if not self.runtime:
            return []
        out = [
            self.stiffness.parameter(
                f"{node}_stiffness", f"stiffness K of impedance controller '{node}' on {axes}", STIFFNESS
            ),
            self.damping.parameter(f"{node}_damping", f"damping D of impedance controller '{node}' on {axes}", DAMPING),
        ]
        if self.inertia is not None:
            out.append(
                self.inertia.parameter(
                    f"{node}_inertia", f"inertia M_d of impedance controller '{node}' on {axes}", INERTIA
                )
            )
        return out


@dataclass(frozen=True, eq=False)
class HybridSettings:
    """Raibert and Craig's selection of position- and force-controlled coordinates, and the
    force loop's gains: kf on the force error (dimensionless), ki on its integral [1/s]. The
    position part uses the node's kp and kv."""

    selection: np.ndarray  # (n,) 1 position-controlled, 0 force-controlled
    kf: float = 0.0
    ki: float = 0.0
    runtime: bool = True

    def parameters(self, node: str, axes: str) -> list[RuntimeParameter]:
        """The run-time parameters of a hybrid node: selection S and the force loop's gains kf and ki."""
        if not self.runtime:
            return []
        return [
            RuntimeParameter(
                f"{node}_selection",
                (len(self.selection),),
                tuple(map(float, self.selection)),
                f"selection S of hybrid controller '{node}' on {axes} (1 position-controlled, 0 force-controlled)",
                SELECTION,
            ),
            RuntimeParameter(
                f"{node}_kf",
                (),
                (float(self.kf),),
                f"force gain kf of hybrid controller '{node}' on the force error",
                FORCE_GAIN,
            ),
            RuntimeParameter(
                f"{node}_ki",
                (),
                (float(self.ki),),
                f"force gain ki of hybrid controller '{node}' on the force error's integral [1/s]",
                FORCE_INTEGRAL_GAIN,
            ),
        ]
