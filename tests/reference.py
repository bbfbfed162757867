"""Independent references for the tests: nothing here imports robotgen.

The spec YAML is read with plain PyYAML and a tiny constant-expression evaluator, and the
reference models are built from those numbers by hand (closed forms) or by Pinocchio, so a
bug in robotgen's spec loader, DH normalisation or dynamics cannot hide in the reference.
"""

from __future__ import annotations

import ast
import math
import operator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

_BINOPS = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
}
_NAMES = {"pi": math.pi, "e": math.e}


def const(value) -> float:
    """A spec number: a YAML number or a string holding a constant expression."""
    if isinstance(value, (int, float)):
        return float(value)
    tree = ast.parse(str(value).replace("^", "**"), mode="eval")

    def ev(node):
        if isinstance(node, ast.Expression):
            return ev(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
            return float(node.value)
        if isinstance(node, ast.Name) and node.id in _NAMES:
            return _NAMES[node.id]
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            v = ev(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            return _BINOPS[type(node.op)](ev(node.left), ev(node.right))
        raise ValueError(f"not a constant expression: {value!r}")

    return ev(tree)


def load_doc(path) -> dict:
    with open(path) as f:
        return yaml.safe_load(f)


def root_define(doc: dict) -> dict:
    return doc["nodes"][doc["root"]]["define"]


# ---------------------------------------------------------------------------------------
# DH chains
# ---------------------------------------------------------------------------------------


@dataclass
class DHJoint:
    prismatic: bool
    a: float
    alpha: float
    d: float
    theta: float
    mass: float
    com: np.ndarray
    inertia: np.ndarray  # 3x3 about the COM, link frame
    armature: float
    viscous: float
    coulomb: float
    lower: float | None
    upper: float | None


@dataclass
class DHChain:
    name: str
    joints: list[DHJoint]
    gravity: np.ndarray
    coulomb_smoothing: float

    @property
    def nq(self) -> int:
        return len(self.joints)


def dh_chain(path) -> DHChain:
    """Reads a `chain` spec with convention dh_standard, identity base and tool."""
    doc = load_doc(path)
    chain = root_define(doc)["chain"]
    assert chain["convention"] == "dh_standard", "reference handles dh_standard only"
    assert "base" not in chain and "tool" not in chain, "reference assumes identity base/tool"
    joints = []
    for j in chain["joints"]:
        dh = {k: const(j["dh"].get(k, 0)) for k in ("a", "alpha", "d", "theta")}
        link = j.get("link", {})
        inr = link.get("inertia", {})
        g = lambda k: const(inr.get(k, 0))  # noqa: E731
        inertia = np.array(
            [
                [g("ixx"), g("ixy"), g("ixz")],
                [g("ixy"), g("iyy"), g("iyz")],
                [g("ixz"), g("iyz"), g("izz")],
            ]
        )
        motor = j.get("motor", {})
        fr = j.get("friction", {})
        lim = j.get("limits", {})
        joints.append(
            DHJoint(
                prismatic=j.get("type", "revolute") == "prismatic",
                mass=const(link.get("mass", 0)),
                com=np.array([const(c) for c in link.get("com", [0, 0, 0])]),
                inertia=inertia,
                armature=const(motor.get("inertia", 0)) * const(motor.get("gear_ratio", 1)) ** 2,
                viscous=const(fr.get("viscous", 0)),
                coulomb=const(fr.get("coulomb", 0)),
                lower=const(lim["lower"]) if "lower" in lim else None,
                upper=const(lim["upper"]) if "upper" in lim else None,
                **dh,
            )
        )
    return DHChain(
        name=doc["name"],
        joints=joints,
        gravity=np.array([const(c) for c in chain.get("gravity", [0, 0, -9.81])]),
        coulomb_smoothing=const(chain.get("coulomb_smoothing", 0.01)),
    )


def rotz(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def rotx(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def trans(x, y, z):
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def dh_fk(chain: DHChain, q) -> np.ndarray:
    """Tip pose by the plain standard-DH product (no Pinocchio): the reference for fk."""
    T = np.eye(4)
    for j, qi in zip(chain.joints, q):
        theta = j.theta + (0.0 if j.prismatic else qi)
        d = j.d + (qi if j.prismatic else 0.0)
        T = T @ rotz(theta) @ trans(0, 0, d) @ trans(j.a, 0, 0) @ rotx(j.alpha)
    return T


def friction_torque(chain: DHChain, qd) -> np.ndarray:
    """spec-format.md: tau_f = viscous * qd + coulomb * tanh(qd / coulomb_smoothing)."""
    qd = np.asarray(qd, dtype=float)
    v = np.array([j.viscous for j in chain.joints])
    c = np.array([j.coulomb for j in chain.joints])
    return v * qd + c * np.tanh(qd / chain.coulomb_smoothing)


def random_q(chain: DHChain, rng, n: int) -> np.ndarray:
    """Random configurations: inside the limits where given, else in [-pi, pi]."""
    lo = np.array([j.lower if j.lower is not None else -math.pi for j in chain.joints])
    hi = np.array([j.upper if j.upper is not None else math.pi for j in chain.joints])
    return lo + (hi - lo) * rng.random((n, chain.nq))


def skew(v) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def wrist_centre_blocks(J: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(J11, J12, J22, r) of a 6-joint arm whose axes 4-6 meet in the wrist centre c, from its
    hand Jacobian J (rows v, w) alone: joint i >= 4 moves the hand origin p at w_i x (p - c),
    so r = p - c solves [w_i x] r = v_i (least squares over the three), and the twist at c,
    (v - w x r, w), has the linear rows J_v + [r x] J_w. J11, J12 are their columns 1-3 and 4-6
    (J12 = 0 when the premise holds), J22 the angular rows' columns 4-6."""
    Jv, Jw = J[:3], J[3:]
    r = np.linalg.lstsq(np.vstack([skew(Jw[:, i]) for i in range(3, 6)]), Jv[:, 3:].T.ravel(), rcond=None)[0]
    Jc = Jv + skew(r) @ Jw
    return Jc[:, :3], Jc[:, 3:], Jw[:, 3:], r


def hadamard_ratios(J: np.ndarray) -> tuple[float, float]:
    """|det| over the product of the column norms (Hadamard's bound) of the two diagonal blocks
    of J at the wrist centre (wrist_centre_blocks): 1 for orthogonal columns, 0 when singular."""
    J11, _, J22, _ = wrist_centre_blocks(J)
    return tuple(abs(np.linalg.det(B)) / np.prod(np.linalg.norm(B, axis=0)) for B in (J11, J22))


# ---------------------------------------------------------------------------------------
# Pinocchio model built from the DH numbers
# ---------------------------------------------------------------------------------------


def pinocchio_model(chain: DHChain):
    """(model, tool_frame_id) of the chain, built joint by joint.

    Standard DH: frame_i = frame_{i-1} Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i), the joint
    variable added to theta_i (revolute) or d_i (prismatic). Pinocchio's joint i is placed at
    frame_{i-1} Rz(theta_i) (the constant theta offset; the motion is Rz(q) or Tz(q) about /
    along its z); the rest of link i, S_i = Tz(d_i) Tx(a_i) Rx(alpha_i), is the placement of
    link frame i in joint i's frame. So joint i+1 sits at S_i Rz(theta_{i+1}) in joint i, and
    body i (COM and inertia given in link frame i) is appended with placement S_i (Pinocchio
    moves the inertia into the joint frame). For a prismatic joint S_i uses the constant d_i.
    The tool frame is link frame n: placement S_n in the last joint.
    """
    import pinocchio as pin

    model = pin.Model()
    model.gravity = pin.Motion(np.concatenate([chain.gravity, np.zeros(3)]))
    parent = 0
    placement = np.eye(4)  # of the next joint in its parent joint's frame (before Rz(theta))
    static_prev = None
    for i, j in enumerate(chain.joints):
        jplace = placement @ rotz(j.theta)
        jm = pin.JointModelPZ() if j.prismatic else pin.JointModelRZ()
        jid = model.addJoint(parent, jm, pin.SE3(jplace[:3, :3], jplace[:3, 3]), f"j{i + 1}")
        S = trans(0, 0, j.d) @ trans(j.a, 0, 0) @ rotx(j.alpha)
        inertia = pin.Inertia(j.mass, j.com, j.inertia)
        model.appendBodyToJoint(jid, inertia, pin.SE3(S[:3, :3], S[:3, 3]))
        parent, placement, static_prev = jid, S, S
    model.armature = np.array([j.armature for j in chain.joints])
    fid = model.addFrame(
        pin.Frame("tool", parent, pin.SE3(static_prev[:3, :3], static_prev[:3, 3]), pin.FrameType.OP_FRAME)
    )
    return model, fid


class PinRef:
    """Pinocchio evaluations of one chain (friction NOT included: Pinocchio has no tanh
    Coulomb model; tests compare friction-free quantities or add friction_torque)."""

    def __init__(self, chain: DHChain):
        import pinocchio as pin

        self.pin = pin
        self.chain = chain
        self.model, self.fid = pinocchio_model(chain)
        self.data = self.model.createData()

    def mass(self, q):
        pin = self.pin
        M = pin.crba(self.model, self.data, np.asarray(q, float)).copy()
        # crba fills the upper triangle only; it adds model.armature on the diagonal
        # (Pinocchio >= 3; test_puma_pinocchio checks that it does).
        return np.triu(M) + np.triu(M, 1).T

    def gravity(self, q):
        return self.pin.computeGeneralizedGravity(self.model, self.data, np.asarray(q, float)).copy()

    def rnea(self, q, qd, qdd):
        return self.pin.rnea(
            self.model, self.data, np.asarray(q, float), np.asarray(qd, float), np.asarray(qdd, float)
        ).copy()

    def fk(self, q):
        pin = self.pin
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, float))
        return self.data.oMf[self.fid].homogeneous.copy()

    def jacobian(self, q):
        pin = self.pin
        return pin.computeFrameJacobian(
            self.model, self.data, np.asarray(q, float), self.fid, pin.LOCAL_WORLD_ALIGNED
        ).copy()


SPECS = Path(__file__).resolve().parent.parent / "specs"
