"""D. C. Deno, R. M. Murray, K. S. J. Pister, S. S. Sastry, "Control Primitives for Robot
Systems" (1990), reproduced with robotgen: chapter 4's two-fingered hand under the three
control structures of Figs 4.1-4.3, simulated on one box path, the chapter's claims checked
with numbers, and Appendix A's sample computations (Examples.m: RobotMass of the finger, the
hand and the two controlled hands).

    python examples/papers/deno_1990.py [--quick] [-o DIR]

The paper reports no numbers of its own for chapter 4. What it claims, and what is checked:

- §4.1: expanded through the primitives, high-level computed torque is
  tau = J^T G^+ [M_h (xdd_d + Kv e' + Kp e) + C_h xd_b] with M_h = M_b + G J^-T M_theta J^-1 G^T
  and C_h = C_b + G J^-T C_theta J^-1 G^T + G J^-T M_theta d/dt(J^-1 G^T). The compiled servo
  step is compared with that formula evaluated here in numpy at random states.
- §4.2: low-level computed torque is exponentially stable with a massless box and degrades as
  the box gets heavier. Both structures fly one box path for a sweep of box masses.
- §4.3: with the PD terms at rest, the box error makes the multi-level structure's fingers
  exert what the high-level structure's do. Compared at states on the resolved trajectory.
- Appendix A: RobotMass[left], RobotMass[hand], RobotMass[HighCThand] ("this should be zero")
  and RobotMass[LowCThand] ("just the box mass") from the compiled node functions, beside
  the closed forms of StyxDefinitions.m.

The closed forms below (StyxDefinitions.m: the fingers, the grasp map, the box) never call
robotgen; they take the numbers in the specs. The §4.1 and §4.3 formulas read M_theta and
C_theta from the compiled leaves (`left_mass` ...), which Appendix A holds to the closed
forms. Modules are built from copies of specs/styx_*.yaml, renamed and with the box's mass
set, in a temporary directory.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import itertools
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from ruamel.yaml import YAML  # noqa: E402

from robotgen.cli import main as robotgen  # noqa: E402
from robotgen.frontend import load_system  # noqa: E402
from robotgen.simulation import tree as simulate  # noqa: E402

SPECS = ROOT / "specs"
DEFAULT_OUTPUT = Path("generated/papers/deno_1990")
# the figure, its spec and what the paper calls the structure
STRUCTURES = {
    "4.1": ("styx_high_ct", "high-level computed torque"),
    "4.2": ("styx_low_ct", "low-level computed torque"),
    "4.3": ("styx_multilevel", "multi-level computed torque / stiffness"),
}
BLOCK = (0.1, 0.06)  # the box is a 10 cm x 6 cm block: J_b = m_b (a^2 + c^2) / 12, as in the specs
SWEEP_MASSES = {False: (0.0, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0), True: (0.0, 0.2, 2.0)}  # [kg]
QUICK_DURATION = 1.5  # [s] of every run in quick mode (the specs' own: 3 s)
STATES = 50  # random states of the §4.1 and §4.3 comparisons
PD_OFF = 1e-9  # the finger PD gains that leave their terms off (the law takes positive gains)
_SERIAL = itertools.count()  # one extension module per name in a process: every build gets its own


def block_inertia(mass: float) -> float:
    return mass * (BLOCK[0] ** 2 + BLOCK[1] ** 2) / 12


# ---- the hand in closed form: StyxDefinitions.m ----------------------------------------------


@dataclass(frozen=True)
class Finger:
    """A finger of StyxDefinitions.m: two links l1, l2, point masses m1, m2 at the link tips,
    ABSOLUTE link angles th = (th1, th2) from the x axis, the base at (base, 0)."""

    base: float
    m1: float
    m2: float
    l1: float
    l2: float

    def tip(self, th) -> np.ndarray:  # TwoLinkKinematics
        return np.array(
            [
                self.base + self.l1 * np.cos(th[0]) + self.l2 * np.cos(th[1]),
                self.l1 * np.sin(th[0]) + self.l2 * np.sin(th[1]),
            ]
        )

    def jacobian(self, th) -> np.ndarray:
        return np.array(
            [[-self.l1 * np.sin(th[0]), -self.l2 * np.sin(th[1])], [self.l1 * np.cos(th[0]), self.l2 * np.cos(th[1])]]
        )

    def jacobian_dot(self, th, thd) -> np.ndarray:
        return np.array(
            [
                [-self.l1 * np.cos(th[0]) * thd[0], -self.l2 * np.cos(th[1]) * thd[1]],
                [-self.l1 * np.sin(th[0]) * thd[0], -self.l2 * np.sin(th[1]) * thd[1]],
            ]
        )

    def two_link_mass(self, th) -> np.ndarray:
        """TwoLinkMass as StyxDefinitions.m and eq 3.1 print it: M11 = m1 l1^2 + m2 l2^2. The
        point masses' kinetic energy gives M11 = (m1 + m2) l1^2 (the specs' form); the two are
        one number when l1 = l2, as on both fingers here."""
        c = self.m2 * self.l1 * self.l2 * np.cos(th[0] - th[1])
        return np.array([[self.m1 * self.l1**2 + self.m2 * self.l2**2, c], [c, self.m2 * self.l2**2]])

    def coriolis(self, th, thd) -> np.ndarray:
        """Coriolis[Mleft, ...] of RobotDynamics.m: Christoffel symbols of TwoLinkMass. Only
        M12 = a cos(th1 - th2), a = m2 l1 l2, depends on th: C12 = a sin(th1 - th2) th2',
        C21 = -a sin(th1 - th2) th1', C11 = C22 = 0."""
        s = self.m2 * self.l1 * self.l2 * np.sin(th[0] - th[1])
        return np.array([[0.0, s * thd[1]], [-s * thd[0], 0.0]])


