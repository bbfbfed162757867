"""Everything the templates show, gathered and checked before anything is rendered."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace

import casadi as ca

import robotgen
from robotgen.emit import c_kernel, lane_names, lanes, sincos
from robotgen.emit.c_kernel import PRECISIONS, KernelError, check_identifier, is_parameter_port
from robotgen.emit.controllers import PARAMETERS_CLASS, ControllerView, controller_view, controllers_note
from robotgen.emit.literals import c_string, py_string
from robotgen.emit.multirate import MultiRateView, multirate_view
from robotgen.emit.sx_program import Program, read_program
from robotgen.emit.views import BoundsView, FunctionView, HelperView, ParameterView, PortView
from robotgen.model.parameters import PIVOT_TOLERANCE, SYMMETRY_TOLERANCE, Bounds, RuntimeParameter
from robotgen.progress import QUIET, Progress
from robotgen.symbolic.kernel import PARAMS, Kernel, Port
from robotgen.symbolic.rate_steps import MultiRate
from robotgen.symbolic.root_laws.law import Controller

# Module attributes the extension defines itself.
MODULE_NAMES = frozenset({"nq", "info"})
# info() keys the emitter owns; extra_info may add others (such as "nodes").
INFO_KEYS = frozenset({"name", "nq", "functions", "robotgen_version", "spec_sha256", "precision"})
# Names the .pyi stub imports (numpy, numpy.typing, typing.Any) at module level.
STUB_NAMES = frozenset({"np", "npt", "Any"})
PARAMS_CHECK = "params_check"  # <name>_params_check, the C check of a parameter struct
OUT_KEYWORD = "out"  # every function's keyword-only argument for result arrays to write into
INFO_DOC = "A new dict describing this module: name, nq, nodes, functions, robotgen_version, spec_sha256, precision."
# A module with run-time parameters also has these attributes and info() key.
PARAMETER_MODULE_NAMES = frozenset({"parameters"})
PARAMETERS_INFO_DOC = INFO_DOC[:-1] + ", parameters."
PARAMETERS_ATTRIBUTE_DOC = (
    "Run-time parameters: {names}. Every function that reads them takes each as a "
    "keyword-only argument whose default is the spec's value; `parameters` maps each name "
    "to that default (a float, or a new float64 array at each import). Changing "
    "`parameters` does not change the defaults; pass the keyword instead. They are not "
    "batched: one value applies to every point of a batch."
)
# A module with controller classes also has the info() key "controllers" (and the stub imports
# these names).
CONTROLLER_STUB_NAMES = frozenset({"Iterator", "Mapping", "final"})
MULTIRATE_DOC = (
    "{name}: the rate groups' steps ({groups}) run on one tick count of the fastest period, "
    "what slower groups write held for faster ones: construct it, call step(theta, theta_dot, x_e, "
    "...) once per fastest period for the torques; help() on the class tells more."
)
CONTROLLERS_DOC = (
    "Controllers: {names}. Each is a class holding one arm's controller state: "
    "construct it, call step(q, qd, pose_d, twist_d, accel_d) once per period "
    "for the torques, reset() to restart; help() on the class tells more."
)
_SIN_COS = frozenset({ca.OP_SIN, ca.OP_COS})
_NOT_ARITHMETIC = frozenset({ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST, ca.OP_ASSIGN})


@dataclass(frozen=True)
class ModuleView:
    """What the templates render for a module: its name, precision, nq, versions, functions, parameters, controllers."""

    name: str
    macro_prefix: str  # NAME
    precision: str
    real: str  # C type
    nq: int
    robotgen_version: str
    casadi_version: str
    spec_sha256: str
    functions: tuple[FunctionView, ...]
    info: dict  # what info() returns
    module_doc: str  # C string literal
    info_json: str  # C string literal holding json of ``info``
    attributes_json: str  # C string literal holding json of the extra module attributes
    keyword_names: tuple[str, ...]  # the distinct input port names, sorted
    attribute_names: tuple[str, ...]  # the extra module attributes, sorted
    stub_doc: str  # Python string literal: the module docstring
    stub_info_doc: str  # Python string literal: info()'s docstring
    # Run-time parameters (empty when no kernel has the PARAMS port; then nothing emitted
    # differs from a module built before parameters existed).
    parameters: tuple[ParameterView, ...] = ()
    params_type: str = ""  # <name>_params
    params_default_macro: str = ""  # <NAME>_PARAMS_DEFAULT
    params_check: str = ""  # <name>_params_check
    bounds_order: int = 0  # the largest order of a positive definite parameter (its check's work)
    symmetry_tolerance: str = ""  # robotgen.model.parameters' tolerances, C literals
    pivot_tolerance: str = ""
    # Controller classes (empty: nothing emitted differs from a module built before them).
    controllers: tuple[ControllerView, ...] = ()
    parameters_class: str = ""  # the type of a controller's `parameters`, when one reads them
    controllers_note: tuple[str, ...] = ()  # the header's first comment on them
    zero: str = "0.0"  # C literals of the module's precision
    one: str = "1.0"
    parts: int = 1  # compile parts of <name>.c (COMPILE_PARTS when the source is large)
    # The double kernels' sin and cos routine (robotgen.emit.sincos), printed once before the
    # functions; with parts, only in the parts whose functions call it (no unused static).
    sincos_helper: str = ""
    sincos_parts: tuple[int, ...] = ()
    helpers: tuple[HelperView, ...] = ()  # after the sin and cos routine, before the functions
    # A multi-rate tree's MultiRateController (None: nothing emitted differs from a module
    # built before it)
    multirate: MultiRateView | None = None
    # Batches across states (robotgen.emit.lanes): the compiler test defining where lanes are
    # compiled, each width's definitions around its copy of the lane code, the lane code (the
    # sin and cos routine and the stage helpers that batched functions call, by part), the width
    # chooser and the parts that have batched functions.
    lanes_guard: str = ""
    lane_widths: tuple[tuple[str, str], ...] = ()
    lane_helpers: tuple[HelperView, ...] = ()
    batch_select: str = ""
    batch_parts: tuple[int, ...] = ()

    @property
    def batch_functions(self) -> tuple[FunctionView, ...]:
        """The functions with a _batch entry point (robotgen.emit.lanes)."""
        return tuple(f for f in self.functions if f.batch)


def module_view(
    name: str,
    kernels: list[Kernel],
    *,
    nq: int,
    precision: str,
    spec_sha256: str,
    extra_info: dict | None,
    attributes: dict | None,
    progress: Progress = QUIET,
    controllers: list[Controller | MultiRate] | tuple[Controller | MultiRate, ...] = (),
) -> ModuleView:
    """The ModuleView of kernels built for module ``name`` (names checked as C identifiers, precision double or
    float)."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {sorted(PRECISIONS)}, got {precision!r}")
    check_identifier(name, "module name")
    names = [k.name for k in kernels]
    for kernel_name in names:
        check_identifier(kernel_name, "kernel name")
    parameters = _module_parameters(name, kernels, PRECISIONS[precision])
    attributes = dict(attributes or {})
    for attribute in attributes:
        check_identifier(attribute, "module attribute")
    rates = [c for c in controllers if isinstance(c, MultiRate)]
    controllers = [c for c in controllers if not isinstance(c, MultiRate)]
    if len(rates) > 1:
        raise KernelError(f"module {name!r}: {len(rates)} multi-rate controllers; a tree has one")
    classes = [c.class_name for c in controllers] + [r.class_name for r in rates]
    parameters_class = PARAMETERS_CLASS if parameters and classes else ""
    taken = [
        *MODULE_NAMES,
        *(PARAMETER_MODULE_NAMES if parameters else ()),
        *names,
        *attributes,
        *classes,
        *([parameters_class] if parameters_class else []),
    ]
    if len(set(taken)) != len(taken):
        raise KernelError(f"module {name!r}: names repeat among {sorted(taken)}")
    stub_names = STUB_NAMES | (CONTROLLER_STUB_NAMES if classes else set())
    if stub_names & set(taken):
        raise KernelError(
            f"module {name!r}: {sorted(stub_names & set(taken))} are reserved (the module's .pyi stub imports them)"
        )
    if parameters and {PARAMS, PARAMS_CHECK} & set(names):
        raise KernelError(
            f"module {name!r}: a function named {PARAMS!r} or {PARAMS_CHECK!r} would clash with "
            f"the C type {c_kernel.params_type(name)} or its check"
        )
    extra_info = dict(extra_info or {})
    info_keys = (
        INFO_KEYS
        | ({"parameters"} if parameters else set())
        | ({"controllers"} if controllers else set())
        | ({"multirate"} if rates else set())
    )
    if info_keys & extra_info.keys():
        raise KernelError(f"extra_info may not set {sorted(info_keys & extra_info.keys())}")
    helpers, helper_names = _stage_helpers(kernels, PRECISIONS[precision])
    printed: list[FunctionView] = []
    stage_counts: dict[str, tuple[int, int]] = {}
    for i, k in enumerate(kernels):
        progress.step(i + 1, len(kernels), f"printing C: {k.name}")
        printed.append(
            _function_view(
                name,
                k,
                PRECISIONS[precision],
                parameters,
                helper_names,
                stage_counts,
                with_lanes=nq <= lanes.LANES_MAX_NQ,
            )
        )
    functions, homes = _assign_parts(tuple(printed), helpers)
    helpers = tuple(
        replace(h, parts=parts, home=homes[h.c_name] if len(parts) > 1 else None)
        for h in helpers
        for parts in [tuple(sorted({f.part for f in functions if h.c_name in f.helpers}))]
    )
    by_name = {f.name: f for f in functions}
    views = tuple(
        controller_view(name, c, by_name, PRECISIONS[precision], parameters)
        for c in controllers
        if isinstance(c, Controller)
    )
    multirate = multirate_view(name, rates[0], by_name, PRECISIONS[precision], parameters) if rates else None
    _check_controller_names(name, functions, views, helpers, multirate)
    _check_macros_unique(name, functions, views, multirate)
    info = {
        "nodes": [],
        **extra_info,
        "name": name,
        "nq": nq,
        "functions": names,
        "robotgen_version": robotgen.__version__,
        "spec_sha256": spec_sha256,
        "precision": precision,
    }
    if parameters:
        info["parameters"] = [
            {
                "name": p.name,
                "shape": list(p.shape),
                "default": p.default,
                "doc": p.doc,
                "range": p.bounds.text if p.bounds else None,
            }
            for p in parameters
        ]
    if views:
        info["controllers"] = [v.info for v in views]
    if multirate is not None:
        info["multirate"] = multirate.info
    module_doc = (
        f"{name}: robot functions generated by robotgen {robotgen.__version__}.\n\n"
        f"Functions: {', '.join(names)}. Arrays are float64, matrices row-major; "
        "a leading batch axis B on every argument gives results with that axis."
    )
    if parameters:
        module_doc += "\n\n" + PARAMETERS_ATTRIBUTE_DOC.format(names=", ".join(p.name for p in parameters))
    if views:
        module_doc += "\n\n" + CONTROLLERS_DOC.format(names=", ".join(v.class_name for v in views))
    if multirate is not None:
        module_doc += "\n\n" + MULTIRATE_DOC.format(
            name=multirate.class_name, groups=", ".join(f"{g.step} ({g.rate_text})" for g in multirate.groups)
        )
    info_doc = PARAMETERS_INFO_DOC if parameters else INFO_DOC
    if views:
        info_doc = info_doc[:-1] + ", controllers."
    if multirate is not None:
        info_doc = info_doc[:-1] + ", multirate."
    keyword_names = {p.name for f in functions for p in f.inputs} | {p.name for p in parameters}
    if OUT_KEYWORD in keyword_names:
        raise KernelError(
            f"module {name!r}: an input or run-time parameter is named {OUT_KEYWORD!r}, "
            "every function's keyword for its result arrays"
        )
    lane_helpers = _lane_helpers(kernels, functions, helper_names, PRECISIONS[precision])
    batch_parts = tuple(sorted({f.part for f in functions if f.batch}))
    laned = any(f.lane_definition for f in functions)
    sincos_parts = tuple(
        sorted(
            {f.part for f in functions if sincos.HELPER + "(" in f.definition}
            | {
                k
                for h in helpers
                if sincos.HELPER + "(" in h.definition
                for k in (h.parts if h.home is None else (h.home,))
            }
        )
    )
    return ModuleView(
        name=name,
        macro_prefix=name.upper(),
        precision=precision,
        real=PRECISIONS[precision].real,
        nq=nq,
        robotgen_version=robotgen.__version__,
        casadi_version=ca.__version__,  # type: ignore[attr-defined]  # casadi's stubs omit __version__
        spec_sha256=spec_sha256,
        functions=functions,
        info=info,
        module_doc=c_string(module_doc),
        info_json=c_string(to_json(info, None)),
        attributes_json=c_string(to_json(attributes, None)),
        keyword_names=tuple(sorted(keyword_names)),
        attribute_names=tuple(sorted(attributes)),
        stub_doc=py_string(module_doc),
        stub_info_doc=py_string(info_doc),
        parameters=parameters,
        params_type=c_kernel.params_type(name) if parameters else "",
        params_default_macro=f"{name.upper()}_PARAMS_DEFAULT" if parameters else "",
        params_check=f"{name}_{PARAMS_CHECK}" if parameters else "",
        bounds_order=max((p.bounds.order for p in parameters if p.bounds), default=0),
        symmetry_tolerance=c_kernel.literal(SYMMETRY_TOLERANCE, PRECISIONS[precision]),
        pivot_tolerance=c_kernel.literal(PIVOT_TOLERANCE, PRECISIONS[precision]),
        controllers=views,
        multirate=multirate,
        parameters_class=parameters_class
        if any(v.reads_parameters for v in views) or (multirate is not None and multirate.reads_parameters)
        else "",
        controllers_note=controllers_note(views),
        parts=max(f.part for f in functions) + 1,
        zero=c_kernel.literal(0.0, PRECISIONS[precision]),
        one=c_kernel.literal(1.0, PRECISIONS[precision]),
        sincos_helper=sincos.helper_source(PRECISIONS[precision].real) if sincos_parts else "",
        sincos_parts=sincos_parts,
        helpers=helpers,
        lanes_guard=lanes.LANES_GUARD if laned else "",
        lane_widths=tuple(
            (lanes.width_open(w, PRECISIONS[precision], lanes.input_sizes(kernels)), lanes.width_close())
            for w in lanes.WIDTHS
        )
        if laned
        else (),
        lane_helpers=lane_helpers,
        batch_select=lanes.select_source(PRECISIONS[precision], laned) if batch_parts else "",
        batch_parts=batch_parts,
    )


