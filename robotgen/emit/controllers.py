"""The controller classes of a module (robotgen.symbolic.root_laws.law.Controller), checked
against their kernels and gathered for the templates: a state struct with reset and step
functions in C, a class in the Python extension.

A controller's C prefix is ``<module>_<snake case of its class without "Controller">_controller``
(AdaptiveController in puma560_rmac: ``puma560_rmac_adaptive_controller``); it names the
struct type, ``<prefix>_reset``, ``<prefix>_step`` and the macros ``<PREFIX>_*``."""

from __future__ import annotations

import re
import textwrap
from dataclasses import dataclass

from robotgen.emit import c_kernel
from robotgen.emit.literals import c_string, py_string
from robotgen.emit.sx_program import KernelError
from robotgen.emit.views import FunctionView, ParameterView, PortView
from robotgen.symbolic.root_laws.law import Controller

# The first inputs of every step kernel (and the only inputs of an init kernel, with params).
TRAJECTORY = ("q", "qd", "pose_d", "twist_d", "accel_d")
STATE, STATE_NEXT = "state", "state_next"
# Python attributes every controller class has (flags and views may not take them).
CLASS_ATTRIBUTES = frozenset({"step", "reset", "period", "state", "last", "parameters"})
# Struct fields every controller struct has (flags and the step's other outputs may not take them).
STRUCT_FIELDS = frozenset({"state", "initialised"})
# The C step's own names (its struct pointer and locals): no port of the step may take them.
C_NAMES = frozenset({"controller"})
# The type of a controller's `parameters` (a module attribute of a module with run-time parameters).
PARAMETERS_CLASS = "ControllerParameters"
WIDTH = 92  # of the header's comment lines


@dataclass(frozen=True)
class ViewView:
    """A block of the state a class shows read-only (a StateView)."""

    name: str
    offset: int
    rows: int
    cols: int
    size: int
    shape: tuple[int, ...]  # (rows,) when cols == 1, else (rows, cols)
    shape_text: str
    doc: str
    doc_line: str  # the doc on one line, safe in a C comment
    offset_macro: str  # <PREFIX>_<VIEW>_OFFSET
    stub_doc: str  # Python string literal
    c_doc: str  # C string literal


@dataclass(frozen=True)
class OutputField:
    """One of the step's outputs other than tau and state_next: a struct field holding its
    value from the last step, and an entry of the Python class's ``last``."""

    name: str
    size: int
    shape: tuple[int, ...]
    shape_text: str
    index: int  # of the port among the step kernel's outputs


@dataclass(frozen=True)
class ControllerView:
    """A root law's controller as the templates show it: the Python class, the C struct with its reset and step,
    their kernels."""

    class_name: str
    snake: str  # "adaptive"
    c_type: str  # <module>_<snake>_controller
    macro: str  # C_TYPE upper case
    c_reset: str
    c_step: str
    step: str  # kernel names
    c_step_kernel: str
    init: str | None
    c_init_kernel: str
    period: float
    period_literal: str  # exact double literal
    state_size: int
    flags: tuple[str, ...]
    views: tuple[ViewView, ...]
    inputs: tuple[PortView, ...]  # the step's trajectory inputs, in order
    tau: PortView  # the step's first output
    tau_index: int
    outputs: tuple[OutputField, ...]  # the step's other outputs, kept in the struct
    step_reads_parameters: bool
    init_reads_parameters: bool
    reads_parameters: bool  # the C step takes params, the class takes parameter keywords
    step_prototype: str
    reset_prototype: str
    # the first step's check (Controller.start): its kernel's C name ("" without), its limits
    # (C literals), and the Python message's words (C string literals)
    start_kernel: str
    start_size: int
    start_limits: tuple[str, ...]
    start_units: tuple[str, ...]
    start_bounds: str  # "at most 0.05 m and 0.2 rad"
    start_hint: str
    layout_lines: tuple[str, ...]  # the header's comment on the struct
    step_lines: tuple[str, ...]  # the header's comment on the step function
    doc: str  # the class doc (Python), plain text
    py_doc: str  # C string literal: the class docstring with its text signature
    step_py_doc: str  # C string literal: step()'s docstring with its text signature
    stub_doc: str  # Python string literal
    step_stub_doc: str
    info: dict