@dataclass(frozen=True)
class StyxHand:
    """The two fingers grasping the box at (-r, 0) and (r, 0) in the box frame (Fig 2.1);
    box coordinates x_b = (x, y, psi), the box a planar rigid body of mass mb, inertia Jb."""

    left: Finger
    right: Finger
    r: float
    mb: float
    Jb: float

    @classmethod
    def from_spec(cls, data: dict, box_mass: float) -> StyxHand:
        def finger(node: str, sign: float) -> Finger:
            p = data["nodes"][node]["define"]["formulas"]["parameters"]
            return Finger(sign * float(p["b"]), float(p["m1"]), float(p["m2"]), float(p["l1"]), float(p["l2"]))

        points = np.array(data["nodes"]["hand"]["attach"]["constraint"]["planar_contacts"]["points"], float)
        r = float(points[1, 0])
        if not np.allclose(points, [[-r, 0.0], [r, 0.0]]) or r <= 0:
            raise ValueError(f"the grasp of Fig 2.1 holds the box at (-r, 0) and (r, 0), not at {points.tolist()}")
        return cls(finger("left", -1.0), finger("right", 1.0), r, box_mass, block_inertia(box_mass))

    def _split(self, theta):
        return np.asarray(theta[:2], float), np.asarray(theta[2:], float)

    def J(self, theta) -> np.ndarray:
        """The finger Jacobian, block diagonal (J of StyxDefinitions.m)."""
        tl, tr = self._split(theta)
        return _blockdiag(self.left.jacobian(tl), self.right.jacobian(tr))

    def Jdot(self, theta, theta_dot) -> np.ndarray:
        tl, tr = self._split(theta)
        dl, dr = self._split(theta_dot)
        return _blockdiag(self.left.jacobian_dot(tl, dl), self.right.jacobian_dot(tr, dr))

    def M_theta(self, theta) -> np.ndarray:
        tl, tr = self._split(theta)
        return _blockdiag(self.left.two_link_mass(tl), self.right.two_link_mass(tr))

    def C_theta(self, theta, theta_dot) -> np.ndarray:
        tl, tr = self._split(theta)
        dl, dr = self._split(theta_dot)
        return _blockdiag(self.left.coriolis(tl, dl), self.right.coriolis(tr, dr))

    def box(self, theta) -> np.ndarray:
        """g: the box between the fingertips. StyxDefinitions.m writes psi = ArcTan[xl - xr,
        yl - yr], which is psi + pi for its own RobotInverse[g] (xl = x - r cos psi; its
        second entry, printed x - r Sin[psi], is y - r sin psi); the inverse is taken as the
        definition: psi = atan2(yr - yl, xr - xl)."""
        tl, tr = self._split(theta)
        pl, pr = self.left.tip(tl), self.right.tip(tr)
        d = pr - pl
        return np.array([*(pl + pr) / 2, np.arctan2(d[1], d[0])])

    def G(self, psi: float) -> np.ndarray:
        """G of StyxDefinitions.m: box wrench (fx, fy, torque) from the fingertip forces."""
        r, c, s = self.r, np.cos(psi), np.sin(psi)
        return np.array([[1, 0, 1, 0], [0, 1, 0, 1], [r * s, -r * c, -r * s, r * c]], float)

    def Gdot(self, psi: float, psi_dot: float) -> np.ndarray:
        r, c, s = self.r, np.cos(psi), np.sin(psi)
        return psi_dot * np.array([[0, 0, 0, 0], [0, 0, 0, 0], [r * c, r * s, -r * c, -r * s]], float)

    def H(self, psi: float) -> np.ndarray:
        """The squeeze (1 x 4, unit, G H^T = 0): each fingertip pushes towards the other."""
        c, s = np.cos(psi), np.sin(psi)
        return np.array([[c, s, -c, -s]]) / np.sqrt(2)

    def Mb(self) -> np.ndarray:  # Mbox; Cbox and the box's N are zero
        return np.diag([self.mb, self.mb, self.Jb])

    def grasp(self, theta, xd_b):
        """At a grasping posture theta and box velocity xd_b: (x_b, G, J, A = J^-1 G^T,
        A' = d/dt(J^-1 G^T), the finger rates theta' = A xd_b (eq 3.3))."""
        x = self.box(theta)
        G, J = self.G(x[2]), self.J(theta)
        Ji = np.linalg.inv(J)
        A = Ji @ G.T
        theta_dot = A @ xd_b
        A_dot = -Ji @ self.Jdot(theta, theta_dot) @ A + Ji @ self.Gdot(x[2], xd_b[2]).T
        return x, G, J, A, A_dot, theta_dot