def _lane_helpers(
    kernels: list[Kernel], functions: tuple[FunctionView, ...], helper_names: dict, precision: c_kernel.Precision
) -> tuple[HelperView, ...]:
    """The lane forms of what the batched functions' lane kernels call, each static in every part
    that calls it: their stages' helpers, and rg_sincos2 first, since those call it too."""
    by_name = {f.name: f for f in functions}
    stages: dict[str, tuple[str, set[int]]] = {}
    sincos_parts: set[int] = set()
    calls_sincos = lane_names.per_width(sincos.LANE_HELPER) + "("
    for kernel in kernels:
        f = by_name[kernel.name]
        if not f.lane_definition:
            continue
        if calls_sincos in f.lane_definition:
            sincos_parts.add(f.part)
        for stage in kernel.schedule.stages if kernel.schedule is not None else ():
            c_name = helper_names[stage]
            if c_name not in stages:
                stages[c_name] = (c_kernel.stage_source(c_name, stage, kernel, precision, lanes=True), set())
            stages[c_name][1].add(f.part)
    for text, parts in stages.values():
        if calls_sincos in text:
            sincos_parts |= parts
    views = (
        [HelperView(sincos.HELPER, sincos.lane_helper_source(precision.real), tuple(sorted(sincos_parts)))]
        if sincos_parts
        else []
    )
    views += [HelperView(c_name, text, tuple(sorted(parts))) for c_name, (text, parts) in stages.items()]
    return tuple(views)


