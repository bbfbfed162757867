"""One build of a robot system, from the checked system to its output directory: the CasADi
graphs (robotgen.symbolic), the module's reports and controller classes, then the files
(robotgen.emit.build.emit). `robotgen build`, `robotgen simulate`, the bench and the tests all
build through ``build``; what differs between them is a ``BuildOptions``."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from robotgen import interrupts, symbolic
from robotgen.emit.build import emit
from robotgen.model.describe import system_info, system_nq
from robotgen.model.system import RobotSystem
from robotgen.progress import QUIET, Progress
from robotgen.symbolic.kernel import Kernel


@dataclass(frozen=True)
class BuildOptions:
    """How a system is built: the kernels' C type (robotgen.emit.c_kernel.PRECISIONS), whether
    the extension is compiled, the microcontrollers the C is also compiled for
    (robotgen.emit.targets), whether a root law's reports (robotgen.symbolic.module_extras) go
    into info() and the module's attributes, where progress goes, and the build cache's key
    stamped into the output (robotgen.emit.cache; None: no stamp)."""

    precision: str = "double"
    compile: bool = True
    targets: tuple[str, ...] = ()
    reports: bool = True
    progress: Progress = QUIET
    build_key: str | None = None


@dataclass(frozen=True)
class Built:
    """What a build made: its output directory, the kernels printed there and the seconds spent
    building their graphs (before any C)."""

    out: Path
    kernels: list[Kernel]
    graph_seconds: float


def build_inputs(system: RobotSystem) -> tuple[Path, ...]:
    """The files a build of ``system`` reads (the spec, the files it names): never replaced by its output."""
    return (Path(system.source), *map(Path, system.dependencies))


def build(system: RobotSystem, out: Path, options: BuildOptions = BuildOptions()) -> Built:
    """Builds ``system`` into ``out`` (robotgen.emit.build.emit: atomically, replacing only an
    earlier output of robotgen) and returns what it made. A signal that CasADi swallowed ends the
    build between its steps."""
    progress = options.progress
    progress.stage(f"building the CasADi graphs of {system.name} ({len(system.nodes)} node(s))")
    start = time.perf_counter()
    kernels = symbolic.kernels_for(system)
    graph_seconds = time.perf_counter() - start
    interrupts.check()
    extra_info, attributes = symbolic.module_extras(system) if options.reports else ({}, {})
    interrupts.check()
    progress.stage(f"printing {len(kernels)} C functions")
    emit(
        out,
        system.name,
        kernels,
        nq=system_nq(system),
        precision=options.precision,
        compile=options.compile,
        extra_info={**system_info(system), **extra_info},
        spec_sha256=system.source_sha256,
        attributes=attributes,
        progress=progress,
        controllers=symbolic.controllers_for(system),
        targets=options.targets,
        inputs=build_inputs(system),
        build_key=options.build_key,
    )
    return Built(Path(out), kernels, graph_seconds)
