"""CasADi graphs for every quantity robotgen emits. Knows nothing about C or files."""
from robotgen.symbolic.kernels import kernels_for, leaf_kernels, module_extras

__all__ = ["kernels_for", "leaf_kernels", "module_extras"]
