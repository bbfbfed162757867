"""A control law described once (Deno et al. 1990, §3.4): its name, what it needs from the
node and the robot it controls, and where each floor keeps its part of it.

The model does not import the floors above it, so a part is named, not held: ``"module:attr"``
(an attribute path after the colon) or ``"module"``, imported when a floor asks for it
(``Law.part``). robotgen.model.laws.registry lists every law, one line each; a test checks
that every named part exists and agrees with the flags here."""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

PARTS = ("settings", "schema", "kernels", "simulation")


@dataclass(frozen=True)
class Law:
    """One control law.

    name:            the spec's ``law``.
    kernels:         the symbolic law: a TreeLaw (robotgen.symbolic.control) or, for a root
                     law, a RootLaw (robotgen.symbolic.root_laws).
    root:            None for a tree law, which composes anywhere in a robot tree; for a root
                     law, why it must be the root of its spec (it makes the module's functions).
    hand_frame:      drives the hand frame of a 6-joint chain (Lee and Lee 1983): its period
                     is its own and its simulation follows a hand path.
    gains:           reads the node's kp, kv (run-time parameters unless folded); ``no_gains``
                     says why it does not.
    internal_forces: resolves internal forces and internal motion (False: it passes the
                     robot's attributes up unchanged, so it can resolve neither).
    reads_forces:    may read the force its robot senses (the servo step then takes tau_sensed).
    stateful:        keeps a controller state (an expected trajectory, a force integral, an
                     identification).
    expected:        integrates an expected trajectory (x_e, xd_e) for the robot below
                     (§3.4), anchored to the sensed state by the node's ``anchor``.
    settings:        the front end's reader of the block named after the law:
                     (reader, system, node, spec, robot signature) -> the checked ControlNode.
    schema:          that block's JSON-schema ``$defs`` entry.
    simulation:      a root law's ``robotgen simulate`` (a module of robotgen.simulation with
                     comparison_system, run, write_csv, plot, summary, compare); tree laws run
                     in the servo step's simulation.
    """

    name: str
    kernels: str
    root: str | None = None
    hand_frame: bool = False
    gains: bool = True
    no_gains: str = ""
    internal_forces: bool = True
    reads_forces: bool = False
    stateful: bool = False
    expected: bool = False
    settings: str | None = None
    schema: str | None = None
    simulation: str | None = None

    @property
    def is_root(self) -> bool:
        """The law must be the tree's root node (a root law)."""
        return self.root is not None

    def part(self, which: str) -> Any:
        """The object a part names (``which`` one of PARTS), None if the law has no such part."""
        where = getattr(self, which)
        if where is None:
            return None
        module, _, attributes = where.partition(":")
        found: Any = importlib.import_module(module)
        for attribute in filter(None, attributes.split(".")):
            found = getattr(found, attribute)
        return found
