"""URDF leaves against Pinocchio on real robots (UR5, Panda with its fingers locked):
the generated module's fk, Jacobian, M, gravity, C, inverse and forward dynamics on 1000
random states each, max relative error <= 1e-9."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from robots import PANDA, UR5, build_urdf, robots_dir

N_STATES = 1000
TOL = 1e-9


def rel_err(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


@pytest.fixture(scope="module", params=[UR5 + ("ur5_pin",), PANDA + ("panda_pin",)], ids=["ur5", "panda"])
def robot(request, tmp_path_factory):
    urdf, tip, name = request.param
    path = robots_dir() / urdf
    module = build_urdf(path, tip, name, tmp_path_factory.mktemp(name))
    model = pin.buildModelFromUrdf(str(path))
    # Pinocchio's model has the fingers; lock them at 0 as robotgen does off the chain.
    locked = [model.getJointId(n) for n in module.info()["nodes"][name]["locked_joints"]]
    if locked:
        model = pin.buildReducedModel(model, locked, pin.neutral(model))
    assert model.nq == module.nq
    return module, model, tip


def states(model, n: int, seed: int):
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(model.lowerPositionLimit), model.lowerPositionLimit, -np.pi)
    hi = np.where(np.isfinite(model.upperPositionLimit), model.upperPositionLimit, np.pi)
    q = rng.uniform(lo, hi, size=(n, model.nq))
    return q, rng.normal(size=q.shape) * 2.0, rng.normal(size=q.shape) * 5.0


def test_damping_is_viscous_friction(robot):
    module, model, _ = robot
    joints = next(iter(module.info()["nodes"].values()))["joints"]
    for j in joints:
        assert j["viscous"] == j["damping"]


def test_against_pinocchio(robot):
    module, model, tip = robot
    data = model.createData()
    fid = model.getFrameId(tip)
    name = next(iter(module.info()["nodes"]))
    damping = np.array([j["damping"] for j in module.info()["nodes"][name]["joints"]])
    q, qd, qdd = states(model, N_STATES, 7)
    fk, J = module.fk(q), module.jacobian(q)
    M, g, C = module.mass(q), module.gravity(q), module.coriolis(q, qd)
    tau = module.inverse_dynamics(q, qd, qdd)
    h = module.nonlinear(q, qd)
    worst = {}
    for k in range(N_STATES):
        pin.framesForwardKinematics(model, data, q[k])
        Mp = pin.crba(model, data, q[k])
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        tau_p = pin.rnea(model, data, q[k], qd[k], qdd[k]) + damping * qd[k]
        errs = {
            "fk": rel_err(fk[k], data.oMf[fid].homogeneous),
            "jacobian": rel_err(J[k], pin.computeFrameJacobian(model, data, q[k], fid, pin.LOCAL_WORLD_ALIGNED)),
            "mass": rel_err(M[k], Mp),
            "gravity": rel_err(g[k], pin.computeGeneralizedGravity(model, data, q[k])),
            "coriolis": rel_err(C[k], pin.computeCoriolisMatrix(model, data, q[k], qd[k])),
            "inverse_dynamics": rel_err(tau[k], tau_p),
            "nonlinear": rel_err(h[k], pin.nonLinearEffects(model, data, q[k], qd[k]) + damping * qd[k]),
        }
        for key, e in errs.items():
            worst[key] = max(worst.get(key, 0.0), e)
    # forward dynamics: Pinocchio's ABA with the damping torque removed from tau
    tau_in = np.random.default_rng(3).normal(size=q.shape) * 20
    qdd_rg = module.forward_dynamics(q, qd, tau_in)
    for k in range(N_STATES):
        qdd_p = pin.aba(model, data, q[k], qd[k], tau_in[k] - damping * qd[k])
        worst["forward_dynamics"] = max(worst.get("forward_dynamics", 0.0), rel_err(qdd_rg[k], qdd_p))
    print({k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) <= TOL, worst


def test_derivatives_against_pinocchio(robot):
    """d tau/dq, d tau/dqd (computeRNEADerivatives), d qdd/dq, d qdd/dqd, M^-1
    (computeABADerivatives), mass_inverse and the Jacobian's time derivative
    (getFrameJacobianTimeVariation) on 1000 random states, <= 1e-9 relative, and the
    semi-implicit Euler step's A and B by the chain rule on Pinocchio's. Pinocchio has
    no joint damping: it adds diag(damping) to d tau/dqd, and -M^-1 diag(damping) to
    d qdd/dqd with tau - damping qd as Pinocchio's torque."""
    module, model, tip = robot
    data = model.createData()
    fid = model.getFrameId(tip)
    name = next(iter(module.info()["nodes"]))
    D = np.diag([j["damping"] for j in module.info()["nodes"][name]["joints"]])
    q, qd, x = states(model, N_STATES, 11)
    dtau_dq, dtau_dqd = module.inverse_dynamics_derivatives(q, qd, x)
    dqdd_dq, dqdd_dqd, dqdd_dtau = module.forward_dynamics_derivatives(q, qd, x)
    Minv, Jdot = module.mass_inverse(q), module.jacobian_derivative(q, qd)
    worst: dict[str, float] = {}
    for k in range(N_STATES):
        pin.computeRNEADerivatives(model, data, q[k], qd[k], x[k])
        errs = {"dtau_dq": rel_err(dtau_dq[k], data.dtau_dq), "dtau_dqd": rel_err(dtau_dqd[k], data.dtau_dv + D)}
        pin.computeABADerivatives(model, data, q[k], qd[k], x[k] - D @ qd[k])
        Minv_p = np.triu(data.Minv) + np.triu(data.Minv, 1).T
        Fq, Fqd = data.ddq_dq, data.ddq_dv - Minv_p @ D
        errs |= {
            "dqdd_dq": rel_err(dqdd_dq[k], Fq),
            "dqdd_dqd": rel_err(dqdd_dqd[k], Fqd),
            "dqdd_dtau": rel_err(dqdd_dtau[k], Minv_p),
            "mass_inverse": rel_err(Minv[k], Minv_p),
        }
        # qd1 = qd + dt qdd(q, qd, tau), q1 = q + dt qd1
        dt, eye = 0.01, np.eye(model.nq)
        _, _, A, B = module.discrete_dynamics_derivatives(q[k], qd[k], x[k], dt)
        dqd1 = np.hstack([dt * Fq, eye + dt * Fqd])
        errs["discrete_A"] = rel_err(A, np.vstack([np.hstack([eye, np.zeros_like(eye)]) + dt * dqd1, dqd1]))
        errs["discrete_B"] = rel_err(B, np.vstack([dt * dt * Minv_p, dt * Minv_p]))
        pin.computeJointJacobiansTimeVariation(model, data, q[k], qd[k])
        pin.updateFramePlacements(model, data)
        errs["jacobian_derivative"] = rel_err(
            Jdot[k], pin.getFrameJacobianTimeVariation(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        )
        for key, e in errs.items():
            worst[key] = max(worst.get(key, 0.0), e)
    print({k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) <= TOL, worst
