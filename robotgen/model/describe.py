"""A robot system as plain data: printed by `robotgen info`, returned by the module's info()."""
from __future__ import annotations

from robotgen.model.system import RobotSystem


def system_info(system: RobotSystem) -> dict:
    """The robot tree as plain data: printed by `info`, returned by the module's info()."""
    nodes = {}
    for name, node in system.nodes.items():
        entry = {"primitive": node.primitive, "nq": node.nq, "coordinates": list(node.coordinates)}
        leaf = node.leaf
        if hasattr(leaf, "joints"):
            entry["kind"] = "chain"
            entry["joints"] = [_joint_info(j) for j in leaf.joints]
            entry["base_link"], entry["tip_link"] = leaf.base_link, leaf.tip_link
            entry["locked_joints"] = list(leaf.locked_joints)
        else:
            entry["kind"] = "formulas"
        nodes[name] = entry
    return {"root": system.root, "nodes": nodes}


def _joint_info(joint) -> dict:
    lim = joint.limits
    return {
        "name": joint.name, "type": joint.type, "parent": joint.parent,
        "armature": joint.armature, "viscous": joint.viscous, "coulomb": joint.coulomb,
        "damping": joint.damping,
        "limits": {"lower": lim.lower, "upper": lim.upper, "velocity": lim.velocity, "effort": lim.effort},
    }
