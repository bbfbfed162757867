"""Stepping the MJCF of robotgen.simulation.mujoco.model under a compiled controller's torques.

One servo period: robotgen's tau goes to the motors (ctrl), held over the period, and
MuJoCo takes ``substeps`` steps of its own RK4 integrator (one without contacts, so that
both plants take the same classical RK4 step; CONTACT_SUBSTEPS with them). The smooth
Coulomb friction c tanh(qd / smoothing) that MJCF cannot express is added to qfrc_passive
in MuJoCo's passive-force callback, which MuJoCo calls at every RK4 stage. After the steps
mj_forward evaluates the new state with the torque still held: what a sensor reads at the
start of the next period (contact forces included).

What the controller senses is robotgen's: theta = T q + offset, theta_dot = T qd per leaf,
and tau_sensed (rd's force term, eq 3.7): the generalized force each leaf exerts through
its contacts, -T^-T qfrc_constraint on its joints (a joint-torque sensor's reading of the
contact load, in robotgen's coordinates)."""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np

from robotgen.errors import UserError
from robotgen.model.system import CONTACT_GRASPS, AttachNode, RobotSystem
from robotgen.simulation.failures import DIVERGED, SimulationError, format_values
from robotgen.simulation.mujoco import require_mujoco
from robotgen.simulation.mujoco.contacts import ContactHistory, Reading, internal_forces
from robotgen.simulation.mujoco.model import PlantModel, below_controls, fingertips, plant_model

# the MuJoCo model must reproduce robotgen's M and C qd + N to this (relative), or the
# mapping is wrong; MIN_INERTIA alone moves the Styx fingers' M by ~1e-11
AGREEMENT = 1e-8


class Diverged(ValueError):
    """MuJoCo's state left the finite numbers (or MuJoCo flagged an unstable acceleration)."""


