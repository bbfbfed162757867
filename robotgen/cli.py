"""The command line: build, check, schema, info, simulate, docs (docs/cli.md).

Exit status: 0 success, 1 the user's input is wrong, 2 usage error, 3 a bug in robotgen."""

from __future__ import annotations

import argparse
import math
import os
import re
import signal
import sys
import threading
import traceback
from dataclasses import replace
from pathlib import Path

import robotgen
from robotgen import interrupts
from robotgen.emit.compile import CompilerSetupError
from robotgen.emit.targets import TARGETS, TargetUnavailable, check_available
from robotgen.errors import MissingDependency, OutputError, UserError, UserErrors
from robotgen.model.coupling import affine
from robotgen.model.derivatives import INTEGRATORS, SEMI_IMPLICIT_EULER, DerivativeSettings
from robotgen.model.describe import system_info, system_nq
from robotgen.model.laws.hand import AdaptiveSettings
from robotgen.model.laws.registry import LAWS
from robotgen.model.names import MAX_LENGTH, PATTERN, name_problem
from robotgen.model.rate_groups import controller_periods, multi_rate_groups, servo_period
from robotgen.model.system import ControlNode
from robotgen.output_files import output_errors, write_files, write_problem
from robotgen.progress import Progress
from robotgen.progress import for_terminal as progress_for_terminal

EXIT_OK, EXIT_USER, EXIT_USAGE, EXIT_BUG = 0, 1, 2, 3
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143  # 128 + SIGINT, 128 + SIGTERM, as a shell reports them


_Terminated = interrupts.Terminated


def _unraisable(hook) -> None:
    """A signal's exception raised where Python cannot pass it on (in a weakref callback of
    the import system, say) would be printed as "Exception ignored" with a traceback and
    lost, and the build would go on. The signal is sent again instead, 10 ms later from
    another thread (sent from here it would be raised here again), to be raised in the main
    thread at the next point that can pass it on."""
    signum = (
        signal.SIGINT
        if issubclass(hook.exc_type, KeyboardInterrupt)
        else signal.SIGTERM
        if issubclass(hook.exc_type, _Terminated)
        else None
    )
    if signum is None:
        sys.__unraisablehook__(hook)
    else:
        resend = threading.Timer(0.01, os.kill, (os.getpid(), signum))
        resend.daemon = True
        resend.start()


def _load(args: argparse.Namespace):
    """A RobotSystem from a YAML spec, or from a URDF or MJCF file with --tip or --tree."""
    path = args.spec
    name = getattr(args, "name", None)
    if name is not None and name_problem(name):
        suggestion = re.sub(r"[^a-z0-9_]", "_", name.lower())[: MAX_LENGTH - 6]
        suggestion = suggestion if PATTERN.match(suggestion) else "_" + suggestion
        suggestion = suggestion if not name_problem(suggestion) else suggestion + "_robot"
        raise _Usage(
            f"--name {name!r} {name_problem(name)} (it names the Python module and prefixes every "
            f"C function); try --name {suggestion}"
        )
    reader = _file_reader(path)
    if reader is not None:
        kind, load_chain, load_tree = reader
        if getattr(args, "tree", False):
            system = load_tree(path, base=args.base, tip=args.tip, name=args.name)
        elif not getattr(args, "tip", None):
            what = "LINK" if kind == "URDF" else "BODY"
            hint = f"; robotgen info {Path(path).name} lists its links" if kind == "URDF" else ""
            raise _Usage(
                f"a{'n' if kind == 'MJCF' else ''} {kind} file needs --tip {what} (or --tree for every "
                f"joint below the base){hint}"
            )
        else:
            system = load_chain(path, tip=args.tip, base=args.base, name=args.name)
        if getattr(args, "no_derivatives", False) or getattr(args, "integrator", None):
            settings = DerivativeSettings(
                False if args.no_derivatives else None, args.integrator or SEMI_IMPLICIT_EULER
            )
            system = replace(system, derivatives=settings)
    else:
        from robotgen.frontend import load_system

        given = [f"--{k}" for k in ("tip", "base", "name") if getattr(args, k, None)]
        given += ["--tree"] if getattr(args, "tree", False) else []
        given += ["--no-derivatives"] if getattr(args, "no_derivatives", False) else []
        given += ["--integrator"] if getattr(args, "integrator", None) else []
        if given:
            raise _Usage(
                f"{', '.join(given)} appl{'ies' if len(given) == 1 else 'y'} to a URDF file (or an MJCF "
                "file); a spec says the same with its name:, nodes: and derivatives: keys"
            )
        system = load_system(path)
    for warning in system.warnings:
        print(warning, file=sys.stderr)
    return system


