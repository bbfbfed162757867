"""A robot system as plain data: printed by `robotgen info`, returned by the module's info()."""

from __future__ import annotations

from robotgen.model.chain import KinematicTree
from robotgen.model.signature import (
    constraint_residual_names,
    coordinate_units,
    internal_force_names,
    robot_leaves,
    signature,
)
from robotgen.model.system import AttachNode, ControlNode, DefineNode, RobotSystem


def system_nq(system: RobotSystem) -> int:
    """Number of sensed joint coordinates: the actuated leaves' coordinates, stacked."""
    return sum(system.leaf(leaf).nq for leaf in robot_leaves(system))


def system_info(system: RobotSystem) -> dict:
    """The system's info(): each node's primitive, coordinates, internal motions and forces, nq and units."""
    nodes = {}
    for node in system.walk():
        sig = signature(system, node.name)
        entry = {
            "primitive": node.primitive,
            "coordinates": list(sig.external),
            "internal_motions": list(sig.internal_motions),
            "internal_forces": list(sig.internal_forces),
            "nq": sig.n_velocity,
            "units": list(coordinate_units(system, node.name)),
        }
        if isinstance(node, DefineNode):
            leaf = node.leaf
            entry["kind"] = type(leaf).__name__
            if isinstance(leaf, KinematicTree):
                entry["kind"] = "chain"
                entry["joints"] = [_joint_info(j) for j in leaf.joints]
                entry["base_link"], entry["tip_link"] = leaf.base_link, leaf.tip_link
                entry["locked_joints"] = list(leaf.locked_joints)
                if leaf.coupling is not None:
                    entry["coupled_joints"] = coupled_joints(leaf)
            elif entry["kind"] == "FormulaRobot":
                entry["kind"] = "formulas"
            else:
                entry["kind"] = "rigid_body"
        elif isinstance(node, AttachNode):
            entry.update(kind=node.constraint.kind, robots=list(node.robots), payload=node.payload)
        elif isinstance(node, ControlNode):
            entry.update(kind=node.law, robot=node.robot)
            if node.internal_forces is not None:  # resolved here, to these values
                resolved = signature(system, node.robot).internal_forces
                entry["internal_force_setpoints"] = dict(zip(resolved, map(float, node.internal_forces)))
        nodes[node.name] = entry
    info = {"root": system.root, "leaves": robot_leaves(system), "nodes": nodes}
    residual = constraint_residual_names(system)
    if residual:
        info["constraint_residual"] = residual
    forces = internal_force_names(system)
    if forces:
        info["internal_forces"] = forces
    return info


def coupled_joints(tree: KinematicTree) -> list[dict]:
    """Each mimic joint and how it moves: q_joint = multiplier q_coordinate + offset, the
    coordinate named after its own joint (model/coupling.py)."""
    c = tree.coupling
    if c is None:
        return []
    return [
        {
            "joint": tree.joints[i].name,
            "coordinate": tree.joints[c.independent[c.coordinate[i]]].name,
            "multiplier": c.multiplier[i],
            "offset": c.offset[i],
        }
        for i in c.followers()
    ]


def _joint_info(joint) -> dict:
    lim = joint.limits
    return {
        "name": joint.name,
        "type": joint.type,
        "parent": joint.parent,
        "armature": joint.armature,
        "viscous": joint.viscous,
        "coulomb": joint.coulomb,
        "damping": joint.damping,
        "limits": {"lower": lim.lower, "upper": lim.upper, "velocity": lim.velocity, "effort": lim.effort},
    }