def rpy_rotation(rpy: np.ndarray) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), robotgen's fixed-axis roll, pitch, yaw."""
    (cr, cp, cy), (sr, sp, sy) = np.cos(rpy), np.sin(rpy)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def rpy_of(R: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw [rad] (Lee and Lee eq 2) of a rotation R (3, 3)."""
    return np.array(
        [np.arctan2(R[2, 1], R[2, 2]), np.arctan2(-R[2, 0], np.hypot(R[2, 1], R[2, 2])), np.arctan2(R[1, 0], R[0, 0])]
    )


def rpy_rate_map(rpy: np.ndarray) -> np.ndarray:
    """E with omega (world axes) = E rpy_dot for R = Rz(yaw) Ry(pitch) Rx(roll)."""
    _, p, y = rpy
    return np.array(
        [[np.cos(y) * np.cos(p), -np.sin(y), 0.0], [np.sin(y) * np.cos(p), np.cos(y), 0.0], [-np.sin(p), 0.0, 1.0]]
    )


class MujocoPlant:
    """A PlantModel loaded in MuJoCo, read and driven in robotgen's coordinates."""

    @property
    def note(self) -> str:
        """How this plant steps, for reports."""
        p = self.plant
        cones = ", elliptic friction cones" if p.contacts else ""
        return (
            f"MuJoCo {self.mj.__version__}, its RK4, {p.substeps} step{'s' if p.substeps > 1 else ''} of "
            f"{p.timestep:g} s per period{cones}"
        )

    def __init__(self, plant: PlantModel):
        mj = require_mujoco()
        self.mj, self.plant = mj, plant
        self.model = mj.MjModel.from_xml_string(plant.xml)
        self.data = mj.MjData(self.model)
        m = self.model

        def joint(name: str) -> int:
            return mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, name)

        self.leaf_qpos = [np.array([m.jnt_qposadr[joint(j)] for j in leaf.joints]) for leaf in plant.leaves]
        self.leaf_dofs = [np.array([m.jnt_dofadr[joint(j)] for j in leaf.joints]) for leaf in plant.leaves]
        self.actuators = np.concatenate(
            [[mj.mj_name2id(m, mj.mjtObj.mjOBJ_ACTUATOR, a) for a in leaf.actuators] for leaf in plant.leaves]
        ).astype(int)
        self.sites = [mj.mj_name2id(m, mj.mjtObj.mjOBJ_SITE, leaf.tip) for leaf in plant.leaves]
        self.payload_qpos = {p.node: int(m.jnt_qposadr[joint(p.joints[0])]) for p in plant.payloads}
        self.payload_dofs = {p.node: int(m.jnt_dofadr[joint(p.joints[0])]) for p in plant.payloads}
        self.payload_body = {p.node: mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, p.body) for p in plant.payloads}
        self.payload_planar = {p.node: p.planar for p in plant.payloads}
        self.wall_geoms = (
            {mj.mj_name2id(m, mj.mjtObj.mjOBJ_GEOM, g) for g in (plant.wall.tip_geom, plant.wall.plane_geom)}
            if plant.wall is not None
            else set()
        )
        self.tip_geoms = [mj.mj_name2id(m, mj.mjtObj.mjOBJ_GEOM, c.tip_geom) for c in plant.contacts]
        self.pad_geoms = [mj.mj_name2id(m, mj.mjtObj.mjOBJ_GEOM, c.pad_geom) for c in plant.contacts]
        self.pad_half_width = [float(m.geom_size[g][0]) for g in self.pad_geoms]
        coulomb, smoothing = np.zeros(m.nv), np.ones(m.nv)
        for leaf, dofs in zip(plant.leaves, self.leaf_dofs):
            coulomb[dofs], smoothing[dofs] = leaf.coulomb, leaf.smoothing
        self.friction_dofs = np.flatnonzero(coulomb)
        self.coulomb, self.smoothing = coulomb[self.friction_dofs], smoothing[self.friction_dofs]
        self.T_inv = [np.linalg.inv(leaf.T) for leaf in plant.leaves]

    # -- the smooth Coulomb term --------------------------------------------------------
    def _passive(self, m, d) -> None:
        d.qfrc_passive[self.friction_dofs] -= self.coulomb * np.tanh(d.qvel[self.friction_dofs] / self.smoothing)

    @contextlib.contextmanager
    def friction(self):
        """MuJoCo's passive-force callback (one per process) set to this model's Coulomb
        friction while the block runs; the callback before it is restored after."""
        if not self.friction_dofs.size:
            yield
            return
        before = self.mj.get_mjcb_passive()
        self.mj.set_mjcb_passive(self._passive)
        try:
            yield
        finally:
            self.mj.set_mjcb_passive(before)

    # -- state in robotgen's coordinates --------------------------------------------------
    def set_leaves(self, theta: np.ndarray, theta_dot: np.ndarray) -> None:
        """Set MuJoCo's qpos and qvel from leaf positions theta (nq,) [rad or m] and rates theta_dot (nq,)."""
        for leaf, T_inv, qpos, dofs in zip(self.plant.leaves, self.T_inv, self.leaf_qpos, self.leaf_dofs):
            self.data.qpos[qpos] = T_inv @ (theta[leaf.theta] - leaf.offset)
            self.data.qvel[dofs] = T_inv @ theta_dot[leaf.theta]

    def set_payload(self, node: str, x: np.ndarray, xd: np.ndarray) -> None:
        """A payload at robotgen's pose x and coordinate rates xd: (x, y, psi) of a planar body,
        (x, y, z, roll, pitch, yaw) of a spatial one (MuJoCo: position, quaternion, and the
        angular velocity in the body frame, R^T E rpy_dot)."""
        a, v = self.payload_qpos[node], self.payload_dofs[node]
        if self.payload_planar[node]:
            self.data.qpos[a : a + 3], self.data.qvel[v : v + 3] = x[:3], xd[:3]
            return
        R = rpy_rotation(x[3:6])
        quat = np.zeros(4)
        self.mj.mju_mat2Quat(quat, R.ravel())
        self.data.qpos[a : a + 7] = np.r_[x[:3], quat]
        self.data.qvel[v : v + 6] = np.r_[xd[:3], R.T @ rpy_rate_map(x[3:6]) @ xd[3:6]]

    def set_mass(self, node: str, mass: float) -> None:
        """Payload ``node``'s mass from now on (MuJoCo's derived constants recomputed), the
        state evaluated again."""
        state = self.data.qpos.copy(), self.data.qvel.copy(), self.data.ctrl.copy()
        self.model.body_mass[self.payload_body[node]] = mass
        self.mj.mj_setConst(self.model, self.data)  # works in data at qpos0: the state is put back
        self.data.qpos[:], self.data.qvel[:], self.data.ctrl[:] = state
        self.forward()

    def payload_pose(self, node: str) -> np.ndarray:
        """A payload's pose: (x, y, psi) when planar, else position (3,) [m] and roll, pitch, yaw (3,) [rad]."""
        a = self.payload_qpos[node]
        if self.payload_planar[node]:
            return self.data.qpos[a : a + 3].copy()
        return np.r_[self.data.qpos[a : a + 3], rpy_of(self.rotation(node))]

    def rotation(self, node: str) -> np.ndarray:
        """A payload's rotation (3, 3) in world axes."""
        return self.data.xmat[self.payload_body[node]].reshape(3, 3).copy()

    def sensed(self) -> tuple[np.ndarray, np.ndarray]:
        """Leaf positions theta (nq,) and rates theta_dot (nq,) from MuJoCo's state, in robotgen's coordinates."""
        theta, theta_dot = np.zeros(self.plant.nq), np.zeros(self.plant.nq)
        for leaf, qpos, dofs in zip(self.plant.leaves, self.leaf_qpos, self.leaf_dofs):
            theta[leaf.theta] = leaf.T @ self.data.qpos[qpos] + leaf.offset
            theta_dot[leaf.theta] = leaf.T @ self.data.qvel[dofs]
        return theta, theta_dot

    def forward(self) -> None:
        """mj_forward with the smooth Coulomb friction applied."""
        with self.friction():
            self.mj.mj_forward(self.model, self.data)

    def step(self, tau: np.ndarray) -> None:
        """One servo period with tau held; then the state is evaluated (mj_forward)."""
        self.data.ctrl[self.actuators] = tau
        with self.friction():
            for _ in range(self.plant.substeps):
                self.mj.mj_step(self.model, self.data)
            self.mj.mj_forward(self.model, self.data)
        unstable = self.data.warning[self.mj.mjtWarning.mjWARN_BADQACC].number
        if unstable or not (np.all(np.abs(self.data.qpos) < DIVERGED) and np.all(np.abs(self.data.qvel) < DIVERGED)):
            raise Diverged("MuJoCo's state diverged")

    # -- what the leaves exert through their contacts -----------------------------------
    def sensed_forces(self) -> np.ndarray:
        """tau_sensed: per leaf, -T^-T qfrc_constraint on its joints (robotgen's order)."""
        out = np.zeros(self.plant.nq)
        for leaf, T_inv, dofs in zip(self.plant.leaves, self.T_inv, self.leaf_dofs):
            out[leaf.theta] = -T_inv.T @ self.data.qfrc_constraint[dofs]
        return out

    def readings(self) -> list[Reading]:
        """Every contact of the model at the current state (mj_forward done)."""
        m, d = self.model, self.data
        forces = [np.zeros(3) for _ in self.plant.contacts]
        speeds = [0.0] * len(self.plant.contacts)
        wrench = np.zeros(6)
        for i in range(d.ncon):
            c = d.contact[i]
            for k, (tip, pad) in enumerate(zip(self.tip_geoms, self.pad_geoms)):
                if {int(c.geom[0]), int(c.geom[1])} == {tip, pad} and c.efc_address >= 0:
                    self.mj.mj_contactForce(m, d, i, wrench)
                    world = c.frame.reshape(3, 3).T @ wrench[:3]  # on geom2 from geom1
                    forces[k] += world if int(c.geom[1]) == pad else -world
                    # an elliptic cone's rows: normal, then the two tangential relative velocities
                    speeds[k] = float(np.linalg.norm(d.efc_vel[c.efc_address + 1 : c.efc_address + c.dim]))
        out = []
        for k, c in enumerate(self.plant.contacts):
            R, p = self.rotation(c.payload), self.data.xpos[self.payload_body[c.payload]]
            tip = self.data.geom_xpos[self.tip_geoms[k]]
            offset = R.T @ (tip - p) - c.point
            n_world = R @ c.normal
            f_n = max(float(forces[k] @ n_world) * -1.0, 0.0)  # the tip pushes the pad inwards, along -n
            f_t = float(np.linalg.norm(forces[k] + f_n * n_world)) if f_n > 0 else 0.0
            out.append(
                Reading(
                    forces[k],
                    f_n,
                    f_t,
                    offset,
                    c.normal,
                    self.pad_half_width[k],
                    c.friction,
                    speeds[k] if f_n > 0 else 0.0,
                )
            )
        return out

    def wall_force(self) -> float:
        """The normal force the wall carries now (mj_forward done): its contacts' normal
        components (the first of each contact frame's force)."""
        wrench, total = np.zeros(6), 0.0
        for i in range(self.data.ncon):
            c = self.data.contact[i]
            if {int(c.geom[0]), int(c.geom[1])} == self.wall_geoms and c.efc_address >= 0:
                self.mj.mj_contactForce(self.model, self.data, i, wrench)
                total += float(wrench[0])
        return total

    def internal_forces(self, readings: list[Reading]) -> list[float]:
        """The grasp's internal forces [N] from the contact readings."""
        return internal_forces(self.plant.contacts, readings, self.rotation)

    # -- the model's dynamics in robotgen's coordinates ------------------------------------
    def dynamics(self, theta: np.ndarray, theta_dot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(M, C theta_dot + N) of the leaves in robotgen's coordinates at (theta, theta_dot)
        (payloads at rest where they are): T^-T M_q T^-1 and T^-T (qfrc_bias - qfrc_passive),
        the passive forces being the damping and the smooth Coulomb term."""
        self.set_leaves(theta, theta_dot)
        self.forward()
        M_full = np.zeros((self.model.nv, self.model.nv))
        self.mj.mj_fullM(self.model, self.data, M_full)
        n = self.plant.nq
        M, bias = np.zeros((n, n)), np.zeros(n)
        for leaf, T_inv, dofs in zip(self.plant.leaves, self.T_inv, self.leaf_dofs):
            s = leaf.theta
            M[s, s] = T_inv.T @ M_full[np.ix_(dofs, dofs)] @ T_inv
            bias[s] = T_inv.T @ (self.data.qfrc_bias[dofs] - self.data.qfrc_passive[dofs])
        return M, bias

    def tips(self) -> list[np.ndarray]:
        """Each fingertip site's position (3,) [m] in world axes."""
        return [self.data.site_xpos[s].copy() for s in self.sites]


def check_agreement(sim: MujocoPlant, leaf_dynamics, theta0: np.ndarray, rng: np.random.Generator, tips=None) -> None:
    """The MuJoCo model reproduces robotgen's: at theta0 and 4 random states about it,
    M and C theta_dot + N of every leaf (``leaf_dynamics(theta, theta_dot) -> [(M, b)]``
    per leaf, from the compiled module) to AGREEMENT (relative), and, for contacts, each
    fingertip where robotgen puts it (``tips(theta) -> [(leaf, position)]``). Raises a
    UserError at the leaf whose model differs: a mechanism that is not the formulas'."""
    states = [(theta0, np.zeros_like(theta0))]
    states += [(theta0 + rng.uniform(-0.3, 0.3, theta0.size), rng.normal(size=theta0.size)) for _ in range(4)]
    for theta, theta_dot in states:
        M, bias = sim.dynamics(theta, theta_dot)
        for leaf, (M_rg, b_rg) in zip(sim.plant.leaves, leaf_dynamics(theta, theta_dot)):
            s = leaf.theta
            for what, mine, theirs in (("M", M[s, s], M_rg), ("C theta_dot + N", bias[s], b_rg)):
                scale = max(float(np.abs(theirs).max()), float(np.abs(M_rg).max()) * 1e-3, 1e-300)
                error = float(np.abs(mine - theirs).max()) / scale
                if error > AGREEMENT:
                    raise UserError(
                        leaf.location,
                        f"the MuJoCo model of leaf '{leaf.name}' does not reproduce "
                        f"robotgen's: {what} differs by {error:.3g} (relative) at "
                        f"theta = {format_values(theta[s])}",
                    )
        if tips is not None:
            positions = dict(zip((leaf.name for leaf in sim.plant.leaves), sim.tips()))
            for leaf, expected in tips(theta):
                where = next(lf.location for lf in sim.plant.leaves if lf.name == leaf)
                found = positions[leaf][: expected.size]
                if np.abs(found - expected).max() > 1e-9:
                    raise UserError(
                        where,
                        f"the MuJoCo model puts the fingertip of leaf '{leaf}' at "
                        f"[{', '.join(f'{v:.6g}' for v in found)}], robotgen at "
                        f"[{', '.join(f'{v:.6g}' for v in expected)}] (theta = "
                        f"{format_values(theta)}): the tip frame is not the "
                        "point the kinematics give",
                    )


@dataclass
class ChainSteps:
    """A contact-free chain as a function of its state, like robotgen's RK4 step: (stage, q, qd,
    tau) -> (q, qd) one period later, the hand holding payload ``stages[stage]`` (mass [kg],
    centre of mass in the hand frame) over it."""

    sim: MujocoPlant
    stages: list[tuple[float, np.ndarray]]

    def __post_init__(self):
        self._stage = None

    def __call__(self, stage: int, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(q, qd) one period on: MuJoCo steps under tau (n,) [N m], the hand carrying stage ``stage``'s payload."""
        if stage != self._stage and self.sim.plant.hand_payload is not None:
            body = self.sim.mj.mj_name2id(self.sim.model, self.sim.mj.mjtObj.mjOBJ_BODY, self.sim.plant.hand_payload)
            mass, com = self.stages[stage]
            self.sim.model.body_mass[body] = mass
            self.sim.model.body_ipos[body] = com
            self.sim.mj.mj_setConst(self.sim.model, self.sim.data)
            self._stage = stage
        self.sim.set_leaves(q, qd)
        self.sim.step(tau)
        return self.sim.sensed()


class TreePlant:
    """A robot tree's MuJoCo plant as robotgen.simulation.tree runs it: started at robotgen's leaf
    state with every payload where the grasp puts it (its attach's rd), stepped with the
    servo step's torques; records the contacts."""

    name = "mujoco"

    def __init__(
        self, sim: MujocoPlant, module, theta: np.ndarray, theta_dot: np.ndarray, n_ext: int, root_payload: str | None
    ):
        self.sim, self.module, self.n_ext = sim, module, n_ext
        sim.set_leaves(theta, theta_dot)
        for p in sim.plant.payloads:
            x, xd = getattr(module, f"{p.attach}_read")(theta, theta_dot)
            n = 3 if p.planar else 6
            sim.set_payload(p.node, np.asarray(x)[:n], np.asarray(xd)[:n])
        sim.forward()
        self.root_payload = root_payload
        self.history = ContactHistory(sim.plant.contacts) if sim.plant.contacts else None
        self._readings = sim.readings() if sim.plant.contacts else []

    @property
    def note(self) -> str:
        """How the plant is integrated, for the report."""
        return self.sim.note

    def sensed(self) -> tuple[np.ndarray, np.ndarray]:
        """Leaf positions and rates (nq,) as the sensors read them."""
        return self.sim.sensed()

    def position(self, theta: np.ndarray) -> np.ndarray:
        """The root's external positions at leaf positions theta (nq,), by the module's plant_position."""
        return self.module.plant_position(theta)[: self.n_ext]

    def sensed_forces(self, tau_before: np.ndarray) -> np.ndarray:
        """What the sensors read now: MuJoCo's state already holds the last torques."""
        return self.sim.sensed_forces()

    def internal_forces(self, tau: np.ndarray) -> np.ndarray:
        """The internal forces the contacts carry now (the new torques act from the next step)."""
        return np.array(self.sim.internal_forces(self._readings))

    def set_wall(self, wall) -> None:
        """The wall is in the MJCF already: the spec's (robotgen.simulation.mujoco.model)."""
        if self.sim.plant.wall is None:
            raise SimulationError(
                "the MuJoCo model was written without a wall: give it in the spec's simulation section", "wall"
            )

    def wall_force(self) -> float:
        """The wall's normal force [N] on its point now."""
        return self.sim.wall_force()

    def set_payload_mass(self, payload: str, mass: float) -> None:
        """From now on payload ``payload`` has ``mass`` (its inertia kept)."""
        self.sim.set_mass(payload, mass)
        self._readings = self.sim.readings() if self.sim.plant.contacts else []

    def record(self, t: float) -> None:
        """Record the contacts at t [s], when a contact history is kept."""
        if self.history is not None:
            pose = self.sim.payload_pose(self.root_payload) if self.root_payload else None
            self.history.add(t, self._readings, pose)

    def step(self, tau: np.ndarray, dt: float, when: str) -> None:
        """Advance one servo period dt [s] under leaf torques tau (nq,); a divergence is a SimulationError."""
        theta = self.sim.sensed()[0]
        try:
            self.sim.step(tau)
        except Diverged:
            raise SimulationError(
                f"the closed loop on the MuJoCo plant diverged {when}: the state before the "
                f"blow-up was theta = {format_values(theta)}, torque = "
                f"{format_values(tau)}; the gains are too high for dt = {dt:g} s "
                "or the loop is unstable: lower kp and kv, or dt"
            ) from None
        self._readings = self.sim.readings() if self.sim.plant.contacts else []


def root_payload(system: RobotSystem) -> str | None:
    """The payload whose pose the root's coordinates are (the root, below its controllers, is a
    contact grasp), else None."""
    node = below_controls(system, system.root)
    return node.payload if isinstance(node, AttachNode) and node.constraint.kind in CONTACT_GRASPS else None


def tree_plant(system: RobotSystem, module, dt: float) -> tuple[PlantModel, object]:
    """The MJCF of a robot tree and the plant factory robotgen.simulation.tree.run takes: each plant
    is first checked against the compiled module (check_agreement: every leaf's M and
    C theta_dot + N, every fingertip where the grasp's robots' rd puts it)."""
    plant = plant_model(system, dt)
    payload = root_payload(system)

    def leaf_dynamics(theta, theta_dot):
        return [
            (
                getattr(module, f"{leaf.name}_mass")(theta),
                getattr(module, f"{leaf.name}_coriolis")(theta, theta_dot) @ theta_dot[leaf.theta]
                + getattr(module, f"{leaf.name}_n")(theta, theta_dot),
            )
            for leaf in plant.leaves
        ]

    def tips(theta):
        theta_dot = np.zeros_like(theta)
        out = []
        wall = system.simulation.wall if system.simulation is not None else None
        if plant.wall is not None and wall is not None:  # the wall's point: where the node's rd puts it
            out.append((plant.wall.leaf, np.asarray(getattr(module, f"{wall.node}_read")(theta, theta_dot)[0])))
        for attach in {c.attach for c in plant.contacts}:
            node = system.attach(attach)
            y = np.concatenate([getattr(module, f"{r}_read")(theta, theta_dot)[0] for r in node.robots])
            dim = CONTACT_GRASPS[node.constraint.kind].tip_dim
            out += [(leaf, y[dim * k : dim * k + dim]) for k, leaf in enumerate(fingertips(system, node))]
        return out

    def make(module, theta, theta_dot, v, n_ext):
        check_agreement(MujocoPlant(plant), leaf_dynamics, theta, np.random.default_rng(0), tips)
        return TreePlant(MujocoPlant(plant), module, theta, theta_dot, n_ext, payload)

    return plant, make


def chain_steps(
    system: RobotSystem,
    module,
    period: float,
    q0: np.ndarray,
    hand_frame: np.ndarray | None = None,
    stages: list[tuple[float, np.ndarray]] | None = None,
) -> tuple[PlantModel, ChainSteps]:
    """The MJCF of a chain controlled at its root (a hand law, a resolved-rate regulator) and
    its step function, checked against the module's mass and nonlinear (C qd + N) first.
    ``stages``: the hand's payloads (mass, centre of mass in the hand frame), by stage."""
    plant = plant_model(system, period, hand_frame)
    sim = MujocoPlant(plant)

    def leaf_dynamics(q, qd):
        return [(module.mass(q), module.nonlinear(q, qd))]

    check_agreement(MujocoPlant(plant), leaf_dynamics, q0, np.random.default_rng(0))
    return plant, ChainSteps(sim, stages or [(0.0, np.zeros(3))])