def _blockdiag(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros((a.shape[0] + b.shape[0], a.shape[1] + b.shape[1]))
    out[: a.shape[0], : a.shape[1]] = a
    out[a.shape[0] :, a.shape[1] :] = b
    return out


def _rel(a, b) -> float:
    """max |a - b| over the larger of max |a| and max |b| (0 when both are zero)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    scale = max(np.abs(b).max(), np.abs(a).max())
    return float(np.abs(a - b).max() / scale) if scale > 0 else 0.0


# ---- modules --------------------------------------------------------------------------------


class Builds:
    """Every (spec, box mass) compiled once into ``root``: a copy of the spec with the box's
    mass (and the block's inertia) set and a name of its own, built by `robotgen build`."""

    def __init__(self, root: Path):
        self.root = root
        self.yaml = YAML(typ="safe")
        self.yaml.default_flow_style = None
        self.yaml.width = 4096
        self.built: dict[tuple[str, float], tuple[object, Path]] = {}

    def spec_data(self, spec: str) -> dict:
        return self.yaml.load(SPECS / f"{spec}.yaml")

    def __call__(self, spec: str, box_mass: float) -> tuple[object, Path]:
        """(the imported module, the spec it was built from)."""
        key = (spec, float(box_mass))
        if key not in self.built:
            data = self.spec_data(spec)
            name = f"deno1990_{spec.removeprefix('styx_')}_{next(_SERIAL)}"
            data["name"] = name
            data["nodes"]["box"]["define"]["rigid_body"]["planar"] = {
                "mass": float(box_mass),
                "inertia": block_inertia(box_mass),
            }
            path = self.root / f"{name}.yaml"
            with open(path, "w") as f:
                self.yaml.dump(data, f)
            out = self.root / name
            with contextlib.redirect_stdout(io.StringIO()):
                status = robotgen(["build", str(path), "-o", str(out), "-q"])
            if status != 0:
                raise RuntimeError(f"robotgen build {path} -o {out} exited with status {status}")
            self.built[key] = (simulate.load_module(out, name), path)
        return self.built[key]


# ---- §4.1: the expanded high-level computed torque law -----------------------------------------


def random_grasp(module, hand: StyxHand, rng, start: np.ndarray):
    """A grasping posture near ``start`` (by the module's inverse kinematics), a box velocity,
    and a desired trajectory near it."""
    theta = module.plant_inverse(start + rng.uniform([-0.02, -0.02, -0.3], [0.02, 0.02, 0.3]))
    xd_b = rng.normal(size=3) * [0.1, 0.1, 1.0]
    x = hand.box(theta)
    x_d = x + rng.normal(size=3) * [0.005, 0.005, 0.05]
    v_d = xd_b + rng.normal(size=3) * [0.02, 0.02, 0.2]
    a_d = rng.normal(size=3) * [0.5, 0.5, 5.0]
    return theta, xd_b, x_d, v_d, a_d


def leaf_attributes(module, theta, theta_dot):
    """M_theta and C_theta: the compiled leaves' own M and C, block diagonal."""
    return (
        _blockdiag(module.left_mass(theta), module.right_mass(theta)),
        _blockdiag(module.left_coriolis(theta, theta_dot), module.right_coriolis(theta, theta_dot)),
    )


def high_level_torque(hand: StyxHand, M_theta, C_theta, theta, xd_b, x_d, v_d, a_d, kp, kv) -> np.ndarray:
    """§4.1's last line: tau = J^T G^+ [(M_b + G J^-T M_theta J^-1 G^T)(xdd_d + Kv e' + Kp e)
    + (C_b + G J^-T C_theta J^-1 G^T) xd_b + G J^-T M_theta d/dt(J^-1 G^T) xd_b], C_b = 0."""
    x, G, J, A, A_dot, _ = hand.grasp(theta, xd_b)
    M_h = hand.Mb() + A.T @ M_theta @ A  # A = J^-1 G^T, so A^T = G J^-T
    C_h = A.T @ C_theta @ A + A.T @ M_theta @ A_dot
    a = a_d + kv * (v_d - xd_b) + kp * (x_d - x)
    G_pinv = G.T @ np.linalg.inv(G @ G.T)
    return J.T @ G_pinv @ (M_h @ a + C_h @ xd_b)


def servo(module, theta, theta_dot, x_d, v_d, a_d, **gains) -> np.ndarray:
    """The compiled servo step's torques, every expected trajectory starting at the current
    state (servo_init), no force from above, no squeeze."""
    state = module.servo_init(theta, theta_dot)
    z = np.zeros(3)
    tau, _ = module.servo_step(theta, theta_dot, x_d, v_d, a_d, z, np.zeros(1), state, 1e-3, **gains)
    return tau


def check_high_level_law(high, hand: StyxHand, rng, start, kp, kv) -> dict[str, float]:
    """The compiled torques against the formula; and in the true plant they give the box the
    acceleration xdd_d + Kv e' + Kp e (computed torque linearises exactly, eq 2.8)."""
    formula = linear = 0.0
    for _ in range(STATES):
        theta, xd_b, x_d, v_d, a_d = random_grasp(high, hand, rng, start)
        x, theta_dot = hand.box(theta), hand.grasp(theta, xd_b)[5]
        M_theta, C_theta = leaf_attributes(high, theta, theta_dot)
        want = high_level_torque(hand, M_theta, C_theta, theta, xd_b, x_d, v_d, a_d, kp, kv)
        got = servo(high, theta, theta_dot, x_d, v_d, a_d, ct_hand_kp=kp, ct_hand_kv=kv)
        formula = max(formula, _rel(got, want))
        a_e = a_d + kv * (v_d - xd_b) + kp * (x_d - x)
        linear = max(linear, _rel(high.plant_dynamics(theta, xd_b, got)[1], a_e))
    return {"s41_formula_rel": formula, "s41_box_acceleration_rel": linear}


# ---- §4.3: multi-level against high-level computed torque ------------------------------------


def check_multilevel(high, multi, hand: StyxHand, rng, start, kp, kv) -> dict[str, float]:
    """At states where every expected trajectory is the current state (servo_init: the
    fingers are on the trajectory the feedforward resolves, so the PD terms vanish), the two
    structures' joint torques are split into the box wrench G J^-T tau and the squeeze
    H J^-T tau. Their box wrenches are compared, also of the part due to the box error alone
    (tau at x_d less tau at x_d = x), and the squeeze of the multi-level torques is compared
    with the closed form H (M_f xdd_f + C_f xd_f) (the feedforward on the fingertips: M_f =
    J^-T M_theta J^-1, C_f = J^-T (C_theta J^-1 + M_theta d/dt J^-1), eqs 3.4-3.5 of the
    frame change; xd_f = G^T xd_b, xdd_f = G^T xdd_e + G'^T xd_b)."""
    w = dict.fromkeys(
        ("pd", "wrench", "error_wrench", "squeeze", "high_squeeze", "accel", "carried_high", "carried_multi"), 0.0
    )
    torque_gap, error_gap = [], []
    # the finger PD gains doubled: the torques move only by what the PD terms add
    doubled_pd = {k: 2 * np.asarray(v) for k, v in multi.parameters.items() if k.startswith("pd_")}
    gains = {"ct_hand_kp": kp, "ct_hand_kv": kv}
    for _ in range(STATES):
        theta, xd_b, x_d, v_d, a_d = random_grasp(high, hand, rng, start)
        x, G, J, A, A_dot, theta_dot = hand.grasp(theta, xd_b)
        Jit = np.linalg.inv(J).T
        H = hand.H(x[2])
        tau_h = servo(high, theta, theta_dot, x_d, v_d, a_d, **gains)
        tau_m = servo(multi, theta, theta_dot, x_d, v_d, a_d, **gains)
        w["pd"] = max(w["pd"], _rel(servo(multi, theta, theta_dot, x_d, v_d, a_d, **gains, **doubled_pd), tau_m))
        w["wrench"] = max(w["wrench"], _rel(G @ Jit @ tau_m, G @ Jit @ tau_h))
        # the part of tau due to the box error e = x_d - x
        d_h = tau_h - servo(high, theta, theta_dot, x, v_d, a_d, **gains)
        d_m = tau_m - servo(multi, theta, theta_dot, x, v_d, a_d, **gains)
        w["error_wrench"] = max(w["error_wrench"], _rel(G @ Jit @ d_m, G @ Jit @ d_h))
        error_gap.append(_rel(d_m, d_h))
        torque_gap.append(_rel(tau_m, tau_h))
        # the squeeze: none in the high-level torques (J^T G^+ has no H part), the feedforward's
        M_theta, C_theta = leaf_attributes(multi, theta, theta_dot)
        Ji = np.linalg.inv(J)
        M_f = Jit @ M_theta @ Ji
        C_f = Jit @ (C_theta @ Ji + M_theta @ (-Ji @ hand.Jdot(theta, theta_dot) @ Ji))
        a_e = a_d + kv * (v_d - xd_b) + kp * (x_d - x)
        xdd_f = G.T @ a_e + hand.Gdot(x[2], xd_b[2]).T @ xd_b
        squeeze = H @ (M_f @ xdd_f + C_f @ (G.T @ xd_b))
        w["squeeze"] = max(w["squeeze"], _rel(H @ Jit @ tau_m, squeeze))
        w["high_squeeze"] = max(w["high_squeeze"], float(np.abs(H @ Jit @ tau_h).max() / np.abs(tau_h).max()))
        # the true plant: both give the box one acceleration, and the grasp carries the squeeze
        # the high-level torques leave to it, -H (M_f xdd_f + C_f xd_f), and none of the others
        v = high.plant_velocity(theta, theta_dot)
        w["accel"] = max(
            w["accel"], _rel(high.plant_dynamics(theta, v, tau_m)[1], high.plant_dynamics(theta, v, tau_h)[1])
        )
        w["carried_high"] = max(w["carried_high"], _rel(high.plant_internal_forces(theta, v, tau_h), -squeeze))
        carried = high.plant_internal_forces(theta, v, tau_m)
        w["carried_multi"] = max(w["carried_multi"], float(np.abs(carried).max() / np.abs(squeeze).max()))
    return {
        "s43_pd_terms_rel": w["pd"],
        "s43_box_wrench_rel": w["wrench"],
        "s43_error_box_wrench_rel": w["error_wrench"],
        "s43_squeeze_rel": w["squeeze"],
        "s43_high_level_squeeze": w["high_squeeze"],
        "s43_box_acceleration_rel": w["accel"],
        "s43_high_carried_squeeze_rel": w["carried_high"],
        "s43_multi_carried_squeeze": w["carried_multi"],
        "s43_joint_torque_gap_median": float(np.median(torque_gap)),
        "s43_error_torque_gap_median": float(np.median(error_gap)),
    }


# ---- Appendix A: Examples.m's sample computations ---------------------------------------------


def appendix_a(high, low, multi, hand: StyxHand, start) -> tuple[dict[str, float], list[tuple]]:
    """RobotMass (and RobotCoriolis[fingers]) at the start pose, from the compiled node
    functions, against StyxDefinitions.m's closed forms. Returns the numbers (``a_<entry>``:
    max |robotgen - closed form| over max |closed form|, or max |robotgen| where the closed form
    is zero) and the report's rows (Examples.m, what the paper says, robotgen, closed form, key)."""
    theta = high.plant_inverse(start)
    x, G, J, A, A_dot, theta_dot = hand.grasp(theta, np.array([0.03, -0.02, 0.4]))
    M_theta, C_theta = hand.M_theta(theta), hand.C_theta(theta, theta_dot)
    Ji = np.linalg.inv(J)
    left = hand.left.two_link_mass(theta[:2])
    box = hand.Mb()
    entries = [  # key, Examples.m, the paper's words, robotgen's value, its name, the closed form and its name
        (
            "left",
            "RobotMass[left]",
            "the finger's mass matrix",
            high.left_mass(theta),
            "left_mass",
            left,
            "TwoLinkMass (eq 3.1)",
        ),
        (
            "hand",
            "RobotMass[hand]",
            "the composite mass in box coordinates",
            high.hand_mass(theta),
            "hand_mass",
            box + G @ Ji.T @ M_theta @ Ji @ G.T,
            "M_b + G J^-T M_theta J^-1 G^T (eqs 2.3, 3.4)",
        ),
        (
            "high_ct_hand",
            "RobotMass[HighCThand]",
            '"this should be zero"',
            high.ct_hand_mass(theta),
            "ct_hand_mass",
            np.zeros((3, 3)),
            "0",
        ),
        (
            "low_ct_hand",
            "RobotMass[LowCThand]",
            '"just the box mass"',
            low.hand_mass(theta),
            "hand_mass (Fig 4.2 tree)",
            box,
            "diag(M_b, M_b, J_b)",
        ),
        (
            "fingers_coriolis",
            "RobotCoriolis[fingers, ...]",
            "evaluated at a point",
            high.fingers_coriolis(theta, theta_dot),
            "fingers_coriolis",
            Ji.T @ (C_theta @ Ji + M_theta @ (-Ji @ hand.Jdot(theta, theta_dot) @ Ji)),
            "J^-T (C_theta J^-1 + M_theta d/dt J^-1) (eq 3.5)",
        ),
        # the multi-level tree (Fig 4.3): the feedforward absorbs the fingers, PD passes them on
        (
            "ff",
            "(Fig 4.3) RobotMass[ff]",
            "feedforward: no mass left",
            multi.ff_mass(theta),
            "ff_mass",
            np.zeros((4, 4)),
            "0",
        ),
        (
            "multilevel_hand",
            "(Fig 4.3) RobotMass[hand]",
            "the box alone",
            multi.hand_mass(theta),
            "hand_mass (Fig 4.3 tree)",
            box,
            "diag(M_b, M_b, J_b)",
        ),
        (
            "pd_left",
            "(Fig 4.3) RobotMass[pd_left]",
            "PD passes the finger on",
            multi.pd_left_mass(theta),
            "pd_left_mass",
            left,
            "TwoLinkMass",
        ),
    ]
    numbers, rows = {}, []
    for key, example, says, got, name, closed, form in entries:
        numbers[f"a_{key}"] = _rel(got, closed) if np.abs(closed).max() > 0 else float(np.abs(got).max())
        rows.append((example, says, name, form, f"a_{key}"))
    numbers["a_hand_min_eig_over_box"] = float(np.linalg.eigvalsh(high.hand_mass(theta) - box).min())
    return numbers, rows


# ---- simulations ------------------------------------------------------------------------------


def settings_of(path: Path, quick: bool, **changes) -> simulate.Settings:
    """The spec's simulation section, without its squeeze: chapter 4 leaves the internal
    forces out (§4.1), and the specs' 1 N squeeze, there for MuJoCo's contacts, moves
    robotgen's plant too, if only by ~1e-6 m (the held torques act at every RK4 stage)."""
    s = load_system(str(path)).simulation
    changes.setdefault("internal_forces", ())
    if quick:
        changes.setdefault("duration", min(s.duration, QUICK_DURATION))
    return dataclasses.replace(s, **changes)


def rms_errors(result: simulate.Result, since: float = 0.0) -> tuple[float, float]:
    """RMS over t >= since of the box centre's position error |(e_x, e_y)| [m] and of the
    angle error e_psi [rad]."""
    late = result.t >= since - 1e-12
    e = result.error[late]
    return float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2))), float(np.sqrt(np.mean(e[:, 2] ** 2)))