def _file_reader(path: str):
    """(kind, chain loader, tree loader) of a robot file read without a spec: a URDF
    (``.urdf``) or an MJCF file (``.xml``, ``.mjcf``, compiled by MuJoCo); None for a spec."""
    suffix = Path(path).suffix.lower()
    if suffix == ".urdf":
        from robotgen.frontend.urdf import load_urdf_system, load_urdf_tree_system

        return "URDF", load_urdf_system, load_urdf_tree_system
    if suffix in (".xml", ".mjcf"):
        from robotgen.frontend.mjcf import load_mjcf_system, load_mjcf_tree_system

        return "MJCF", load_mjcf_system, load_mjcf_tree_system
    return None


class _Usage(Exception):
    pass


def _progress(args: argparse.Namespace) -> Progress:
    return progress_for_terminal(getattr(args, "quiet", False))


def _cmd_build(args: argparse.Namespace) -> int:
    progress = _progress(args)
    progress.stage(f"reading {args.spec}")
    system = _load(args)
    from robotgen.emit import cache

    out = Path(args.output) if args.output else Path("generated") / system.name
    targets = tuple(sorted(set(args.target)))
    try:
        for target in targets:
            check_available(target)
    except TargetUnavailable as e:
        print(f"robotgen: error: {e}", file=sys.stderr)
        return EXIT_USER
    options = {
        "name": system.name,
        "precision": args.precision,
        "compile": not args.no_compile,
        "tip": args.tip,
        "base": args.base,
        "tree": getattr(args, "tree", False),
        "source_sha256": system.source_sha256,  # an MJCF file's: its includes and meshes too
        **({"targets": list(targets)} if targets else {}),
    }
    from robotgen.emit.build import parent_locked, replace_problem
    from robotgen.emit.pipeline import BuildOptions, build, build_inputs

    inputs = build_inputs(system)
    key = cache.build_key(list(inputs), options)
    with output_errors(out), parent_locked(out, shared=True):  # (not while another build swaps in)
        if cache.is_current(out, key, not args.no_compile, system.name):
            print(f"robotgen: {out} is up to date")
            return EXIT_OK
        problem = replace_problem(out, inputs)  # before the graphs are built: say it at once
    if problem:
        raise OutputError(problem)
    built = build(
        system,
        out,
        BuildOptions(
            precision=args.precision,
            compile=not args.no_compile,
            targets=targets,
            progress=progress,
            build_key=key,
        ),
    )
    print(f"robotgen: built {system.name} ({len(built.kernels)} functions) in {out}")
    return EXIT_OK


