"""CONTROL (Deno et al. 1990, §3.4), one module per law.

Tree laws (computed_torque, feedforward, pd_feedforward, pd, and the force laws impedance and
hybrid, which read the force their robot senses) implement
robotgen.symbolic.control.law.TreeLaw and are listed in tree_laws; root laws (resolved_rate)
make a module's functions themselves and are listed in root_laws."""
