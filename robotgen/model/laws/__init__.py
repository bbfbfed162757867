"""The control laws a CONTROL node can carry (Deno et al. 1990, §3.4), by name: the one list
the spec schema, the spec front end and the symbolic layer read.

Tree laws compose anywhere in a robot tree: they have attributes (what the node above sees)
and a write (the force sent down to the controlled robot), and their gains kp, kv act on
the robot's external coordinates. The force laws (robotgen.model.laws.force) also read the
force their robot senses: impedance control (Hogan 1985) and hybrid force/position control
(Raibert and Craig 1981). Root laws are the root of their spec and make the
module's own functions (resolved rate control: joint rates from hand rates)."""
from __future__ import annotations

COMPUTED_TORQUE = "computed_torque"
FEEDFORWARD = "feedforward"
PD_FEEDFORWARD = "pd_feedforward"
PD = "pd"
IMPEDANCE = "impedance"
HYBRID = "hybrid"
RESOLVED_RATE = "resolved_rate"
RESOLVED_ACCELERATION = "resolved_acceleration"
RESOLVED_ADAPTIVE = "resolved_adaptive"

TREE_LAWS = (COMPUTED_TORQUE, FEEDFORWARD, PD_FEEDFORWARD, PD, IMPEDANCE, HYBRID)
# tree laws with settings of their own (a block named after the law), and no kp, kv of the
# node but the hybrid law's position gains
FORCE_LAWS = (IMPEDANCE, HYBRID)
ROOT_LAWS = (RESOLVED_RATE, RESOLVED_ACCELERATION, RESOLVED_ADAPTIVE)
# root laws that output joint torques for a hand trajectory (robotgen.model.laws.hand)
HAND_LAWS = (RESOLVED_ACCELERATION, RESOLVED_ADAPTIVE)
LAWS = TREE_LAWS + ROOT_LAWS