def _cmd_simulate(args: argparse.Namespace) -> int:
    import dataclasses
    import tempfile

    from robotgen import documentation
    from robotgen.emit.pipeline import BuildOptions, build, build_inputs
    from robotgen.model.signature import robot_leaves
    from robotgen.model.simulation import BOTH_PLANTS, MUJOCO_PLANT, ROBOTGEN_PLANT, SimulationSettings, rest_posture
    from robotgen.simulation import multirate as multirate_simulation
    from robotgen.simulation import tree as simulate
    from robotgen.simulation.failures import SimulationError
    from robotgen.simulation.mujoco import MujocoMissing, require_mujoco
    from robotgen.simulation.mujoco.run import tree_plant

    progress = _progress(args)
    system = _load(args)
    if system.is_single_leaf:
        raise _Usage(
            "simulate needs a robot tree (attach/control); a chain's module closes a loop in a few "
            f"lines of Python: {documentation.hint('python-api', 'A chain')}"
        )
    law = LAWS[system.root_law] if system.root_law is not None else None
    own = law.part("simulation") if law is not None else None  # a root law's own simulation
    if law is not None and own is None:
        raise _Usage(f"simulate has no run for a {law.name} controller")
    refusal = own.refusal(system) if own is not None else None
    if refusal:
        raise _Usage(refusal)
    hand = law is not None and law.hand_frame
    if hand and args.dt is not None:
        raise _Usage(
            f"a {system.root_law} controller runs at its own period "
            f"({system.root_control.hand_settings.period:g} s); --dt applies to robot trees"
        )
    settings = system.simulation or SimulationSettings()
    groups = multi_rate_groups(system)
    if groups is not None and args.dt is not None:
        raise _Usage(
            f"a multi-rate tree runs at its controllers' periods (the fastest {groups.base_period:g} s, the "
            "plant's step); --dt applies to single-rate trees"
        )
    period = groups.base_period if groups is not None else servo_period(system)
    if period is not None:  # the controllers' period (the plant steps at the fastest)
        settings = dataclasses.replace(settings, dt=period)
    overrides = {k: getattr(args, k) for k in ("duration", "dt") if getattr(args, k) is not None}
    for k, value in overrides.items():
        if not value > 0:
            raise _Usage(f"--{k} must be positive, got {value:g}")
    settings = dataclasses.replace(settings, **overrides)
    # each internal-force PI loop stable at the period it runs at: its rate group's, or the one period
    periods = controller_periods(system) if groups is not None else {}
    for node in system.nodes.values():
        period = periods.get(node.name, settings.dt)
        problem = node.internal_force_loop_problem(period) if isinstance(node, ControlNode) else None
        if problem and "dt" in overrides:
            raise _Usage(f"--dt {settings.dt:g}: controller '{node.name}': {problem}")
        if problem:
            raise UserError(system.location_of(node.name), f"controller '{node.name}': {problem}")
    plant = args.plant or settings.plant
    if groups is not None and plant == BOTH_PLANTS:
        raise _Usage(
            "a multi-rate tree is simulated beside its single-rate run on one plant; choose --plant robotgen "
            "or --plant mujoco"
        )
    plants = (ROBOTGEN_PLANT, MUJOCO_PLANT) if plant == BOTH_PLANTS else (plant,)
    if MUJOCO_PLANT in plants:
        try:
            require_mujoco()
        except MujocoMissing as e:
            if args.plant or "plant" not in settings.locations:
                print(f"robotgen: error: --plant {plant}: {e}", file=sys.stderr)
                return EXIT_USER
            raise UserError(settings.locations["plant"], f"simulation.plant: {e}") from None
    out = Path(args.output) if args.output else Path("generated") / f"{system.name}_simulation"
    inputs = build_inputs(system)
    stems = (
        [(system.name, " (multi-rate)"), (f"{system.name}_{multirate_simulation.SINGLE_RATE}", " (single rate)")]
        if groups is not None
        else [(f"{system.name}{'' if p == plants[0] else '_' + p}", "") for p in plants]
    )
    names = [f"{stem}.{ext}" for stem, _ in stems for ext in ("csv", "png")]
    names += [f"{system.name}.xml"] if MUJOCO_PLANT in plants else []
    with output_errors(out):  # before the simulation: say it at once
        problem = write_problem(out, names, inputs)
    if problem:
        raise OutputError(problem)
    rest = rest_posture([system.leaf(leaf) for leaf in robot_leaves(system)])
    results, mjcf = [], None
    with tempfile.TemporaryDirectory(prefix="robotgen-sim-") as tmp:
        module_dir = Path(tmp) / system.name
        progress.stage(f"compiling {system.name}'s servo step and plant")
        build(system, module_dir, BuildOptions(reports=False))  # the run's module, not the user's: no reports
        module = simulate.load_module(module_dir, system.name)
        comparison = None
        twin = own.comparison_system(system) if own is not None else None
        if twin is not None:  # another law on the same path
            progress.stage(f"compiling {twin.name}, {twin.root_law.replace('_', ' ')} control for comparison")
            build(twin, Path(tmp) / twin.name, BuildOptions(reports=False))
            comparison = simulate.load_module(Path(tmp) / twin.name, twin.name)
        step = system.root_control.hand_settings.period if hand else settings.dt
        for p in plants:
            progress.stage(f"simulating {settings.duration:g} s at dt = {step:g} s on the {p} plant")
            try:
                if own is not None:
                    result, xml = own.simulate(module, system, settings, p, comparison)
                    mjcf = xml or mjcf
                elif p == MUJOCO_PLANT:
                    model, make = tree_plant(system, module, settings.dt)
                    if groups is not None:
                        both, mjcf = multirate_simulation.run(module, settings, rest, make), model.xml
                    else:
                        result, mjcf = simulate.run(module, settings, rest, make), model.xml
                elif groups is not None:
                    both = multirate_simulation.run(module, settings, rest)
                else:
                    result = simulate.run(module, settings, rest)
            except SimulationError as e:
                in_spec = e.field is not None and e.field in settings.locations
                where = (
                    settings.locations[e.field] if in_spec and e.field is not None else system.location_of(system.root)
                )
                raise UserError(where, f"simulation.{e.field}: {e}" if in_spec else str(e)) from None
            results += list(both) if groups is not None else [result]
        info = module.info()
    kind = own if own is not None else simulate
    wrote = _write_simulation(out, system, kind, results, mjcf, inputs, stems)
    if groups is not None:
        multi, single = results
        print(multirate_simulation.compare(multi, single, info))
    else:
        print(kind.summary(results[0]) if len(results) == 1 else kind.compare(*results))
    print(wrote)
    return EXIT_OK


