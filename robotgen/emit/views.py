"""The views the templates show that several modules of emit build: a kernel's ports and
function, a run-time parameter and its bounds, a stage helper. ``context`` assembles them into the
module's view; ``controllers`` and ``multirate`` read them, so they sit here, below all three."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PortView:
    """A kernel port as the templates show it: its rows x cols, numpy shape (one value, and batched), size macro."""

    name: str
    rows: int
    cols: int
    size: int
    shape: tuple[int, ...]  # numpy shape of one (unbatched) value
    shape_text: str  # "(7,)" / "(4, 4)"
    batch_shape_text: str  # "(B, 7)" / "(B, 4, 4)"
    size_macro: str  # <NAME>_<FN>_<PORT>_SIZE


@dataclass(frozen=True)
class BoundsView:
    """A parameter's Bounds as the C check reads them (templates/params_check.c.jinja) and the
    words of its messages (C string literals), which robotgen.model.parameters also builds."""

    minimum: int  # 0 none, 1 at least lower, 2 above lower
    lower: str  # C literals in the module's precision
    maximum: int  # 0 none, 1 at most upper
    upper: str
    order: int  # a positive definite matrix: its order; else 0
    what: str
    noun: str
    relation: str
    suffix: str
    text: str  # the range in words (plain text)


@dataclass(frozen=True)
class ParameterView:
    """One field of the module's ``<name>_params`` struct and keyword-only Python argument."""

    name: str
    shape: tuple[int, ...]  # () a number, (n,), (r, c) row-major
    ndim: int
    dims: tuple[int, int]  # the shape padded with zeros to two entries
    size: int
    offset: int  # index of its first element in the parameters' values concatenated
    shape_text: str  # "()" / "(3,)" / "(3, 3)"
    expected: str  # what a value must be, for error messages
    declaration: str  # the C field: "double kp" / "double kd[3]" / "double K[9]"
    doc: str
    doc_lines: tuple[str, ...]  # the doc, safe inside a C comment
    c_default: tuple[str, ...]  # C initializer of the field, in the module's precision: a line per row
    default_values: tuple[str, ...]  # exact double literals of the default, row-major
    default: float | list  # the default shaped (json and info())
    py_default: str  # Python literal of the default (the text signature)
    stub_type: str  # "float" / "npt.ArrayLike"
    bounds: BoundsView | None = None  # None: any number


@dataclass(frozen=True)
class FunctionView:
    """A kernel as the templates show it: its Python and C names, doc, prototype and C definition, ports, Python
    docstring."""

    name: str  # Python name and kernel name
    c_name: str  # <module>_<name>
    doc: str
    doc_lines: tuple[str, ...]  # kernel.doc, safe inside a C comment
    prototype: str
    definition: str  # C source of the kernel
    inputs: tuple[PortView, ...]
    outputs: tuple[PortView, ...]
    py_doc: str  # C string literal: the Python docstring with its text signature
    stub_doc: str  # Python string literal: the doc's first paragraph on one line (for the .pyi)
    arithmetic_ops: int  # SX instructions other than input, output, constant, copy
    sin_cos_ops: int
    reads_parameters: bool  # the kernel has the PARAMS port: every parameter is a keyword
    guarded: bool = False  # the C checks inputs and results (Kernel.guarded)
    takes_step: bool = False  # it has a step dt and returns 3 for dt <= 0 (c_kernel.STEP_PORT)
    part: int = 0  # which of the module's compile parts holds it (COMPILE_PARTS)
    helpers: tuple[str, ...] = ()  # the stage helpers it calls (HelperView.c_name)
    singular_error: str = ""  # C string literal: the error of status 2 when Kernel.singular says why
    # Its batch form (robotgen.emit.lanes), when it has one: the prototypes of <fn>_batch and
    # <fn>_batch_lanes, the lane kernel and block driver (printed once, compiled per width) and
    # the two public functions.
    batch_prototype: str = ""
    batch_lanes_prototype: str = ""
    lane_definition: str = ""
    batch_definition: str = ""

    @property
    def batch(self) -> bool:
        """The function has a _batch entry point."""
        return bool(self.batch_definition)


@dataclass(frozen=True)
class HelperView:
    """A function of <name>.c that several kernels call: a schedule's stage
    (robotgen.symbolic.schedule.Stage), printed once; static, or RG_SHARED when functions of
    several compile parts call it."""

    c_name: str
    definition: str  # static void rg_<stage>(...) {...}
    parts: tuple[int, ...] = ()  # the compile parts whose functions call it
    home: int | None = None  # when several parts call it: the one part that defines it

    @property
    def shared_definition(self) -> str:
        """The definition with the linkage RG_SHARED (external in robotgen's own build, so
        that the other parts call this one copy; static in a user's build of the file)."""
        return "RG_SHARED " + self.definition.removeprefix("static ")

    @property
    def prototype(self) -> str:
        """The helper's declaration for the compile parts that link to it (RG_SHARED, not static)."""
        return "RG_SHARED " + self.definition.removeprefix("static ").split(" {", 1)[0] + ";"