def snake_case(class_name: str) -> str:
    """AdaptiveController -> adaptive, ResolvedAccelerationController -> resolved_acceleration,
    PDController -> pd."""
    stem = (
        class_name[: -len("Controller")]
        if class_name.endswith("Controller") and class_name != "Controller"
        else class_name
    )
    stem = re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1_\2", stem)
    return re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", stem).lower()


def controller_view(
    module: str,
    controller: Controller,
    functions: dict[str, FunctionView],
    precision: c_kernel.Precision,
    parameters: tuple[ParameterView, ...],
) -> ControllerView:
    """The view of ``controller``, checked against its kernels (``functions``: name ->
    FunctionView of the module) and the Controller contract."""
    what = f"controller {controller.class_name!r}"
    snake = _checked_snake_case(controller, what)
    c_type = f"{module}_{snake}_controller"
    step = module_function(functions, controller.step, f"{what}: step kernel")
    init = module_function(functions, controller.init, f"{what}: init kernel") if controller.init else None
    _check_state_and_period(controller, what)
    inputs = _step_inputs(controller, what, step, bool(parameters))
    others = _step_outputs(controller, what, step)
    if init is not None:
        _check_init(controller, what, init, step, inputs)
    start = _start_check(what, controller, functions, inputs)
    _check_names(controller, what, step, others)
    macro = c_type.upper()
    views = _state_views(controller, what, macro)
    reads = step.reads_parameters or bool(init is not None and init.reads_parameters)
    params = f"const {c_kernel.params_type(module)} *params, " if reads else ""
    real = precision.real
    arrays = "".join(f"const {real} *{p.name}, " for p in inputs)
    period_literal = repr(float(controller.period))
    return ControllerView(
        class_name=controller.class_name,
        snake=snake,
        c_type=c_type,
        macro=macro,
        c_reset=f"{c_type}_reset",
        c_step=f"{c_type}_step",
        step=step.name,
        c_step_kernel=step.c_name,
        init=init.name if init is not None else None,
        c_init_kernel=init.c_name if init is not None else "",
        period=float(controller.period),
        period_literal=period_literal,
        state_size=controller.state_size,
        flags=tuple(controller.flags),
        views=views,
        inputs=inputs,
        tau=step.outputs[0],
        tau_index=0,
        outputs=others,
        step_reads_parameters=step.reads_parameters,
        init_reads_parameters=bool(init is not None and init.reads_parameters),
        reads_parameters=reads,
        step_prototype=f"int {c_type}_step({c_type} *controller, {arrays}{params}{real} *{step.outputs[0].name})",
        reset_prototype=f"void {c_type}_reset({c_type} *controller)",
        **_start_fields(controller, start, precision),
        layout_lines=_layout(controller, step, init, views, others, period_literal),
        step_lines=_step_comment(
            f"{c_type}_step",
            controller.class_name,
            step,
            init,
            controller.flags,
            others,
            controller.state_size,
            real,
            controller.start,
            start,
        ),
        **_docs(controller, step, init, views, inputs, others, parameters if reads else ()),
        info=_info(controller, c_type, step, init, views, others, reads, start),
    )


def _checked_snake_case(controller: Controller, what: str) -> str:
    """The controller's class name in snake case (its C prefix's middle), both checked as identifiers."""
    c_kernel.check_identifier(controller.class_name, what)
    snake = snake_case(controller.class_name)
    c_kernel.check_identifier(snake, f"{what}: its C name {snake!r}")
    return snake


def _check_state_and_period(controller: Controller, what: str) -> None:
    """A state size of at least 0 (positive when the controller has an init kernel or views) and a positive period."""
    n = controller.state_size
    if n < 0 or (n == 0 and (controller.init or controller.views)):
        raise KernelError(
            f"{what}: state size {n} with init {controller.init!r} and views {[v.name for v in controller.views]}"
        )
    if not controller.period > 0:
        raise KernelError(f"{what}: period {controller.period!r} is not positive")


