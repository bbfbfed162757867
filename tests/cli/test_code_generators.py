"""The code-generating peers of `make bench` (bench/code_generators.py, bench/peers/): what the
agreement check expects of a peer is Pinocchio's result on the peers' model, the harness finds a
peer that disagrees, and, where the peers' packages are installed, their generated C agrees
with robotgen's kernels on the harness's 256 states."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from conftest import ROOT

sys.path.insert(0, str(ROOT / "bench"))

import run  # noqa: E402
from peers import arms, harness, pinocchio_cg  # noqa: E402
from peers import casadi_kin_dyn_peer as casadi_kin_dyn  # noqa: E402

QUICK = ["-std=c99", "-O1", "-ffp-contract=off"]  # an agreement check needs no -O2


@pytest.fixture(scope="module")
def panda(tmp_path_factory):
    """The Panda: locked fingers and joint damping, what the peers' model differs in."""
    return arms.build("panda", tmp_path_factory.mktemp("arms"))


@pytest.fixture(scope="module")
def ur5(tmp_path_factory):
    return arms.build("ur5", tmp_path_factory.mktemp("arms"))


def test_the_check_expects_pinocchio_on_the_peers_model(panda):
    """harness.reference (robotgen's module, its damping taken out, in each layout a peer
    writes) equals Pinocchio's algorithms on the URDF the peers read (fingers fixed)."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(panda.model_urdf))
    data = model.createData()
    assert model.nq == panda.nq == 7 and panda.locked and max(panda.damping) > 0
    rng = np.random.default_rng(7)
    n = panda.nq
    x = np.hstack([rng.uniform(-np.pi, np.pi, (5, n)), rng.uniform(-2, 2, (5, 2 * n))])
    ref = harness.reference(panda, x)
    upper = np.triu_indices(n)
    for s, (q, v, u) in enumerate(zip(x[:, :n], x[:, n : 2 * n], x[:, 2 * n :])):
        mass = pin.crba(model, data, q)[upper]
        minv = pin.computeMinverse(model, data, q)
        minv = np.triu(minv) + np.triu(minv, 1).T
        tau = pin.rnea(model, data, q, v, u).copy()
        ddq = pin.aba(model, data, q, v, u).copy()
        dq, dv, da = (m.copy() for m in pin.computeRNEADerivatives(model, data, q, v, u))
        da = np.triu(da) + np.triu(da, 1).T  # M; the code generation's writes its upper triangle
        fq, fv, ft = (m.copy() for m in pin.computeABADerivatives(model, data, q, v, u))
        ft = np.triu(ft) + np.triu(ft, 1).T
        want = {
            "mass_upper": mass,
            "mass_inverse_upper": minv[upper],
            "mass_inverse": minv.ravel(),
            "tau": tau,
            "ddq": ddq,
            "dtau_dq_dv": np.hstack([dq.ravel(), dv.ravel()]),
            "dtau_dq_dv_da": np.hstack([dq.ravel(), dv.ravel(), np.triu(da).ravel()]),
            "rnea_jacobian": np.hstack([dq, dv, da]).ravel(),
            "dddq": np.hstack([fq.ravel(), fv.ravel(), ft.ravel()]),
            "aba_jacobian": np.hstack([fq, fv, ft]).ravel(),
        }
        for layout, value in want.items():
            assert harness.relative_difference(ref[layout][s], value) < 1e-10, layout


FAKE_PEER = """/* two peers in CasADi's calling convention, made of robotgen's own kernel: one without the
   joint damping (as a peer's model has none), one with it (so it disagrees) */
