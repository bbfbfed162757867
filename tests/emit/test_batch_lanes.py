"""Batches across states (robotgen.emit.lanes): a batch call of the module goes through the C's
<fn>_batch, W states per vector, and must give n single calls' results bit for bit, at every
width this CPU runs (ROBOTGEN_BATCH_LANES caps it: 1 is the loop of single calls), for n with
and without a remainder, on the UR5 and the Panda (straight-line and looped kernels) and on a
branched tree past 12 joints (loops through parent tables, a prismatic joint). States include
angles past rg_sincos2's bound (libm in that lane) and, for checked functions, a NaN state and a
singular one: each state's outputs are what its single call leaves (untouched, zeros)."""

from __future__ import annotations

import ctypes
import os
import platform
import shutil
import subprocess

import numpy as np
import pytest
from batch_states import built, single_calls, states
from robots import PANDA, UR5, robots_dir

from robotgen.emit import lanes
from robotgen.frontend.urdf import load_urdf_system
from robotgen.model.chain import Body, Joint, KinematicTree
from robotgen.model.describe import system_nq
from robotgen.symbolic import kernels_for, leaf_kernels

WIDTHS = (1, 2, 4, 8, 16)  # caps tried; the module says which width each one gets


def branched_tree(seed: int = 3, parents: tuple[int, ...] = (-1, 0, 1, 2, 1, 4, 5, 0, 7)) -> KinematicTree:
    """A tree on oblique axes with one prismatic joint: 9 joints, three branches of several lengths
    (lanes are compiled up to 12 coordinates, robotgen.emit.lanes.LANES_MAX_NQ)."""
    rng = np.random.default_rng(seed)
    joints = []
    for i, parent in enumerate(parents):
        T = np.eye(4)
        T[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        if np.linalg.det(T[:3, :3]) < 0:
            T[:3, 2] *= -1
        T[:3, 3] = rng.normal(size=3) * 0.2
        axis = rng.normal(size=3)
        joints.append(
            Joint(
                f"j{i}",
                "prismatic" if i == 3 else "revolute",
                parent,
                T,
                axis / np.linalg.norm(axis),
                Body(rng.uniform(0.5, 2.0), rng.normal(size=3) * 0.1, np.diag(rng.uniform(0.01, 0.1, 3))),
            )
        )
    return KinematicTree("branched", tuple(joints), 7, np.eye(4), np.array([0.0, 0.0, -9.81]))


@pytest.fixture(scope="module")
def ur5(tmp_path_factory):
    system = load_urdf_system(str(robots_dir() / UR5[0]), UR5[1])
    return built(
        tmp_path_factory,
        "lanes_ur5",
        kernels_for(system),
        system_nq(system),
        ("mass", "inverse_dynamics", "forward_dynamics", "discrete_dynamics_derivatives"),
    )


@pytest.fixture(scope="module")
def panda(tmp_path_factory):
    system = load_urdf_system(str(robots_dir() / PANDA[0]), PANDA[1])
    kernels = kernels_for(system)
    assert next(k for k in kernels if k.name == "forward_dynamics_derivatives").schedule is not None
    return built(tmp_path_factory, "lanes_panda", kernels, system_nq(system), ("mass", "forward_dynamics_derivatives"))


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    t = branched_tree()
    return built(
        tmp_path_factory, "lanes_tree", leaf_kernels(t), t.nq, ("mass", "inverse_dynamics", "forward_dynamics")
    )


def widths(module) -> list[int]:
    """The distinct widths a batch call takes on this CPU, each cap's (the C's <name>_batch_lanes)."""
    library = ctypes.CDLL(module.__file__)
    select = getattr(library, f"{module.__name__}_batch_lanes")
    return sorted({select(cap) for cap in WIDTHS})


def lanes_expected() -> bool:
    """This machine compiles and runs a vector width: x86-64 with AVX2 (or wider), or aarch64."""
    machine = platform.machine()
    if machine == "aarch64":
        return True
    if machine != "x86_64" or not os.path.exists("/proc/cpuinfo"):
        return False
    with open("/proc/cpuinfo") as f:
        return " avx2" in f.read()


def assert_batch_is_single_calls(module, kernels, names, ns, rng, poison=False):
    seen = widths(module)
    assert seen[0] == 1
    for kernel in kernels:
        if kernel.name not in names:
            continue
        fn = getattr(module, kernel.name)
        for n in ns:
            arrays = states(kernel, n, rng)
            if poison and n > 3:
                arrays[0][2, 1] = np.nan  # status 1: nothing written
                arrays[0][3, 0] = np.inf
            expected, failed = single_calls(fn, arrays, n, kernel.outputs)
            for cap in WIDTHS:
                got = [np.full((n, p.size), -7.0) for p in kernel.outputs]
                out = tuple(
                    g.reshape((n, p.rows, p.cols) if p.cols > 1 else (n, p.rows)) for g, p in zip(got, kernel.outputs)
                )
                os.environ["ROBOTGEN_BATCH_LANES"] = str(cap)
                try:
                    fn(*arrays, out=out if len(out) > 1 else out[0])
                    raised = False
                except FloatingPointError:
                    raised = True
                finally:
                    del os.environ["ROBOTGEN_BATCH_LANES"]
                assert raised == bool(failed), (kernel.name, n, cap)
                for g, e, p in zip(got, expected, kernel.outputs):
                    same = np.all(g.view(np.uint64) == e.view(np.uint64), axis=1)
                    assert same.all(), (
                        f"{kernel.name}.{p.name}, n={n}, lanes {cap}: states "
                        f"{np.flatnonzero(~same)[:8]} differ from single calls"
                    )
    return seen


def test_ur5_batches_are_single_calls_bit_for_bit(ur5):
    module, kernels = ur5
    seen = assert_batch_is_single_calls(
        module, kernels, lanes.BATCH_FUNCTIONS, (1, 3, 7, 8, 9, 1023), np.random.default_rng(1), poison=True
    )
    print("widths run:", seen)
    assert len(seen) > 1 or not lanes_expected()  # the lanes ran, not only the loop of single calls


def test_panda_batches_are_single_calls_bit_for_bit(panda):
    module, kernels = panda
    seen = assert_batch_is_single_calls(
        module, kernels, lanes.BATCH_FUNCTIONS, (1, 7, 8, 1023), np.random.default_rng(2), poison=True
    )
    assert len(seen) > 1 or not lanes_expected()


def test_branched_tree_batches_are_single_calls_bit_for_bit(tree):
    module, kernels = tree
    seen = assert_batch_is_single_calls(
        module, kernels, lanes.BATCH_FUNCTIONS, (1, 7, 8, 1023), np.random.default_rng(3)
    )
    assert len(seen) > 1 or not lanes_expected()


@pytest.mark.parametrize("precision", ["double", "float"])
def test_comparisons_and_selections_are_masks_on_whole_vectors(tmp_path_factory, precision):
    """A lane kernel computes comparisons, logic, if_else and fabs on whole vectors through masks
    (no loop over lanes), and each lane still gives what C's scalar statement gives: 1.0 or 0.0,
    a condition true where it is not 0 (NaN too), fabs(-0.0) = +0.0. The states tie, flip and
    divide 0 by 0 lane by lane; the kernel is one the batch entry points cover (named gravity)."""
    import casadi as ca

    from robotgen.symbolic.kernel import make_kernel

    q = ca.SX.sym("q", 4)
    a, b, c, d = (q[i] for i in range(4))
    ratio = a / b  # NaN where a = b = 0, infinite where only b is
    values = [
        a < b,
        a <= b,
        a == b,
        a != b,
        ca.logic_not(a),
        ca.logic_and(a, b),
        ca.logic_or(a, c),
        ca.if_else(a < c, c, d),
        ca.fabs(a),
        ca.logic_not(ratio),
        ca.logic_and(ratio, c),
        ca.if_else(ratio, c, 0),
    ]
    kernel = make_kernel("gravity", "masks", [("q", q)], [("gravity", ca.vertcat(*values), (len(values), 1))])
    module, kernels = built(tmp_path_factory, f"lanes_masks_{precision}", [kernel], 4, ("gravity",), precision)
    source = open(os.path.join(os.path.dirname(module.__file__), f"lanes_masks_{precision}.c")).read()
    lane_kernel = source[source.index("RG_L(rgl_gravity)(") :]
    assert "rg_l < RG_W" not in lane_kernel[: lane_kernel.index("\n}")]
    n = 1023
    rng = np.random.default_rng(8)
    chosen = rng.choice([-1.0, -0.0, 0.0, 1.0, 2.0], (n, 4))
    expected, failed = single_calls(module.gravity, [chosen], n, kernel.outputs)
    assert not failed
    with np.errstate(divide="ignore", invalid="ignore"):
        x, y, z, w = chosen.T
        r = x / y
        closed = np.stack(
            [
                x < y,
                x <= y,
                x == y,
                x != y,
                x == 0,
                (x != 0) & (y != 0),
                (x != 0) | (z != 0),
                np.where(x < z, z, w),
                np.abs(x),
                r == 0,  # !r: NaN and infinities are true, so !r is 1 only where r is 0
                (r != 0) & (z != 0),
                np.where(r != 0, z, 0.0),
            ],
            axis=1,
        ).astype(float)
    assert np.array_equal(expected[0], closed)
    assert not np.signbit(expected[0][:, 8]).any()  # fabs(-0.0) is +0.0
    assert_every_width_gives(module.gravity, chosen, expected[0])
    assert len(widths(module)) > 1 or not lanes_expected()


def assert_every_width_gives(fn, states: np.ndarray, expected: np.ndarray) -> None:
    """A one-port, one-output batch call at every cap gives ``expected`` (the single calls') bit for bit."""
    for cap in WIDTHS:
        got = np.full(expected.shape, -7.0)
        os.environ["ROBOTGEN_BATCH_LANES"] = str(cap)
        try:
            fn(states, out=got)
        finally:
            del os.environ["ROBOTGEN_BATCH_LANES"]
        same = np.all(got.view(np.uint64) == expected.view(np.uint64), axis=1)
        assert same.all(), f"lanes {cap}: states {np.flatnonzero(~same)[:8]} differ from single calls"


@pytest.mark.parametrize("precision", ["double", "float"])
def test_lane_sines_where_the_quadrant_changes_are_the_single_calls(tmp_path_factory, precision):
    """rg_sincos1 takes rg_sincos2's floor of 2x/pi + 1/2 by adding 2^52 (2^23) and its
    quadrant's choice and signs by bits, where rg_sincos2 converts to int and multiplies by 0
    and 1. The two must agree where they could part: angles a few units in the last place
    either side of (k + 1/2) pi/2, where the floor steps, and at k pi/2, +-0, tiny angles and
    the bound (past it, libm)."""
    import casadi as ca

    from robotgen.emit.sincos import ROUTINES
    from robotgen.symbolic.kernel import make_kernel

    real = np.float64 if precision == "double" else np.float32
    q = ca.SX.sym("q", 4)
    kernel = make_kernel("gravity", "sines", [("q", q)], [("gravity", ca.vertcat(ca.sin(q), ca.cos(q)), (8, 1))])
    module, _ = built(tmp_path_factory, f"lanes_quadrants_{precision}", [kernel], 4, ("gravity",), precision)
    edges = [real((k + 0.5) * np.pi / 2) for k in range(-9, 9)] + [real(k * np.pi / 2) for k in range(-8, 9)]
    angles = list(edges)
    for a in edges:
        below = above = a
        for _ in range(3):
            below, above = np.nextafter(below, real(-np.inf)), np.nextafter(above, real(np.inf))
            angles += [below, above]
    bound = real(ROUTINES[precision].above)
    tiny = real(1e-300 if precision == "double" else 1e-40)
    angles += [real(0.0), real(-0.0), tiny, -tiny, bound, -bound, np.nextafter(bound, real(np.inf))]
    rng = np.random.default_rng(9)
    n = 4 * 255
    chosen = rng.permutation(np.resize(np.array(angles, dtype=np.float64), n)).reshape(-1, 4)
    expected, failed = single_calls(module.gravity, [chosen], len(chosen), kernel.outputs)
    assert not failed
    assert np.all(np.abs(expected[0] - np.concatenate([np.sin(chosen), np.cos(chosen)], axis=1)) < 2e-7)
    assert_every_width_gives(module.gravity, chosen, expected[0])
    assert len(widths(module)) > 1 or not lanes_expected()


def test_a_singular_state_in_a_batch_is_zeroed_as_its_single_call(ur5):
    """Forward dynamics at a state where M's solve overflows returns status 2 and zeros, in a
    batch as alone; the other states of its block are written."""
    module, kernels = ur5
    fn = module.forward_dynamics
    rng = np.random.default_rng(4)
    q, qd, tau = rng.uniform(-1, 1, (16, 6)), rng.uniform(-1, 1, (16, 6)), rng.uniform(-1, 1, (16, 6))
    qd[5] = 1e200  # C qd overflows: the result is not finite
    for cap in WIDTHS:
        out = np.full((16, 6), -7.0)
        os.environ["ROBOTGEN_BATCH_LANES"] = str(cap)
        try:
            with pytest.raises(FloatingPointError, match="status 2"):
                fn(q, qd, tau, out=out)
        finally:
            del os.environ["ROBOTGEN_BATCH_LANES"]
        assert np.all(out[5] == 0.0)
        for k in (0, 4, 6, 15):
            assert np.array_equal(out[k], fn(q[k], qd[k], tau[k]))


def test_unbatched_arguments_apply_to_every_state(ur5):
    """dt without the batch axis is one step length for every state, as in the loop."""
    module, _ = ur5
    rng = np.random.default_rng(5)
    q, qd, tau = rng.uniform(-1, 1, (9, 6)), rng.uniform(-1, 1, (9, 6)), rng.uniform(-1, 1, (9, 6))
    batch = module.discrete_dynamics_derivatives(q, qd, tau, 0.01)
    for k in range(9):
        for b, s in zip(batch, module.discrete_dynamics_derivatives(q[k], qd[k], tau[k], 0.01)):
            assert np.array_equal(b[k], s)


@pytest.mark.parametrize("compiler", ["gcc", "clang"])
def test_the_batch_c_builds_pedantic_and_without_lanes(ur5, compiler, tmp_path):
    """The source with its lanes compiles warning-free as C99 -pedantic under gcc and clang, and
    with -DRG_NO_LANES (every state through the single-state function)."""
    if shutil.which(compiler) is None:
        pytest.skip(f"{compiler} is not installed")
    module, _ = ur5
    source = os.path.join(os.path.dirname(module.__file__), "lanes_ur5.c")
    for extra in ([], ["-DRG_NO_LANES"]):
        result = subprocess.run(
            [
                compiler,
                "-std=c99",
                "-pedantic",
                "-Wall",
                "-Wextra",
                "-Werror",
                "-O1",
                *extra,
                "-c",
                source,
                "-o",
                str(tmp_path / "lanes.o"),
            ],
            capture_output=True,
            text=True,
        )
        assert result.returncode == 0, result.stderr[-3000:]


def test_past_12_coordinates_a_batch_is_a_loop_of_single_calls(tmp_path_factory):
    """An 18-joint tree (its kernels loops through parent tables) gets the batch entry points
    without lanes: width 1 at every cap, the single calls' bits."""
    t = branched_tree(4, (-1, 0, 1, 2, 1, 4, 5, 6, 0, 8, 9, 10, 9, 12, 13, -1, 15, 16))
    module, kernels = built(tmp_path_factory, "lanes_long_tree", leaf_kernels(t), t.nq, ("mass", "forward_dynamics"))
    assert "RG_LANES_X86" not in open(os.path.join(os.path.dirname(module.__file__), "lanes_long_tree.c")).read()
    assert assert_batch_is_single_calls(module, kernels, lanes.BATCH_FUNCTIONS, (1, 9), np.random.default_rng(7)) == [1]


@pytest.mark.parametrize("compiler", ["gcc", "clang"])
def test_a_users_build_in_gnu_mode_keeps_the_bits(ur5, compiler, tmp_path):
    """Built as a user might (-O2, GNU C, where GCC fuses multiply-adds and AVX-512F has them;
    Clang fuses within an expression), every width still gives the single calls' bits: the lane
    code turns contraction off itself. bench/batch.py's harness compares them with memcmp."""
    import json
    import sys

    from conftest import ROOT

    if shutil.which(compiler) is None:
        pytest.skip(f"{compiler} is not installed")
    sys.path.insert(0, str(ROOT / "bench"))
    try:
        import batch as bench_batch
    finally:
        sys.path.remove(str(ROOT / "bench"))
    module, _ = ur5
    out = os.path.dirname(module.__file__)
    manifest = json.loads(open(os.path.join(out, "manifest.json")).read())
    (tmp_path / "check.c").write_text(bench_batch.harness("lanes_ur5", "double", manifest["functions"], 1))
    exe = tmp_path / "check"
    subprocess.run(
        [
            compiler,
            "-O2",
            "-std=gnu99",
            "-I",
            out,
            str(tmp_path / "check.c"),
            os.path.join(out, "lanes_ur5.c"),
            "-lm",
            "-o",
            str(exe),
        ],
        check=True,
    )
    result = subprocess.run([str(exe)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["widths"] == widths(module)


def test_float_batches_are_single_calls_bit_for_bit(tmp_path_factory):
    """--precision float: 16 and 8 floats a vector, sinf and cosf lane by lane."""
    system = load_urdf_system(str(robots_dir() / UR5[0]), UR5[1])
    module, kernels = built(
        tmp_path_factory,
        "lanes_ur5f",
        kernels_for(system),
        system_nq(system),
        ("mass", "forward_dynamics"),
        precision="float",
    )
    assert_batch_is_single_calls(
        module, kernels, lanes.BATCH_FUNCTIONS, (1, 15, 16, 17, 1023), np.random.default_rng(6)
    )


def test_a_tree_specs_plant_reads_the_parameters_in_every_lane(build_module):
    """specs/styx_squeeze.yaml: a robot tree whose plant_dynamics reads run-time parameters (the
    box's mass: one struct for every state of the batch), with the default and with a value passed."""
    import json

    from conftest import SPECS

    module = build_module(SPECS / "styx_squeeze.yaml")
    manifest = json.loads(open(os.path.join(os.path.dirname(module.__file__), "manifest.json")).read())
    plant = next(f for f in manifest["functions"] if f["name"] == "plant_dynamics")
    assert plant["reads_parameters"]
    name, value = next((k, v) for k, v in module.parameters.items() if "mass" in k)
    rng = np.random.default_rng(8)
    n = 19
    arrays = [rng.uniform(-0.5, 0.5, (n, *p["shape"])) for p in plant["inputs"]]
    for keywords in ({}, {name: value * 1.25}):
        single = [module.plant_dynamics(*(a[k] for a in arrays), **keywords) for k in range(n)]
        for cap in WIDTHS:
            os.environ["ROBOTGEN_BATCH_LANES"] = str(cap)
            try:
                batch = module.plant_dynamics(*arrays, **keywords)
            finally:
                del os.environ["ROBOTGEN_BATCH_LANES"]
            for j, part in enumerate(batch):
                for k in range(n):
                    assert part[k].tobytes() == single[k][j].tobytes(), (keywords, cap, j, k)
    changed = module.plant_dynamics(*arrays, **{name: value * 1.25})
    assert any(not np.array_equal(a, b) for a, b in zip(changed, module.plant_dynamics(*arrays))), name