def _step_inputs(controller: Controller, what: str, step: FunctionView, has_parameters: bool) -> tuple[PortView, ...]:
    """The step's trajectory inputs, after checking that it takes the trajectory, the state (when
    there is one) and one number per flag, in this order (then params, not a port view)."""
    n = controller.state_size
    names = [p.name for p in step.inputs]
    expected = [*TRAJECTORY, *([STATE] if n else []), *controller.flags]
    if names != expected:
        raise KernelError(
            f"{what}: step kernel {step.name!r} has inputs {names}, the Controller contract "
            f"wants {expected}{' and params' if has_parameters else ''}"
        )
    if n and step.inputs[len(TRAJECTORY)].size != n:
        raise KernelError(
            f"{what}: input {STATE!r} of {step.name!r} holds {step.inputs[len(TRAJECTORY)].size}, the state {n}"
        )
    for flag in step.inputs[len(TRAJECTORY) + bool(n) :]:
        if flag.size != 1:
            raise KernelError(f"{what}: flag {flag.name!r} is {flag.rows}x{flag.cols}, not a number")
    return step.inputs[: len(TRAJECTORY)]


def _step_outputs(controller: Controller, what: str, step: FunctionView) -> tuple[OutputField, ...]:
    """The step's outputs between tau (first) and the next state (last, when there is a state),
    after checking that order."""
    n = controller.state_size
    outputs = [p.name for p in step.outputs]
    if not outputs or (n and (len(outputs) < 2 or outputs[-1] != STATE_NEXT or step.outputs[-1].size != n)):
        raise KernelError(
            f"{what}: step kernel {step.name!r} has outputs {outputs}; the contract wants tau "
            f"first{f', then {STATE_NEXT!r} of {n} last' if n else ''}"
        )
    if STATE_NEXT in outputs[1 : len(outputs) - bool(n)] or (not n and STATE_NEXT in outputs):
        raise KernelError(f"{what}: {STATE_NEXT!r} is only the step's last output, with a state")
    return tuple(
        OutputField(p.name, p.size, p.shape, p.shape_text, k + 1)
        for k, p in enumerate(step.outputs[1 : len(step.outputs) - bool(n)])
    )


def _check_init(
    controller: Controller, what: str, init: FunctionView, step: FunctionView, inputs: tuple[PortView, ...]
) -> None:
    """The init kernel takes the step's trajectory inputs, shapes included, and returns the state alone."""
    init_names = [p.name for p in init.inputs]
    init_shapes = [p.shape for p in init.inputs]
    if init_names != list(TRAJECTORY) or init_shapes != [p.shape for p in inputs]:
        raise KernelError(
            f"{what}: init kernel {init.name!r} has inputs {init_names} {init_shapes}; the "
            f"contract wants those of {step.name!r}: {list(TRAJECTORY)} "
            f"{[p.shape for p in inputs]}"
        )
    if [p.name for p in init.outputs] != [STATE] or init.outputs[0].size != controller.state_size:
        raise KernelError(
            f"{what}: init kernel {init.name!r} must have the one output {STATE!r} of {controller.state_size}"
        )


def _check_names(controller: Controller, what: str, step: FunctionView, others: tuple[OutputField, ...]) -> None:
    """Flags and views as identifiers, none taking a Python attribute, struct field or C local
    every controller has."""
    for flag in controller.flags:
        c_kernel.check_identifier(flag, f"{what}: flag")
    for view in controller.views:
        c_kernel.check_identifier(view.name, f"{what}: view")
    attributes = [*CLASS_ATTRIBUTES, *controller.flags, *(v.name for v in controller.views)]
    if len(set(attributes)) != len(attributes) or any(a.startswith("__") for a in attributes):
        raise KernelError(
            f"{what}: attribute names repeat or are reserved: flags {list(controller.flags)}, "
            f"views {[v.name for v in controller.views]}, and {sorted(CLASS_ATTRIBUTES)}"
        )
    fields = [*STRUCT_FIELDS, *controller.flags, *(o.name for o in others)]
    if len(set(fields)) != len(fields) or set(fields) & c_kernel.RESERVED:
        raise KernelError(f"{what}: struct fields repeat or are reserved: {fields}")
    ports = [p.name for p in (*step.inputs, *step.outputs)]
    if C_NAMES & set(ports) or any(p.startswith("rg_") for p in ports):
        raise KernelError(f"{what}: ports {ports} take the C step's names {sorted(C_NAMES)} or rg_*")


