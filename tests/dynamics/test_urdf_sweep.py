"""Every URDF of example-robot-data and pybullet_data, as found (tests/urdf_sweep.py):
built as a tree and as a chain to its deepest link, compared with Pinocchio, every refusal
listed in docs/robots.md with its reason.

`make test` keeps a sample: a few files that exercise what issue 33 made readable (each
against Pinocchio to 1e-12), and the refusals that docs/robots.md lists (each file still
refused as the table says). `make test-slow` sweeps every file: the whole tables must be what
`python tests/urdf_sweep.py --write` writes, and every build must agree with Pinocchio."""

from __future__ import annotations

import pytest
import urdf_sweep as sweep

TOL = 1e-12

# (collection, file, what it shows, the builds that Pinocchio must agree with)
SAMPLE = [
    (
        "example-robot-data",
        "anymal_b_simple_description/robots/anymal.urdf",
        "pybullet's <contact> skipped",
        ("tree", "chain"),
    ),
    ("example-robot-data", "iris_description/robots/iris.urdf", "limits of 1e16: no limit", ("tree", "chain")),
    ("example-robot-data", "so_arm_description/urdf/so101.urdf", "an <origin> in a link skipped", ("tree", "chain")),
    (
        "example-robot-data",
        "ur_description/urdf/ur5_robot.urdf",
        "rpy 1.57079632679 kept, not snapped",
        ("tree", "chain"),
    ),
    (
        "example-robot-data",
        "romeo_description/urdf/romeo_laas_small.urdf",
        "rpy of 1e-8 .. 1e-11 kept; the tree has a bad inertia",
        ("chain",),
    ),
    ("pybullet_data", "differential/diff_ring.urdf", "a declaration after whitespace", ("tree", "chain")),
    ("pybullet_data", "cube_no_rotation.urdf", 'pybullet\'s lower="1" upper="-1"', ("tree", "chain")),
    ("pybullet_data", "r2d2.urdf", "<joint_properties> with 0 damping and friction", ("tree", "chain")),
]


def _source(source: str):
    if source not in sweep.sources():
        pytest.skip(f"{source} is not installed (pip install pybullet)")
    return sweep.sources()[source]


def _agrees(r: sweep.Read, builds) -> dict[str, float]:
    assert r.structure is not None
    worst: dict[str, float] = {}
    for kind in builds:
        system = r.tree if kind == "tree" else r.chain
        assert not isinstance(system, str) and system is not None, (kind, system)
        expected = r.structure.tree_joints() if kind == "tree" else r.structure.chain_joints(r.tip)
        for key, e in sweep.compare(system, r.path, expected, r.structure).items():
            worst[f"{kind} {key}"] = e
    return worst


@pytest.mark.parametrize("source, name, shows, builds", SAMPLE, ids=[s[1].split("/")[-1] for s in SAMPLE])
def test_a_sample_builds_unmodified_and_agrees_with_pinocchio(source, name, shows, builds):
    r = sweep.read(source, _source(source) / name)
    worst = _agrees(r, builds)
    print(name, {k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) <= TOL, worst


@pytest.mark.parametrize("source", ["example-robot-data", "pybullet_data"])
def test_the_files_docs_robots_md_names_are_read_as_it_says(source):
    """Every refusal row and every file without a movable joint in the table is what the
    readers make of those files today (the counts line is the slow sweep's)."""
    _source(source)
    reads = [sweep.read(source, path) for path in sweep.documented_files(source)]
    documented = sweep.current_section(source).split("\n")[3:]
    assert sweep.body(reads) == documented


@pytest.mark.slow
@pytest.mark.parametrize("source", ["example-robot-data", "pybullet_data"])
def test_every_file_is_swept_and_the_table_is_current(source):
    """The whole section of docs/robots.md, counts included, is the sweep's; every file that
    builds (as a tree and as a chain) agrees with Pinocchio to 1e-12."""
    _source(source)
    reads = sweep.read_all(source)
    assert sweep.table(source, reads) == sweep.current_section(source), (
        "docs/robots.md is out of date: python tests/urdf_sweep.py --write"
    )
    worst: dict[str, float] = {}
    for r in reads:
        if r.builds:
            worst[r.name] = max(_agrees(r, ("tree", "chain")).values())
    print(f"{len(worst)} builds; worst {max(worst.values()):.1e} in {max(worst, key=worst.get)}")
    assert worst and max(worst.values()) <= TOL, {k: v for k, v in worst.items() if v > TOL}
