"""MuJoCo as an independent plant for `robotgen simulate --plant mujoco`.

- ``model``: a robotgen system written as MJCF (chains and formulas leaves' mechanisms as
  nested bodies, payloads free or planar, grasps as fingertip-on-pad contacts with the
  spec's friction coefficient), with the maps between robotgen's coordinates and MuJoCo's;
- ``run``: stepping that model under a compiled controller's torques, reading back what a
  servo loop senses (joint states, and the forces the leaves exert through their contacts);
- ``contacts``: what the contacts do (normal force, friction-cone usage, slip, separation).

The ``mujoco`` package is an optional dependency (``pip install 'robotgen[mujoco]'``); only
``run`` imports it, through ``require_mujoco``."""

from __future__ import annotations

from robotgen.errors import MUJOCO_INSTALL, MissingDependency


class MujocoMissing(MissingDependency):
    """The mujoco package is not installed (the MuJoCo plant was asked for)."""


def require_mujoco():
    """The mujoco module, or MujocoMissing with the install hint."""
    try:
        import mujoco
    except ImportError as e:
        raise MujocoMissing(f"the MuJoCo plant needs the mujoco package: {MUJOCO_INSTALL}") from e
    return mujoco
