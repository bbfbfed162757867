"""Robot trees in specs (attach, control, rigid_body): the Chapter 4 Styx systems load into
the right nodes, gains and signatures; every tree error is reported where it is wrong."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from robotgen.errors import UserError, UserErrors
from robotgen.frontend import load_system
from robotgen.model.expression import MATH_LIB, evaluate
from robotgen.model.formula import FormulaRobot
from robotgen.model.laws import COMPUTED_TORQUE, FEEDFORWARD, PD
from robotgen.model.signature import signature
from robotgen.model.system import (
    CONSTRAINT_FORMULAS,
    FRAME_CHANGE,
    PLANAR_CONTACTS,
    AttachNode,
    ControlNode,
    DefineNode,
    PlanarBody,
)

SPECS = Path(__file__).resolve().parents[2] / "specs"


def write(tmp_path, text: str) -> str:
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    return str(path)


def errors_of(tmp_path, text: str) -> list[UserError]:
    with pytest.raises(UserErrors) as caught:
        load_system(write(tmp_path, text))
    return caught.value.errors


def values(expressions, env) -> list[float]:
    return [evaluate(e, env, MATH_LIB) for e in expressions]


# ---- the Styx hand of Chapter 4 ----------------------------------------------------------


def test_styx_high_level_computed_torque_tree():
    system = load_system(str(SPECS / "styx_high_ct.yaml"))
    nodes = system.nodes
    assert system.root == "ct_hand" and not system.is_single_leaf
    assert [n.name for n in system.walk()] == ["left", "right", "fingers", "box", "hand", "ct_hand"]

    left, right = nodes["left"].leaf, nodes["right"].leaf
    assert isinstance(left, FormulaRobot) and isinstance(right, FormulaRobot)
    assert left.outputs == ("xl", "yl") and right.outputs == ("xr", "yr")
    assert left.coordinates == ("lth1", "lth2") and left.velocities == ("dlth1", "dlth2")

    box = nodes["box"]
    assert isinstance(box, DefineNode) and isinstance(box.leaf, PlanarBody)
    assert box.leaf.coordinates == ("x", "y", "psi") and box.leaf.mass == 0.2
    assert box.leaf.inertia == pytest.approx(0.2 * (0.1**2 + 0.06**2) / 12)
    np.testing.assert_array_equal(box.leaf.gravity, [0, 0])

    fingers, hand, ct = nodes["fingers"], nodes["hand"], nodes["ct_hand"]
    assert isinstance(fingers, AttachNode) and fingers.constraint.kind == FRAME_CHANGE
    assert fingers.robots == ("left", "right") and fingers.payload is None
    assert isinstance(hand, AttachNode) and hand.constraint.kind == PLANAR_CONTACTS
    assert hand.robots == ("fingers",) and hand.payload == "box"
    np.testing.assert_array_equal(hand.constraint.contacts, [[-0.05, 0], [0.05, 0]])
    assert isinstance(ct, ControlNode) and ct.law == COMPUTED_TORQUE and ct.robot == "hand"
    np.testing.assert_array_equal(ct.kp, 100 * np.eye(3))
    np.testing.assert_array_equal(ct.kv, 20 * np.eye(3))
    assert ct.internal_forces is None and not ct.resolve_internal_motion and ct.kv_internal == 0

    assert signature(system, "fingers").external == ("xl", "yl", "xr", "yr")
    sig = signature(system, "hand")
    assert sig.external == ("x", "y", "psi")
    assert sig.internal_forces == ("hand_f1",) and sig.internal_motions == ()
    assert signature(system, "ct_hand") == sig  # nothing resolved: the squeeze is an input


def test_styx_finger_inverse_kinematics_inverts_kinematics():
    """Box centre (0, 0.12), half-width 0.05: the tips at (-0.05, 0.12) and (0.05, 0.12);
    elbows outward (left elbow left of its base, right elbow right of its base)."""
    system = load_system(str(SPECS / "styx_high_ct.yaml"))
    rng = np.random.default_rng(1)
    for name, tip, side in (("left", (-0.05, 0.12), -1), ("right", (0.05, 0.12), 1)):
        finger = system.nodes[name].leaf
        for target in [tip] + [np.add(tip, rng.uniform(-0.02, 0.02, 2)) for _ in range(5)]:
            q = values(finger.inverse_kinematics, {**finger.parameters, **dict(zip(finger.outputs, target))})
            env = {**finger.parameters, **dict(zip(finger.coordinates, q))}
            np.testing.assert_allclose(values(finger.kinematics, env), target, atol=1e-12)
            base = side * finger.parameters["b"]
            elbow = base + finger.parameters["l1"] * math.cos(q[0])
            assert side * (elbow - base) > 0  # the elbow bulges away from the box
    q = values(
        system.nodes["left"].leaf.inverse_kinematics, {**system.nodes["left"].leaf.parameters, "xl": -0.05, "yl": 0.12}
    )
    np.testing.assert_allclose(q, [2.0392, 0.3128], atol=1e-4)


def test_styx_finger_mass_matrix_is_the_point_mass_one():
    finger = load_system(str(SPECS / "styx_high_ct.yaml")).nodes["left"].leaf
    p = finger.parameters
    th1, th2 = 0.7, -0.4
    M = [values(row, {**p, "lth1": th1, "lth2": th2}) for row in finger.mass]
    c = p["m2"] * p["l1"] * p["l2"] * math.cos(th1 - th2)
    np.testing.assert_allclose(M, [[(p["m1"] + p["m2"]) * p["l1"] ** 2, c], [c, p["m2"] * p["l2"] ** 2]])


def test_styx_low_level_and_multilevel_trees():
    low = load_system(str(SPECS / "styx_low_ct.yaml"))
    assert low.root == "hand"
    for name, robot in (("ct_left", "left"), ("ct_right", "right")):
        ct = low.nodes[name]
        assert isinstance(ct, ControlNode) and ct.law == COMPUTED_TORQUE and ct.robot == robot
        np.testing.assert_array_equal(ct.kp, 100 * np.eye(2))
    assert signature(low, "fingers").external == ("xl", "yl", "xr", "yr")
    assert signature(low, "hand").internal_forces == ("hand_f1",)

    multi = load_system(str(SPECS / "styx_multilevel.yaml"))
    assert [n.name for n in multi.walk()] == [
        "left",
        "pd_left",
        "right",
        "pd_right",
        "fingers",
        "ff",
        "box",
        "hand",
        "ct_hand",
    ]
    pd = multi.nodes["pd_left"]
    assert pd.law == PD
    np.testing.assert_array_equal(pd.kp, 2.0 * np.eye(2))
    np.testing.assert_array_equal(pd.kv, 0.1 * np.eye(2))
    ff = multi.nodes["ff"]
    assert ff.law == FEEDFORWARD and ff.robot == "fingers"
    np.testing.assert_array_equal(ff.kp, np.zeros((4, 4)))
    np.testing.assert_array_equal(ff.kv, np.zeros((4, 4)))
    assert signature(multi, "ct_hand").external == ("x", "y", "psi")


def test_redundant_fingers_have_two_internal_motions():
    system = load_system(str(SPECS / "styx_redundant.yaml"))
    assert system.nodes["left"].leaf.nq == 3 and system.nodes["left"].leaf.inverse_kinematics is None
    fingers = signature(system, "fingers")
    assert fingers.external == ("xl", "yl", "xr", "yr")
    assert fingers.internal_motions == ("fingers_m1", "fingers_m2")
    hand = signature(system, "hand")
    assert len(hand.internal_motions) == 2 and hand.internal_forces == ("hand_f1",)
    ct = system.nodes["ct_hand"]
    assert ct.resolve_internal_motion and ct.kv_internal == 5
    np.testing.assert_array_equal(ct.internal_forces, [1.0])
    top = signature(system, "ct_hand")
    assert top.internal_motions == () and top.internal_forces == ()


def test_gains_and_constraint_formulas(tmp_path):
    system = load_system(
        write(
            tmp_path,
            HEAD.replace("root: top", "root: joined")
            + LEAVES
            + FINGERS
            + """\
  top:
    control:
      robot: fingers
      law: pd_feedforward
      kp: [1, 2, 3, "pi"]
      kv: [[2, 1, 0, 0], [1, 2, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
  third:
    define: {formulas: {coordinates: [z1, z2, z3], M: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}}
  held:
    attach:
      robots: [third]
      payload: box
      constraint:
        formulas:
          coordinates: [u, v, w]
          h: [z1, z2, z3]
          h_inverse: [u, v, w]
          G: [[1, 0, 0], [0, 1, 0], [0, 0, "z1 + u"]]
  joined:
    attach:
      robots: [top, held]
      constraint:
        formulas:
          coordinates: [s]
          parameters: {k: 2}
          h: ["k*xl + u"]
          J: [[1, 0, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0, 0]]
          G: [[s, xl]]
""",
        )
    )
    top = system.nodes["top"]
    np.testing.assert_allclose(top.kp, np.diag([1, 2, 3, math.pi]))
    np.testing.assert_array_equal(top.kv[0], [2, 1, 0, 0])
    held = system.nodes["held"].constraint
    assert held.kind == CONSTRAINT_FORMULAS and held.J is None and held.G[2][2].names == {"z1", "u"}
    assert [e.text for e in held.h_inverse] == ["u", "v", "w"]
    joined = system.nodes["joined"].constraint
    assert joined.parameters == {"k": 2.0} and len(joined.J) == 2 and len(joined.J[0]) == 7
    assert joined.h[0].names == {"k", "xl", "u"}
    sig = signature(system, "joined")
    assert sig.external == ("s",) and len(sig.internal_motions) == 5 and len(sig.internal_forces) == 1


# ---- tree errors, each at its place --------------------------------------------------------

HEAD = """\
robotgen: 1
name: tree_test
root: top
nodes:
"""
# lines 5-8
LEFT_RIGHT = """\
  left:
    define: {formulas: {coordinates: [a1, a2], M: [[1, 0], [0, 1]], kinematics: [a1, a2], outputs: [xl, yl]}}
  right:
    define: {formulas: {coordinates: [b1, b2], M: [[1, 0], [0, 1]], kinematics: [b1, b2], outputs: [xr, yr]}}
"""
# lines 5-10
LEAVES = (
    LEFT_RIGHT
    + """\
  box:
    define: {rigid_body: {planar: {mass: 1, inertia: 0.1}}}
"""
)
# lines 11-12
FINGERS = """\
  fingers:
    attach: {robots: [left, right], constraint: {frame_change: {}}}
"""
# lines 13-14 (after FINGERS)
HAND = """\
  hand:
    attach: {robots: [fingers], payload: box, constraint: {planar_contacts: {points: [[-1, 0], [1, 0]]}}}
"""
TREE = HEAD + LEAVES + FINGERS + HAND  # top starts at line 15


def control(body: str) -> str:
    """A control node ``top`` on ``hand``; ``body`` lines start at line 18, column 7."""
    return TREE + "  top:\n    control:\n      robot: hand\n" + body


TREE_ERRORS = [
    (
        "missing node",
        HEAD
        + LEAVES
        + FINGERS
        + """\
  top:
    attach: {robots: [fingres], payload: box, constraint: {planar_contacts: {points: [[-1, 0], [1, 0]]}}}
""",
        14,
        23,
        "nodes.top.attach.robots[0]: 'fingres' is not a node",
    ),
    (
        "node used twice",
        HEAD
        + LEAVES
        + FINGERS
        + HAND
        + """\
  top:
    attach: {robots: [hand, fingers], constraint: {formulas: {coordinates: [u], h: [x], G: [[1, 0, 0, 0, 0, 0, 0]]}}}
""",
        16,
        29,
        "nodes.top.attach.robots[1]: 'fingers' is already used by nodes.hand.attach.robots[0]; "
        "each node is used at most once",
    ),
    (
        "unreachable node",
        HEAD
        + LEAVES
        + FINGERS
        + HAND
        + """\
  top:
    control: {robot: hand, law: feedforward}
  spare:
    define: {formulas: {coordinates: [z], M: [[1]]}}
""",
        17,
        3,
        "nodes.spare: node 'spare' is not reachable from the root 'top'",
    ),
    (
        "cycle",
        HEAD
        + LEAVES
        + FINGERS
        + HAND
        + """\
  top:
    control: {robot: hand, law: feedforward}
  c1:
    control: {robot: c2, law: feedforward}
  c2:
    control: {robot: c1, law: feedforward}
""",
        20,
        22,
        "nodes.c2.control.robot: 'c1' makes a cycle: c1 -> c2 -> c1",
    ),
    (
        "root used by a node",
        HEAD
        + LEAVES
        + FINGERS
        + HAND
        + """\
  top:
    control: {robot: hand, law: feedforward}
  c1:
    control: {robot: top, law: feedforward}
""",
        18,
        22,
        "nodes.c1.control.robot: 'top' is the root; the root cannot be used by another node",
    ),
    (
        "payload is a chain",
        HEAD
        + LEFT_RIGHT
        + FINGERS
        + """\
  top:
    attach: {robots: [fingers], payload: arm, constraint: {planar_contacts: {points: [[-1, 0], [1, 0]]}}}
  arm:
    define: {chain: {convention: joints, joints: [{type: revolute, axis: [0, 0, 1]}]}}
""",
        12,
        42,
        "nodes.top.attach.payload: payload 'arm' must be a define node with rigid_body or formulas (it is a chain)",
    ),
    (
        "payload is a control node",
        HEAD
        + LEFT_RIGHT
        + FINGERS
        + """\
  top:
    attach: {robots: [fingers], payload: c, constraint: {planar_contacts: {points: [[-1, 0], [1, 0]]}}}
  c:
    control: {robot: spare, law: feedforward}
  spare:
    define: {formulas: {coordinates: [z1, z2, z3], M: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}}
""",
        12,
        42,
        "payload 'c' must be a define node with rigid_body or formulas (it is a control node)",
    ),
    (
        "rigid body as a robot",
        HEAD
        + LEAVES
        + """\
  top:
    attach: {robots: [left, right, box], constraint: {formulas: {coordinates: [u], h: [a1], G: [[1, 0, 0, 0, 0, 0, 0]]}}}
""",
        12,
        36,
        "nodes.top.attach.robots[2]: 'box' is a rigid_body, a payload without actuators",
    ),
    (
        "planar contacts without payload",
        HEAD
        + LEFT_RIGHT
        + FINGERS
        + """\
  top:
    attach: {robots: [fingers], constraint: {planar_contacts: {points: [[-1, 0], [1, 0]]}}}
""",
        12,
        46,
        "nodes.top.attach.constraint.planar_contacts: planar_contacts needs a payload",
    ),
    (
        "planar contacts with a 2-coordinate payload",
        HEAD
        + LEFT_RIGHT
        + FINGERS
        + """\
  top:
    attach: {robots: [fingers], payload: flat, constraint: {planar_contacts: {points: [[-1, 0], [1, 0]]}}}
  flat:
    define: {formulas: {coordinates: [u, v], M: [[1, 0], [0, 1]]}}
""",
        12,
        42,
        "payload 'flat' has 2 coordinates; planar_contacts needs a planar body (x, y, psi)",
    ),
    (
        "planar contacts: points do not match the fingertips",
        HEAD
        + LEAVES
        + FINGERS
        + """\
  top:
    attach:
      robots: [fingers]
      payload: box
      constraint:
        planar_contacts: {points: [[-1, 0], [1, 0], [0, 1]]}
""",
        18,
        27,
        "planar_contacts.points: 3 contact points need 6 robot coordinates (fingertip x, y each); "
        "robots fingers have 4",
    ),
    (
        "frame change of a robot without kinematics",
        HEAD
        + LEFT_RIGHT
        + """\
  top:
    attach: {robots: [left, right, plain], constraint: {frame_change: {}}}
  plain:
    define: {formulas: {coordinates: [z], M: [[1]]}}
""",
        10,
        36,
        "nodes.top.attach.robots[2]: robot 'plain' (plain) has no kinematics",
    ),
    (
        "frame change of an attach under control",
        HEAD
        + LEAVES
        + FINGERS
        + HAND
        + """\
  top:
    attach: {robots: [c], constraint: {frame_change: {}}}
  c:
    control: {robot: hand, law: feedforward}
""",
        16,
        23,
        "'c' is a control of attach node 'hand'; frame_change needs a chain or a formulas leaf",
    ),
    (
        "frame change with a payload",
        HEAD
        + LEAVES
        + """\
  top:
    attach: {robots: [left, right], payload: box, constraint: {frame_change: {}}}
""",
        12,
        37,
        "nodes.top.attach.payload: frame_change takes no payload",
    ),
    (
        "frame change: outputs named alike",
        HEAD
        + LEFT_RIGHT.replace("[xr, yr]", "[xl, yr]")
        + """\
  top:
    attach: {robots: [left, right], constraint: {frame_change: {}}}
""",
        10,
        29,
        "robots[1]: output 'xl' of 'right' is also one of 'left'",
    ),
    (
        "internal forces of the wrong length",
        control("""\
      law: computed_torque
      kp: 1
      kv: 1
      internal_forces: [1, 2]
"""),
        21,
        7,
        "nodes.top.control.internal_forces: expected 1 values, one per internal force of 'hand' (hand_f1), got 2",
    ),
    (
        "no internal motion to resolve",
        control("""\
      law: computed_torque
      kp: 1
      kv: 1
      resolve_internal_motion: true
"""),
        21,
        7,
        "resolve_internal_motion: robot 'hand' has no internal motions to resolve",
    ),
    (
        "pd cannot resolve internal forces",
        control("""\
      law: pd
      kp: 1
      kv: 1
      internal_forces: [1]
"""),
        21,
        7,
        "nodes.top.control.internal_forces: law pd cannot resolve internal forces",
    ),
    (
        "feedforward takes no gains",
        control("""\
      law: feedforward
      kv: 1
"""),
        19,
        7,
        "nodes.top.control.kv: law feedforward takes no kv",
    ),
    (
        "pd integrates no expected trajectory",
        control("""\
      law: pd
      kp: 1
      kv: 1
      anchor: 0.5
"""),
        21,
        7,
        "nodes.top.control.anchor: law pd integrates no expected trajectory to anchor",
    ),
    (
        "anchor true",
        control("""\
      law: feedforward
      anchor: true
"""),
        19,
        15,
        "nodes.top.control.anchor: anchor takes a time constant [s] > 0, or false",
    ),
    (
        "anchor not positive",
        control("""\
      law: feedforward
      anchor: 0
"""),
        19,
        15,
        "nodes.top.control.anchor",
    ),
    (
        "computed torque needs kv",
        control("""\
      law: computed_torque
      kp: 1
"""),
        16,
        5,
        "nodes.top.control: missing required key 'kv' (law computed_torque)",
    ),
    (
        "gain list of the wrong length",
        control("""\
      law: computed_torque
      kp: [1, 2]
      kv: 1
"""),
        19,
        7,
        "nodes.top.control.kp: expected 3 entries ('hand' has 3 external coordinates: x, y, psi), got 2",
    ),
    (
        "gain not positive",
        control("""\
      law: pd_feedforward
      kp: 1
      kv: -2
"""),
        20,
        11,
        "nodes.top.control.kv: gain -2 must be positive",
    ),
    (
        "gain matrix not symmetric",
        control("""\
      law: pd_feedforward
      kp: [[1, 0, 0], [0.5, 1, 0], [0, 0, 1]]
      kv: 1
"""),
        19,
        16,
        "nodes.top.control.kp[0][1]: gain matrix must be symmetric: entry (0, 1) = 0 but (1, 0) = 0.5",
    ),
    (
        "gain matrix not positive definite",
        control("""\
      law: pd_feedforward
      kp: [[1, 2, 0], [2, 1, 0], [0, 0, 1]]
      kv: 1
"""),
        19,
        7,
        "nodes.top.control.kp: gain matrix must be positive definite: its smallest eigenvalue is -1",
    ),
    (
        "gain matrix of the wrong size",
        control("""\
      law: pd_feedforward
      kp: [[1, 0], [0, 1]]
      kv: 1
"""),
        19,
        7,
        "kp: expected a 3 x 3 matrix ('hand' has 3 external coordinates: x, y, psi), got 2 rows of 2",
    ),
    (
        "controlling a rigid body",
        HEAD
        + LEAVES
        + FINGERS
        + HAND.replace("payload: box", "payload: c")
        + """\
  top:
    control: {robot: hand, law: feedforward}
  c:
    control: {robot: box, law: feedforward}
""",
        18,
        22,
        "nodes.c.control.robot: 'box' is a rigid_body, a payload without actuators; it cannot be controlled",
    ),
    (
        "bad law",
        control("""\
      law: pid
      kp: 1
      kv: 1
"""),
        18,
        12,
        "nodes.top.control.law: 'pid' is not one of: computed_torque, feedforward, pd_feedforward, pd",
    ),
    (
        "two constraints",
        HEAD
        + LEAVES
        + """\
  top:
    attach:
      robots: [left, right]
      constraint: {frame_change: {}, planar_contacts: {points: [[0, 0], [1, 0]]}}
""",
        14,
        38,
        "nodes.top.attach.constraint: frame_change and planar_contacts exclude each other",
    ),
    (
        "one contact point",
        HEAD
        + LEAVES
        + FINGERS
        + """\
  top:
    attach: {robots: [fingers], payload: box, constraint: {planar_contacts: {points: [[0, 0]]}}}
""",
        14,
        86,
        "planar_contacts.points: expected at least 2 items, got 1",
    ),
]


@pytest.mark.parametrize(
    "text, line, col, message", [case[1:] for case in TREE_ERRORS], ids=[case[0] for case in TREE_ERRORS]
)
def test_tree_error_is_reported_where_it_is_wrong(tmp_path, text, line, col, message):
    errors = errors_of(tmp_path, text)
    assert len(errors) == 1, "\n".join(map(str, errors))
    (error,) = errors
    assert (error.location.line, error.location.col) == (line, col), error
    assert message in error.message, error


def constraint(body: str) -> str:
    """``top`` attaches left and right (coordinates a1 a2 b1 b2) by a formulas constraint;
    ``body`` starts at line 14, column 11."""
    return (
        HEAD
        + LEFT_RIGHT
        + "  top:\n    attach:\n      robots: [left, right]\n      constraint:\n"
        + "        formulas:\n"
        + "".join("          " + line + "\n" for line in body.splitlines())
    )


CONSTRAINT_ERRORS = [
    (
        "robots' coordinates named alike",
        HEAD
        + LEFT_RIGHT.replace("b1", "a1")
        + """\
  top:
    attach:
      robots: [left, right]
      constraint:
        formulas: {coordinates: [u], h: [a1], G: [[1, 1, 1, 1]]}
""",
        11,
        22,
        "nodes.top.attach.robots[1]: coordinate 'a1' of 'right' is also one of 'left'; names must be "
        "unique across the robots: the formulas constraint reads robot coordinates by name; rename one",
    ),
    (
        "h reads a node coordinate",
        constraint("""\
coordinates: [u, v]
h: [a1, "u + b1"]
G: [[1, 0, 0, 0], [0, 1, 0, 0]]"""),
        15,
        20,
        "constraint.formulas.h[1]: unknown name 'u'",
    ),
    (
        "h of the wrong length",
        constraint("""\
coordinates: [u, v]
h: [a1]
G: [[1, 0, 0, 0], [0, 1, 0, 0]]"""),
        15,
        11,
        "constraint.formulas.h: expected 2 entries (one per node coordinate), got 1",
    ),
    (
        "h_inverse of the wrong length",
        constraint("""\
coordinates: [u]
h: [a1]
h_inverse: [u, u, u]
G: [[1, 0, 0, 0]]"""),
        16,
        11,
        "formulas.h_inverse: expected 4 entries (one per robot coordinate), got 3",
    ),
    (
        "h_inverse reads a robot coordinate",
        constraint("""\
coordinates: [u]
h: [a1]
h_inverse: [u, u, u, a2]
G: [[1, 0, 0, 0]]"""),
        16,
        32,
        "formulas.h_inverse[3]: unknown name 'a2'",
    ),
    (
        "J row of the wrong length",
        constraint("""\
coordinates: [u]
h: [a1]
J: [[1, 0, 0, 0], [0, 1, 0]]
G: [[1, 0]]"""),
        16,
        29,
        "formulas.J[1]: expected 4 entries in each row (one per robot coordinate), got 3",
    ),
    (
        "G columns not the rows of J",
        constraint("""\
coordinates: [u]
h: [a1]
J: [[1, 0, 0, 0], [0, 1, 0, 0]]
G: [[1, 0, 0]]"""),
        17,
        15,
        "formulas.G[0]: expected 2 entries in each row (one per row of J), got 3",
    ),
    (
        "G rows not the node coordinates",
        constraint("""\
coordinates: [u, v]
h: [a1, a2]
G: [[1, 0, 0, 0]]"""),
        16,
        11,
        "formulas.G: expected 2 rows (one per node coordinate), got 1",
    ),
    (
        "node coordinate named like a robot's",
        constraint("""\
coordinates: [b2]
h: [a1]
G: [[1, 0, 0, 0]]"""),
        14,
        25,
        "formulas.coordinates[0]: coordinate 'b2' is also a coordinate of robot 'right'",
    ),
    (
        "fewer constraint rows than node coordinates",
        constraint("""\
coordinates: [u, v, w]
h: [a1, a2, b1]
J: [[1, 0, 0, 0], [0, 1, 0, 0]]
G: [[1, 0], [0, 1], [1, 1]]"""),
        10,
        5,
        "nodes.top.attach: attach 'top': 4 robot coordinates, 2 constraint rows and 3 node coordinates do not fit",
    ),
]


@pytest.mark.parametrize(
    "text, line, col, message", [case[1:] for case in CONSTRAINT_ERRORS], ids=[case[0] for case in CONSTRAINT_ERRORS]
)
def test_constraint_formula_error_is_reported_where_it_is_wrong(tmp_path, text, line, col, message):
    errors = errors_of(tmp_path, text)
    assert len(errors) == 1, "\n".join(map(str, errors))
    (error,) = errors
    assert (error.location.line, error.location.col) == (line, col), error
    assert message in error.message, error


LEAF_ERRORS = [
    (
        "outputs without matching kinematics",
        """\
  top:
    define:
      formulas:
        coordinates: [a]
        M: [[1]]
        kinematics: [a, 2*a]
        outputs: [x]
""",
        11,
        9,
        "nodes.top.define.formulas.outputs: expected 2 names (one per kinematics entry), got 1",
    ),
    (
        "inverse kinematics reads a coordinate",
        """\
  top:
    define:
      formulas:
        coordinates: [a]
        M: [[1]]
        kinematics: [2*a]
        outputs: [x]
        inverse_kinematics: ["a/2"]
""",
        12,
        31,
        "formulas.inverse_kinematics[0]: unknown name 'a'",
    ),
    (
        "inverse kinematics of the wrong length",
        """\
  top:
    define:
      formulas:
        coordinates: [a, c]
        M: [[1, 0], [0, 1]]
        kinematics: [a + c]
        inverse_kinematics: [top_x1]
""",
        11,
        9,
        "formulas.inverse_kinematics: expected 2 entries (nq = 2), got 1",
    ),
    (
        "output named like a parameter",
        """\
  top:
    define:
      formulas:
        coordinates: [a]
        parameters: {k: 1}
        M: [[1]]
        kinematics: [k*a]
        outputs: [k]
""",
        12,
        19,
        "formulas.outputs[0]: output 'k' is already a parameter name",
    ),
    (
        "rigid body coordinates named alike",
        """\
  top:
    define:
      rigid_body:
        planar: {mass: 1, inertia: 0.1}
        coordinates: [x, x, psi]
""",
        9,
        26,
        "nodes.top.define.rigid_body.coordinates[1]: coordinate 'x' is already a coordinate name",
    ),
    (
        "rigid body with negative inertia",
        """\
  top:
    define:
      rigid_body:
        planar: {mass: 1, inertia: -0.1}
""",
        8,
        36,
        "rigid_body.planar.inertia: -0.1 is less than the minimum of 0",
    ),
]


@pytest.mark.parametrize(
    "text, line, col, message", [case[1:] for case in LEAF_ERRORS], ids=[case[0] for case in LEAF_ERRORS]
)
def test_leaf_error_is_reported_where_it_is_wrong(tmp_path, text, line, col, message):
    errors = errors_of(tmp_path, HEAD + text)
    assert len(errors) == 1, "\n".join(map(str, errors))
    (error,) = errors
    assert (error.location.line, error.location.col) == (line, col), error
    assert message in error.message, error


def test_tree_errors_are_all_collected_in_file_order(tmp_path):
    errors = errors_of(
        tmp_path,
        HEAD
        + LEAVES
        + FINGERS
        + """\
  top:
    control: {robot: fingers, law: pd, kp: [1, 2], kv: 1, resolve_internal_motion: true}
  spare:
    define: {formulas: {coordinates: [z], M: [[1]]}}
""",
    )
    assert [(e.location.line, e.location.col) for e in errors] == [(9, 3), (14, 40), (14, 59), (15, 3)], "\n".join(
        map(str, errors)
    )
    assert "nodes.box: node 'box' is not reachable" in errors[0].message
    assert "kp: expected 4 entries ('fingers' has 4 external coordinates: xl, yl, xr, yr), got 2" in errors[1].message
    assert "resolve_internal_motion: law pd cannot resolve internal motion" in errors[2].message
    assert "nodes.spare: node 'spare' is not reachable" in errors[3].message


def test_frame_change_of_controlled_chains(tmp_path):
    """A chain's kinematic outputs are its tip position, <robot>_x, _y (_z), looked up
    through the control nodes above it."""
    arm = """\
    define:
      chain:
        convention: joints
        gravity: [0, 0, 0]
        joints:
          - {type: revolute, axis: [0, 0, 1], link: {mass: 1, com: [0.5, 0, 0]}}
          - {type: revolute, axis: [0, 0, 1], origin: {xyz: [1, 0, 0]}, link: {mass: 1}}
"""
    system = load_system(
        write(
            tmp_path,
            HEAD
            + "  arm1:\n"
            + arm
            + "  arm2:\n"
            + arm
            + """\
  pd1:
    control: {robot: arm1, law: pd, kp: [3, 4], kv: 1}
  both:
    attach: {robots: [pd1, arm2], constraint: {frame_change: {output: planar}}}
  top:
    control: {robot: both, law: computed_torque, kp: 9, kv: 6}
""",
        )
    )
    assert system.nodes["both"].constraint.output == "planar"
    np.testing.assert_array_equal(system.nodes["pd1"].kp, np.diag([3, 4]))
    assert signature(system, "top").external == ("pd1_x", "pd1_y", "arm2_x", "arm2_y")
    np.testing.assert_array_equal(system.nodes["top"].kv, 6 * np.eye(4))