def _module_parameters(name: str, kernels: list[Kernel], precision: c_kernel.Precision) -> tuple[ParameterView, ...]:
    """The module's parameter struct: the one ``parameters`` tuple that every PARAMS port
    shares (checked, as is the port's place and size), as views; () without such ports."""
    found: tuple[RuntimeParameter, ...] | None = None
    for kernel in kernels:
        for i, port in enumerate(kernel.inputs):
            if not port.parameters:
                continue
            if port.name != PARAMS or i != len(kernel.inputs) - 1:
                raise KernelError(
                    f"kernel {kernel.name!r}: run-time parameters ride only on the "
                    f"last input, named {PARAMS!r}; got {port.name!r} at {i}"
                )
            if found is not None and port.parameters != found:
                raise KernelError(
                    f"module {name!r}: kernel {kernel.name!r} lists other run-time "
                    "parameters than an earlier kernel; a module has one struct"
                )
            found = port.parameters
            total = sum(p.size for p in found)
            if port.cols != 1 or port.rows != total:
                raise KernelError(
                    f"kernel {kernel.name!r}: port {PARAMS!r} is {port.rows}x{port.cols}, its parameters hold {total}"
                )
    if found is None:
        return ()
    views, offset = [], 0
    for parameter in found:
        views.append(_parameter_view(parameter, offset, precision))
        offset += parameter.size
    names = [p.name for p in views]
    if len(set(names)) != len(names):
        raise KernelError(f"module {name!r}: run-time parameter names repeat: {names}")
    for kernel in kernels:
        if kernel.inputs and is_parameter_port(kernel.inputs[-1]):
            clash = sorted({p.name for p in kernel.inputs[:-1]} & set(names))
            if clash:
                raise KernelError(
                    f"kernel {kernel.name!r}: inputs {clash} have the names of "
                    "run-time parameters (its keyword arguments)"
                )
    return tuple(views)


