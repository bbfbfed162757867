"""A multi-rate tree's MultiRateController (robotgen.symbolic.rate_steps.MultiRate), checked
against its group steps and gathered for the templates: a C struct ``<module>_multirate`` with
``_reset`` and ``_step`` (one call per fastest period, the groups due at that tick run in it),
and a class in the Python extension around the same struct.

The struct holds every group's controller state (``state_g<k>``), the trajectories slower
groups hold for faster ones (``wr_<node>``), each group's last torques (``tau_g<k>``), the tick
within the slowest period and whether a step has run since the reset. A step is atomic: it
works on a copy of the struct and writes it back, and tau, only when every group's step
returned 0."""

from __future__ import annotations

from dataclasses import dataclass

from robotgen.emit import c_kernel
from robotgen.emit.controllers import comment_lines, module_function
from robotgen.emit.literals import c_string, py_string
from robotgen.emit.sx_program import KernelError
from robotgen.emit.views import FunctionView, ParameterView, PortView
from robotgen.symbolic.rate_steps import MultiRate

# the desired root trajectory a group that starts at the root reads, in the order its step takes it
ROOT_INPUTS = ("x_e", "xd_e", "xdd_e", "f_e", "f_i")
SENSED = ("theta", "theta_dot")
TAU_SENSED = "tau_sensed"
HELD_PREFIX = "wr_"


@dataclass(frozen=True)
class GroupView:
    """One rate group as the templates show it: its step and init kernels, its period [s] and its ticks of the
    fastest period."""

    index: int
    step: str  # kernel name
    c_step: str  # its C function
    init: str | None
    c_init: str
    period: float
    period_literal: str
    rate_text: str  # "2000 Hz"
    ticks: int
    controllers: tuple[str, ...]
    macro: str  # <MODULE>_MULTIRATE_G<k>
    state_size: int
    operations: int  # arithmetic operations of one step (the emitted C's)
    step_args: str  # the C arguments of its step call inside the driver
    init_args: str


@dataclass(frozen=True)
class HeldView:
    """A held trajectory wr_<node>: the slower group that writes it, the faster one that reads it, its size."""

    name: str  # the port and struct field, wr_<node>
    node: str
    size: int
    writer: int  # group indices
    reader: int
    macro: str  # <MODULE>_MULTIRATE_WR_<NODE>_SIZE


@dataclass(frozen=True)
class MultiRateView:
    """A MultiRateController as the templates show it: the C struct, reset and step, the groups and held
    trajectories, the step's ports."""

    class_name: str
    c_type: str  # <module>_multirate
    macro: str  # <MODULE>_MULTIRATE
    c_reset: str
    c_step: str
    groups: tuple[GroupView, ...]  # fastest first
    slowest_first: tuple[GroupView, ...]
    held: tuple[HeldView, ...]
    inputs: tuple[PortView, ...]  # the step's inputs: sensed state, root trajectory, tau_sensed
    tau: PortView
    nq: int
    frame_ticks: int
    reads_parameters: bool
    step_prototype: str
    reset_prototype: str
    struct_lines: tuple[str, ...]  # the header's comment on the struct
    step_lines: tuple[str, ...]  # the header's comment on the step
    py_doc: str  # C string literals
    step_py_doc: str
    stub_doc: str  # Python string literals
    step_stub_doc: str
    info: dict


def _rate(period: float) -> str:
    return f"{1 / period:.4g} Hz"


