"""The code-generating peers of `make bench` (bench/code_generators.py drives them):

- arms.py: the UR5, the Panda and the KUKA iiwa, robotgen's build of each and the URDF the peers read;
- pinocchio_cg.py, pinocchio_codegen.cpp: Pinocchio's code generation (CppADCodeGen), every variant;
- casadi_kin_dyn_peer.py, casadi_kin_dyn_codegen.py: casadi_kin_dyn's functions as CasADi's C;
- harness.py, peer_harness.c, peer_harness.h: one C program per arm with robotgen's kernels and the
  peers' functions, the agreement check on its 256 states and the interleaved timing.
"""