def _parameter_view(parameter: RuntimeParameter, offset: int, precision: c_kernel.Precision) -> ParameterView:
    what = f"run-time parameter {parameter.name!r}"
    check_identifier(parameter.name, what)
    if parameter.name in c_kernel.RESERVED:
        raise KernelError(f"{what}: the name is reserved in C")
    shape = tuple(int(d) for d in parameter.shape)
    if len(shape) > 2 or any(d < 1 for d in shape):
        raise KernelError(f"{what}: shape {shape} is not (), (n,) or (rows, cols)")
    values = [float(v) for v in parameter.default]
    if len(values) != parameter.size or not all(math.isfinite(v) for v in values):
        raise KernelError(f"{what}: default {parameter.default} is not {parameter.size} finite numbers")
    dims = ", ".join(str(d) for d in shape)
    shape_text = f"({dims},)" if len(shape) == 1 else f"({dims})"
    literals = [c_kernel.literal(v, precision) for v in values]
    if shape:
        default: float | list = (
            values if len(shape) == 1 else [values[r * shape[1] : (r + 1) * shape[1]] for r in range(shape[0])]
        )
    else:
        default = values[0]
    doc = parameter.doc.strip()
    return ParameterView(
        name=parameter.name,
        shape=shape,
        ndim=len(shape),
        dims=(shape[0] if shape else 0, shape[1] if len(shape) > 1 else 0),
        size=parameter.size,
        offset=offset,
        shape_text=shape_text,
        expected=f"a float64 array of shape {shape_text}" if shape else "a number (float64 of shape ())",
        declaration=f"{precision.real} {parameter.name}" + (f"[{parameter.size}]" if shape else ""),
        doc=doc,
        doc_lines=tuple(line.replace("*/", "* /").rstrip() for line in (doc or parameter.name).splitlines()),
        c_default=_initializer(literals, shape),
        default_values=tuple(repr(v) for v in values),
        default=default,
        py_default=repr(default),
        stub_type="npt.ArrayLike" if shape else "float",
        bounds=None if parameter.bounds is None else _bounds_view(parameter.bounds, shape, precision),
    )


