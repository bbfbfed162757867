"""robotgen: a compiler for robot control code.

Data flows spec (YAML) -> model (plain immutable data) -> symbolic (CasADi graphs)
-> emit (C, Python extension, manifest). See docs/ARCHITECTURE.md.
"""

__version__ = "0.1.0"