def _state_views(controller: Controller, what: str, macro: str) -> tuple[ViewView, ...]:
    """The controller's views of its state, each checked to lie inside it."""
    n = controller.state_size
    built: list[ViewView] = []
    for view in controller.views:
        end = view.offset + view.rows * view.cols
        if view.offset < 0 or view.rows < 1 or view.cols < 1 or end > n:
            raise KernelError(
                f"{what}: view {view.name!r} ({view.rows}x{view.cols} at {view.offset}) is not inside the state of {n}"
            )
        shape = (view.rows,) if view.cols == 1 else (view.rows, view.cols)
        doc = " ".join(view.doc.split())
        built.append(
            ViewView(
                name=view.name,
                offset=view.offset,
                rows=view.rows,
                cols=view.cols,
                size=view.rows * view.cols,
                shape=shape,
                shape_text=_shape_text(shape),
                doc=doc,
                doc_line=doc.replace("*/", "* /"),
                offset_macro=f"{macro}_{view.name.upper()}_OFFSET",
                stub_doc=py_string(_view_doc(doc, shape)),
                c_doc=c_string(_view_doc(doc, shape)),
            )
        )
    return tuple(built)


def _docs(
    controller: Controller,
    step: FunctionView,
    init: FunctionView | None,
    views: tuple[ViewView, ...],
    inputs: tuple[PortView, ...],
    others: tuple[OutputField, ...],
    parameters: tuple[ParameterView, ...],
) -> dict:
    """The ControllerView fields of the class's and its step's docstrings (``parameters``: those
    the controller reads, its constructor's keywords)."""
    doc = _class_doc(controller, step, init, views, others, parameters)
    keywords = [f"{p.name}={p.py_default}" for p in parameters]
    signature = f"{controller.class_name}({', '.join(['*', *keywords]) if keywords else ''})"
    step_signature = f"step($self, {', '.join(p.name for p in inputs)}, *, out=None)"
    step_doc = _step_doc(step, inputs, others)
    return {
        "doc": doc,
        "py_doc": c_string(f"{signature}\n--\n\n{doc}"),
        "step_py_doc": c_string(f"{step_signature}\n--\n\n{step_doc}"),
        "stub_doc": py_string(doc),
        "step_stub_doc": py_string(_summary(step_doc)),
    }


def _start_fields(controller: Controller, start: FunctionView | None, precision: c_kernel.Precision) -> dict:
    """The ControllerView fields of the first step's check (empty when the controller has none)."""
    if start is None or controller.start is None:
        return {
            "start_kernel": start.c_name if start else "",
            "start_size": 0,
            "start_limits": (),
            "start_units": (),
            "start_bounds": "",
            "start_hint": "",
        }
    return {
        "start_kernel": start.c_name,
        "start_size": len(controller.start.limits),
        "start_limits": tuple(c_kernel.literal(v, precision) for v in controller.start.limits),
        "start_units": tuple(c_string(u) for u in controller.start.units),
        "start_bounds": c_string(_start_bounds(controller.start)),
        "start_hint": c_string(controller.start.hint),
    }


def _info(
    controller: Controller,
    c_type: str,
    step: FunctionView,
    init: FunctionView | None,
    views: tuple[ViewView, ...],
    others: tuple[OutputField, ...],
    reads: bool,
    start: FunctionView | None,
) -> dict:
    """The controller's entry in the module's info()["controllers"]."""
    return {
        "class": controller.class_name,
        "c_type": c_type,
        "step": step.name,
        "init": init.name if init is not None else None,
        "period": float(controller.period),
        "state_size": controller.state_size,
        "flags": list(controller.flags),
        "views": [{"name": v.name, "offset": v.offset, "shape": list(v.shape), "doc": v.doc} for v in views],
        "outputs": [o.name for o in others],
        "reads_parameters": reads,
        "start_check": None
        if start is None or controller.start is None
        else {"function": start.name, "limits": list(controller.start.limits), "units": list(controller.start.units)},
    }


