"""What a root law gives (robotgen.model.laws.registry: laws whose ``root`` is set): a root law
is the root of its spec and makes the module's functions itself, its kernels and a report
(info() keys and module attributes), and, if it has one, the controller class the module
offers."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from robotgen.model.system import RobotSystem
from robotgen.symbolic.kernel import Kernel


@dataclass(frozen=True)
class StateView:
    """A block of a controller's state that its class shows read-only (an estimate)."""

    name: str
    offset: int
    rows: int
    cols: int
    doc: str


@dataclass(frozen=True)
class StartCheck:
    """What the first step after a reset refuses: ``kernel`` (inputs q and pose_d, one output)
    gives one distance per entry of ``limits`` (in ``units``); when one is above its limit (or
    NaN) the step returns status 3 having written nothing, and the controller stays reset.
    ``hint`` says what to do instead, in the Python message."""

    kernel: str
    limits: tuple[float, ...]
    units: tuple[str, ...]
    hint: str


@dataclass(frozen=True)
class Controller:
    """A controller object around one step kernel: a Python class in the module and a state
    struct with step/reset functions in C.

    The step kernel's inputs are q, qd, pose_d, twist_d, accel_d, then ``state`` (if
    state_size), then one input per flag (a number: 1 true, 0 false), then the parameters;
    its outputs tau, then ``state_next`` (if state_size). ``init`` (a kernel of the first five
    inputs and the parameters, output ``state``) gives the state the first step after a
    reset starts from."""

    class_name: str
    step: str
    period: float
    state_size: int = 0
    init: str | None = None
    flags: tuple[str, ...] = ()  # boolean attributes, True after construction
    views: tuple[StateView, ...] = ()
    start: StartCheck | None = None  # checked on the first step after a reset


@dataclass(frozen=True)
class RootLaw:
    """A CONTROL law that is the root of its spec: kernels(system) are the module's
    functions, report(system) its extra info() keys and module attributes, and
    controller(system), if any, the controller class the module offers."""

    name: str
    kernels: Callable[[RobotSystem], list[Kernel]]
    report: Callable[[RobotSystem], tuple[dict, dict]]
    controller: Callable[[RobotSystem], Controller] | None = None