class WithGains:
    """A module whose servo_step runs with some run-time gains changed."""

    def __init__(self, module, **gains):
        self._module, self._gains = module, gains

    def __getattr__(self, name):
        return getattr(self._module, name)

    def servo_step(self, *args):
        return self._module.servo_step(*args, **self._gains)


def simulate_structures(builds: Builds, mass: float, quick: bool, out: Path) -> tuple[dict, dict]:
    """Figs 4.1-4.3 on the specs' common box path (from start + initial_error), each plotted
    as `robotgen simulate` plots it; Fig 4.3 once more with its finger PDs' gains at zero."""
    results, numbers = {}, {}
    for fig, (spec, what) in STRUCTURES.items():
        module, path = builds(spec, mass)
        s = settings_of(path, quick)
        res = simulate.run(module, s)
        results[fig] = res
        simulate.plot(res, out / f"fig{fig.replace('.', '_')}.png", f"Fig {fig}: {what} ({spec}, box {mass:g} kg)")
        key = f"fig{fig.replace('.', '')}"
        numbers[f"{key}_position_rms_late"], numbers[f"{key}_angle_rms_late"] = rms_errors(res, s.duration / 2)
        numbers[f"{key}_max_torque"] = float(np.abs(res.tau).max())
        numbers[f"{key}_max_squeeze"] = float(np.abs(res.f_actual).max())
    # the PD gains as small as the law takes them (positive): 1e-9, their terms effectively off
    no_pd = WithGains(
        builds(STRUCTURES["4.3"][0], mass)[0],
        **{f"pd_{side}_{k}": PD_OFF for side in ("left", "right") for k in ("kp", "kv")},
    )
    res = simulate.run(no_pd, s)
    numbers["fig43_max_squeeze_without_pd"] = float(np.abs(res.f_actual).max())
    return results, numbers