def _write_simulation(
    out: Path, system, kind, results: list, mjcf: str | None, inputs: tuple[Path, ...], stems: list[tuple[str, str]]
) -> str:
    """<stem>.csv and <stem>.png of each run (``stems``, one (stem, what the plot's title adds)
    per result: the first plant's <name>, a second plant's <name>_<plant>, a multi-rate tree's
    single-rate run <name>_single_rate; ``kind``: robotgen.simulation.tree or a root law's simulation, whose
    write_csv and plot these are), and the MJCF simulated as <name>.xml, made aside, then put
    into ``out`` replacing only files robotgen can prove it wrote there
    (robotgen.output_files); the line that says what was written."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="robotgen-results-") as tmp:
        made: dict[str, Path] = {}
        for result, (stem, note) in zip(results, stems):
            made[f"{stem}.csv"] = Path(tmp) / f"{stem}.csv"
            kind.write_csv(result, made[f"{stem}.csv"])
            try:
                png = Path(tmp) / f"{stem}.png"
                kind.plot(
                    result,
                    png,
                    f"{system.name}: {system.root} ({system.root_node.primitive}), {result.plant} plant{note}",
                )
                made[png.name] = png
            except ImportError:
                print("robotgen: no PNG: matplotlib is missing; pip install matplotlib", file=sys.stderr)
        if mjcf is not None:
            made[f"{system.name}.xml"] = Path(tmp) / f"{system.name}.xml"
            made[f"{system.name}.xml"].write_text(mjcf)
        interrupts.check()
        write_files(out, made, inputs)
    written = [str(out / name) for name in made]
    return (
        f"robotgen: wrote {', '.join(written[:-1])} and {written[-1]}"
        if len(written) > 1
        else f"robotgen: wrote {written[0]}"
    )


def _cmd_check(args: argparse.Namespace) -> int:
    system = _load(args)
    print(f"{args.spec}: ok ({len(system.nodes)} node(s), root '{system.root}')")
    return EXIT_OK


def _cmd_docs(args: argparse.Namespace) -> int:
    from robotgen import documentation

    pages = documentation.pages()
    if not pages:
        print("robotgen: error: the documentation pages are missing from this installation", file=sys.stderr)
        return EXIT_USER
    if args.page is None:
        print(f"robotgen's documentation ({documentation.directory()}):")
        for name, (_, title) in pages.items():
            print(f"  {name:20} {title}")
        print("robotgen docs PAGE prints one (Markdown).")
        return EXIT_OK
    page = args.page.removesuffix(".md")
    if page not in pages:
        raise _Usage(f"no page {args.page!r}; the pages are {', '.join(pages)}")
    sys.stdout.write(pages[page][0].read_text(encoding="utf-8"))
    return EXIT_OK


def _cmd_schema(args: argparse.Namespace) -> int:
    from robotgen.frontend.schema import schema_json

    print(schema_json())
    return EXIT_OK


def _cmd_info(args: argparse.Namespace) -> int:
    if args.spec.lower().endswith(".urdf") and not args.tip and not args.tree:  # the file's tree, to choose a tip
        from robotgen.frontend.urdf import read_urdf_file
        from robotgen.frontend.urdf_outline import outline

        urdf = read_urdf_file(args.spec)
        for note in urdf.notes:
            print(note, file=sys.stderr)
        print(outline(urdf, args.base))
        return EXIT_OK
    system = _load(args)
    info = system_info(system)
    print(f"{system.name} (root: {system.root}; sensed joints: {system_nq(system)} in {', '.join(info['leaves'])})")
    for name, node in info["nodes"].items():
        print(f"  {name}: {node['primitive']} {node['kind']}, nq = {node['nq']}")
        coordinates = [f"{c} [{u}]" if u else c for c, u in zip(node["coordinates"], node["units"])]
        print(f"    coordinates: {', '.join(coordinates)}")
        for label in ("internal_motions", "internal_forces"):
            if node[label]:
                print(f"    {label.replace('_', ' ')}: {', '.join(node[label])}")
        for key in ("robots", "payload", "robot"):
            if node.get(key):
                value = node[key]
                print(f"    {key}: {', '.join(value) if isinstance(value, list) else value}")
        for j in node.get("joints", []):
            lim = j["limits"]
            bounds = (
                -math.inf if lim["lower"] is None else lim["lower"],
                math.inf if lim["upper"] is None else lim["upper"],
            )
            rng = "" if lim["lower"] is None and lim["upper"] is None else f" [{bounds[0]:g}, {bounds[1]:g}]"
            print(f"    - {j['name']}: {j['type']}, parent {j['parent']}{rng}")
        if node.get("locked_joints"):
            print(f"    locked at q = 0: {', '.join(node['locked_joints'])}")
        for c in node.get("coupled_joints", []):
            print(f"    mimic: {c['joint']} = {affine(c['multiplier'], c['coordinate'], c['offset'])}")
    groups = multi_rate_groups(system)
    if groups is not None:
        from robotgen.symbolic.lifted_loop import OperatingPointError, lifted_loop  # lazy: CasADi where needed

        print(rate_group_lines(groups))
        try:
            print(lifted_loop_line(lifted_loop(system, groups)))
        except OperatingPointError as e:
            print(f"  lifted closed loop: not linearised: {e}")
    if system.root_law is not None and isinstance(system.root_control.hand, AdaptiveSettings):
        from robotgen.symbolic import module_extras  # lazy: CasADi only where it is needed
        from robotgen.symbolic.root_laws.resolved_adaptive import closed_loop

        print(closed_loop_line(closed_loop(system), system.root_control.hand_settings.period))
        print(operation_table(module_extras(system)[0]["hand_control"]))
    return EXIT_OK


def operation_table(hand: dict) -> str:
    """One period of the adaptive controller beside Lee and Lee's Table 1, row by row, with
    the paper's accounting of parallel parts in the totals."""
    counts = hand["operation_counts"]
    head = f"    {'stage':46} {'paper mul':>9} {'add':>5}   {'robotgen mul':>12} {'add':>5} {'trig':>5} {'other':>5}"
    lines = [
        "  operations per sampling period (Lee and Lee 1983, Table 1; other = divisions, square roots, selections):",
        head,
    ]
    part = None
    for row in counts["rows"]:
        if row["part"] != part:
            part = row["part"]
            lines.append(f"    {part}")
        p, r = row["paper"], row["robotgen"]
        more = f"   more: {row['note']}" if row["note"] else ""  # computes more than the paper's quantity
        lines.append(
            f"      {row['stage'] + ' ' + row['name']:44} {p['mul']:9d} {p['add']:5d}   {r['mul']:12d} "
            f"{r['add']:5d} {r['trig']:5d} {r['other']:5d}{more}"
        )
    labels = {
        "feedforward": "total feedforward",
        "feedback": "total feedback (stage 1: the larger part)",
        "period": "period: feedforward and feedback in parallel",
        "sequential": "every stage on one processor",
    }
    for key, label in labels.items():
        p, r = counts["paper"][key], counts["robotgen"][key]
        lines.append(
            f"    {label:46} {p['mul']:9d} {p['add']:5d}   {r['mul']:12d} {r['add']:5d} {r['trig']:5d} {r['other']:5d}"
        )
    step = counts["step"]
    lines.append(
        f"    {'emitted step (its prologue and loops)':46} {'':9} {'':5}   {step['mul']:12d} "
        f"{step['add']:5d} {step['trig']:5d} {step['other']:5d}"
    )
    return "\n".join(lines)