def multirate_view(
    module: str,
    spec: MultiRate,
    functions: dict[str, FunctionView],
    precision: c_kernel.Precision,
    parameters: tuple[ParameterView, ...] = (),
) -> MultiRateView:
    """The view of ``spec``, checked against its kernels (``functions``: name -> FunctionView)."""
    what = f"multi-rate controller {spec.class_name!r}"
    c_kernel.check_identifier(spec.class_name, what)
    c_type, macro = f"{module}_multirate", f"{module}_multirate".upper()
    if len(spec.groups) < 2:
        raise KernelError(f"{what}: {len(spec.groups)} group(s); a multi-rate tree has at least two")
    if (
        spec.groups[0].ticks != 1
        or any(g.ticks <= 0 or spec.frame_ticks % g.ticks for g in spec.groups)
        or any(a.ticks >= b.ticks for a, b in zip(spec.groups, spec.groups[1:]))
    ):
        raise KernelError(f"{what}: ticks {[g.ticks for g in spec.groups]} must rise from 1 and divide the last")
    single = module_function(functions, spec.single_rate, f"{what}:")
    tau = single.outputs[0]
    steps = [module_function(functions, g.step, f"{what}:") for g in spec.groups]
    inits = [module_function(functions, g.init, f"{what}:") if g.init else None for g in spec.groups]
    held_sizes: dict[str, int] = {}
    writer: dict[str, int] = {}
    reader: dict[str, int] = {}
    driver_inputs: dict[str, PortView] = {}
    reads_parameters = False
    for k, step in enumerate(steps):
        names = [p.name for p in step.inputs]
        if names[:2] != list(SENSED):
            raise KernelError(f"{what}: step {step.name!r} must take {SENSED} first, takes {names}")
        if [p.name for p in step.outputs][:1] != ["tau"] or step.outputs[0].shape != tau.shape:
            raise KernelError(f"{what}: step {step.name!r} must give tau {tau.shape_text} first")
        has_state = "state" in names
        if has_state != (inits[k] is not None) or has_state != (step.outputs[-1].name == "state_next"):
            raise KernelError(f"{what}: step {step.name!r}: a state input, a state_next output and an init go together")
        for p in step.inputs:
            if p.name in (*SENSED, *ROOT_INPUTS, TAU_SENSED):
                if p.name in driver_inputs and driver_inputs[p.name].shape != p.shape:
                    raise KernelError(f"{what}: input {p.name!r} has two shapes among the group steps")
                driver_inputs.setdefault(p.name, p)
            elif p.name.startswith(HELD_PREFIX):
                reader[p.name] = k
                held_sizes.setdefault(p.name, p.size)
                if held_sizes[p.name] != p.size:
                    raise KernelError(f"{what}: held {p.name!r} is written and read with different sizes")
            elif p.name != "state":
                raise KernelError(f"{what}: step {step.name!r} has an input {p.name!r} the driver cannot give")
        for p in step.outputs[1 : len(step.outputs) - has_state]:
            if not p.name.startswith(HELD_PREFIX) or p.name in writer:
                raise KernelError(f"{what}: step {step.name!r} has an output {p.name!r} that is no held trajectory")
            writer[p.name] = k
            held_sizes.setdefault(p.name, p.size)
            if held_sizes[p.name] != p.size:
                raise KernelError(f"{what}: held {p.name!r} is written and read with different sizes")
        init = inits[k]
        if init is not None and (
            [p.name for p in init.inputs] != list(SENSED)
            or [(p.name, p.size) for p in init.outputs] != [("state", step.inputs[names.index("state")].size)]
        ):
            raise KernelError(f"{what}: init {init.name!r} must map {SENSED} to the state of {step.name!r}")
        reads_parameters = reads_parameters or step.reads_parameters or bool(init and init.reads_parameters)
    if sorted(writer) != sorted(spec.held) or sorted(reader) != sorted(spec.held):
        raise KernelError(f"{what}: held {list(spec.held)}, written {sorted(writer)}, read {sorted(reader)}")
    for name in spec.held:
        if not writer[name] > reader[name]:
            raise KernelError(
                f"{what}: {name!r} is written by group {writer[name]}, read by the faster or same "
                f"group {reader[name]}; a slower group writes what a faster one holds"
            )
        c_kernel.check_identifier(name, f"{what}: held trajectory")
    order = [*SENSED, *ROOT_INPUTS, TAU_SENSED]
    inputs = tuple(sorted(driver_inputs.values(), key=lambda p: order.index(p.name)))
    if [p.name for p in inputs[:2]] != list(SENSED) or not any(p.name == "x_e" for p in inputs):
        raise KernelError(f"{what}: no group step reads the root trajectory")

    built: list[GroupView] = []
    for k, (g, step, init) in enumerate(zip(spec.groups, steps, inits)):
        gm = f"{macro}_G{k}"
        args = []
        for p in step.inputs:
            if p.name.startswith(HELD_PREFIX):
                args.append(f"rg_next.{p.name}")
            elif p.name == "state":
                args.append(f"rg_next.state_g{k}")
            else:
                args.append(p.name)
        if step.reads_parameters:
            args.append("params")
        for p in step.outputs:
            args.append(
                f"rg_next.tau_g{k}"
                if p.name == "tau"
                else f"rg_state_g{k}"
                if p.name == "state_next"
                else f"rg_next.{p.name}"
            )
        init_args = (
            f"theta, theta_dot, {'params, ' if init is not None and init.reads_parameters else ''}rg_next.state_g{k}"
        )
        state_size = next((p.size for p in step.inputs if p.name == "state"), 0)
        built.append(
            GroupView(
                index=k,
                step=step.name,
                c_step=step.c_name,
                init=init.name if init else None,
                c_init=init.c_name if init else "",
                period=float(g.period),
                period_literal=repr(float(g.period)),
                rate_text=_rate(g.period),
                ticks=g.ticks,
                controllers=tuple(g.controllers),
                macro=gm,
                state_size=state_size,
                operations=step.arithmetic_ops,
                step_args=", ".join(args),
                init_args=init_args,
            )
        )
    groups = tuple(built)
    held = tuple(
        HeldView(
            name, name[len(HELD_PREFIX) :], held_sizes[name], writer[name], reader[name], f"{macro}_{name.upper()}_SIZE"
        )
        for name in spec.held
    )
    real = precision.real
    arrays = "".join(f"const {real} *{p.name}, " for p in inputs)
    params = f"const {c_kernel.params_type(module)} *params, " if reads_parameters else ""
    step_prototype = f"int {c_type}_step({c_type} *controller, {arrays}{params}{real} *tau)"
    info = {
        "class": spec.class_name,
        "c_type": c_type,
        "single_rate": spec.single_rate,
        "single_rate_operations": single.arithmetic_ops,
        "frame_ticks": spec.frame_ticks,
        "held": [{"name": h.name, "size": h.size, "writer": h.writer, "reader": h.reader} for h in held],
        "groups": [
            {
                "step": g.step,
                "init": g.init,
                "period": g.period,
                "ticks": g.ticks,
                "controllers": list(g.controllers),
                "operations": g.operations,
            }
            for g in groups
        ],
        "reads_parameters": reads_parameters,
    }
    doc = _doc(spec, groups, held, inputs, reads_parameters)
    step_doc = _step_doc(inputs, tau)
    keywords = ", ".join(["*", *(f"{p.name}={p.py_default}" for p in parameters)]) if reads_parameters else ""
    return MultiRateView(
        class_name=spec.class_name,
        c_type=c_type,
        macro=macro,
        c_reset=f"{c_type}_reset",
        c_step=f"{c_type}_step",
        groups=groups,
        slowest_first=tuple(reversed(groups)),
        held=held,
        inputs=inputs,
        tau=tau,
        nq=tau.size,
        frame_ticks=spec.frame_ticks,
        reads_parameters=reads_parameters,
        step_prototype=step_prototype,
        reset_prototype=f"void {c_type}_reset({c_type} *controller)",
        struct_lines=_struct_comment(spec, groups, held),
        step_lines=_step_comment(c_type, groups),
        py_doc=c_string(f"{spec.class_name}({keywords})\n--\n\n{doc}"),
        step_py_doc=c_string(f"step($self, {', '.join(p.name for p in inputs)}, *, out=None)\n--\n\n{step_doc}"),
        stub_doc=py_string(doc),
        step_stub_doc=py_string(" ".join(step_doc.split("\n\n")[0].split())),
        info=info,
    )


