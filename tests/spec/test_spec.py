"""The spec layer: located errors for malformed specs, canonical joints for valid ones."""

from __future__ import annotations

import json
import math
import textwrap

import numpy as np
import pytest
from jsonschema import Draft202012Validator

from robotgen.errors import Location, UserError, UserErrors
from robotgen.frontend import load_system, schema_json, spec_schema
from robotgen.model.chain import PRISMATIC
from robotgen.model.expression import MATH_LIB, evaluate, parse_constant, parse_expression
from robotgen.model.formula import FormulaRobot


def write(tmp_path, text: str) -> str:
    path = tmp_path / "spec.yaml"
    path.write_text(textwrap.dedent(text).lstrip("\n"))
    return str(path)


def errors_of(tmp_path, text: str) -> list[UserError]:
    with pytest.raises(UserErrors) as caught:
        load_system(write(tmp_path, text))
    return caught.value.errors


HEADER = """
robotgen: 1
name: arm_test
root: arm
nodes:
  arm:
    define:
"""


def chain_spec(body: str) -> str:
    """A spec with ``chain:`` at line 7, column 7; ``body`` starts at line 8, column 9."""
    return HEADER + "      chain:\n" + textwrap.indent(textwrap.dedent(body).lstrip("\n"), " " * 8)


def formula_spec(body: str) -> str:
    """A spec with ``formulas:`` at line 7, column 7; ``body`` starts at line 8, column 9."""
    return HEADER + "      formulas:\n" + textwrap.indent(textwrap.dedent(body).lstrip("\n"), " " * 8)