def _bounds_view(bounds: Bounds, shape: tuple[int, ...], precision: c_kernel.Precision) -> BoundsView:
    order = shape[0] if bounds.positive_definite else 0
    return BoundsView(
        minimum=0 if bounds.minimum is None else 2 if bounds.exclusive else 1,
        lower=c_kernel.literal(bounds.minimum or 0.0, precision),
        maximum=0 if bounds.maximum is None else 2 if bounds.exclusive_maximum else 1,
        upper=c_kernel.literal(bounds.maximum or 0.0, precision),
        order=order,
        what=c_string(bounds.what),
        noun=c_string(bounds.noun),
        relation=c_string(bounds.relation),
        suffix=c_string(bounds.suffix),
        text=bounds.text,
    )


def to_json(value, indent: int | None = 2) -> str:
    """Deterministic json text (sorted keys); ``indent=None`` gives one line."""
    return json.dumps(
        value,
        sort_keys=True,
        indent=indent,
        ensure_ascii=True,
        allow_nan=False,
        separators=None if indent else (",", ":"),
    )


def _summary(doc: str, fallback: str) -> str:
    """The first paragraph of ``doc`` on one line."""
    paragraph = doc.strip().split("\n\n")[0]
    return " ".join(paragraph.split()) or fallback


# A source past COMPILE_PARTS_ABOVE characters is compiled in COMPILE_PARTS processes at once
# (robotgen.emit.compile): each kernel is in one part (#if RG_PART == k in <name>.c), and each
# stage helper in one part, its home, which the other parts that call it link to (RG_SHARED),
# so that a large tree's kinematics is not compiled in every part. The
# number is fixed, not the machine's cores, so that the emitted text is the same everywhere; a
# user's own build of <name>.c (no RG_PART) takes every kernel.
COMPILE_PARTS = 2
COMPILE_PARTS_ABOVE = 300_000
# gcc -O2 spends more time on a statement inside a loop body than on one of straight-line code,
# most of it in SLP vectorisation of the body's stores; counting loop statements this many
# times balances the parts' compile times best (docs/performance-log.md).
LOOP_STATEMENT_COST = 5


