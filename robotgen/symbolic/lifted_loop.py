"""The lifted closed loop of a multi-rate tree: its rate groups' steps (robotgen.symbolic.rate_steps)
and the true plant (robotgen.symbolic.plant) as one discrete map over one period of the slowest
group, linearised at the start pose. Its spectral radius says whether a slower upper level
keeps the hierarchy stable: below 1 an error decays by that factor per slowest period, above 1
it grows.

One tick of the fastest period maps z = (Theta, v, every group's controller state, the held
trajectories, every group's last torques) to its next value as the MultiRateController and
`robotgen simulate` run it: the groups due at the tick run on the sensed state, the slowest
first (each reading the held trajectories as they are after the slower ones ran), their
torques are held (zero-order hold), and the plant takes one classical RK4 step of the fastest
period under their sum. The lifted transition matrix is the product of the per-tick Jacobians
(CasADi's AD of each tick's map) along one slowest period from the operating point: the start
pose at rest, the desired trajectory held there, the controllers' states where their init puts
them.

Two kinds of directions are left out before the radius is taken. The leaf positions Theta
carry the grasps' constraints, which the plant keeps (Theta_dot = A(Theta) v), so Theta moves
only along the range of A: the map is restricted to that tangent space. And a controller's
integrated trajectory that nothing below reads at the operating point (computed torque's
expected trajectory under a feedforward node, a squeeze direction no motion can follow) is a
neutral mode the plant never sees: only the modes observable from the plant's state (Theta, v)
count, the Kalman decomposition's observable part (Krylov subspace of the state rows)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca
import numpy as np

from robotgen.model.parameter_struct import runtime_parameters
from robotgen.model.rate_groups import RateGroups
from robotgen.model.signature import robot_leaves
from robotgen.model.simulation import RESIDUAL_TOLERANCE, SimulationSettings, rest_posture
from robotgen.model.system import RobotSystem
from robotgen.numeric.rk4 import rk4_step
from robotgen.symbolic.kernel import PARAMS, ParameterSymbols
from robotgen.symbolic.plant import Plant, sensed_forces
from robotgen.symbolic.rate_steps import HELD, INIT, STEP, rate_kernels
from robotgen.symbolic.system import SystemGraphs

# relative size of a singular value below which a direction counts as absent (rank decisions)
RANK_TOLERANCE = 1e-9


class OperatingPointError(ValueError):
    """The start pose cannot be linearised at: it breaks a grasp, or the map is not finite there."""


@dataclass(frozen=True)
class LiftedLoop:
    """A multi-rate tree's closed loop over one slowest period, linearised at the start pose: its spectrum and
    transition."""

    spectral_radius: float  # of the observable part on the constraint manifold
    frame: float  # the lifted period [s]: one period of the slowest group
    ticks: int  # fastest periods in it
    x: np.ndarray  # the start pose (root positions)
    theta: np.ndarray  # the operating point's leaf positions
    eigenvalues: np.ndarray  # of the observable part, largest modulus first
    dimension: int  # of the whole lifted state
    transition: np.ndarray  # the lifted transition matrix in the full coordinates z

    @property
    def stable(self) -> bool:
        """Whether the spectral radius is below 1."""
        return self.spectral_radius < 1.0

    @property
    def time_constant(self) -> float:
        """-frame / ln(radius): the slowest mode's time constant [s] (negative: its growth's)."""
        return -self.frame / np.log(self.spectral_radius) if self.spectral_radius > 0 else 0.0


class TickMaps:
    """The per-tick map z -> z' of a multi-rate tree as CasADi Functions, one per set of
    groups due, and the layout of z. The run-time parameters take the spec's values. ``root``
    is the desired root trajectory every group that starts at the root reads (held constant)."""

    def __init__(self, system: RobotSystem, groups: RateGroups):
        parameters = ParameterSymbols.of(runtime_parameters(system))
        self.values = ca.DM([v for p in parameters.parameters for v in np.ravel(p.default)])
        g = SystemGraphs(system, parameters)
        self.groups = groups
        self.kernels = {k.name: k for k in rate_kernels(g, groups)}
        self.plant = plant = Plant(system, parameters)
        pg = plant.graphs
        self.n, self.n_v = pg.n, plant.n_v
        root = g.graph(system.root).sig
        self.root = {
            "x_e": np.zeros(root.n_external),
            "xd_e": np.zeros(root.n_velocity),
            "xdd_e": np.zeros(root.n_velocity),
            "f_e": np.zeros(root.n_velocity),
            "f_i": np.zeros(root.n_internal_forces),
        }

        def known(name: str, inputs: list[ca.SX], outputs: list[ca.SX]) -> ca.Function:
            """A Function of ``inputs`` with the parameters at their values."""
            return ca.Function(name, inputs, [ca.substitute(o, parameters.vector, self.values) for o in outputs])

        theta, v, tau = pg.theta, plant.v, plant.tau
        self.plant_rates = known("plant", [theta, v, tau], [plant.theta_dot, plant.v_dot])
        self.sensed_forces = known("sensed", [theta, v, tau], [sensed_forces(plant)])
        self.rate_map = known("A", [theta], [ca.jacobian(plant.theta_dot, v)])  # eqs 3.3, 5.8
        self.position = known("x", [theta], [plant.x])
        self.inverse = known("inverse", [plant.x_sym], [plant.inverse]) if plant.inverse is not None else None
        self.residual = known("residual", [theta], [plant.residual]) if plant.residual.shape[0] else None
        # the layout of z: Theta, v, states, held trajectories, torques
        sizes = [("theta", self.n), ("v", self.n_v)]
        for grp in groups.groups:
            step = self.kernels[STEP.format(grp.index)]
            state = next((p.size for p in step.inputs if p.name == "state"), 0)
            if state:
                sizes.append((f"state_g{grp.index}", state))
        for name in groups.boundaries:
            port = HELD.format(name)
            writer = self.kernels[STEP.format(next(grp.index for grp in groups.groups if name in grp.writes))]
            sizes.append((port, next(p.size for p in writer.outputs if p.name == port)))
        sizes += [(f"tau_g{grp.index}", self.n) for grp in groups.groups]
        self.slices, o = {}, 0
        for key, size in sizes:
            self.slices[key] = slice(o, o + size)
            o += size
        self.size = o
        self._maps: dict[tuple[int, ...], tuple[ca.Function, ca.Function]] = {}

    def _call(self, name: str, args: Mapping[str, ca.SX | ca.DM]) -> dict[str, ca.SX]:
        kernel = self.kernels[name]
        values = [args[p.name] if p.name != PARAMS else self.values for p in kernel.inputs]
        return dict(zip((p.name for p in kernel.outputs), kernel.function.call(values)))

    def tick(self, due: tuple[int, ...], dt: float) -> tuple[ca.Function, ca.Function]:
        """(F, dF/dz) of one tick at which the groups ``due`` run (slowest first)."""
        if due in self._maps:
            return self._maps[due]
        z = ca.SX.sym("z", self.size)
        part = {key: z[s] for key, s in self.slices.items()}
        theta, v = part["theta"], part["v"]
        theta_dot = self.plant_rates(theta, v, ca.DM.zeros(self.n))[0]
        tau_before = sum((part[f"tau_g{grp.index}"] for grp in self.groups.groups), ca.SX.zeros(self.n))
        new = dict(part)
        for k in due:
            args: dict[str, ca.SX | ca.DM] = {
                "theta": theta,
                "theta_dot": theta_dot,
                **{key: ca.DM(val) for key, val in self.root.items()},
            }
            args.update({key: new[key] for key in new if key.startswith(HELD.format(""))})
            if f"state_g{k}" in new:  # a group with a state
                args["state"] = new[f"state_g{k}"]
            args["tau_sensed"] = self.sensed_forces(theta, v, tau_before)  # the last torques still applied
            out = self._call(STEP.format(k), args)
            new[f"tau_g{k}"] = out["tau"]
            if "state_next" in out:
                new[f"state_g{k}"] = out["state_next"]
            new.update({key: value for key, value in out.items() if key.startswith(HELD.format(""))})
        tau = sum((new[f"tau_g{grp.index}"] for grp in self.groups.groups), ca.SX.zeros(self.n))
        new["theta"], new["v"] = rk4_step(lambda th, vel: self.plant_rates(th, vel, tau), theta, v, dt)
        z_next = ca.vertcat(*[new[key] for key in self.slices])
        maps = (ca.Function("tick", [z], [z_next]), ca.Function("tick_jacobian", [z], [ca.jacobian(z_next, z)]))
        self._maps[due] = maps
        return maps

    def start(self, theta: np.ndarray) -> np.ndarray:
        """z at the operating point: at rest, every group's state from its init, nothing held."""
        z = np.zeros(self.size)
        z[self.slices["theta"]] = theta
        for grp in self.groups.groups:
            init = INIT.format(grp.index)
            if init in self.kernels:
                out = self._call(init, {"theta": ca.DM(theta), "theta_dot": ca.DM.zeros(self.n)})
                z[self.slices[f"state_g{grp.index}"]] = np.asarray(out["state"]).ravel()
        return z