def _start_check(what: str, controller: Controller, functions: dict, inputs: tuple) -> FunctionView | None:
    """The kernel of controller.start, checked against the contract: inputs q and pose_d as the
    step has them, one output of a distance per limit, no parameters."""
    start = controller.start
    if start is None:
        return None
    kernel = module_function(functions, start.kernel, f"{what}: start check kernel")
    wanted = [(p.name, p.shape) for p in inputs if p.name in ("q", "pose_d")]
    if [(p.name, p.shape) for p in kernel.inputs] != wanted or kernel.reads_parameters:
        raise KernelError(
            f"{what}: start check kernel {kernel.name!r} has inputs "
            f"{[(p.name, p.shape) for p in kernel.inputs]}; the contract wants {wanted}, no parameters"
        )
    n = len(start.limits)
    if len(kernel.outputs) != 1 or kernel.outputs[0].size != n or len(start.units) != n or n == 0:
        raise KernelError(
            f"{what}: start check kernel {kernel.name!r} must give one distance per limit "
            f"{start.limits} (units {start.units})"
        )
    if not all(v > 0 for v in start.limits):
        raise KernelError(f"{what}: start check limits {start.limits} must be positive")
    return kernel


def _start_bounds(start) -> str:
    """ "at most 0.05 m and 0.2 rad"."""
    parts = [f"{limit:g} {unit}" for limit, unit in zip(start.limits, start.units)]
    return "at most " + (", ".join(parts[:-1]) + " and " + parts[-1] if len(parts) > 1 else parts[0])


def controllers_note(views: tuple[ControllerView, ...]) -> tuple[str, ...]:
    """The header's first comment on a module's controllers (() without any)."""
    if not views:
        return ()
    return tuple(
        comment_lines(
            f"The controllers at the end ({', '.join(v.c_type for v in views)}) keep one arm's "
            "controller state in a struct the caller owns: one struct per controlled arm, reset once, "
            "then stepped once per period from one thread (a struct is not for sharing between "
            "threads). Their functions use no heap, no global state and no I/O either."
        )
    )


def _summary(doc: str) -> str:
    return " ".join(doc.strip().split("\n\n")[0].split())


def module_function(functions: dict, name: str, what: str):
    """The module's function ``name`` (a FunctionView), or a KernelError that ``what`` names."""
    if name not in functions:
        raise KernelError(f"{what} {name!r} is not among the module's functions {sorted(functions)}")
    return functions[name]


def _view_doc(doc: str, shape: tuple[int, ...]) -> str:
    return (
        f"{doc[:1].upper()}{doc[1:]}: a new float64 array {_shape_text(shape)} (read-only; zeros before the "
        "first step)."
    )


def _shape_text(shape: tuple[int, ...]) -> str:
    dims = ", ".join(str(d) for d in shape)
    return f"({dims},)" if len(shape) == 1 else f"({dims})"


def _class_doc(controller: Controller, step, init, views, others, parameters) -> str:
    first = " ".join(step.doc.split("\n\n")[0].split()) or step.name
    lines = [
        f"A controller around {step.name}"
        + (f" (and {init.name}, the state of the first step after a reset)" if init is not None else "")
        + f", one step every period = {controller.period!r} s: {first}",
        "",
        "step(q, qd, pose_d, twist_d, accel_d) returns tau and carries the state; reset() restarts "
        "(the next step runs "
        + (init.name if init is not None else "from a zero state" if controller.state_size else "as the first")
        + ").",
    ]
    for flag in controller.flags:
        lines.append(f"{flag}: bool, the step's {flag!r} input; True after construction and reset().")
    for view in views:
        lines.append(f"{view.name}: {view.shape_text}, read-only: {view.doc}.")
    if controller.state_size:
        lines.append(f"state: ({controller.state_size},), read-only: the raw state the next step reads.")
    if others:
        lines.append(
            f"last: dict of the last step's other outputs ({', '.join(o.name for o in others)}); "
            "empty before the first step."
        )
    else:
        lines.append("last: dict of the last step's other outputs (none).")
    if parameters:
        lines.append(
            "parameters: the run-time parameters the steps read, a mapping settable per key or as a "
            "whole (keys left out take the spec's value); the keyword arguments set them. Changes apply "
            "to the next step."
        )
    lines += ["", "Not thread-safe: one object per controlled arm, stepped from one thread."]
    return "\n".join(lines)