# (case, spec text, line, column, text the first message must contain)
MALFORMED = [
    (
        "wrong type",
        chain_spec("""
        convention: dh_standard
        gravity: 9.81
        joints:
          - {type: revolute, dh: {a: 1}}
        """),
        9,
        18,
        "nodes.arm.define.chain.gravity: expected a list, got 9.81",
    ),
    (
        "unknown key",
        chain_spec("""
        convention: dh_standard
        joints:
          - type: revolute
            dh: {a: 1}
            link: {mass: 1, masss: 2}
        """),
        12,
        29,
        "nodes.arm.define.chain.joints[0].link.masss: unknown key",
    ),
    (
        "missing field",
        chain_spec("""
        convention: dh_standard
        joints:
          - type: revolute
            dh: {a: 1}
          - dh: {a: 1}
        """),
        12,
        13,
        "nodes.arm.define.chain.joints[1]: missing required key 'type'",
    ),
    (
        "missing convention",
        chain_spec("""
        joints:
          - {type: revolute, dh: {a: 1}}
        """),
        7,
        7,
        "nodes.arm.define.chain: missing required key 'convention'",
    ),
    (
        "bad convention",
        chain_spec("""
        convention: dh_std
        joints:
          - {type: revolute, dh: {a: 1}}
        """),
        8,
        21,
        "nodes.arm.define.chain.convention: 'dh_std' is not one of: dh_standard",
    ),
    (
        "dh row missing in a dh chain",
        chain_spec("""
        convention: dh_modified
        joints:
          - type: revolute
            axis: [0, 0, 1]
        """),
        10,
        13,
        "nodes.arm.define.chain.joints[0]: missing required key 'dh' (convention dh_modified)",
    ),
    (
        "non-PSD inertia",
        chain_spec("""
        convention: dh_standard
        joints:
          - type: revolute
            dh: {a: 1}
            link:
              mass: 1
              inertia: {ixx: 1, iyy: 1, izz: 1, ixy: 2}
        """),
        14,
        15,
        "joints[0].link.inertia: inertia is not positive semi-definite",
    ),
    (
        "negative mass",
        chain_spec("""
        convention: dh_standard
        joints:
          - {type: revolute, dh: {a: 1}}
          - type: revolute
            dh: {a: 1}
            link: {mass: -1.0}
        """),
        13,
        26,
        "nodes.arm.define.chain.joints[1].link.mass: -1.0 is less than the minimum of 0",
    ),
    (
        "negative mass by expression",
        chain_spec("""
        convention: dh_standard
        joints:
          - type: revolute
            dh: {a: 1}
            link: {mass: "-pi"}
        """),
        12,
        26,
        "joints[0].link.mass: '-pi' = -3.14159 is less than the minimum of 0",
    ),
    (
        "constant with a name",
        chain_spec("""
        convention: dh_standard
        joints:
          - type: revolute
            dh: {a: 1, alpha: pi/two}
        """),
        11,
        34,
        "joints[0].dh.alpha: unknown name 'two'",
    ),
    (
        "zero axis",
        chain_spec("""
        convention: joints
        joints:
          - type: revolute
            axis: [0, 0, 0]
        """),
        11,
        19,
        "joints[0].axis: joint axis must not be the zero vector",
    ),
    (
        "duplicate joint name",
        chain_spec("""
        convention: joints
        joints:
          - {name: shoulder, type: revolute, axis: [0, 0, 1]}
          - {name: shoulder, type: revolute, axis: [0, 0, 1]}
        """),
        11,
        14,
        "joints[1].name: joint name 'shoulder' is used twice",
    ),
    (
        "formula with unknown name",
        formula_spec("""
        coordinates: [th1]
        parameters: {m1: 1.0}
        M: [["m1 * l1^2"]]
        """),
        10,
        20,
        "nodes.arm.define.formulas.M[0][0]: unknown name 'l1'",
    ),
    (
        "formula calls __import__",
        formula_spec("""
        coordinates: [th1]
        M: [["1 + __import__('os')"]]
        """),
        9,
        19,
        "formulas.M[0][0]: '__import__' is not a known function",
    ),
    (
        "formula with attribute access",
        formula_spec("""
        coordinates: [th1]
        M: [[1.0]]
        N: [th1.real]
        """),
        10,
        16,
        "formulas.N[0]: attribute access is not allowed",
    ),
    (
        "velocity in kinematics",
        formula_spec("""
        coordinates: [th1]
        M: [[2]]
        kinematics: ['cos(th1) + dth1']
        """),
        10,
        34,
        "formulas.kinematics[0]: unknown name 'dth1'",
    ),
    (
        "M not nq x nq",
        formula_spec("""
        coordinates: [a, b]
        M: [["1", "0"], ["0"]]
        """),
        9,
        25,
        "formulas.M[1]: expected 2 entries in each row, got 1",
    ),
    (
        "coordinate shadows a function",
        formula_spec("""
        coordinates: [sin]
        M: [[1]]
        """),
        8,
        23,
        "formulas.coordinates[0]: coordinate 'sin' shadows the function 'sin'",
    ),
    (
        "chain and formulas together",
        HEADER
        + """\
      chain: {convention: joints, joints: [{type: revolute, axis: [0, 0, 1]}]}
      formulas: {coordinates: [x], M: [[1]]}
""",
        8,
        7,
        "nodes.arm.define: chain and formulas exclude each other",
    ),
    (
        "root is not a node",
        """
robotgen: 1
name: arm_test
root: hand
nodes:
  arm:
    define:
      formulas: {coordinates: [x], M: [[1]]}
""",
        3,
        7,
        "root: 'hand' is not a node (nodes: arm)",
    ),
    (
        "bad node name",
        """
robotgen: 1
name: arm_test
root: arm
nodes:
  my-arm:
    define:
      formulas: {coordinates: [x], M: [[1]]}
""",
        5,
        3,
        "nodes: name 'my-arm' is not an identifier",
    ),
    (
        "wrong format version",
        """
robotgen: 2
name: arm_test
root: arm
nodes: {arm: {define: {formulas: {coordinates: [x], M: [[1]]}}}}
""",
        1,
        11,
        "robotgen: must be 1, got 2",
    ),
    (
        "YAML syntax error",
        """
robotgen: 1
name: arm_test
root: arm
nodes:
  arm: {define: [1, 2}
""",
        5,
        22,
        "YAML: expected ',' or ']'",
    ),
    (
        "duplicate key",
        """
robotgen: 1
name: arm_test
root: arm
name: other
nodes: {arm: {define: {formulas: {coordinates: [x], M: [[1]]}}}}
""",
        4,
        1,
        'duplicate key "name"',
    ),
    ("not a mapping", "- robotgen: 1\n", 1, 1, "a spec must be a YAML mapping"),
]


@pytest.mark.parametrize(
    "text, line, col, message", [case[1:] for case in MALFORMED], ids=[case[0] for case in MALFORMED]
)
def test_malformed_spec_is_reported_where_it_is_wrong(tmp_path, text, line, col, message):
    first = errors_of(tmp_path, text)[0]
    assert (first.location.line, first.location.col) == (line, col), first
    assert message in first.message
    assert first.location.file.endswith("spec.yaml")