def rate_group_lines(groups) -> str:
    """The rate groups of a multi-rate tree, fastest first."""
    lines = [f"  rate groups (one step function each, run on ticks of {groups.base_period:g} s):"]
    for g in groups.groups:
        lines.append(
            f"    servo_step_g{g.index}: every {g.period:g} s ({g.rate:g} Hz, {g.ticks} tick"
            f"{'s' if g.ticks > 1 else ''}): {', '.join(g.controllers)}"
            + (f"; holds what it writes to {', '.join(g.writes)}" if g.writes else "")
        )
    return "\n".join(lines)


def lifted_loop_line(loop) -> str:
    """The lifted closed loop's spectral radius at the start pose."""
    x = ", ".join(f"{v:.4g}" for v in loop.x)
    verdict = (
        f"stable: an error decays by that factor per {1e3 * loop.frame:g} ms (time constant "
        f"{1e3 * loop.time_constant:.3g} ms)"
        if loop.stable
        else f"UNSTABLE: an error grows by that factor per {1e3 * loop.frame:g} ms; run the slower groups faster "
        "or lower their gains"
    )
    return (
        f"  lifted closed loop over one slowest period ({1e3 * loop.frame:g} ms, {loop.ticks} ticks) at the start "
        f"pose x = ({x}), at rest: spectral radius {loop.spectral_radius:.4f}, {verdict}"
    )


