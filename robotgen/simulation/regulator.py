"""`robotgen simulate` for a resolved-rate spec with an optimal regulator (Whitney 1972, eq 19):
the compiled ``lqr_step`` (tau = tau0 - K (q - q0, qd)) closed around the chain's dynamics.

A resolved-rate controller outputs joint rates, which a plant cannot take; its regulator
outputs torques. The chain starts at the simulation's theta0 at rest and the regulator
brings it back to the nominal posture q0: the "tracking error" is q - q0. The plant is the
chain's forward dynamics integrated by RK4 (robotgen.simulation.hand.chain_rk4) or a MuJoCo model of
the same chain (robotgen.simulation.mujoco), the torque held over each period dt."""

from __future__ import annotations

import numpy as np

from robotgen.documentation import hint
from robotgen.model.chain import REVOLUTE
from robotgen.model.signature import METRE, RADIAN
from robotgen.model.simulation import MUJOCO_PLANT, ROBOTGEN_PLANT, SimulationSettings
from robotgen.model.system import RobotSystem
from robotgen.simulation.failures import DIVERGED, SimulationError, format_values
from robotgen.simulation.hand import PlantStep, chain_rk4
from robotgen.simulation.mujoco.run import Diverged, chain_steps
from robotgen.simulation.tree import Result
from robotgen.simulation.tree import compare as compare  # its records are a tree run's
from robotgen.simulation.tree import plot as plot
from robotgen.simulation.tree import summary as summary
from robotgen.simulation.tree import write_csv as write_csv


def refusal(system: RobotSystem) -> str | None:
    """Why ``robotgen simulate`` cannot run this resolved-rate controller: it outputs joint
    rates, so only a chain's regulator (lqr settings) is simulated."""
    if system.rate_controls_composite or system.root_control.chain_rate.lqr is None:
        where = hint("python-api", "Resolved-rate controllers")
        return (
            "simulate runs torque controllers; a resolved_rate controller outputs joint rates (with lqr "
            "settings its regulator's lqr_step is simulated): integrate its rate_step / position_step "
            f"({where} shows how)"
        )
    return None


def comparison_system(system: RobotSystem) -> None:
    """A regulator is simulated alone."""
    return None


def simulate(
    module, system: RobotSystem, s: SimulationSettings, plant: str, comparison=None
) -> tuple[Result, str | None]:
    """The laws' simulation entry (robotgen.model.laws.registry): ``run``; ``comparison`` is
    always None."""
    return run(module, system, s, plant)


def run(module, system: RobotSystem, s: SimulationSettings, plant: str = ROBOTGEN_PLANT) -> tuple[Result, str | None]:
    """(the regulated run, the MuJoCo plant's MJCF or None)."""
    tree = system.tree(system.root_control.robot)
    lqr = system.root_control.chain_rate.lqr
    if lqr is None:  # (refusal says so first)
        raise TypeError("the regulator's simulation needs lqr settings")
    nominal = np.asarray(lqr.nominal, float)
    q = np.asarray(s.theta0, float) if s.theta0 is not None else nominal.copy()
    qd = np.zeros_like(q)
    mjcf, note = None, "classical RK4 of the chain's forward dynamics, one step per period"
    step: PlantStep
    if plant == MUJOCO_PLANT:
        model, chain_step = chain_steps(system, module, s.dt, q)
        mjcf, note, step = model.xml, chain_step.sim.note, chain_step
    else:
        rk4 = chain_rk4(tree, s.dt)

        def rk4_plant(stage: int, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, ...]:
            with np.errstate(all="ignore"):
                return tuple(np.array(v).ravel() for v in rk4(q, qd, tau))

        step = rk4_plant
    steps = int(round(s.duration / s.dt))
    T, Q, TAU = [], [], []
    for k in range(steps + 1):
        tau = np.asarray(module.lqr_step(q, qd), float)
        T.append(k * s.dt)
        Q.append(q)
        TAU.append(tau)
        if k == steps:
            break
        try:
            q_next, qd_next = step(0, q, qd, tau)
        except Diverged:
            q_next = qd_next = np.full_like(q, np.nan)
        if not (np.all(np.abs(q_next) < DIVERGED) and np.all(np.abs(qd_next) < DIVERGED)):
            raise SimulationError(
                f"the regulated loop diverged at t = {(k + 1) * s.dt:.4f} s (step {k + 1} of "
                f"{steps}): the state before the blow-up was q = {format_values(q)}, qd = "
                f"{format_values(qd)}, torque = {format_values(tau)}; lower dt"
            )
        q, qd = q_next, qd_next
    names = [j.name for j in tree.joints]
    units = [RADIAN if j.type == REVOLUTE else METRE for j in tree.joints]
    t = np.array(T)
    result = Result(
        t,
        np.array(Q),
        np.tile(nominal, (t.size, 1)),
        np.array(TAU),
        np.array(Q),
        names,
        units,
        names,
        units,
        plant=plant,
        plant_note=note,
    )
    return result, mjcf
