"""What MuJoCo's contacts do in a grasp, step by step: each fingertip's normal and tangential
force on its pad, how much of its friction cone that uses, how far the tip sits from its
contact point on the payload (across the face: the slip, the contact point's tangential
displacement on the payload, rolling of the tip's sphere included; along the normal: the
separation), how far it slid (the integral of the tangential sliding speed MuJoCo's friction
constraint allows, sampled once per servo period), and the internal forces the grasp
carries, in robotgen's basis H (Deno et al. 1990, eq 2.4).

A contact is *open* when MuJoCo finds no force between the tip and its pad. The grasp
*holds* when no contact opens after the first SETTLE seconds (the tips start touching their
pads with no force; the commanded squeeze presses them in) and every tip stays on its pad.
It is *lost* when a tip is a whole FINGERTIP_RADIUS off its pad's face or past the pad's
edge: the payload is then no longer between the fingertips."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robotgen.simulation.mujoco.model import FINGERTIP_RADIUS, ContactMap

# the first servo periods, while the commanded squeeze first presses the tips into their pads
# (they start exactly touching, with no force): not counted as open contacts
SETTLE = 0.02  # [s]


@dataclass(frozen=True)
class Reading:
    """One contact at one instant, in world axes and the payload's frame."""

    force: np.ndarray  # (3,) the tip's force on the pad, world axes [N]
    normal: float  # f_n >= 0 [N]
    tangential: float  # |f_t| [N]
    offset: np.ndarray  # (3,) tip centre minus the contact point, payload frame [m]
    normal_axis: np.ndarray  # (3,) the pad's outward normal, payload frame
    pad_half_width: float
    friction: float
    sliding_speed: float = 0.0  # |v_t| at the contact [m/s]

    @property
    def gap(self) -> float:
        """The tip's distance off its pad face (negative: pressed in) [m]."""
        return float(self.offset @ self.normal_axis)

    @property
    def slip(self) -> float:
        """How far across the face the tip is from its contact point [m]."""
        return float(np.linalg.norm(self.offset - self.gap * self.normal_axis))

    @property
    def usage(self) -> float:
        """|f_t| / (mu f_n): at most 1 (MuJoCo's elliptic cone), 1 while sliding; NaN open."""
        return self.tangential / (self.friction * self.normal) if self.normal > 0 else float("nan")

    @property
    def lost(self) -> bool:
        """Whether the fingertip has left its pad: apart by more than its radius, or slid off the pad's half-width."""
        return self.gap > FINGERTIP_RADIUS or self.slip > self.pad_half_width