def closed_loop_line(loop: dict, period: float) -> str:
    """The one-step control's closed loop at the nominal pose."""
    pose = ", ".join(f"{v:.4g}" for v in loop["pose"])
    return (
        f"  one-step control's closed loop at q = ({pose}), hand at rest: spectral radius "
        f"{loop['spectral_radius']:.4g} (margin {loop['margin']:.4g}), slowest time constant "
        f"{1e3 * loop['time_constant']:.3g} ms at T = {1e3 * period:g} ms"
    )


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="robotgen",
        description="Compile robot systems to C and Python.",
        epilog="Exit status: 0 success, 1 your input is wrong (FILE:LINE:COL: message), "
        "2 usage error, 3 a bug in robotgen. Documentation: robotgen docs "
        "(the pages installed with robotgen).",
    )
    p.add_argument(
        "--version",
        action="version",
        version=f"robotgen {robotgen.__version__} (casadi {_casadi_version()}, Python {sys.version.split()[0]})",
    )
    quiet = argparse.ArgumentParser(add_help=False)
    quiet.add_argument("-q", "--quiet", action="store_true", help="no progress messages on stderr")
    sub = p.add_subparsers(dest="command", required=True)
    b = sub.add_parser(
        "build", parents=[quiet], help="compile a spec (or a URDF or MJCF chain) to C and a Python module"
    )
    b.add_argument("spec", help="SPEC.yaml, ROBOT.urdf or ROBOT.xml (MJCF)")
    b.add_argument("-o", "--output", help="output directory (default generated/<name>/)")
    b.add_argument("--precision", choices=["double", "float"], default="double")
    b.add_argument("--no-compile", action="store_true", help="emit sources only")
    b.add_argument(
        "--target",
        action="append",
        choices=sorted(TARGETS),
        default=[],
        help="also compile the C for this microcontroller and record each function's code and "
        "stack bytes in manifest.json (needs its compiler, e.g. arm-none-eabi-gcc)",
    )
    b.add_argument("--tip", help="URDF: the tip link; MJCF: the tip body or site")
    b.add_argument(
        "--base", help="URDF: the base link (default: the root link); MJCF: the base body (default: the world)"
    )
    b.add_argument("--name", help="URDF, MJCF: module name (default: the robot's or model's name)")
    b.add_argument(
        "--tree",
        action="store_true",
        help="URDF, MJCF: keep every movable joint below the base (a branched tree); --tip then "
        "only names the frame of fk and jacobian",
    )
    b.add_argument(
        "--no-derivatives",
        action="store_true",
        help="URDF, MJCF: leave out the derivative functions (a spec says so in its derivatives section)",
    )
    b.add_argument(
        "--integrator",
        choices=list(INTEGRATORS),
        help="URDF, MJCF: the step of discrete_dynamics (default semi_implicit_euler)",
    )
    b.set_defaults(run=_cmd_build)
    for name, run, text in (("check", _cmd_check, "validate only"), ("info", _cmd_info, "print the robot tree")):
        c = sub.add_parser(name, help=text)
        c.add_argument("spec", help="SPEC.yaml, ROBOT.urdf or ROBOT.xml (MJCF)")
        c.add_argument("--tip", help="URDF: the tip link; MJCF: the tip body or site")
        c.add_argument(
            "--base", help="URDF: the base link (default: the root link); MJCF: the base body (default: the world)"
        )
        c.add_argument("--name", help="URDF, MJCF: module name (default: the robot's or model's name)")
        c.add_argument("--tree", action="store_true", help="URDF, MJCF: every movable joint below the base")
        c.set_defaults(run=run)
    sim = sub.add_parser(
        "simulate", parents=[quiet], help="run a tree's servo step against its true constrained plant (or MuJoCo's)"
    )
    sim.add_argument("spec")
    sim.add_argument(
        "-o", "--output", help="directory for the CSV, PNG and MJCF (default generated/<name>_simulation/)"
    )
    sim.add_argument("--duration", type=float, help="seconds (default: the spec's simulation section)")
    sim.add_argument("--dt", type=float, help="servo period and RK4 step [s]")
    sim.add_argument(
        "--plant",
        choices=["robotgen", "mujoco", "both"],
        help="the plant the loop is closed around: robotgen's own model, an independent MuJoCo "
        "model of the same system (contacts instead of the bilateral grasp; needs pip install "
        "'robotgen[mujoco]'), or both side by side (default: the spec's simulation.plant, else "
        "robotgen)",
    )
    sim.set_defaults(run=_cmd_simulate, tip=None, base=None, name=None)
    s = sub.add_parser("schema", help="print the JSON Schema of the spec format")
    s.set_defaults(run=_cmd_schema)
    d = sub.add_parser("docs", help="list the documentation pages, or print one")
    d.add_argument("page", nargs="?", help="a page: cli, spec-format, python-api, c-api, ...")
    d.set_defaults(run=_cmd_docs)
    return p