def operating_point(system: RobotSystem, maps: TickMaps) -> tuple[np.ndarray, np.ndarray]:
    """(Theta, x) of the start pose: simulation.theta0, else the inverse kinematics of
    simulation.start (without initial_error), else the rest posture."""
    s = system.simulation or SimulationSettings()
    if s.theta0 is not None:
        theta = np.asarray(s.theta0, float)
    elif s.start is not None and maps.inverse is not None:
        theta = np.asarray(maps.inverse(s.start)).ravel()
    else:
        theta = np.asarray(rest_posture([system.leaf(leaf) for leaf in robot_leaves(system)]), float)
    return theta, np.asarray(maps.position(theta)).ravel()


def lifted_loop(system: RobotSystem, groups: RateGroups) -> LiftedLoop:
    """The lifted closed loop of ``system`` run in ``groups`` at its start pose; raises
    OperatingPointError where it cannot be linearised."""
    s = system.simulation or SimulationSettings()
    maps = TickMaps(system, groups)
    theta0, x0 = operating_point(system, maps)
    if maps.residual is not None:
        residual = np.abs(np.asarray(maps.residual(theta0)).ravel())
        if not np.all(residual <= RESIDUAL_TOLERANCE):  # also NaN: out of the inverse kinematics' reach
            where = (
                "simulation.theta0"
                if s.theta0 is not None
                else "simulation.start"
                if s.start is not None
                else "the rest posture (no simulation.start or theta0)"
            )
            how = (
                f"constraint residual up to {residual.max():.3g}"
                if np.all(np.isfinite(residual))
                else "out of the inverse kinematics' reach"
            )
            raise OperatingPointError(
                f"the start pose, from {where}, breaks a grasp ({how}); give simulation.start or theta0 on every grasp"
            )
    maps.root["x_e"] = x0
    if s.internal_forces:
        maps.root["f_i"] = np.asarray(s.internal_forces, float)
    dt = groups.base_period
    z = maps.start(theta0)
    phi = np.eye(maps.size)
    for tick in range(groups.frame_ticks):
        step, jacobian = maps.tick(groups.due(tick), dt)
        phi = np.asarray(jacobian(z)) @ phi
        z = np.asarray(step(z)).ravel()
    if not np.all(np.isfinite(phi)):
        raise OperatingPointError("the closed loop is not finite over one slowest period from the start pose")
    eigenvalues = observable_eigenvalues(phi, maps, theta0)
    radius = float(np.abs(eigenvalues).max()) if eigenvalues.size else 0.0
    return LiftedLoop(radius, groups.frame_ticks * dt, groups.frame_ticks, x0, theta0, eigenvalues, maps.size, phi)


