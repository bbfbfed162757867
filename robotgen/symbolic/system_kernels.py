"""Kernels of a robot tree (ATTACH / CONTROL): every node's M, C, N, rd and wr in that
node's coordinates, the fused servo step of the whole tree, and the true plant."""

from __future__ import annotations

import functools

import casadi as ca

from robotgen.model.parameter_struct import runtime_parameters
from robotgen.model.rate_groups import multi_rate_groups
from robotgen.model.signature import internal_force_names
from robotgen.model.system import DefineNode, RobotSystem
from robotgen.symbolic.control.law import expected_start
from robotgen.symbolic.control.tree_laws import tree_law
from robotgen.symbolic.differentiation import reverse_jacobian
from robotgen.symbolic.kernel import Kernel, ParameterSymbols, make_kernel
from robotgen.symbolic.plant import Plant, sensed_forces
from robotgen.symbolic.rate_steps import rate_kernels
from robotgen.symbolic.servo import LAW_STATE, Servo, Trajectory, reads_sensed_forces
from robotgen.symbolic.system import SystemGraphs


def _write_kernel(g: SystemGraphs, name: str, kernel_name: str, doc: str) -> Kernel:
    sig = g.graph(name).sig
    servo = Servo(g, name)
    x_e = ca.SX.sym("x_e", sig.n_external)
    xd_e, xdd_e, f_e = (ca.SX.sym(s, sig.n_velocity) for s in ("xd_e", "xdd_e", "f_e"))
    f_i = ca.SX.sym("f_i", sig.n_internal_forces)
    servo.write(name, Trajectory(x_e, xd_e, xdd_e, f_e, f_i))
    inputs = [
        ("theta", g.theta),
        ("theta_dot", g.theta_dot),
        ("x_e", x_e),
        ("xd_e", xd_e),
        ("xdd_e", xdd_e),
        ("f_e", f_e),
    ]
    if sig.n_internal_forces:
        inputs.append(("f_i", f_i))
    if servo.reads_forces:
        inputs.append(("tau_sensed", servo.tau_sensed))
    outputs = [("tau", servo.tau(), (g.n, 1))]
    if servo.n_state:
        inputs += [("state", servo.state), ("dt", servo.dt)]
        outputs.append(("state_next", servo.state_next(), (servo.n_state, 1)))
    return make_kernel(kernel_name, doc, inputs, outputs, g.parameters, guarded=kernel_name == "servo_step")


def _plant_derivatives(plant: Plant, parameters: ParameterSymbols) -> list[Kernel]:
    """The partial derivatives of the tree's constrained dynamics (plant_dynamics), for
    trajectory optimisation and MPC of a robot tree: one reverse sweep of CasADi's AD per output
    row (the spec asks for them with derivatives: {include: true})."""
    pg = plant.graphs
    theta, v, tau = pg.theta, plant.v, plant.tau
    n, m = pg.n, plant.n_v
    outputs = [
        ("dtheta_dot_dtheta", reverse_jacobian(plant.theta_dot, theta), (n, n)),
        ("dtheta_dot_dv", reverse_jacobian(plant.theta_dot, v), (n, m)),
        ("dv_dot_dtheta", reverse_jacobian(plant.v_dot, theta), (m, n)),
        ("dv_dot_dv", reverse_jacobian(plant.v_dot, v), (m, m)),
        ("dv_dot_dtau", reverse_jacobian(plant.v_dot, tau), (m, n)),
    ]
    return [
        make_kernel(
            "plant_dynamics_derivatives",
            "Partial derivatives of plant_dynamics: d theta_dot/d theta, "
            "d theta_dot/d v, d v_dot/d theta, d v_dot/d v and d v_dot/d tau.",
            [("theta", theta), ("v", v), ("tau", tau)],
            [(name, ca.densify(x), shape) for name, x, shape in outputs],
            parameters,
            guarded=True,
        )
    ]