# A function's lane form (robotgen.emit.lanes) is compiled once per width of the machine's family:
# twice on x86-64 (AVX-512F, AVX2), where robotgen's builds mostly run.
LANE_COPIES = 2


def compile_cost(definition: str) -> int:
    """Statements of a C function, those in a schedule's loops (indented past the loop
    headers, which follow the prologue) counted LOOP_STATEMENT_COST times."""
    cost, looping = 0, False
    for line in definition.splitlines():
        looping = looping or line.startswith(("  for (rg_i", "  for (rg_j", "  for (rg_m"))
        if line.endswith(";"):
            cost += LOOP_STATEMENT_COST if looping and line.startswith("    ") else 1
    return cost


def _assign_parts(
    functions: tuple[FunctionView, ...], helpers: tuple[HelperView, ...] = ()
) -> tuple[tuple[FunctionView, ...], dict[str, int]]:
    """Each function into the part whose load (compile_cost, with the helpers it would be the
    first to call) grows least, the costliest functions first; and each helper's home: the
    part of its first caller."""
    if (
        sum(len(f.definition) + LANE_COPIES * len(f.lane_definition) for f in functions)
        + sum(len(h.definition) for h in helpers)
        <= COMPILE_PARTS_ABOVE
    ):
        return functions, {h.c_name: 0 for h in helpers}
    own = {f.name: compile_cost(f.definition) + LANE_COPIES * compile_cost(f.lane_definition) for f in functions}
    shared = {h.c_name: compile_cost(h.definition) for h in helpers}
    load: list[int] = [0] * COMPILE_PARTS
    home: dict[str, int] = {}
    part = {}
    for f in sorted(functions, key=lambda f: (-own[f.name] - sum(shared[h] for h in f.helpers), f.name)):
        after = [
            load[k] + own[f.name] + sum(shared[h] for h in f.helpers if h not in home) for k in range(COMPILE_PARTS)
        ]
        k = after.index(min(after))
        part[f.name], load[k] = k, after[k]
        for h in f.helpers:
            home.setdefault(h, k)
    return tuple(replace(f, part=part[f.name]) for f in functions), home


def _stage_helpers(kernels: list[Kernel], precision: c_kernel.Precision) -> tuple[tuple[HelperView, ...], dict]:
    """One static helper per distinct stage of the kernels' schedules (the same function,
    ports and names: the kernels of a chain repeat its kinematics), and the C name of each
    stage; a different stage of a name already taken is rg_<stage>_2, ..."""
    helpers: dict[tuple, HelperView] = {}
    count: dict[str, int] = {}
    names = {}
    for kernel in kernels:
        for stage in kernel.schedule.stages if kernel.schedule is not None else ():
            same = (stage.function.serialize(), stage.names, tuple(kernel.inputs[k] for k in stage.inputs))
            if same not in helpers:
                base = c_kernel.stage_name(stage)
                count[base] = count.get(base, 0) + 1
                c_name = base if count[base] == 1 else f"{base}_{count[base]}"
                helpers[same] = HelperView(c_name, c_kernel.stage_source(c_name, stage, kernel, precision))
            names[stage] = helpers[same].c_name
    return tuple(helpers.values()), names


