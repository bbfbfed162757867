"""The speed measures keep the numbers: snapped constants, the O(n^2) spatial Coriolis
matrix, the fused servo terms, and the content-hash build cache."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
from robots import PANDA, UR5, robots_dir
from test_tree_pinocchio import pinocchio_model, random_tree

from robotgen.cli import main
from robotgen.frontend.urdf import read_urdf
from robotgen.model.snap import noise_bound, snap_axis, snap_rotation, snap_tree
from robotgen.numeric import exact
from robotgen.symbolic.leaf_kernels import leaf_kernels
from robotgen.symbolic.op_count import count_operations
from robotgen.symbolic.rigid_body.base_turn import base_axis, turned
from robotgen.symbolic.rigid_body.chain import ChainGraphs, Symbols
from robotgen.symbolic.rigid_body.kinematics import forward_kinematics

TWO_LINK = Path(__file__).resolve().parents[2] / "specs" / "two_link.yaml"


def test_snapping_removes_only_noise():
    """Panda's rpy of pi/2 (1.5707963267948966) leaves 6e-17 in every joint rotation: snapped
    away, with fewer operations, and every quantity of the snapped model equals the unsnapped
    one to the rounding. The UR5's 1.57079632679 leaves 4.9e-12, which is what its file says:
    kept (model/snap.py)."""
    tree = read_urdf(str(robots_dir() / PANDA[0]), PANDA[1]).tree
    snapped = snap_tree(tree)
    noise = max(np.abs(a.origin - b.origin).max() for a, b in zip(tree.joints, snapped.joints))
    assert 0 < noise <= noise_bound(1.0) == 4 * 2.0**-52
    n = tree.nq
    raw_sym, snap_sym = Symbols.make(n), Symbols.make(n)
    raw = ChainGraphs(tree, raw_sym, snap=False)
    new = ChainGraphs(tree, snap_sym)
    for name in ("mass", "gravity", "fk", "jacobian"):
        f_raw = ca.Function("a", [raw_sym.q], [getattr(raw, name)()])
        f_new = ca.Function("b", [snap_sym.q], [getattr(new, name)()])
        assert (
            count_operations([snap_sym.q], [getattr(new, name)()])["total"]
            < count_operations([raw_sym.q], [getattr(raw, name)()])["total"]
        ), name
        for q in np.random.default_rng(0).uniform(-2, 2, (20, n)):
            np.testing.assert_allclose(np.array(f_new(q)), np.array(f_raw(q)), rtol=0, atol=1e-14, err_msg=name)
    ur5 = read_urdf(str(robots_dir() / UR5[0]), UR5[1]).tree
    small = [j.name for j in ur5.joints if np.any((np.abs(j.origin[:3, :3]) > 0) & (np.abs(j.origin[:3, :3]) < 1e-11))]
    assert small == ["shoulder_lift_joint", "wrist_1_joint"]  # rpy 1.57079632679: entries of 4.9e-12
    ur5_snapped = snap_tree(ur5)
    for a, b in zip(ur5.joints, ur5_snapped.joints):
        np.testing.assert_array_equal(a.origin, b.origin)
        np.testing.assert_array_equal(a.axis, b.axis)
    np.testing.assert_array_equal(ur5.tool, ur5_snapped.tool)


def test_snapping_bounds():
    """Entries within 4 units in the last place of 1 (rotations, axes) or of the translation's
    largest entry snap to 0 or +-1; a rotation entry of 1e-9 or a translation entry of 1e-9 m
    beside 0.3 m stays."""
    c, s = np.cos(np.pi / 2), np.sin(np.pi / 2)  # 6.1e-17, 1.0
    T = np.eye(4)
    T[:3, :3] = [[1, 0, 0], [0, c, -s], [0, s, c]]
    T[:3, 3] = [0.3, 3e-17, 0.0]
    snapped = snap_rotation(T)
    np.testing.assert_array_equal(snapped[:3, :3], [[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    np.testing.assert_array_equal(snapped[:3, 3], [0.3, 0.0, 0.0])
    t = 1e-9
    T[:3, :3] = [[1, 0, 0], [0, np.cos(t), -np.sin(t)], [0, np.sin(t), np.cos(t)]]
    T[:3, 3] = [0.3, 1e-9, 0.0]
    np.testing.assert_array_equal(snap_rotation(T), T)
    np.testing.assert_array_equal(snap_axis(np.array([1e-9, 0.0, 1.0])), exact.unit(np.array([1e-9, 0.0, 1.0])))
    np.testing.assert_array_equal(snap_axis(np.array([4e-16, 0.0, 1.0 - 2**-53])), [0.0, 0.0, 1.0])
    assert noise_bound(0.3) == 4 * np.spacing(0.3)


def test_every_coriolis_form_equals_pinocchio():
    """The three forms ChainGraphs.coriolis picks from, on a branched tree (the forces'
    form with the q_i that M does not read set to 0) and on the Panda."""
    for tree in (random_tree(4), read_urdf(str(robots_dir() / PANDA[0]), PANDA[1]).tree):
        n = tree.nq
        sym = Symbols.make(n)
        candidates = ChainGraphs(tree, sym).coriolis_candidates()
        assert sorted(candidates) == ["christoffel", "forces", "spatial"]
        f = ca.Function("c", [sym.q, sym.qd], list(candidates.values()))
        model, _ = pinocchio_model(tree)
        data = model.createData()
        for q, qd in np.random.default_rng(5).normal(size=(20, 2, n)):
            expected = pin.computeCoriolisMatrix(model, data, q, qd)
            for name, C in zip(candidates, f(q, qd)):
                np.testing.assert_allclose(
                    np.array(C), expected, atol=1e-12 * max(1, np.abs(expected).max()), err_msg=name
                )


def test_fused_servo_terms_equal_the_separate_functions():
    tree = read_urdf(str(robots_dir() / PANDA[0]), PANDA[1]).tree
    k = {kern.name: kern.function for kern in leaf_kernels(tree)}
    n = tree.nq
    for q, qd in np.random.default_rng(2).normal(size=(10, 2, n)):
        M, h, J, a = (np.array(x).ravel() for x in k["servo_terms"](q, qd))
        np.testing.assert_array_equal(M, np.array(k["mass"](q)).ravel())
        np.testing.assert_array_equal(h, np.array(k["nonlinear"](q, qd)).ravel())
        np.testing.assert_array_equal(J, np.array(k["jacobian"](q)).ravel())
        np.testing.assert_array_equal(a, np.array(k["jacobian_dot_qd"](q, qd)).ravel())


def test_the_first_joints_turn_factored_out_changes_nothing():
    """fk, J and Jdot qd at q_0 = 0 turned by R(q_0) equal the direct forms, on a branched
    tree whose first axis is oblique and passes through the base origin (gravity not along
    it), on the UR5 and on the Panda; a first axis off the origin has no such turn."""
    tree = random_tree(7)
    assert base_axis(tree) is None  # its first joint sits off its axis line through the origin
    first = tree.joints[0]
    origin = first.origin.copy()
    origin[:3, 3] = 0.4 * (origin[:3, :3] @ first.axis)
    oblique = replace(tree, joints=(replace(first, origin=origin), *tree.joints[1:]))
    for t in (
        oblique,
        read_urdf(str(robots_dir() / UR5[0]), UR5[1]).tree,
        read_urdf(str(robots_dir() / PANDA[0]), PANDA[1]).tree,
    ):
        n = t.nq
        sym = Symbols.make(n)
        g = ChainGraphs(t, sym)
        assert base_axis(g.tree) is not None
        direct = [forward_kinematics(g.tree, sym.q), g._jacobian_direct(), g._jacobian_dot_qd_direct()]
        turn = [turned(g.tree, sym.q, direct[0], 0), g._turned("jacobian"), g._turned("jacobian_dot_qd")]
        f = ca.Function("f", [sym.q, sym.qd], direct + turn)
        for q, qd in np.random.default_rng(3).normal(size=(20, 2, n)):
            out = [np.array(x) for x in f(q, qd)]
            for a, b in zip(out[:3], out[3:]):
                np.testing.assert_allclose(b, a, atol=1e-13 * max(1.0, np.abs(a).max()))


def test_unchanged_spec_is_not_rebuilt(tmp_path, capsys):
    spec = tmp_path / "two_link.yaml"
    spec.write_text(TWO_LINK.read_text())
    out = tmp_path / "out"
    assert main(["build", str(spec), "-o", str(out)]) == 0
    so = next(out.glob("two_link*.so"))
    stamp = so.stat().st_mtime_ns
    capsys.readouterr()
    assert main(["build", str(spec), "-o", str(out)]) == 0
    assert "up to date" in capsys.readouterr().out
    assert so.stat().st_mtime_ns == stamp
    spec.write_text(spec.read_text().replace("robotgen: 1", "robotgen: 1\n# edited"))
    assert main(["build", str(spec), "-o", str(out)]) == 0
    assert "built two_link" in capsys.readouterr().out


def test_build_refuses_to_replace_a_foreign_directory(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    assert main(["build", str(TWO_LINK), "-o", str(out)]) == 1
    assert "refusing to replace" in capsys.readouterr().err
    assert (out / "notes.txt").read_text() == "keep me"


def test_module_takes_arrays_of_any_layout(build_module):
    """Contiguous float64 arrays are used in place (the servo-loop fast path); anything else
    (read-only, strided, float32, lists, big-endian) is converted and gives the same numbers."""
    mod = build_module(TWO_LINK)
    q = np.array([0.3, -0.7])
    expected = mod.mass(q)
    ro = q.copy()
    ro.flags.writeable = False
    strided = np.array([0.3, 9.0, -0.7, 9.0])[::2]
    for variant in (ro, strided, list(q), q.astype(">f8")):
        np.testing.assert_array_equal(mod.mass(variant), expected)
    np.testing.assert_allclose(mod.mass(q.astype(np.float32)), expected, rtol=1e-6)