def test_missing_file_is_a_user_error(tmp_path):
    with pytest.raises(UserErrors) as caught:
        load_system(str(tmp_path / "absent.yaml"))
    (error,) = caught.value.errors
    assert (error.location.line, error.location.col) == (1, 1)
    assert "cannot read spec" in error.message


def test_every_problem_is_reported_in_file_order(tmp_path):
    errors = errors_of(
        tmp_path,
        chain_spec("""
        convention: dh_standard
        joints:
          - type: revolute
            dh: {a: 1, bogus: 0}
            link: {mass: -2}
          - type: spinning
        """),
    )
    assert [(e.location.line, e.location.col) for e in errors] == [(11, 24), (12, 26), (13, 19)]
    assert "unknown key" in errors[0].message
    assert "-2 is less than the minimum of 0" in errors[1].message
    assert "'spinning' is not one of: revolute, prismatic" in errors[2].message


def test_semantic_errors_are_all_collected(tmp_path):
    errors = errors_of(
        tmp_path,
        formula_spec("""
        coordinates: [q, p]
        velocities: [v]
        M: [["q^2", "foo"], ["0", "1"]]
        N: ["v", "w"]
        """),
    )
    assert [(e.location.line, e.location.col) for e in errors] == [(9, 9), (10, 22), (11, 19)]
    assert "expected 2 names" in errors[0].message
    assert "unknown name 'foo'" in errors[1].message
    assert "unknown name 'w'" in errors[2].message


# ---- valid specs: canonical joints reproduce the convention's forward kinematics ----------


def dh_standard_matrix(a, alpha, d, theta):
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])


def dh_modified_matrix(a, alpha, d, theta):
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st, 0, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d], [0, 0, 0, 1]])


def rodrigues(axis, angle):
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    T = np.eye(4)
    T[:3, :3] = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
    return T


def translation(v):
    T = np.eye(4)
    T[:3, 3] = v
    return T


def urdf_origin(xyz, rpy):
    r, p, y = rpy
    Rx = rodrigues([1, 0, 0], r)
    Ry = rodrigues([0, 1, 0], p)
    Rz = rodrigues([0, 0, 1], y)
    return translation(xyz) @ Rz @ Ry @ Rx


def canonical_frames(tree, q):
    """frame(i) = frame(i-1) @ origin_i @ motion(axis_i, q_i), and the tip frame."""
    frames, T = [], np.eye(4)
    for joint, qi in zip(tree.joints, q):
        motion = translation(joint.axis * qi) if joint.type == PRISMATIC else rodrigues(joint.axis, qi)
        T = T @ joint.origin @ motion
        frames.append(T)
    return frames, T @ tree.tool


DH_ROWS = [  # a, alpha, d, theta, type
    (0.4, math.pi / 2, 0.3, 0.2, "revolute"),
    (0.25, -0.7, 0.15, math.pi / 4, "prismatic"),
]
COMS = [(-0.2, 0.01, 0.05), (0.03, -0.1, 0.02)]
INERTIAS = [
    dict(ixx=0.3, iyy=0.4, izz=0.5, ixy=0.01, ixz=-0.02, iyz=0.03),
    dict(ixx=0.1, iyy=0.15, izz=0.2, ixy=0.0, ixz=0.01, iyz=0.0),
]


def inertia_matrix(i):
    return np.array([[i["ixx"], i["ixy"], i["ixz"]], [i["ixy"], i["iyy"], i["iyz"]], [i["ixz"], i["iyz"], i["izz"]]])


def dh_chain_text(convention):
    joints = ""
    for (a, alpha, d, theta, kind), com, inertia in zip(DH_ROWS, COMS, INERTIAS):
        joints += (
            f"  - type: {kind}\n"
            f"    dh: {{a: {a!r}, alpha: {alpha!r}, d: {d!r}, theta: {theta!r}}}\n"
            f"    link: {{mass: 1.5, com: {list(com)}, inertia: {json.dumps(inertia)}}}\n"
            f"    motor: {{inertia: 2.0e-4, gear_ratio: -50}}\n"
            f"    friction: {{viscous: 0.5, coulomb: 0.25}}\n"
        )
    return chain_spec(
        f"convention: {convention}\n"
        "base: {xyz: [0.1, -0.2, 0.3], rpy: [0.1, 0.2, 0.3]}\n"
        "tool: {xyz: [0, 0, 0.12], rpy: [0, pi/2, 0]}\n"
        "joints:\n" + joints
    )


