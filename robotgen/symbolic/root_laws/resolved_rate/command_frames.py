"""Command coordinates of resolved motion rate control (Whitney 1972, eqs 7-10).

Every frame is a 6 x 6 map M(q) from the hand's base-frame twist (v of the controlled point;
omega) to the six command rates, so the task Jacobian is M [J_v; J_w] with J_v, J_w the
cross-product Jacobian of eqs 8-9:

- base:          M = I (eq 8 without C7^T: motion along and about the shoulder axes).
- hand:          M = diag(C7^T, C7^T) (eq 7): sweep, reach, lift along hand x, y, z; tilt,
                 twist, turn about them.
- tool:          the same for a tool frame fixed in the hand; the tool origin is the
                 controlled point (v = v_hand + omega x r).
- line_of_sight: the reach row replaced by b87^T v, b87 the unit vector from the eye O8 to
                 the hand (eq 10, no C7^T on that row). So that holding sweep and lift keeps
                 the hand on the line, those rows are the hand axes (z for lift, x for sweep,
                 whichever is further from the line is used first) made perpendicular to it.
- spherical:     radius, azimuth and elevation rates of the controlled point about a centre,
                 base z the polar axis; rotations in hand axes.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from robotgen.model.chain import KinematicTree
from robotgen.model.laws.resolved_rate import BASE, HAND, LINE_OF_SIGHT, SPHERICAL, TOOL, CommandFrame
from robotgen.symbolic.rigid_body.jacobian import geometric_jacobian
from robotgen.symbolic.rigid_body.kinematics import joint_motions, joint_poses, tip_pose
from robotgen.symbolic.rigid_body.spatial import const, skew


@dataclass(frozen=True, eq=False)
class Hand:
    """The controlled frame at q: orientation C7 and origin b17 in base coordinates, and the
    base-frame Jacobians of its origin's velocity and of its angular velocity."""

    R: ca.SX
    p: ca.SX
    Jv: ca.SX
    Jw: ca.SX


def hand(tree: KinematicTree, frame: CommandFrame, q: ca.SX) -> Hand:
    """The command frame's pose and Jacobian rows (Jv, Jw) at joint positions q (n,)."""
    R, p = tip_pose(tree, joint_poses(tree, joint_motions(tree, q)))
    J = geometric_jacobian(tree, q)
    Jv, Jw = J[:3, :], J[3:, :]
    if frame.kind == TOOL:
        r = R @ const(frame.tool_pose[:3, 3])
        return Hand(R @ const(frame.tool_pose[:3, :3]), p + r, Jv - skew(r) @ Jw, Jw)
    return Hand(R, p, Jv, Jw)


def _unit(v: ca.SX) -> ca.SX:
    return v / ca.norm_2(v)


def _blocks(top: ca.SX, bottom: ca.SX) -> ca.SX:
    return ca.vertcat(ca.horzcat(top, ca.SX.zeros(3, 3)), ca.horzcat(ca.SX.zeros(3, 3), bottom))


def twist_map(frame: CommandFrame, h: Hand) -> ca.SX:
    """M(q): command rates = M [v; omega] (base coordinates)."""
    Rt = h.R.T
    if frame.kind == BASE:
        return ca.SX.eye(6)
    if frame.kind in (HAND, TOOL):
        return _blocks(Rt, Rt)
    if frame.kind == LINE_OF_SIGHT:
        sight = _unit(h.p - const(frame.centre))  # b87 / |b87|, eq 10
        x, z = h.R[:, 0], h.R[:, 2]
        lift_z = _unit(z - ca.dot(z, sight) * sight)
        sweep_x = _unit(x - ca.dot(x, sight) * sight)
        use_z = ca.fabs(ca.dot(z, sight)) <= ca.fabs(ca.dot(x, sight))
        lift = ca.if_else(use_z, lift_z, ca.cross(sweep_x, sight))
        sweep = ca.if_else(use_z, ca.cross(sight, lift_z), sweep_x)
        return _blocks(ca.horzcat(sweep, sight, lift).T, Rt)
    if frame.kind == SPHERICAL:
        d = h.p - const(frame.centre)
        dx, dy, dz = d[0], d[1], d[2]
        h2 = dx * dx + dy * dy
        horizontal = ca.sqrt(h2)
        rho2 = h2 + dz * dz
        radius = (d / ca.sqrt(rho2)).T
        azimuth = ca.horzcat(-dy / h2, dx / h2, 0)
        elevation = ca.horzcat(-dx * dz / (horizontal * rho2), -dy * dz / (horizontal * rho2), horizontal / rho2)
        return _blocks(ca.vertcat(radius, azimuth, elevation), Rt)
    raise ValueError(f"unknown command frame {frame.kind}")


def command_jacobian(frame: CommandFrame, h: Hand) -> ca.SX:
    """6 x n: command rates per unit joint rate (eq 3)."""
    return twist_map(frame, h) @ ca.vertcat(h.Jv, h.Jw)