def system_kernels(system: RobotSystem) -> list[Kernel]:
    """Every node's functions, the servo step and the plant; a kernel that reads a run-time
    parameter (a gain, a payload mass) takes the module's parameter struct."""
    parameters = ParameterSymbols.of(runtime_parameters(system))
    kernel = functools.partial(make_kernel, parameters=parameters)
    g = SystemGraphs(system, parameters)
    th, thd = ("theta", g.theta), ("theta_dot", g.theta_dot)
    kernels: list[Kernel] = []
    for node in system.walk():
        if isinstance(node, DefineNode) and node.name not in g.offsets:
            continue  # a payload: no actuators, no sensors of its own
        ng = g.graph(node.name)
        n, ne = ng.sig.n_velocity, ng.sig.n_external
        p = node.name
        kernels += [
            kernel(
                f"{p}_mass", f"M of node '{p}' ({node.primitive}) in its coordinates.", [th], [("mass", ng.M, (n, n))]
            ),
            kernel(f"{p}_coriolis", f"C of node '{p}' in its coordinates.", [th, thd], [("coriolis", ng.C, (n, n))]),
            kernel(
                f"{p}_n", f"N (gravity, friction) of node '{p}' in its coordinates.", [th, thd], [("n", ng.N, (n, 1))]
            ),
            kernel(
                f"{p}_read",
                f"rd of node '{p}': its positions x and velocity xd.",
                [th, thd],
                [("x", ng.x, (ne, 1)), ("xd", ng.v, (n, 1))],
            ),
            _write_kernel(
                g,
                p,
                f"{p}_write",
                f"wr of node '{p}': the leaf torques that writing "
                f"(x_e, xd_e, xdd_e, f_e{', f_i' if ng.sig.n_internal_forces else ''}) at this node "
                "produces, every controller below evaluated.",
            ),
        ]
    root = system.root
    step = _write_kernel(
        g,
        root,
        "servo_step",
        "One servo step of the whole tree: sensed leaf "
        "states and the desired root trajectory in, actuator torques (and the next "
        "controller state) out.",
    )
    kernels.append(step)
    servo = Servo(g, root)
    if servo.n_state:
        integrals = any(
            kind != LAW_STATE or tree_law(node.law).state is not expected_start for node, kind, _ in servo.blocks
        )
        kernels.append(
            kernel(
                "servo_init",
                "Controller state after a reset: every expected trajectory at the current state, every "
                "integral at zero."
                if integrals
                else "Controller state that starts every expected trajectory at the current state.",
                [th, thd],
                [("state", servo.initial_state(), (servo.n_state, 1))],
            )
        )
    groups = multi_rate_groups(system)
    if groups is not None:
        kernels += rate_kernels(g, groups)
    plant = Plant(system, parameters)
    pg = plant.graphs
    theta, v, tau = ("theta", pg.theta), ("v", plant.v), ("tau", plant.tau)
    kernels += [
        kernel(
            "plant_dynamics",
            "The uncontrolled tree's constrained dynamics in root velocity "
            "coordinates v: (theta_dot, v_dot) for torques tau.",
            [theta, v, tau],
            [("theta_dot", plant.theta_dot, (pg.n, 1)), ("v_dot", plant.v_dot, (plant.n_v, 1))],
            guarded=True,
        ),
        kernel(
            "plant_velocity",
            "Root velocity v of the uncontrolled tree from sensed leaf rates.",
            [theta, ("theta_dot", pg.theta_dot)],
            [("v", plant.read_v, (plant.n_v, 1))],
        ),
        kernel(
            "plant_position",
            "Root positions of the uncontrolled tree.",
            [theta],
            [("x", plant.x, (plant.x.shape[0], 1))],
        ),
    ]
    if plant.internal_forces.shape[0]:
        names = ", ".join(internal_force_names(system))
        kernels.append(
            kernel(
                "plant_internal_forces",
                f"The internal forces the grasps carry in the plant ({names}): H lambda at "
                "every attach that creates them, lambda the force its robots exert on the constraint, for torques "
                "tau at (theta, v).",
                [theta, v, tau],
                [("f", plant.internal_forces, (plant.internal_forces.shape[0], 1))],
            )
        )
    if reads_sensed_forces(g, root):
        kernels.append(
            kernel(
                "plant_sensed_forces",
                "What each leaf exerts on the grasps it acts through, in its coordinates (the "
                "servo step's tau_sensed): tau - (M theta_ddot + C theta_dot + N) of the leaf alone, for torques "
                "tau at (theta, v).",
                [theta, v, tau],
                [("tau_sensed", sensed_forces(plant), (pg.n, 1))],
            )
        )
    if plant.residual.shape[0]:
        kernels.append(
            kernel(
                "constraint_residual",
                "Position-level constraint residual y - h^-1(h(y)) at every attach with an "
                f"inverse map, y its robots' stacked positions ({', '.join(plant.residual_names)}): zero when the leaf "
                "positions satisfy every grasp.",
                [theta],
                [("residual", plant.residual, (plant.residual.shape[0], 1))],
            )
        )
    if system.derivatives.include:
        kernels += _plant_derivatives(plant, parameters)
    if plant.inverse is not None:
        kernels.append(
            kernel(
                "plant_inverse",
                "Leaf joint positions for root positions x, through every attach's inverse kinematics.",
                [("x", plant.x_sym)],
                [("theta", plant.inverse, (pg.n, 1))],
            )
        )
    return kernels
