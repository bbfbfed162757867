"""A wall in robotgen's plant (the spec's simulation.wall): a frictionless half-space that a
node's point touches, as a spring and damper along its normal.

The node's coordinates x are the point (a frame change's tip): x and xd = J theta_dot come
from the module's ``<node>_read``, J column by column (xd is linear in theta_dot). With n the
wall's unit normal, the point is d = (point - x) . n deep and the wall pushes it out with

    f_n = max(0, stiffness d + damping d_dot)   (d > 0; 0 outside),  d_dot = -xd . n,

never pulling. That force acts on the leaves as joint torques J^T n f_n, added to the
actuators' in every stage of the plant's RK4 step. What a leaf senses (tau_sensed, rd's force
term) is what it exerts on everything it touches: the grasps' share from the module's
plant_sensed_forces, and -J^T n f_n on the wall."""

from __future__ import annotations

import numpy as np

from robotgen.model.simulation import Wall


class WallContact:
    """A wall in robotgen's plant: a frictionless spring-damper half-space acting on one node's point."""

    def __init__(self, module, wall: Wall):
        self.wall = wall
        self.read = getattr(module, f"{wall.node}_read")
        self.point, self.normal = np.asarray(wall.point, float), np.asarray(wall.normal, float)
        self.unit = np.eye(module.nq)

    def depth(self, theta: np.ndarray, theta_dot: np.ndarray) -> tuple[float, float, np.ndarray]:
        """(d, d_dot, J^T n): how deep the point is, how fast it goes in, and the joint torques
        of a unit push along the normal."""
        x, xd = self.read(theta, theta_dot)
        _, columns = self.read(np.tile(theta, (len(theta), 1)), self.unit)  # row j: J e_j
        return float((self.point - x) @ self.normal), float(-xd @ self.normal), columns @ self.normal

    def normal_force(self, theta: np.ndarray, theta_dot: np.ndarray) -> float:
        """The wall's normal force [N] at leaf positions theta and rates theta_dot (nq,)."""
        d, d_dot, _ = self.depth(theta, theta_dot)
        return self._force(d, d_dot)

    def torque(self, theta: np.ndarray, theta_dot: np.ndarray) -> np.ndarray:
        """J^T n f_n: the wall's push on the leaves' joints."""
        d, d_dot, push = self.depth(theta, theta_dot)
        return push * self._force(d, d_dot)

    def _force(self, d: float, d_dot: float) -> float:
        return max(0.0, self.wall.stiffness * d + self.wall.damping * d_dot) if d > 0 else 0.0