def observable_eigenvalues(phi: np.ndarray, maps: TickMaps, theta0: np.ndarray) -> np.ndarray:
    """The eigenvalues of the lifted map ``phi`` restricted to Theta's tangent space at
    ``theta0`` (the range of A = d Theta_dot / d v) and to the part observable from
    (Theta, v), largest modulus first."""
    theta, v = maps.slices["theta"], maps.slices["v"]
    A = np.asarray(maps.rate_map(theta0))  # Theta_dot = A(Theta) v
    u, sigma, _ = np.linalg.svd(A, full_matrices=False)
    tangent = u[:, sigma > RANK_TOLERANCE * max(sigma.max(initial=0.0), 1.0)]
    m, n = tangent.shape[1], maps.size
    rest = [i for i in range(n) if not theta.start <= i < theta.stop]
    basis = np.zeros((n, m + len(rest)))
    basis[theta, :m] = tangent
    basis[rest, m:] = np.eye(len(rest))
    reduced = basis.T @ phi @ basis  # Theta's tangent space is invariant: the plant keeps its grasps
    plant = list(range(m)) + [m + rest.index(i) for i in range(v.start, v.stop)]
    Q = _observable_rows(np.eye(reduced.shape[0])[plant], reduced)
    return np.array(sorted(np.linalg.eigvals(Q @ reduced @ Q.T), key=lambda e: -abs(e)))


def _observable_rows(C: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """An orthonormal basis (rows) of the observable subspace of (phi, C): the span of the rows
    of C, C phi, C phi^2, ..., grown until it stops growing."""
    basis = _orthonormal_rows(C)
    while True:
        grown = _orthonormal_rows(np.vstack([basis, basis @ phi]))
        if grown.shape[0] == basis.shape[0]:
            return grown
        basis = grown


def _orthonormal_rows(rows: np.ndarray) -> np.ndarray:
    _, sigma, vt = np.linalg.svd(rows, full_matrices=False)
    rank = int(np.sum(sigma > RANK_TOLERANCE * max(sigma.max(initial=0.0), 1.0)))
    return vt[:rank]
