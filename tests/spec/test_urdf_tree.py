"""A humanoid URDF read as a whole tree (robotgen.frontend.urdf.read_urdf_tree): iCub's 32
revolute joints below its root link against Pinocchio's fixed-base model of the same file
(buildModelFromUrdf without a root joint). M, gravity, inverse dynamics and C at 20 random
states, evaluated through CasADi (leaf_kernels -> Kernel.function), no compile. Plus the
tree reader's own errors (mimic and floating joints), on small URDFs."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from robots import robots_dir

from robotgen.errors import UserError
from robotgen.frontend.urdf import read_urdf, read_urdf_tree
from robotgen.symbolic import leaf_kernels

ICUB = "icub_description/robots/icub.urdf"
N_STATES = 20
TOL = 1e-9


def rel_err(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


@pytest.fixture(scope="module")
def icub():
    path = robots_dir() / ICUB
    tree = read_urdf_tree(str(path)).tree
    model = pin.buildModelFromUrdf(str(path))  # no root joint: fixed base, like robotgen's
    return tree, model


def test_tree_keeps_every_movable_joint(icub):
    tree, model = icub
    assert tree.nq == model.nq == 32
    assert tree.locked_joints == ()
    assert sorted(j.name for j in tree.joints) == sorted(model.names[1:])
    assert all(j.parent < i for i, j in enumerate(tree.joints))
    assert sum(j.parent == -1 for j in tree.joints) == 3  # two legs and the torso hang from the root
    # Pinocchio's parent structure, by name
    for j in tree.joints:
        jid = model.getJointId(j.name)
        pin_parent = model.names[model.parents[jid]] if model.parents[jid] > 0 else None
        assert pin_parent == (tree.joints[j.parent].name if j.parent >= 0 else None), j.name


def test_dynamics_match_pinocchio(icub):
    tree, model = icub
    data = model.createData()
    n = tree.nq
    # robotgen's coordinate i is Pinocchio's coordinate perm[i]
    perm = np.array([model.joints[model.getJointId(j.name)].idx_q for j in tree.joints])
    damping = np.array([j.damping for j in tree.joints])
    f = {k.name: k.function for k in leaf_kernels(tree)}
    rng = np.random.default_rng(11)
    worst: dict[str, float] = {}
    for _ in range(N_STATES):
        q, qd, qdd = rng.uniform(-np.pi, np.pi, n), rng.normal(size=n) * 2.0, rng.normal(size=n) * 5.0
        qp, qdp, qddp = (np.empty(n) for _ in range(3))
        qp[perm], qdp[perm], qddp[perm] = q, qd, qdd
        Mp = pin.crba(model, data, qp)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        Cp = pin.computeCoriolisMatrix(model, data, qp, qdp)
        errs = {
            "mass": rel_err(np.array(f["mass"](q)).reshape(n, n), Mp[np.ix_(perm, perm)]),
            "gravity": rel_err(np.array(f["gravity"](q)).ravel(), pin.computeGeneralizedGravity(model, data, qp)[perm]),
            # URDF <dynamics damping> is viscous friction in robotgen's inverse dynamics
            "inverse_dynamics": rel_err(
                np.array(f["inverse_dynamics"](q, qd, qdd)).ravel() - damping * qd,
                pin.rnea(model, data, qp, qdp, qddp)[perm],
            ),
            "coriolis": rel_err(np.array(f["coriolis"](q, qd)).reshape(n, n), Cp[np.ix_(perm, perm)]),
        }
        for key, e in errs.items():
            worst[key] = max(worst.get(key, 0.0), e)
    print({k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) <= TOL, worst


def test_default_tip_is_the_first_leaf_and_a_named_tip_is_used(icub):
    tree, _ = icub
    assert tree.tip >= 0 and tree.tip_link
    path = str(robots_dir() / ICUB)
    named = read_urdf_tree(path, tip="l_sole").tree
    assert named.tip_link == "l_sole" and named.joints[named.tip].name == "l_ankle_roll"
    # the same tip as a chain: the chain is the tree's support path of that joint
    chain = read_urdf(path, "l_sole").tree
    assert [j.name for j in chain.joints] == [named.joints[i].name for i in named.support(named.tip)]


# --- the tree reader's errors, on small files ---------------------------------------------

LINK = (
    '<link name="{0}"><inertial><mass value="1"/>'
    '<inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
)


def joint(name, type_, parent, child, extra=""):
    return (
        f'<joint name="{name}" type="{type_}"><parent link="{parent}"/><child link="{child}"/>'
        f'<axis xyz="0 0 1"/>{extra}</joint>'
    )


def write(tmp_path, *joints, links=("world", "pelvis", "l1", "l2", "r1")):
    body = "\n".join(LINK.format(n) for n in links)
    path = tmp_path / "r.urdf"
    path.write_text(f'<?xml version="1.0"?>\n<robot name="r">\n{body}\n' + "\n".join(joints) + "\n</robot>\n")
    return str(path)


TREE = [
    joint("root", "floating", "world", "pelvis"),
    joint("jl1", "revolute", "pelvis", "l1"),
    joint("jl2", "continuous", "l1", "l2"),
    joint("jr1", "prismatic", "pelvis", "r1"),
]


def test_floating_root_needs_the_base_below_it(tmp_path):
    path = write(tmp_path, *TREE)
    with pytest.raises(UserError) as e:
        read_urdf_tree(path)
    assert "'root' is a floating joint" in str(e.value) and "base='pelvis'" in str(e.value)
    assert e.value.location.line >= 8
    tree = read_urdf_tree(path, base="pelvis").tree
    assert [(j.name, j.parent) for j in tree.joints] == [("jl1", -1), ("jl2", 0), ("jr1", -1)]
    assert tree.tip_link == "l2" and tree.tip == 1
    # the chain reader reads below its base the same way: the floating joint above it is no error
    chain = read_urdf(path, "l2", base="pelvis").tree
    assert [(j.name, j.parent) for j in chain.joints] == [("jl1", -1), ("jl2", 0)]
    assert chain.locked_joints == ("jr1",)
    with pytest.raises(UserError, match="'root' is a floating joint at the root.*base='pelvis'"):
        read_urdf(path, "l2")


def test_mimic_joint_is_coupled_in_a_tree(tmp_path):
    """A mimic joint stays a joint of the tree, its link its own body, coupled to the coordinate
    of the joint it follows (one coordinate fewer); joints below it stay movable; one note names it."""
    links = ("world", "pelvis", "l1", "l2", "r1", "r2")
    mimic = joint(
        "jm", "revolute", "l1", "r1", '<origin xyz="0 0.5 0"/><mimic joint="jl1" multiplier="-1" offset="0.25"/>'
    )
    below = joint("jr2", "revolute", "r1", "r2", '<origin xyz="0.25 0 0"/>')
    path = write(tmp_path, *TREE[:3], mimic, below, links=links)
    chain = read_urdf_tree(path, base="pelvis")
    tree = chain.tree
    assert [(j.name, j.parent) for j in tree.joints] == [("jl1", -1), ("jl2", 0), ("jm", 0), ("jr2", 2)]
    assert tree.nq == 3 and [j.name for j in tree.coordinate_joints] == ["jl1", "jl2", "jr2"]
    assert tree.locked_joints == ()
    c = tree.coupling
    assert (c.coordinate, c.multiplier, c.offset) == ((0, 1, 0, 2), (1.0, 1.0, -1.0, 1.0), (0.0, 0.0, 0.25, 0.0))
    assert tree.joints[0].body.mass == 1.0 and tree.joints[2].body.mass == 1.0
    np.testing.assert_array_equal(tree.joints[2].origin[:3, 3], [0.0, 0.5, 0.0])
    # the <mimic> element is on line 12 of the file (links on 3-8, joints from 9)
    assert chain.notes == (
        f"{path}:12:{mimic.index('<mimic') + 1}: note: a mimic joint moves with the coordinate "
        "of the joint it follows (no coordinate of its own): 'jm' = -1 * 'jl1' + 0.25",
    )
    # two mimic joints: one note naming both, at the first
    second = joint("jm2", "prismatic", "l2", "r2", '<mimic joint="jl2"/>')
    path = write(tmp_path, *TREE[:3], mimic, second, links=links)
    notes = read_urdf_tree(path, base="pelvis").notes
    assert len(notes) == 1 and "2 mimic joints move with the coordinates" in notes[0], notes
    assert "'jm' = -1 * 'jl1' + 0.25, 'jm2' = 'jl2'" in notes[0] and notes[0].startswith(f"{path}:12:"), notes


def test_floating_or_planar_joint_below_the_base_is_an_error(tmp_path):
    path = write(tmp_path, *TREE[:3], joint("jr1", "planar", "pelvis", "r1"))
    with pytest.raises(UserError, match="'jr1' is a planar joint"):
        read_urdf_tree(path, base="pelvis")
    path = write(
        tmp_path, joint("root", "revolute", "world", "pelvis"), *TREE[1:3], joint("jr1", "floating", "pelvis", "r1")
    )
    with pytest.raises(UserError, match="'jr1' is a floating joint"):
        read_urdf_tree(path)


def test_tip_outside_the_tree_is_an_error(tmp_path):
    path = write(tmp_path, *TREE)
    with pytest.raises(UserError, match="tip link 'world' is not below base link 'pelvis'"):
        read_urdf_tree(path, base="pelvis", tip="world")
    with pytest.raises(UserError, match="no movable joint between 'pelvis' and 'pelvis'"):
        read_urdf_tree(path, base="pelvis", tip="pelvis")