def _function_view(
    prefix: str,
    kernel: Kernel,
    precision: c_kernel.Precision,
    parameters: tuple[ParameterView, ...],
    helper_names: dict | None = None,
    stage_counts: dict | None = None,
    with_lanes: bool = True,
) -> FunctionView:
    if not kernel.outputs:
        raise KernelError(f"kernel {kernel.name!r} has no outputs")
    program = read_program(kernel) if kernel.schedule is None else None
    macro = f"{prefix}_{kernel.name}".upper()
    reads_parameters = bool(kernel.inputs) and is_parameter_port(kernel.inputs[-1])
    arrays = kernel.inputs[:-1] if reads_parameters else kernel.inputs
    inputs = tuple(_port_view(p, macro) for p in arrays)
    outputs = tuple(_port_view(p, macro) for p in kernel.outputs)
    arithmetic, sin_cos = _count_operations(program) if program is not None else _count_scheduled(kernel, stage_counts)
    keywords = parameters if reads_parameters else ()
    return FunctionView(
        name=kernel.name,
        c_name=c_kernel.function_name(prefix, kernel),
        doc=kernel.doc.strip(),
        doc_lines=tuple(
            line.replace("*/", "* /").rstrip() for line in (kernel.doc.strip() or kernel.name).splitlines()
        ),
        prototype=c_kernel.prototype(prefix, kernel, precision),
        definition=c_kernel.kernel_source(prefix, kernel, precision, program, helper_names),
        inputs=inputs,
        outputs=outputs,
        py_doc=c_string(_py_doc(kernel, inputs, outputs, keywords)),
        stub_doc=py_string(_summary(kernel.doc, kernel.name)),
        arithmetic_ops=arithmetic,
        sin_cos_ops=sin_cos,
        reads_parameters=reads_parameters,
        guarded=kernel.guarded,
        singular_error=c_string(
            f"{kernel.name}(): the result is not finite: {kernel.singular}; the outputs were set to 0 (status 2)"
        )
        if kernel.guarded and kernel.singular
        else "",
        takes_step=any(p.name == c_kernel.STEP_PORT and p.size == 1 for p in kernel.inputs),
        helpers=tuple(dict.fromkeys(helper_names[stage] for stage in kernel.schedule.stages))
        if kernel.schedule is not None and helper_names
        else (),
        **_batch_fields(prefix, kernel, precision, program, helper_names, with_lanes),
    )


def _batch_fields(
    prefix: str,
    kernel: Kernel,
    precision: c_kernel.Precision,
    program: Program | None,
    helper_names: dict | None,
    with_lanes: bool,
) -> dict:
    if not lanes.has_batch(kernel):
        return {}
    whole, capped = lanes.batch_prototypes(prefix, kernel, precision)
    lane_definition = (
        (
            c_kernel.lane_kernel_source(prefix, kernel, precision, program, helper_names)
            + "\n"
            + lanes.driver_source(prefix, kernel, precision)
        )
        if with_lanes
        else ""
    )
    return dict(
        batch_prototype=whole,
        batch_lanes_prototype=capped,
        lane_definition=lane_definition,
        batch_definition=lanes.batch_source(prefix, kernel, precision, with_lanes),
    )


def _port_view(port: Port, macro: str) -> PortView:
    if port.rows < 1 or port.cols < 1:
        raise KernelError(f"port {port.name!r} is {port.rows}x{port.cols}; ports are not empty")
    shape = (port.rows, port.cols) if port.is_matrix else (port.rows,)
    dims = ", ".join(str(d) for d in shape)
    return PortView(
        name=port.name,
        rows=port.rows,
        cols=port.cols,
        size=port.size,
        shape=shape,
        shape_text=f"({dims},)" if len(shape) == 1 else f"({dims})",
        batch_shape_text=f"(B, {dims})",
        size_macro=f"{macro}_{port.name.upper()}_SIZE",
    )


def _initializer(literals: list[str], shape: tuple[int, ...]) -> tuple[str, ...]:
    """A field's C initializer: ``2.5``, ``{1.0, 2.0}``, or a matrix's rows on lines of
    their own (``{1.0, 0.0,`` / `` 0.0, 1.0}``)."""
    if not shape:
        return (literals[0],)
    cols = shape[-1] if len(shape) == 2 else len(literals)
    rows = [", ".join(literals[r : r + cols]) for r in range(0, len(literals), cols)]
    return tuple(("{" if r == 0 else " ") + row + ("}" if r == len(rows) - 1 else ",") for r, row in enumerate(rows))


