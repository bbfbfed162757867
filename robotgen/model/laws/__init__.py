"""The control laws a CONTROL node can carry (Deno et al. 1990, §3.4): their names here, each
law described once in robotgen.model.laws.registry (what it needs, and where each floor keeps
its settings reader, schema block, kernels and simulation).

Tree laws compose anywhere in a robot tree: they have attributes (what the node above sees)
and a write (the force sent down to the controlled robot), and their gains kp, kv act on
the robot's external coordinates. The force laws (robotgen.model.laws.force) also read the
force their robot senses: impedance control (Hogan 1985) and hybrid force/position control
(Raibert and Craig 1981). Root laws are the root of their spec and make the module's own
functions (resolved rate control, Whitney 1972: joint rates from hand rates; the hand laws of
robotgen.model.laws.hand, Lee and Lee 1983)."""

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
