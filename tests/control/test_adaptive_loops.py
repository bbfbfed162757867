"""The adaptive step as loops (robotgen.symbolic.root_laws.adaptive_loops) computes what its
straight-line graph (resolved_adaptive.step_graph) computes, bit for bit, over successive
periods that move A, B, c and P, for every form of the weights and the identification: the
weight rule with run-time or folded gains, a given Q (diagonal by blocks, or full) and R, no
affine term, and eq 37's forgetting with its trace limit; so does the reset's state, its
discretisation (eqs 29-32) as loops, against resolved_adaptive.initial_state. The emitted C
of four of them (compiled warning-free by the build) gives the same numbers."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from robotgen.frontend import load_system
from robotgen.model.parameter_struct import runtime_parameters
from robotgen.symbolic.root_laws import resolved_adaptive as ra
from robotgen.symbolic.root_laws.hand import Hand

RMAC = Path(__file__).resolve().parents[2] / "specs" / "puma560_rmac.yaml"
ANCHOR = "        tool: {xyz: [0, 0, 0.1], rpy: [0, pi/2, 0]}   # hand x along the tool: pitch 0 at the start\n"
L = np.tril(np.arange(1.0, 37.0).reshape(6, 6)) / 10 + np.eye(6)
Q = np.eye(12) * 2.0 + np.diag(np.full(11, 0.5), 1) + np.diag(np.full(11, 0.5), -1)


def _rows(matrix: np.ndarray) -> str:
    return "".join(f"          - [{', '.join(repr(float(v)) for v in row)}]\n" for row in matrix)


COMPILED = ("defaults", "eq 37's forgetting", "given q and r, no affine term", "full q")
SETTINGS = {
    "defaults": "",
    "folded gains": "        gains: folded\n",
    "given q and r, no affine term": "        q: [1e5, 1e5, 1, 1]\n        r:\n"
    + _rows(L @ L.T)
    + "        affine: false\n",
    "full q": "        q:\n" + _rows(Q),
    "eq 37's forgetting": "        directional: false\n        covariance_limit: 12.1\n",
}


CASES = [(case, case in COMPILED) for case in SETTINGS]


@pytest.mark.parametrize("case,compiled", CASES)
def test_the_looped_step_is_the_straight_line_step(tmp_path, build_module, case, compiled):
    text = RMAC.read_text()
    assert ANCHOR in text and "name: puma560_rmac\n" in text
    name = "rmac_loops_" + str(list(SETTINGS).index(case))
    path = tmp_path / f"{name}.yaml"
    path.write_text(text.replace(ANCHOR, ANCHOR + SETTINGS[case]).replace("name: puma560_rmac\n", f"name: {name}\n"))
    system = load_system(str(path))
    kernels = {k.name: k for k in ra.kernels(system)}
    step, init = kernels[ra.STEP], kernels[ra.INIT]
    assert step.schedule is not None and len(step.schedule.loops) >= 10
    inputs, outputs, parameters = ra.step_graph(system)
    symbols = [i[1] for i in inputs] + ([parameters.vector] if parameters.parameters else [])
    straight = ca.Function("straight", symbols, [ca.vec(o[1].T) for o in outputs])
    assert step.function.n_in() == straight.n_in()
    extra = [np.concatenate([np.ravel(p.default) for p in runtime_parameters(system)])] if parameters.parameters else []
    pose = kernels["hand_pose"].function
    q = np.array([0.1, 0.5, -0.3, 0.2, 0.4, -0.1])
    pose_d = np.ravel(np.array(pose(q)))
    zero = np.zeros(6)
    # the reset's state, its discretisation as loops, against initial_state's graph
    assert init.schedule is not None
    hand = Hand(system.tree(system.root_control.robot), system.root_control.adaptive.tool)
    i = ra.Inputs()
    reset = ca.Function("reset", [p[1] for p in i.ports()], [ra.initial_state(hand, system.root_control.adaptive, i)])
    for q_k in (q, q[::-1]):
        looped_state = np.array(init.function(q_k, 0.1 * q_k, pose_d, zero, zero)).ravel()
        expected_state = np.array(reset(q_k, 0.1 * q_k, pose_d, zero, zero)).ravel()
        assert np.all(np.isfinite(expected_state))
        assert np.array_equal(looped_state.view(np.uint64), expected_state.view(np.uint64))
    state = np.array(init.function(q, zero, pose_d, zero, zero)).ravel()
    if compiled:
        emitted_state = np.ravel(build_module(str(path)).adaptive_init(q, zero, pose_d.reshape(4, 4), zero, zero))
        np.testing.assert_allclose(emitted_state, state, rtol=1e-12, atol=1e-12 * max(1.0, np.max(np.abs(state))))
    for k in range(6):  # the state moves: A, B, c and P identified, phi the last period's
        q_k = q + 1e-3 * np.sin(np.arange(6) + k)
        qd_k = 1e-2 * np.cos(np.arange(6) * (k + 1))
        looped = [np.array(x).ravel() for x in step.function(q_k, qd_k, pose_d, zero, zero, state, 1.0, *extra)]
        expected = [np.array(x).ravel() for x in straight(q_k, qd_k, pose_d, zero, zero, state, 1.0, *extra)]
        for name, a, b in zip(("tau", "dx", "state_next"), looped, expected):
            assert np.all(np.isfinite(b)), name
            assert np.array_equal(a.view(np.uint64), b.view(np.uint64)), (k, name, np.max(np.abs(a - b)))
        assert not np.array_equal(looped[2], state)  # the identification moved
        if compiled:
            module = build_module(str(path))
            emitted = module.adaptive_step(q_k, qd_k, pose_d.reshape(4, 4), zero, zero, state=state, adapt=1.0)
            for name, a, b in zip(("tau", "dx", "state_next"), emitted, expected):
                np.testing.assert_allclose(np.ravel(a), b, rtol=1e-12, atol=1e-12 * max(1.0, np.max(np.abs(b))))
        state = looped[2]