@dataclass
class ContactHistory:
    """Every contact's readings over a run (rows: servo steps)."""

    contacts: tuple[ContactMap, ...]
    t: list[float] = field(default_factory=list)
    normal: list[np.ndarray] = field(default_factory=list)
    tangential: list[np.ndarray] = field(default_factory=list)
    usage: list[np.ndarray] = field(default_factory=list)
    gap: list[np.ndarray] = field(default_factory=list)
    slip: list[np.ndarray] = field(default_factory=list)
    lost: list[np.ndarray] = field(default_factory=list)
    sliding: list[np.ndarray] = field(default_factory=list)  # accumulated sliding distance [m]
    payload_pose: list[np.ndarray] = field(default_factory=list)  # the root's payload, when it is the root's

    def add(self, t: float, readings: list[Reading], pose: np.ndarray | None) -> None:
        """Append the readings at t [s] (and the payload pose, if any), integrating each contact's sliding distance."""
        speed = np.array([r.sliding_speed for r in readings])
        before = self.sliding[-1] if self.sliding else np.zeros(len(readings))
        self.sliding.append(before + (t - self.t[-1]) * speed if self.t else before)
        self.t.append(t)
        self.normal.append(np.array([r.normal for r in readings]))
        self.tangential.append(np.array([r.tangential for r in readings]))
        self.usage.append(np.array([r.usage for r in readings]))
        self.gap.append(np.array([r.gap for r in readings]))
        self.slip.append(np.array([r.slip for r in readings]))
        self.lost.append(np.array([r.lost for r in readings]))
        if pose is not None:
            self.payload_pose.append(pose)

    @property
    def names(self) -> list[str]:
        """The contacts' names, as the CSV's columns use them."""
        return [f"{c.name}" for c in self.contacts]

    def array(self, key: str) -> np.ndarray:
        """The recorded series ``key`` as an array (steps, contacts)."""
        return np.array(getattr(self, key))

    @property
    def first_loss(self) -> tuple[float, int] | None:
        """(time, contact index) the grasp was first lost, None if it held."""
        lost = self.array("lost")
        if not lost.any():
            return None
        k, c = np.argwhere(lost)[0]
        return self.t[k], int(c)

    def settled(self) -> np.ndarray:
        """Mask of the samples after the first SETTLE seconds."""
        return np.asarray(self.t) >= SETTLE

    @property
    def holds(self) -> bool:
        """Whether the grasp held: no contact lost and none open after settling."""
        return self.first_loss is None and not self.open_fraction().any()

    def worst_usage(self) -> np.ndarray:
        """Per contact, the largest |f_t| / (mu f_n) after SETTLE while it was closed (NaN:
        never closed)."""
        usage = self.array("usage")[self.settled()]
        return np.array([np.nanmax(u) if np.isfinite(u).any() else np.nan for u in usage.T])

    def open_fraction(self) -> np.ndarray:
        """Per contact, the fraction of servo steps after SETTLE without contact force."""
        normal = self.array("normal")[self.settled()]
        return (normal <= 0).mean(axis=0) if normal.size else np.zeros(len(self.contacts))

    def largest_slip(self) -> np.ndarray:
        """Each contact's largest slip [m] over the run."""
        return self.array("slip").max(axis=0)

    def summary(self) -> list[str]:
        """The lines simulate prints about the contacts: whether the grasp held, forces, friction-cone usage, slip."""
        loss = self.first_loss
        grasps = sorted({c.attach for c in self.contacts})
        friction = ", ".join(sorted({f"{c.friction:g}" for c in self.contacts}))
        opened = self.open_fraction()
        if self.holds:
            verdict = (
                f"held: after the first {1e3 * SETTLE:g} ms every contact stayed closed and every fingertip on its pad"
            )
        elif loss is None:
            verdict = (
                f"kept, but contacts opened ({', '.join(c.name for c, o in zip(self.contacts, opened) if o)}"
                "): the box stayed between the fingertips"
            )
        else:
            t, c = loss
            verdict = (
                f"LOST at t = {t:.3f} s: the fingertip of '{self.contacts[c].leaf}' left its pad "
                f"({self.contacts[c].name})"
            )
        lines = [
            f"grasp {', '.join(grasps)} on MuJoCo's contacts (friction coefficient {friction}): {verdict}",
            f"  cone usage, f_n and open after the first {1e3 * SETTLE:g} ms; slip (the contact point's largest "
            "displacement on the payload) and slid (the distance it slid) over the run:",
            f"  {'contact':>10} {'leaf':>10} {'max |f_t|/(mu f_n)':>19} {'f_n min [N]':>12} {'f_n max [N]':>12} "
            f"{'slip [mm]':>10} {'slid [mm]':>10} {'open':>6}",
        ]
        settled = self.settled() if self.settled().any() else np.ones(len(self.t), bool)
        normal = self.array("normal")[settled]
        usage, slip, slid = self.worst_usage(), self.largest_slip(), self.array("sliding")[-1]
        for i, contact in enumerate(self.contacts):
            lines.append(
                f"  {contact.name:>10} {contact.leaf:>10} {usage[i]:19.4f} {normal[:, i].min():12.4f} "
                f"{normal[:, i].max():12.4f} {1e3 * slip[i]:10.4f} {1e3 * slid[i]:10.4f} "
                f"{100 * opened[i]:5.1f}%"
            )
        return lines


def internal_forces(contacts: tuple[ContactMap, ...], readings: list[Reading], rotation) -> list[float]:
    """The internal forces of each grasp (in walk order, as robotgen names them) from the
    tips' forces on the payload, f_i = H f with robotgen's H (symbolic/attach.py) at the
    payload's orientation ``rotation(payload) -> R``: two planar contacts, the squeeze
    (u, -u) / sqrt(2), u from contact 1 to 2; three point contacts, the squeezes along the
    lines between contact pairs (1, 2), (1, 3), (2, 3), orthonormalised in that order. Other
    grasps' bases come from a symbolic null space robotgen does not repeat here: NaN."""
    out: list[float] = []
    by_attach: dict[str, list[int]] = {}
    for i, c in enumerate(contacts):
        by_attach.setdefault(c.attach, []).append(i)
    for indices in by_attach.values():
        cs = [contacts[i] for i in indices]
        dim = 2 if cs[0].planar else 3
        f = np.concatenate([readings[i].force[:dim] for i in indices])
        R = rotation(cs[0].payload)[:dim, :dim]
        n_forces = dim * len(cs) - (3 if cs[0].planar else 6)
        if cs[0].planar and len(cs) == 2:
            u = R @ _unit(cs[1].point[:2] - cs[0].point[:2])
            out.append(float(np.r_[u, -u] @ f / np.sqrt(2.0)))
        elif not cs[0].planar and len(cs) == 3:
            rows: list[np.ndarray] = []
            for i, j in ((0, 1), (0, 2), (1, 2)):
                s = np.zeros(9)
                u = R @ _unit(cs[j].point - cs[i].point)
                s[3 * i : 3 * i + 3], s[3 * j : 3 * j + 3] = u, -u
                for r in rows:
                    s = s - (r @ s) * r
                rows.append(s / np.linalg.norm(s))
            out += [float(r @ f) for r in rows]
        else:
            out += [float("nan")] * n_forces
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)