BASE = urdf_origin([0.1, -0.2, 0.3], [0.1, 0.2, 0.3])
TOOL = urdf_origin([0, 0, 0.12], [0, math.pi / 2, 0])


@pytest.mark.parametrize(
    "convention, dh_matrix", [("dh_standard", dh_standard_matrix), ("dh_modified", dh_modified_matrix)]
)
def test_dh_chain_matches_the_dh_product(tmp_path, convention, dh_matrix):
    tree = load_system(write(tmp_path, dh_chain_text(convention))).root_node.leaf
    assert [j.name for j in tree.joints] == ["q1", "q2"]
    assert [j.armature for j in tree.joints] == pytest.approx([0.5, 0.5])
    assert (tree.joints[1].viscous, tree.joints[1].coulomb) == (0.5, 0.25)
    rng = np.random.default_rng(7)
    for _ in range(5):
        q = rng.uniform(-2, 2, size=2)
        links, T = [], BASE
        for (a, alpha, d, theta, kind), qi in zip(DH_ROWS, q):
            T = T @ (dh_matrix(a, alpha, d + qi, theta) if kind == "prismatic" else dh_matrix(a, alpha, d, theta + qi))
            links.append(T)
        frames, tip = canonical_frames(tree, q)
        np.testing.assert_allclose(tip, links[-1] @ TOOL, atol=1e-12)
        for frame, link, joint, com, inertia in zip(frames, links, tree.joints, COMS, INERTIAS):
            # the body is the same physical body in the base frame, whichever frame it is written in
            np.testing.assert_allclose(
                frame[:3, :3] @ joint.body.com + frame[:3, 3], link[:3, :3] @ com + link[:3, 3], atol=1e-12
            )
            np.testing.assert_allclose(
                frame[:3, :3] @ joint.body.inertia @ frame[:3, :3].T,
                link[:3, :3] @ inertia_matrix(inertia) @ link[:3, :3].T,
                atol=1e-12,
            )


def test_joint_list_chain_matches_the_urdf_product(tmp_path):
    text = chain_spec("""
        convention: joints
        gravity: [0, -9.81, 0]
        coulomb_smoothing: 0.05
        base: {xyz: [0, 0, 1]}
        joints:
          - name: hip
            type: revolute
            origin: {xyz: [0.1, 0, 0.2], rpy: [0.3, -0.2, 0.1]}
            axis: [0, 2, 0]
            limits: {lower: -1, upper: 1.5, effort: 20}
          - name: slide
            type: prismatic
            origin: {rpy: [0, 0, "pi/2"]}
            axis: [1, 1, 0]
            link: {mass: 2, com: [0.1, 0.2, 0.3], inertia: {ixx: 1, iyy: 1, izz: 1}}
        """)
    tree = load_system(write(tmp_path, text)).root_node.leaf
    assert tree.nq == 2 and tree.tip == 1 and [j.name for j in tree.joints] == ["hip", "slide"]
    np.testing.assert_allclose(tree.gravity, [0, -9.81, 0])
    assert tree.coulomb_smoothing == 0.05
    assert (tree.joints[0].limits.lower, tree.joints[0].limits.upper, tree.joints[0].limits.effort) == (-1, 1.5, 20)
    np.testing.assert_allclose(tree.joints[1].axis, [math.sqrt(0.5), math.sqrt(0.5), 0])
    np.testing.assert_allclose(tree.joints[1].body.com, [0.1, 0.2, 0.3])
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-2, 2, size=2)
        expected = (
            translation([0, 0, 1])
            @ urdf_origin([0.1, 0, 0.2], [0.3, -0.2, 0.1])
            @ rodrigues([0, 1, 0], q[0])
            @ urdf_origin([0, 0, 0], [0, 0, math.pi / 2])
            @ translation(np.array([1, 1, 0]) / math.sqrt(2) * q[1])
        )
        np.testing.assert_allclose(canonical_frames(tree, q)[1], expected, atol=1e-12)


