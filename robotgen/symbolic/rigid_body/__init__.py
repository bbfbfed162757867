"""Rigid-body algorithms on a KinematicTree as CasADi SX graphs: kinematics, CRBA, RNEA, Coriolis, derivatives,
loops."""