def _py_doc(
    kernel: Kernel, inputs: tuple[PortView, ...], outputs: tuple[PortView, ...], parameters: tuple[ParameterView, ...]
) -> str:
    keywords = ["*", *(f"{p.name}={p.py_default}" for p in parameters), "out=None"]
    signature = ", ".join(["$module", *(p.name for p in inputs), *keywords])
    lines = [f"{kernel.name}({signature})", "--", "", kernel.doc.strip() or kernel.name, ""]
    lines += [f"{p.name}: float64 array {p.shape_text} or {p.batch_shape_text}" for p in inputs]
    for p in parameters:
        kind = "float64 array " + p.shape_text if p.shape else "number"
        lines.append(
            f"{p.name}: {kind}, keyword-only, default {p.py_default}" + (f". {_summary(p.doc, '')}" if p.doc else "")
        )
    if len(outputs) == 1:
        lines.append(
            f"out: None, or a float64 array {outputs[0].shape_text} (or {outputs[0].batch_shape_text} "
            "for a batch) to write the result into, then returned: no allocation"
        )
    else:
        lines.append(
            f"out: None, or a tuple of {len(outputs)} float64 arrays of the results' shapes to write "
            "them into, then returned: no allocation"
        )
    returned = ", ".join(f"{p.name} {p.shape_text}" for p in outputs)
    lines.append(
        f"Returns {returned}" + (" as a tuple" if len(outputs) > 1 else "") + "; batched inputs give a leading B axis."
    )
    if parameters:
        lines.append("The run-time parameters are not batched: one value applies to every point.")
    return "\n".join(lines)


def _count_operations(program: Program) -> tuple[int, int]:
    ops = [step.op for step in program.instructions]
    return (sum(op not in _NOT_ARITHMETIC for op in ops), sum(op in _SIN_COS for op in ops))


def _count_scheduled(kernel: Kernel, stages: dict[str, tuple[int, int]] | None = None) -> tuple[int, int]:
    """Operations a scheduled kernel performs: its stages' and prologue's, and each loop body's
    times the loop's iterations. ``stages``: counts of stages already seen (by their serialized
    function: the kernels of a module repeat one stage)."""
    schedule = kernel.schedule
    assert schedule is not None  # a scheduled kernel's
    stages = {} if stages is None else stages
    arithmetic = sin_cos = 0
    for stage in schedule.stages:
        key = stage.function.serialize()
        if key not in stages:
            stages[key] = _count_operations(read_program(c_kernel.part_kernel(stage.name, stage.function)))
        arithmetic, sin_cos = arithmetic + stages[key][0], sin_cos + stages[key][1]
    for function, times in schedule.executed():
        a, s = _count_operations(read_program(c_kernel.part_kernel(function.name(), function)))
        arithmetic, sin_cos = arithmetic + times * a, sin_cos + times * s
    return arithmetic, sin_cos


def _check_controller_names(
    name: str,
    functions: tuple[FunctionView, ...],
    controllers: tuple[ControllerView, ...],
    helpers: tuple[HelperView, ...] = (),
    multirate: MultiRateView | None = None,
) -> None:
    """The controllers' C names (struct types, reset and step) clash neither with each other
    nor with the kernels, the stage helpers and the parameter struct."""
    c_names = [f.c_name for f in functions] + [h.c_name for h in helpers] + [c_kernel.params_type(name)]
    classes: tuple[ControllerView | MultiRateView, ...] = (
        *controllers,
        *([multirate] if multirate is not None else []),
    )
    for c in classes:
        c_names += [c.c_type, c.c_reset, c.c_step]
    if len(set(c_names)) != len(c_names):
        raise KernelError(f"module {name!r}: C names of the controllers clash: {sorted(c_names)}")


def _check_macros_unique(
    name: str,
    functions: tuple[FunctionView, ...],
    controllers: tuple[ControllerView, ...] = (),
    multirate: MultiRateView | None = None,
) -> None:
    macros = [p.size_macro for f in functions for p in (*f.inputs, *f.outputs)]
    macros.append(f"{name.upper()}_NQ")
    for c in controllers:
        macros += [f"{c.macro}_PERIOD", f"{c.macro}_STATE_SIZE", *(v.offset_macro for v in c.views)]
    if multirate is not None:
        macros += [f"{multirate.macro}_GROUPS", f"{multirate.macro}_FRAME_TICKS", *(h.macro for h in multirate.held)]
        macros += [f"{g.macro}_{what}" for g in multirate.groups for what in ("PERIOD", "TICKS")]
        macros += [f"{g.macro}_STATE_SIZE" for g in multirate.groups if g.state_size]
    if len(set(macros)) != len(macros):
        raise KernelError(f"module {name!r}: size macros clash: {sorted(macros)}")