def _doc(spec: MultiRate, groups, held, inputs, reads_parameters: bool) -> str:
    lines = [
        f"Runs the rate groups' steps on one tick count of the fastest period ({groups[0].period!r} s): at each "
        "step every group due at this tick runs, the slowest first, so that what a slower group writes to a "
        "faster group's controllers is held for it from this tick on; the torques are the sum of each group's "
        "last.",
        "",
    ]
    for g in groups:
        lines.append(
            f"group {g.index}: {g.step} every {g.ticks} tick{'s' if g.ticks > 1 else ''} "
            f"({g.period!r} s, {g.rate_text}): {', '.join(g.controllers)}"
        )
    inits = [g.init for g in groups if g.init]
    restart = (
        f"the next step runs at tick 0 and starts every expected trajectory at the sensed state: {', '.join(inits)}"
        if inits
        else "the next step runs at tick 0"
    )
    lines += [
        "",
        f"step({', '.join(p.name for p in inputs)}) returns tau (the actuators' torques); reset() "
        f"restarts ({restart}).",
        "tick: int, the tick the next step runs, within the slowest period (0 after a reset).",
        "periods, ticks: each group's period [s] and its ticks of the fastest.",
        f"held: dict of the held trajectories ({', '.join(h.name for h in held)}): [x_e; xd_e; xdd_e; F_e; F_i] "
        "as the slower group last wrote them.",
        "torques: (groups, nq) array, each group's last torques.",
        "state: dict group -> its controllers' state (groups with a stateful controller).",
    ]
    if reads_parameters:
        lines.append(
            "parameters: the run-time parameters the steps read, settable per key or as a whole; the "
            "keyword arguments set them."
        )
    lines += ["", "Not thread-safe: one object per controlled tree, stepped from one thread."]
    return "\n".join(lines)


