"""CONTROL (Deno et al. 1990, §3.4): the tree laws, one module per law.

Tree laws (computed_torque, feedforward, pd_feedforward, pd, and the force laws impedance and
hybrid, which read the force their robot senses) implement
robotgen.symbolic.control.law.TreeLaw and are listed in robotgen.model.laws.registry; root
laws, which make a module's functions themselves, are robotgen.symbolic.root_laws."""
