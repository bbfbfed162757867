"""The robot model: plain immutable data, built from a validated spec (or a URDF)."""