int panda_inverse_dynamics(const double *q, const double *qd, const double *qdd, double *tau);
static const double D[7] = {%s};
int fake_rnea(const double **arg, double **res, long long int *iw, double *w, int mem) {
    int i;
    (void)iw; (void)w; (void)mem;
    panda_inverse_dynamics(arg[0], arg[1], arg[2], res[0]);
    for (i = 0; i < 7; i++) res[0][i] -= D[i] * arg[1][i];
    return 0;
}
int fake_rnea_damped(const double **arg, double **res, long long int *iw, double *w, int mem) {
    (void)iw; (void)w; (void)mem;
    return panda_inverse_dynamics(arg[0], arg[1], arg[2], res[0]);
}
"""


def test_the_harness_finds_a_peer_that_disagrees(panda, tmp_path):
    source = tmp_path / "fake_peer.c"
    source.write_text(FAKE_PEER % ", ".join(repr(d) for d in panda.damping))
    fakes = [
        pinocchio_cg.PeerFunction(
            "inverse_dynamics",
            "casadi_kin_dyn",
            name,
            name,
            source,
            "casadi",
            "tau",
            7,
            out_sizes=(7,),
            work=(3, 1, 0, 0),
        )
        for name in ("fake_rnea", "fake_rnea_damped")
    ]
    exe, rows = harness.build(panda, fakes, tmp_path / "harness", QUICK)
    assert [(r["who"], r["kernel"]) for r in rows[:6]] == [("robotgen", k) for k in harness.KERNELS]
    differences = dict(zip([r["variant"] for r in rows], harness.check(panda, exe, rows)))
    assert all(differences[k] == 0 for k in harness.KERNELS)  # robotgen's C is its module's
    assert differences["fake_rnea"] < 1e-14
    assert differences["fake_rnea_damped"] > 1e-5  # 0.003 qd of torques of tens of N m
    timed = harness.time_rounds(exe, rows, 1, ["inverse_dynamics"])
    assert len(timed) == 3 and all(t["ns_min"] > 0 and t["iterations"] >= 1000 for t in timed)


def _agree(arm, peers, tmp_path):
    exe, rows = harness.build(arm, peers, tmp_path / "harness", QUICK)
    differences = harness.check(arm, exe, rows)
    bad = {(r["who"], r["variant"], r["kernel"]): d for r, d in zip(rows, differences) if not d <= harness.CHECK_TOL}
    assert bad == {}
    assert {r["kernel"] for r in rows if r["who"] != "robotgen"} == set(harness.KERNELS)


def test_casadi_kin_dyn_agrees_with_robotgen(request, tmp_path):
    try:
        casadi_kin_dyn.version()
    except pinocchio_cg.PeerUnavailable as e:
        pytest.skip(f"casadi_kin_dyn is installed by `make bench` only: {e}")
    ur5 = request.getfixturevalue("ur5")
    peers, _ = casadi_kin_dyn.functions(ur5.name, ur5.model_urdf)
    assert len(peers) == 9
    _agree(ur5, peers, tmp_path)


@pytest.mark.slow  # Pinocchio's generator compiles in ~5 minutes (once: cached in bench/out/peers/)
def test_pinocchio_codegen_agrees_with_robotgen(ur5, tmp_path):
    try:
        gen = pinocchio_cg.Generator(run.pinocchio_toolchain(run.cmeel_prefix()))
        peers = gen.functions(ur5.name, ur5.model_urdf, ur5.nq)
    except (pinocchio_cg.PeerUnavailable, run.ToolchainError) as e:
        pytest.skip(f"Pinocchio's code generation needs the packages `make bench` installs: {e}")
    assert len(peers) == len(pinocchio_cg.VARIANTS)
    _agree(ur5, peers, tmp_path)


def test_with_fixed_joints_fixes_only_the_locked():
    urdf = """<robot name="r"><link name="a"/><link name="b"/><link name="c"/>
      <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
        <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      <joint name="f1" type="prismatic"><parent link="b"/><child link="c"/><axis xyz="0 1 0"/>
        <limit lower="0" upper="0.04" effort="1" velocity="1"/><dynamics damping="0.1"/></joint></robot>"""
    out = arms.with_fixed_joints(urdf, ["f1"])
    assert '<joint name="f1" type="fixed"><parent link="b" /><child link="c" /></joint>' in out
    assert '<joint name="j1" type="revolute">' in out and '<axis xyz="0 0 1" />' in out