def test_formula_spec_parses_into_expressions(tmp_path):
    text = formula_spec("""
        coordinates: [th1, th2]
        parameters: {m1: 1.0, m2: 2.0, l1: 0.5, l2: "pi/4"}
        M: [["m1*l1^2 + m2*l2^2", "m2*l1*l2*cos(th1 - th2)"],
            ["m2*l1*l2*cos(th1 - th2)", "m2*l2^2"]]
        N: ["0.1*dth1", "9.81*m2*l2*sin(th2)"]
        kinematics: ["l1*cos(th1) + l2*cos(th2)", "l1*sin(th1) + l2*sin(th2)"]
        """)
    system = load_system(write(tmp_path, text))
    robot = system.root_node.leaf
    assert isinstance(robot, FormulaRobot)
    assert robot.velocities == ("dth1", "dth2") and robot.coriolis is None
    assert robot.parameters["l2"] == pytest.approx(math.pi / 4)
    env = {"th1": 0.3, "th2": -0.4, "dth1": 2.0, **robot.parameters}
    l2 = math.pi / 4
    M = [[evaluate(e, env, MATH_LIB) for e in row] for row in robot.mass]
    np.testing.assert_allclose(
        M, [[0.25 + 2 * l2**2, 2 * 0.5 * l2 * math.cos(0.7)], [2 * 0.5 * l2 * math.cos(0.7), 2 * l2**2]]
    )
    assert evaluate(robot.nonlinear[0], env, MATH_LIB) == pytest.approx(0.2)
    assert robot.kinematics[1].names == {"l1", "l2", "th1", "th2"}
    assert robot.mass[0][1].location.line == 10


# ---- the expression parser on its own ------------------------------------------------------

AT = Location("f.yaml", 3, 10)


@pytest.mark.parametrize(
    "text, col, message",
    [
        ("m1*l1 + foo", 18, "unknown name 'foo'"),
        ("sin(x).imag", 16, "attribute access"),
        ("x[0]", 11, "indexing"),
        ("x % 2", 12, "operator not allowed"),
        ("atan2(x)", 10, "atan2() takes 2 arguments, got 1"),
        ("max(x, y=1)", 17, "takes no keyword arguments"),
        ("x ^ (lambda: 1)", 15, "lambda"),
        ("x + 'a'", 14, "a string"),
        ("x +* 2", 13, "syntax error"),
        ("x^2 + x^2 + y", 22, "unknown name 'y'"),  # ^ -> ** must not shift columns
    ],
)
def test_parse_expression_points_at_the_offending_token(text, col, message):
    with pytest.raises(UserError) as caught:
        parse_expression(text, AT, {"x", "m1", "l1"})
    assert (caught.value.location.line, caught.value.location.col) == (3, col)
    assert message in caught.value.message


def test_caret_is_power_with_power_precedence():
    expr = parse_expression("2*x^2 + 1", AT, {"x"})
    assert evaluate(expr, {"x": 3.0}, MATH_LIB) == 19.0
    assert evaluate(parse_expression("-x^2", AT, {"x"}), {"x": 3.0}, MATH_LIB) == -9.0


def test_multiline_text_points_at_its_start():
    with pytest.raises(UserError) as caught:
        parse_expression("x +\n bad", AT, {"x"}, exact_columns=True)
    assert caught.value.location == AT


def test_constants():
    assert parse_constant("pi/2", AT) == pytest.approx(math.pi / 2)
    assert parse_constant("-0.5*pi", AT) == pytest.approx(-math.pi / 2)
    assert parse_constant(3, AT) == 3.0
    for bad in ("1/0", "x", "9^9^9", True):
        with pytest.raises(UserError):
            parse_constant(bad, AT)


def test_schema_is_valid_and_deterministic():
    Draft202012Validator.check_schema(spec_schema())
    assert schema_json() == schema_json()
    assert json.loads(schema_json())["properties"]["robotgen"]["const"] == 1


def test_triangle_inequality_is_a_located_warning(tmp_path):
    """Published sets (the PUMA 560's) carry inertias no rigid body has: warned, not refused."""
    path = tmp_path / "spec.yaml"
    path.write_text(
        chain_spec("""
        convention: dh_standard
        joints:
          - type: revolute
            dh: {a: 1}
            link:
              mass: 1
              inertia: {ixx: 0.1, iyy: 0.1, izz: 0.5}
        """)
    )
    system = load_system(str(path))
    line = next(k for k, text in enumerate(path.read_text().splitlines(), 1) if "inertia:" in text)
    col = path.read_text().splitlines()[line - 1].index("inertia") + 1
    assert len(system.warnings) == 1
    assert system.warnings[0].startswith(f"{path}:{line}:{col}: warning: ")
    assert "principal moments 0.1, 0.1, 0.5 violate the triangle" in system.warnings[0]