def _casadi_version() -> str:
    from importlib import metadata

    try:
        return metadata.version("casadi")
    except metadata.PackageNotFoundError:
        return "missing"


def main(argv: list[str] | None = None) -> int:
    """Run the robotgen command with ``argv`` (default sys.argv[1:]); return its exit status 0/1/2/3."""
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # argparse: usage error (2) or --help (0)
        return int(e.code or 0)
    try:
        with interrupts.noting():
            try:
                status = args.run(args)
            except Exception:
                interrupts.check()  # a signal swallowed on the way (and the error it left) ends the command
                raise
            interrupts.check()
        return status
    except UserErrors as e:
        for err in e.errors:
            print(err, file=sys.stderr)
        return EXIT_USER
    except UserError as e:
        print(e, file=sys.stderr)
        return EXIT_USER
    except _Usage as e:
        print(f"robotgen: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except (CompilerSetupError, MissingDependency, OutputError) as e:
        print(f"robotgen: error: {e}", file=sys.stderr)
        return EXIT_USER
    except KeyboardInterrupt:  # Ctrl-C: the build's staging directory is already cleaned up
        print("robotgen: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except _Terminated:
        print("robotgen: terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except BrokenPipeError:
        # the reader closed the pipe (`robotgen schema | head -1`): it has what it wanted
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_OK
    except Exception:  # noqa: BLE001 - a bug in robotgen, not the user's fault
        traceback.print_exc()
        print("robotgen: internal error (a bug in robotgen, not in your input); please report it", file=sys.stderr)
        return EXIT_BUG


def answer_signals() -> None:
    """SIGTERM raised as _Terminated and SIGINT as KeyboardInterrupt, each noted so that one
    swallowed on the way is raised again (robotgen.interrupts), and either one sent again when
    it lands where it cannot be raised (_unraisable)."""
    interrupts.answer_both()
    sys.unraisablehook = _unraisable


def entry() -> None:
    """The console script: main() with SIGINT and SIGTERM answered, its status passed to sys.exit."""
    answer_signals()
    try:
        status = main()
    except KeyboardInterrupt:  # before or after main's own handling (argument parsing, exit)
        print("robotgen: interrupted", file=sys.stderr)
        status = EXIT_INTERRUPTED
    except _Terminated:
        print("robotgen: terminated", file=sys.stderr)
        status = EXIT_TERMINATED
    sys.exit(status)


if __name__ == "__main__":
    entry()