def sweep_box_mass(builds: Builds, masses, quick: bool) -> dict[str, float]:
    """Figs 4.1 and 4.2 on the same path, started on it (no initial error), for each box mass:
    the RMS tracking errors of the whole run; Fig 4.1 at the first mass also at half the
    servo period."""
    numbers: dict[str, float] = {}
    for i, mass in enumerate(masses):
        numbers[f"sweep_mass_{i}"] = float(mass)
        for fig in ("4.1", "4.2"):
            module, path = builds(STRUCTURES[fig][0], mass)
            res = simulate.run(module, settings_of(path, quick, initial_error=()))
            key = f"fig{fig.replace('.', '')}"
            numbers[f"{key}_position_rms_{i}"], numbers[f"{key}_angle_rms_{i}"] = rms_errors(res)
    # the servo's zero-order hold: Fig 4.1's error at half the period (first order: half of it)
    module, path = builds(STRUCTURES["4.1"][0], masses[0])
    s = settings_of(path, quick, initial_error=())
    res = simulate.run(module, dataclasses.replace(s, dt=s.dt / 2))
    numbers["fig41_position_rms_half_dt"] = rms_errors(res)[0]
    return numbers


# ---- figures and report -----------------------------------------------------------------------


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_structures(results: dict[str, simulate.Result], path: Path, mass: float, offset) -> None:
    """The three structures' box errors and squeeze on one time axis."""
    plt = _pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    for fig_no, res in results.items():
        label = f"Fig {fig_no}: {STRUCTURES[fig_no][1]}"
        e = res.error
        axes[0].semilogy(res.t, np.maximum(np.hypot(e[:, 0], e[:, 1]), 1e-12), label=label)
        axes[1].semilogy(res.t, np.maximum(np.abs(e[:, 2]), 1e-12), label=label)
        axes[2].plot(res.t, res.f_actual[:, 0], label=label)
    axes[0].set_ylabel("|(e_x, e_y)| [m]")
    axes[1].set_ylabel("|e_psi| [rad]")
    axes[2].set_ylabel("squeeze carried [N]")
    axes[2].set_xlabel("t [s]")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    off = ", ".join(f"{v:g}" for v in offset)
    fig.suptitle(f"Deno et al. 1990, Figs 4.1-4.3 on one box path (box {mass:g} kg, started ({off}) off it)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_sweep(numbers: dict[str, float], n: int, path: Path) -> None:
    plt = _pyplot()
    masses = [numbers[f"sweep_mass_{i}"] for i in range(n)]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, what, unit in ((axes[0], "position", "m"), (axes[1], "angle", "rad")):
        for key, label, marker in (
            ("fig41", "Fig 4.1: high-level computed torque", "o"),
            ("fig42", "Fig 4.2: low-level computed torque", "s"),
        ):
            ax.semilogy(masses, [numbers[f"{key}_{what}_rms_{i}"] for i in range(n)], marker=marker, label=label)
        ax.set_xscale("symlog", linthresh=0.05)
        ax.set_xticks(masses, [f"{m:g}" for m in masses])
        ax.set_xlabel("box mass [kg] (a 10 cm x 6 cm block; symlog axis)")
        ax.set_ylabel(f"RMS {what} error [{unit}]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("§4.2: tracking error against box mass, one box path, started on it")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def write_report(
    path: Path,
    numbers: dict[str, float],
    rows: list[tuple],
    n_sweep: int,
    mass: float,
    quick: bool,
    duration: float,
    initial_error,
) -> None:
    g = numbers
    offset = ", ".join(f"{v:g}" for v in initial_error)
    lines = [
        "# Deno, Murray, Pister, Sastry 1990: control primitives, reproduced",
        "",
        '"Control Primitives for Robot Systems" (UCB/ERL M90/39) builds a planar two-fingered hand',
        "holding a box from DEFINE, ATTACH and CONTROL and puts it under three control structures",
        "(Figs 4.1-4.3). The paper gives the structures, the expanded high-level law (§4.1) and",
        "qualitative claims; Appendix A's Examples.m lists sample computations with the expected",
        "answers in comments. It reports no simulation. robotgen compiles the three trees",
        "(specs/styx_high_ct.yaml, styx_low_ct.yaml, styx_multilevel.yaml) and the numbers below",
        "come from the compiled modules against closed forms written from StyxDefinitions.m."
        + (" **Quick mode**: shorter runs, fewer box masses." if quick else ""),
        "",
        "## Appendix A: Examples.m at the start pose (box at (0, 0.12 m, 0))",
        "",
        "| Examples.m | the paper says | robotgen | closed form | difference (relative; absolute where 0) |",
        "| --- | --- | --- | --- | --- |",
    ]
    lines += [f"| `{a}` | {b} | `{c}` | {d} | {g[k]:.1e} |" for a, b, c, d, k in rows]
    lines += [
        "",
        "A controlled node's M, C, N are what the law leaves to the level above (§3.4): zero for",
        "computed torque and feedforward (Examples.m's `zeroMass`), the robot's own for PD. robotgen",
        "exposes them as `<node>_mass` etc., so each entry is read directly.",
        "The uncontrolled hand's M exceeds the box's by a positive definite matrix (smallest",
        f"eigenvalue {g['a_hand_min_eig_over_box']:.3g}): the fingers' share, which both controlled hands hide.",
        "",
        "## §4.1: the expanded high-level computed torque law",
        "",
        f"At {STATES} random grasping states (box velocity, desired position, velocity and acceleration",
        "random), the compiled servo step of Fig 4.1 against the paper's formula evaluated in numpy",
        "from the leaves' M and C and the closed-form J, J', G, G':",
        f"largest relative difference **{g['s41_formula_rel']:.1e}**. In the true plant these torques",
        "give the box the acceleration xdd_d + Kv e' + Kp e (exact linearisation, eq 2.8): largest",
        f"relative difference {g['s41_box_acceleration_rel']:.1e}.",
        "",
        "## §4.2: low-level computed torque against box mass",
        "",
        '"This controller is provably exponentially stable when the mass of the box is zero. However,',
        "this controller does not compensate for the mass of the box. As a result, we expect degraded",
        "performance if the mass of the box is large.\" Both structures fly the specs' box path",
        f"({duration:g} s, started on the path), the box's inertia that of a 10 cm x 6 cm block:",
        "",
        "| box mass [kg] | Fig 4.1 RMS position [m] | Fig 4.2 RMS position [m] | Fig 4.1 RMS angle [rad] "
        "| Fig 4.2 RMS angle [rad] |",
        "| --- | --- | --- | --- | --- |",
    ]
    for i in range(n_sweep):
        lines.append(
            f"| {g[f'sweep_mass_{i}']:g} | {g[f'fig41_position_rms_{i}']:.2e} | "
            f"{g[f'fig42_position_rms_{i}']:.2e} | {g[f'fig41_angle_rms_{i}']:.2e} | "
            f"{g[f'fig42_angle_rms_{i}']:.2e} |"
        )
    lines += [
        "",
        "Fig 4.2's error grows with the box mass, about in proportion; Fig 4.1's, whose top",
        "controller carries the box in M_h, does not. With a massless box the two are equal, both",
        "at the level the servo's zero-order hold leaves: Fig 4.1 at half the servo period",
        f"({g['sweep_mass_0']:g} kg) has {g['fig41_position_rms_half_dt']:.2e} m instead of "
        f"{g['fig41_position_rms_0']:.2e} m (`box_mass_sweep.png`).",
        "",
        "## §4.3: multi-level against high-level computed torque",
        "",
        '"If we ignore the additional torques due to the PD terms, the joint torques generated due',
        "to an error in the box position are the same as those of the high level computed torque",
        f'scheme." At {STATES} random states on the resolved trajectory (every expected trajectory',
        "at the current state, so the PD terms vanish):",
        "",
        "| quantity | largest relative difference |",
        "| --- | --- |",
        f"| multi-level torques with the PD gains and with them doubled | {g['s43_pd_terms_rel']:.1e} |",
        f"| box wrench G J^-T tau, multi-level vs high-level | {g['s43_box_wrench_rel']:.1e} |",
        f"| box wrench of the error-driven torques (tau at x_d less tau at x) | {g['s43_error_box_wrench_rel']:.1e} |",
        f"| the box's acceleration in the true plant under either torque | {g['s43_box_acceleration_rel']:.1e} |",
        f"| multi-level squeeze H J^-T tau vs H (M_f xdd_f + C_f xd_f) | {g['s43_squeeze_rel']:.1e} |",
        f"| high-level squeeze H J^-T tau over max abs tau | {g['s43_high_level_squeeze']:.1e} |",
        f"| squeeze the grasp carries (plant) under the high-level torques vs -H (M_f xdd_f + C_f xd_f) "
        f"| {g['s43_high_carried_squeeze_rel']:.1e} |",
        f"| squeeze the grasp carries under the multi-level torques, over the above | "
        f"{g['s43_multi_carried_squeeze']:.1e} |",
        "",
        "The claim holds for everything that moves the box: the wrench on it, and so its",
        "acceleration, are the same. The joint torques themselves are not: they differ by a squeeze",
        f"(median relative difference {g['s43_joint_torque_gap_median']:.2f} of the whole torques,",
        f"{g['s43_error_torque_gap_median']:.2f} of the error-driven ones). The high-level law sends",
        "J^T G^+ M_h xdd_e: fingertip forces in the range of G^+, no squeeze commanded. But part of",
        "them accelerates the fingers, M_f xdd_f + C_f xd_f, and that part's squeeze component is",
        "left to the contacts: the grasp carries -H (M_f xdd_f + C_f xd_f) although the command",
        "was zero. The multi-level feedforward sends that force on the fingertips itself",
        "(J^T (M_f xdd_f + C_f xd_f + G^+ M_b xdd_e)), and the grasp carries no squeeze. Chapters",
        '3-4 leave internal forces out (§3; §4.1: "with the omission of internal forces"); in that',
        "sense the two are equal.",
        "",
        f"## Figs 4.1-4.3 on one box path (box {mass:g} kg)",
        "",
        f"The specs' path over {duration:g} s, the plant started ({offset}) off it (x, y [m], psi [rad]).",
        "RMS over the second half of the run:",
        "",
        "| structure | RMS position [m] | RMS angle [rad] | max abs torque [N m] | max abs squeeze [N] |",
        "| --- | --- | --- | --- | --- |",
    ]
    for fig, (_, what) in STRUCTURES.items():
        k = f"fig{fig.replace('.', '')}"
        lines.append(
            f"| Fig {fig}: {what} | {g[f'{k}_position_rms_late']:.2e} | {g[f'{k}_angle_rms_late']:.2e} | "
            f"{g[f'{k}_max_torque']:.3g} | {g[f'{k}_max_squeeze']:.3g} |"
        )
    lines += [
        "",
        "Figs 4.1 and 4.3 move the box alike (their error curves in `structures.png` overlap);",
        "Fig 4.2 keeps an error after the transient, the box's inertia that no controller",
        "compensates. No squeeze is commanded, and the grasp carries one in Figs 4.1 and 4.2 (in",
        "Fig 4.1 the fingers' inertial squeeze, see §4.3). In Fig 4.3 it stays small but grows: the feedforward",
        "integrates its expected fingertip path open loop, that path drifts from the grasp, and the",
        f"finger PDs press against it; with their gains at {PD_OFF:g} the squeeze stays below",
        f"{g['fig43_max_squeeze_without_pd']:.1e} N.",
        "",
        "Figures: `fig4_1.png`, `fig4_2.png`, `fig4_3.png` (each as `robotgen simulate` plots it:",
        "box coordinates against the reference, errors, joint torques, the squeeze the grasp",
        "carries), `structures.png` (the three side by side), `box_mass_sweep.png`.",
        "",
    ]
    path.write_text("\n".join(lines))


# ---- the whole reproduction --------------------------------------------------------------------


def reproduce(out: Path, quick: bool = False) -> dict[str, float]:
    """Builds the hand's trees, checks the claims, writes the PNGs and report.md into ``out``
    and returns the numbers."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(1990)
    masses = SWEEP_MASSES[quick]
    with tempfile.TemporaryDirectory(prefix="deno1990-") as tmp:
        builds = Builds(Path(tmp))
        data = builds.spec_data(STRUCTURES["4.1"][0])
        mass = float(data["nodes"]["box"]["define"]["rigid_body"]["planar"]["mass"])
        ct = data["nodes"]["ct_hand"]["control"]
        kp, kv = float(ct["kp"]), float(ct["kv"])
        start = np.asarray(data["simulation"]["start"], float)
        hand = StyxHand.from_spec(data, mass)
        (high, _), (low, _), (multi, _) = (builds(spec, mass) for spec, _ in STRUCTURES.values())

        numbers: dict[str, float] = {}
        a_numbers, rows = appendix_a(high, low, multi, hand, start)
        numbers.update(a_numbers)
        numbers.update(check_high_level_law(high, hand, rng, start, kp, kv))
        numbers.update(check_multilevel(high, multi, hand, rng, start, kp, kv))
        results, fig_numbers = simulate_structures(builds, mass, quick, out)
        numbers.update(fig_numbers)
        plot_structures(results, out / "structures.png", mass, data["simulation"]["initial_error"])
        numbers.update(sweep_box_mass(builds, masses, quick))
        plot_sweep(numbers, len(masses), out / "box_mass_sweep.png")
        duration = float(results["4.1"].t[-1])
    write_report(
        out / "report.md", numbers, rows, len(masses), mass, quick, duration, data["simulation"]["initial_error"]
    )
    return numbers


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--quick", action="store_true", help=f"{QUICK_DURATION:g} s runs, {len(SWEEP_MASSES[True])} box masses"
    )
    p.add_argument("-o", "--output", type=Path, default=DEFAULT_OUTPUT, help=f"default {DEFAULT_OUTPUT}")
    args = p.parse_args()
    if args.output.exists() and not args.output.is_dir():
        p.error(f"-o {args.output}: not a directory")
    numbers = reproduce(args.output, quick=args.quick)
    width = max(map(len, numbers))
    for k, v in numbers.items():
        print(f"{k:<{width}}  {v:.6g}")
    for f in sorted(args.output.iterdir()):
        print(f"wrote {f}")


if __name__ == "__main__":
    main()