def _step_doc(step, inputs, others) -> str:
    lines = [step.doc.strip() or step.name, ""]
    lines += [f"{p.name}: float64 array {p.shape_text} (no batch axis)" for p in inputs]
    extra = f"; the other outputs ({', '.join(o.name for o in others)}) are in .last" if others else ""
    lines.append(
        f"out: None, or a float64 array {step.outputs[0].shape_text} to write "
        f"{step.outputs[0].name} into (then returned: no allocation)"
    )
    lines.append(f"Returns {step.outputs[0].name} {step.outputs[0].shape_text}{extra}.")
    return "\n".join(lines)


def comment_lines(text: str, indent: str = "") -> list[str]:
    """``text`` on lines of at most WIDTH characters inside a C comment."""
    return textwrap.wrap(text, WIDTH, subsequent_indent=indent, break_long_words=False, break_on_hyphens=False)


def _layout(controller: Controller, step, init, views, others, period_literal: str) -> tuple[str, ...]:
    n = controller.state_size
    lines = comment_lines(
        f"{controller.class_name}: {step.c_name} every {period_literal} s"
        + (f", after {init.c_name} on the first step after a reset." if init is not None else ".")
        + " The caller owns the struct: one per controlled arm, stepped from one thread (it is "
        "not for sharing between threads). Call reset before the first step."
    ) + [""]
    if n:
        lines.append(f"state[{n}]: what the next step reads (written by the step only):")
        covered = 0
        for view in sorted(views, key=lambda v: v.offset):
            if view.offset > covered:
                lines.append(f"  [{covered}, {view.offset}) the law's own")
            row_major = " row-major" if view.cols > 1 else ""
            lines += comment_lines(
                f"  [{view.offset}, {view.offset + view.size}) {view.name} {view.shape_text}{row_major}: "
                f"{view.doc_line}",
                "      ",
            )
            covered = max(covered, view.offset + view.size)
        if covered < n:
            lines.append(f"  [{covered}, {n}) the law's own")
    for o in others:
        lines.append(f"{o.name} {o.shape_text}: the step's {o.name!r} output of the last step")
    lines += comment_lines(
        "initialised: 0 after reset"
        + (f" (the next step runs {init.c_name} first)" if init is not None else "")
        + ", 1 after a step",
        "    ",
    )
    for flag in controller.flags:
        lines.append(f"{flag}: the step's {flag!r} input, 1 (true, after reset) or 0")
    return tuple(lines)


def _step_comment(
    c_step: str, class_name: str, step, init, flags, others, state_size: int, real: str, start=None, start_kernel=None
) -> tuple[str, ...]:
    text = f"{c_step}: one period of {class_name}. "
    if start is not None:
        text += (
            f"On the first step after a reset it first runs {start_kernel.c_name}: when one of its distances "
            f"is above its limit ({_start_bounds(start)}) it returns 3, having written nothing (the struct "
            "stays reset; the desired path must start at the hand). "
        )
    if init is not None:
        text += f"On the first step after a reset it runs {init.c_name} into controller->state; then it runs "
    else:
        text += "It runs "
    written = [step.outputs[0].name, *(f"controller->{o.name}" for o in others)]
    if state_size:
        written.append(f"the next state (through a stack buffer of {state_size} {real}s)")
    with_flags = " with the struct's flags" if flags else ""
    text += (
        f"{step.c_name}{with_flags}, writing "
        + (", ".join(written[:-1]) + " and " + written[-1] if len(written) > 1 else written[0])
        + ". "
        + "Returns the kernel's status: 0"
        + (" (on another value the state is not advanced)." if state_size else ".")
    )
    return tuple(comment_lines(text))