def _step_doc(inputs, tau) -> str:
    lines = ["One tick of the fastest period: the groups due run, the slowest first; returns the torques.", ""]
    lines += [f"{p.name}: float64 array {p.shape_text} (no batch axis)" for p in inputs]
    lines.append(f"out: None, or a float64 array {tau.shape_text} to write tau into (then returned: no allocation)")
    lines.append(f"Returns tau {tau.shape_text}.")
    return "\n".join(lines)


def _struct_comment(spec: MultiRate, groups, held) -> tuple[str, ...]:
    lines = comment_lines(
        f"{spec.class_name}: the rate groups' steps on one tick count of the fastest period. The caller "
        "owns the struct: one per controlled tree, stepped from one thread. Call reset before the first "
        "step."
    ) + [""]
    for g in groups:
        lines += comment_lines(
            f"group {g.index}, {g.c_step} every {g.ticks} tick{'s' if g.ticks > 1 else ''} "
            f"({g.period_literal} s, {g.rate_text}): {', '.join(g.controllers)}",
            "    ",
        )
    lines.append("")
    for g in groups:
        if g.state_size:
            lines.append(f"state_g{g.index}[{g.state_size}]: group {g.index}'s controllers' state")
    for h in held:
        lines += comment_lines(
            f"{h.name}[{h.size}]: the trajectory group {h.writer} last wrote to '{h.node}' "
            f"[x_e; xd_e; xdd_e; F_e; F_i], held for group {h.reader}",
            "    ",
        )
    for g in groups:
        lines.append(f"tau_g{g.index}[nq]: group {g.index}'s last torques")
    lines += comment_lines(
        f"tick: the tick the next step runs, 0 to {spec.frame_ticks - 1} (one slowest period); "
        "initialised: 0 after reset, 1 after a step",
        "    ",
    )
    return tuple(lines)


def _step_comment(c_type: str, groups) -> tuple[str, ...]:
    inits = [g.c_init for g in groups if g.init]
    text = (
        f"{c_type}_step: one tick of the fastest period. "
        + (
            f"On the first step after a reset it runs {', '.join(inits)} (the expected trajectories start at the "
            "sensed state); then "
            if inits
            else ""
        )
        + "every group whose ticks divide the tick runs, the slowest first, each reading the held trajectories "
        "its slower groups wrote (at this tick, when they ran too). tau is the sum of every group's last "
        "torques. It works on a copy of the struct: on a nonzero status (a group's step's, returned as is) "
        "the struct and tau are left as they were."
    )
    return tuple(comment_lines(text))
