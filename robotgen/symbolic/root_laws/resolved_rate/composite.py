"""Resolved motion rate control (Whitney 1972) of a composite robot (Deno et al. 1990).

The module of a spec whose root is ``control: {law: resolved_rate, robot: R}``, R an ATTACH
node (possibly under control nodes; controllers anywhere below), has the functions of the
robot tree below the controller (every node's mass, coriolis, n, read, write; plant_*; no
servo_step) and:

- ``velocity_map(theta)`` (nq x k): A(theta), leaf joint rates per unit velocity of R: every
  ATTACH's A (eqs 3.3, 5.8-5.9) composed down to the leaves (robotgen.symbolic.plant).
- ``command_jacobian(theta)`` (k x nq): R's rd map, velocity of R per unit leaf rate; it is
  a left inverse of the velocity map (J A = I).
- ``rate_step(theta, command) -> (theta_dot, manipulability, condition)``: theta_dot =
  A(theta) command, command a velocity of R in its coordinates (R's rd: external rates,
  then the internal-motion rates R exposes, a null-space command). Internal motions that a
  controller in R's tree resolves (R's rd does not carry them) are not commanded: rate zero.
- ``position_step(theta, target) -> (theta_dot, error, manipulability, condition)``: the
  external rates (target - x) / T (angles wrapped), internal-motion rates zero, resolved as
  rate_step does.
- ``arrival_step(theta, target, remaining) -> (theta_dot, error, rate_scale, manipulability,
  condition)``: the same with T the time remaining until arrival (Whitney's eq 11 with a new
  T at every call), at least ``arrival.minimum_remaining``: x moves on the straight line in
  R's coordinates at constant speed. Only when the spec has ``arrival``.

The leaf rates lie in the range of A, so every constraint of the tree holds (fingertips
stay on the payload) whatever the command, damping and rate limits. The singularity
measures are those of the composite Jacobian on the constraint-consistent leaf rates: the
rd map restricted to range(A), whose singular values are 1 / sigma_i(A). Damping is damped
least squares of that map: theta_dot = A (I + lambda^2 A^T A)^-1 command.
"""

from __future__ import annotations

import dataclasses

import casadi as ca

from robotgen.model.system import RobotSystem
from robotgen.symbolic.kernel import Kernel, make_kernel
from robotgen.symbolic.plant import leaf_velocities, strip_controls
from robotgen.symbolic.rigid_body.cholesky import cholesky_solve
from robotgen.symbolic.root_laws.resolved_rate.resolution import (
    conditioning,
    damping_squared,
    limited,
    scale_to_limits,
)
from robotgen.symbolic.system import SystemGraphs
from robotgen.symbolic.system_kernels import system_kernels

# The torque tree's fused step is the controlled robot's write: a rate-controlled module
# leaves it out (`<robot>_write` is the same function).
_TORQUE_STEPS = ("servo_step", "servo_init")


def robot_subsystem(system: RobotSystem) -> RobotSystem:
    """The tree below the resolved-rate root, with the controlled robot as its root."""
    root = system.root_control
    nodes = {k: v for k, v in system.nodes.items() if k != system.root}
    return dataclasses.replace(system, nodes=nodes, root=root.robot)


