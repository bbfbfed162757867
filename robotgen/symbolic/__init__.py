"""CasADi graphs for every quantity robotgen emits. Knows nothing about C or files.

rigid_body/ holds the algorithms on one kinematic tree (kinematics, Jacobian, CRBA, RNEA,
Coriolis, L D L^T); define, attach and control/ the three primitives of Deno et al. 1990;
system composes them over a robot tree, servo into one servo step, plant into the true
constrained dynamics; module says what a system's module emits."""

from robotgen.symbolic.leaf_kernels import leaf_kernels
from robotgen.symbolic.module import controllers_for, kernels_for, module_extras

__all__ = ["controllers_for", "kernels_for", "leaf_kernels", "module_extras"]