class CompositeRateLaw:
    """Rate and position control of the robot below ``system``'s root, as SX of theta."""

    def __init__(self, system: RobotSystem):
        node = system.root_control
        s = node.composite_rate
        self.s = s
        # Controllers below do not change the kinematics: the velocity map is the
        # uncontrolled tree's, as the plant has it.
        g = self.g = SystemGraphs(strip_controls(system))
        root = g.graph(g.system.root)
        self.theta, self.n = g.theta, g.n
        names = root.sig.velocity_names
        self.names = s.robot_names  # the command's entries: R's rd
        self.n_external = s.n_external
        self.columns = [names.index(nm) for nm in self.names]
        v = ca.SX.sym("v", len(names))
        A = ca.jacobian(leaf_velocities(g, v), v)  # the map is linear in v
        assert not ca.depends_on(A, g.theta_dot) and not ca.depends_on(A, v)
        self.A = A[:, self.columns]
        self.J = ca.jacobian(root.v, g.theta_dot)[self.columns, :]
        self.x = root.x
        self.angles = s.angles
        self.k = len(self.names)
        # The composite Jacobian on range(A) has singular values 1 / sigma_i(A).
        metric = conditioning(self.A.T)  # of A^T A
        self.manipulability = 1 / metric.manipulability
        self.condition = metric.condition
        self._AtA = self.A.T @ self.A
        d = s.damping
        self._lam2 = damping_squared(self.manipulability, d.lambda_max, d.threshold) if d is not None else None

    def unlimited(self, command: ca.SX) -> ca.SX:
        """Leaf joint rates for a velocity of R, damped, before the rate limits."""
        if self._lam2 is None:
            u = command
        else:
            u = cholesky_solve(ca.SX.eye(self.k) + self._lam2 * self._AtA, command)
        return self.A @ u

    def resolve(self, command: ca.SX) -> ca.SX:
        """Leaf joint rates for a velocity of R, damped and limited."""
        return scale_to_limits(self.unlimited(command), self.s.rate_limits)

    def rates(self, target: ca.SX, T: float | ca.SX) -> tuple[ca.SX, ca.SX]:
        """The velocity of R that reaches the external coordinates ``target`` in time T
        (internal-motion rates zero), and the error target - x (angles wrapped)."""
        e = target - self.x
        error = ca.vertcat(*[ca.atan2(ca.sin(e[i]), ca.cos(e[i])) if a else e[i] for i, a in enumerate(self.angles)])
        return ca.vertcat(error / T, ca.SX.zeros(self.k - self.n_external)), error

    def position_step(self, target: ca.SX) -> tuple[ca.SX, ca.SX]:
        """(joint rates, error) of position control toward ``target``: the error over the horizon, resolved."""
        rates, error = self.rates(target, self.s.horizon)
        return self.resolve(rates), error

    def arrival_step(self, target: ca.SX, remaining: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        """T the remaining time, at least the minimum: (theta_dot, error, rate_scale)."""
        if self.s.arrival is None:
            raise TypeError("arrival_step needs the settings' arrival")
        rates, error = self.rates(target, ca.fmax(remaining, self.s.arrival.minimum_remaining))
        theta_dot, scale = limited(self.unlimited(rates), self.s.rate_limits)
        return theta_dot, error, scale


def composite_kernels(system: RobotSystem) -> list[Kernel]:
    """The resolved-rate kernels of a composite root (robots joined through an ATTACH)."""
    law = CompositeRateLaw(system)
    robot = system.root_control.robot
    th, n, k, ne = law.theta, law.n, law.k, law.n_external
    names = ", ".join(law.names)
    wrapped = [nm for nm, a in zip(law.names, law.angles) if a]
    command = ca.SX.sym("command", k)
    target = ca.SX.sym("target", ne)
    qd_rate = law.resolve(command)
    qd_pos, error = law.position_step(target)
    kernels = [kern for kern in system_kernels(robot_subsystem(system)) if kern.name not in _TORQUE_STEPS]
    measures = [("manipulability", law.manipulability, (1, 1)), ("condition", law.condition, (1, 1))]
    kernels += [
        make_kernel(
            "velocity_map",
            f"Leaf joint rates per unit velocity of '{robot}' ({names}): every attach's A composed down to the leaves.",
            [("theta", th, (n, 1))],
            [("velocity_map", law.A, (n, k))],
        ),
        make_kernel(
            "command_jacobian",
            f"Velocity of '{robot}' ({names}) per unit leaf joint rate: its rd map, a left inverse of velocity_map.",
            [("theta", th, (n, 1))],
            [("command_jacobian", law.J, (k, n))],
        ),
        make_kernel(
            "rate_step",
            f"Resolved rate control of the composite robot '{robot}': leaf joint rates "
            f"A(theta) command for a velocity command ({names}) of '{robot}', damped near singularities "
            "of the tree's velocity map, scaled to the rate limits; every constraint of the tree holds. "
            "Also the manipulability and condition number of the composite Jacobian on the "
            "constraint-consistent leaf rates (singular values 1 / sigma_i(A)).",
            [("theta", th, (n, 1)), ("command", command, (k, 1))],
            [("theta_dot", qd_rate, (n, 1))] + measures,
        ),
        make_kernel(
            "position_step",
            f"Position control through rates of '{robot}': the velocity (target - x) / T, "
            f"T = {law.s.horizon:g} s, on its external coordinates ("
            f"{', '.join(law.names[:ne])}; wrapped to (-pi, pi]: {', '.join(wrapped) or 'none'}), "
            "internal-motion rates zero, resolved as rate_step does. error = target - x (wrapped).",
            [("theta", th, (n, 1)), ("target", target, (ne, 1))],
            [("theta_dot", qd_pos, (n, 1)), ("error", error, (ne, 1))] + measures,
        ),
    ]
    if law.s.arrival is not None:
        remaining = ca.SX.sym("remaining")
        qd_arr, error_arr, scale = law.arrival_step(target, remaining)
        kernels.append(
            make_kernel(
                "arrival_step",
                f"Position control through rates of '{robot}' with the remaining time (eq 11 with a "
                f"new T at every call): the velocity (target - x) / max(remaining, {law.s.arrival.minimum_remaining:g} "
                "s) on its external coordinates, internal-motion rates zero, resolved as rate_step does: a straight "
                "line in those coordinates at constant speed. error as position_step's; rate_scale = "
                "1 / max(1, max_i |theta_dot_i| / limit_i), below 1 when the rate limits slowed it (it arrives late).",
                [("theta", th, (n, 1)), ("target", target, (ne, 1)), ("remaining", remaining)],
                [("theta_dot", qd_arr, (n, 1)), ("error", error_arr, (ne, 1)), ("rate_scale", scale, (1, 1))]
                + measures,
            )
        )
    return kernels


def composite_report(system: RobotSystem) -> tuple[dict, dict]:
    """(extra info() keys, module attributes) of a rate-controlled composite robot."""
    node = system.root_control
    return {"rate_control": {"controller": system.root, "robot": node.robot, **node.rate_settings.summary()}}, {}
