"""Whitney 1972, "The Mathematics of Coordinated Control of Prostheses and Manipulators":
the optimal linear servo of "Dynamic Control of Arms" and its three-link arm (Fig 5).

    python examples/papers/whitney_1972.py [--quick] [-o DIR]

The paper linearises the arm's dynamics about a nominal (eq 19, state s = (dtheta,
dtheta_dot); its printed blocks are garbled in our copy, re-derived as in
robotgen/symbolic/root_laws/resolved_rate/regulator.py: sdot = [0 I; -M^-1 K  -M^-1 B] s +
[0; M^-1] dtau, K gravity stiffness, B damping), assumes that model holds for the whole
state, designs feedback gains and "control functions" by optimal linear servo theory, and
applies them to the full nonlinear dynamics. Fig 5 shows the three joint angles against
their targets (rad) and the torques (foot-pounds) of "three link arm test no. 21", with no
numbers beyond "the errors are quite small, as are the required torques". Neither the arm
nor the path is given: the arm here is robotgen's choice (whitney_1972_arm.yaml beside this
script), the path a leisurely one.

What this script does:
1. builds the arm's module (its forward dynamics, lqr_step and servo_step, K printed in C);
2. computes the servo's feedforward v(t) = R^-1 B^T g(t) offline, g by integrating the
   backward equation over the reference (robotgen.numeric.linear_servo);
3. runs the servo and, for comparison, the same gains on the error alone (no feedforward)
   against the full nonlinear dynamics (RK4, 1 ms, the law evaluated at every stage), and both
   on the linear model (eq 19) as the design predicts them;
4. bounds the servo's nonlinear error by the linear prediction plus the closed loop's
   peak-to-peak gain times the largest linearisation residual met on the way;
5. solves the same finite-horizon problem on the linear model directly, as one sparse least
   squares over the whole horizon (trapezoidal transcription, Richardson-extrapolated), as an
   independent check of the servo;
6. writes fig5.png and report.md into the output directory and returns the numbers;
7. moves the PUMA 560 of specs/puma560_rmrc.yaml to a pose 0.2 m and 30 degrees away by
   position control through rates (eqs 11-18), once with today's fixed horizon (an
   exponential approach) and once with eq 11's remaining time T (arriving at T), and writes
   eq11.png.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from ruamel.yaml import YAML  # noqa: E402

from robotgen.cli import main as robotgen  # noqa: E402
from robotgen.numeric.linear_servo import LinearServo, costate, design  # noqa: E402
from robotgen.simulation.approach_paths import approach_paths  # noqa: E402

SPEC = Path(__file__).with_name("whitney_1972_arm.yaml")
NAME = "whitney_1972_arm"
JOINTS = ("sweep", "flexion", "elbow")
NM_PER_FT_LB = 0.3048 * 4.4482216152605  # 1 ft lbf in N m (international foot and pound-force)
STEP = 1e-3  # s, RK4 step of every simulation
DIRECT_STEP = 0.01  # s, the coarser grid of the direct solution (and half of it)

# The path: minimum-jerk moves between joint postures (rad), each held still before and after.
# The postures span [-0.25, 0.55] x [0.6, 1.2] x [-1.4, -0.6]: their centre is the spec's
# nominal (0.15, 0.9, -1.0), where eq 19 is linearised.
POSTURES = np.array(
    [
        [-0.25, 1.2, -1.4],  # hand low in front of the body
        [0.55, 0.6, -1.1],  # swept outwards and raised
        [0.15, 0.9, -0.6],  # reaching forwards and down
        [-0.25, 1.2, -1.4],
    ]
)  # back
MOVE, REST = 3.0, 0.5  # s per move; s still at each posture
QUICK_MOVES = 1
# eq 11: the PUMA moved DISTANCE along DIRECTION and turned TURN about AXIS (base axes) in T
RMRC = ROOT / "specs" / "puma560_rmrc.yaml"
PUMA_START = np.array([0, np.pi / 4, np.pi, 0, np.pi / 4, 0])
DISTANCE, TURN = 0.2, np.radians(30)
DIRECTION = np.array([0.12, -0.08, 0.14]) / np.linalg.norm([0.12, -0.08, 0.14])
AXIS = np.array([0.3, -0.8, 0.5]) / np.linalg.norm([0.3, -0.8, 0.5])
ARRIVAL_TIME = {False: 2.0, True: 1.0}  # [s]
HORIZON = 0.5  # [s] of the exponential approach


@dataclass(frozen=True, eq=False)
class JointPath:
    """theta_d(t): minimum-jerk moves s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5 between
    postures, still for ``rest`` before the first move and after each."""

    postures: np.ndarray
    move: float
    rest: float

    @property
    def duration(self) -> float:
        return self.rest + (len(self.postures) - 1) * (self.move + self.rest)

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(theta_d, theta_d_dot, theta_d_ddot) at t."""
        span = self.move + self.rest
        k = min(max(int((t - self.rest) // span), 0), len(self.postures) - 2)
        a, b = self.postures[k], self.postures[k + 1]
        tau = min(max((t - self.rest - k * span) / self.move, 0.0), 1.0)
        s = tau**3 * (10 - 15 * tau + 6 * tau**2)
        ds = 30 * tau**2 * (1 - tau) ** 2 / self.move
        dds = 60 * tau * (1 - tau) * (1 - 2 * tau) / self.move**2
        return a + s * (b - a), ds * (b - a), dds * (b - a)


@dataclass
class Run:
    """One closed loop sampled at the RK4 nodes."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    cost: float  # int (x - r)^T Q (x - r) + (tau - tau0)^T R (tau - tau0) dt
    residual: np.ndarray | None = None  # (N+1, n) true qdd - eq 19's, along this run


def build(out: Path):
    """The arm's module, built from the spec into ``out`` (imported once per process)."""
    if NAME in sys.modules:
        return sys.modules[NAME]
    if robotgen(["build", str(SPEC), "-o", str(out), "-q"]) != 0:
        raise SystemExit(f"robotgen build {SPEC} failed")
    sys.path.insert(0, str(out))
    try:
        importlib.invalidate_caches()
        return importlib.import_module(NAME)
    finally:
        sys.path.remove(str(out))


def simulate(plant, law, ref: np.ndarray, Q: np.ndarray, R: np.ndarray, tau0: np.ndarray, h: float, linear=None) -> Run:
    """RK4 over the half grid of ``ref`` ((2N+1, 2n): theta_d, theta_d_dot at t_0, t_0 + h/2, ...):
    qdd = plant(q, qd, tau), tau = law(i, q, qd) with i the half-grid index of the stage, the
    cost integrated with the state; ``linear(q, qd, tau)`` also records the residual
    plant - linear at the nodes."""
    steps = (len(ref) - 1) // 2
    n = ref.shape[1] // 2

    def rates(i, x):
        q, qd = x[:n], x[n : 2 * n]
        tau = law(i, q, qd)
        e = x[: 2 * n] - ref[i]
        du = tau - tau0
        return np.r_[qd, plant(q, qd, tau), e @ Q @ e + du @ R @ du], tau

    x = np.r_[ref[0], 0.0]
    X = np.zeros((steps + 1, 2 * n))
    T = np.zeros((steps + 1, n))
    D = np.zeros((steps + 1, n))
    for k in range(steps + 1):
        k1, tau = rates(2 * k, x)
        X[k], T[k] = x[: 2 * n], tau
        if linear is not None:
            D[k] = k1[n : 2 * n] - linear(x[:n], x[n : 2 * n], tau)
        if k == steps:
            break
        k2, _ = rates(2 * k + 1, x + h / 2 * k1)
        k3, _ = rates(2 * k + 1, x + h / 2 * k2)
        k4, _ = rates(2 * k + 2, x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    t = h * np.arange(steps + 1)
    return Run(t, X[:, :n], X[:, n:], T, float(x[-1]), D if linear is not None else None)


def peak_to_peak_gain(closed: np.ndarray, n: int, dt: float = 1e-3, floor: float = 1e-12) -> np.ndarray:
    """gamma_ij = int_0^inf |exp(A_c t)_(i, n+j)| dt, angle i from acceleration input j: then
    |e_i(t)| <= sum_j gamma_ij max |d_j| for edot = A_c e + (0, d). exp(A_c dt) by its
    Taylor series to the 8th power, the integral by trapezoids until |exp(A_c t)| < floor."""
    m = closed.shape[0]
    E, term = np.eye(m), np.eye(m)
    for p in range(1, 9):
        term = term @ (closed * dt) / p
        E = E + term
    Phi = np.eye(m)
    block = np.abs(Phi[:n, n:])
    gamma = 0.5 * dt * block
    while np.abs(Phi).max() > floor:
        Phi = E @ Phi
        block = np.abs(Phi[:n, n:])
        gamma += dt * block
    return gamma - 0.5 * dt * block


def direct_solution(
    servo: LinearServo, s0: np.ndarray, ref, t_end: float, h: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """The finite-horizon problem the steady servo solves exactly (linear_servo S1-S4: the
    terminal cost s^T P s - 2 g_f^T s at t_end), minimised directly over the states and
    inputs at every node of a grid of step h: trapezoidal dynamics s_(k+1) - s_k = h/2
    (f_k + f_(k+1)), trapezoidal cost, one sparse KKT system (CasADi's csparse). Returns
    (times, du (N+1, m), cost)."""
    A, B, Q, R, P = servo.A, servo.B, servo.Q, servo.R, servo.P
    nx, nu = B.shape
    steps = int(round(t_end / h))
    times = h * np.arange(steps + 1)
    r = np.array([ref(t) for t in times])
    g_f = servo.held_costate(r[-1])
    nz = (steps + 1) * (nx + nu)
    weights = np.full(steps + 1, h)
    weights[[0, -1]] = h / 2
    rows, cols, vals = [], [], []

    def put(i0, j0, block):
        ii, jj = np.nonzero(block)
        rows.extend((i0 + ii).tolist())
        cols.extend((j0 + jj).tolist())
        vals.extend(block[ii, jj].tolist())

    c = np.zeros(nz)
    for k in range(steps + 1):  # the cost's Hessian (2 w Q, 2 w R) and gradient (-2 w Q r)
        z = k * (nx + nu)
        put(z, z, 2 * weights[k] * Q + (2 * P if k == steps else 0))
        put(z + nx, z + nx, 2 * weights[k] * R)
        c[z : z + nx] = -2 * weights[k] * Q @ r[k]
    c[steps * (nx + nu) : steps * (nx + nu) + nx] -= 2 * g_f
    E_s0 = np.eye(nx)
    lam = nz  # constraint rows after the variables: s_0 = s0, then the N trapezoid steps
    put(lam, 0, E_s0)
    put(0, lam, E_s0.T)
    left = np.hstack([np.eye(nx) + h / 2 * A, h / 2 * B])  # acting on (s_k, du_k)
    right = np.hstack([-np.eye(nx) + h / 2 * A, h / 2 * B])  # on (s_(k+1), du_(k+1))
    for k in range(steps):
        row, z = lam + nx * (k + 1), k * (nx + nu)
        put(row, z, left)
        put(row, z + nx + nu, right)
        put(z, row, left.T)
        put(z + nx + nu, row, right.T)
    size = nz + nx * (steps + 1)
    kkt = ca.DM.triplet(rows, cols, ca.DM(vals), size, size)
    rhs = np.r_[-c, s0, np.zeros(nx * steps)]
    z = np.array(ca.solve(kkt, ca.DM(rhs), "csparse")).ravel()[:nz].reshape(steps + 1, nx + nu)
    s, du = z[:, :nx], z[:, nx:]
    e = s - r
    running = np.einsum("k,ki,ij,kj->", weights, e, Q, e) + np.einsum("k,ki,ij,kj->", weights, du, R, du)
    return times, du, float(running + s[-1] @ P @ s[-1] - 2 * g_f @ s[-1])


def reproduce(out: Path, quick: bool = False) -> dict:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    arm = build(out / "module")
    lqr = arm.lqr
    A, B, K = (np.array(lqr[k]) for k in ("A", "B", "K"))
    Q, R = np.diag(lqr["Q"]), np.diag(lqr["R"])
    q0, tau0 = np.array(lqr["nominal"]), np.array(lqr["tau0"])
    n = len(q0)
    # the servo on eq 19 with y = s, the whole state (its gains are lqr_step's: the same Riccati solve)
    servo = design(A, B, np.eye(2 * n), Q, R)
    if not np.array_equal(servo.K, K):
        raise RuntimeError("the servo's gains differ from the module's lqr_step gains")

    path = JointPath(POSTURES[: QUICK_MOVES + 1] if quick else POSTURES, MOVE, REST)
    t_end = path.duration
    steps = int(round(t_end / STEP))
    half = 0.5 * STEP * np.arange(2 * steps + 1)
    samples = [path(t) for t in half]
    ref = np.array([np.r_[a, b] for a, b, _ in samples])  # (theta_d, theta_d_dot) on the half grid
    nominal = np.r_[q0, np.zeros(n)]

    def deviation(t):  # r(t) of the servo: the reference as a deviation from the nominal
        a, b, _ = path(t)
        return np.r_[a - q0, b]

    _, g = costate(servo, deviation, 0.0, t_end, 2 * steps)
    v = servo.feedforward(g)  # (2N+1, n) on the half grid

    def linear_qdd(q, qd, tau):  # eq 19 applied to the whole state
        return A[n:] @ np.r_[q - q0, qd] + B[n:] @ (tau - tau0)

    def servo_law(i, q, qd):
        return arm.servo_step(q, qd, v[i])

    def regulator_law(i, q, qd):  # the same gains on the error from the moving reference, no feedforward
        return arm.lqr_step(q - ref[i, :n] + q0, qd - ref[i, n:])

    runs = {}
    for label, law in (("servo", servo_law), ("regulator", regulator_law)):
        runs[label] = simulate(arm.forward_dynamics, law, ref, Q, R, tau0, STEP, linear_qdd)
        runs[label + "_linear"] = simulate(linear_qdd, law, ref, Q, R, tau0, STEP)
    nodes = ref[::2]

    def errors(run):
        return run.q - nodes[:, :n]

    # the bound: e = x - x_lin obeys edot = A_c e + (0, d), d the residual along the nonlinear run
    gamma = peak_to_peak_gain(servo.closed, n)
    d_max = np.abs(runs["servo"].residual).max(axis=0)
    linear_err = np.abs(errors(runs["servo_linear"])).max(axis=0)
    bound = linear_err + gamma @ d_max

    # the servo on the linear model, with the terminal cost, against the direct solution
    s_end = np.r_[runs["servo_linear"].q[-1], runs["servo_linear"].qd[-1]] - nominal
    g_f = servo.held_costate(deviation(t_end))
    servo_linear_cost = runs["servo_linear"].cost + s_end @ servo.P @ s_end - 2 * g_f @ s_end
    s0 = ref[0] - nominal
    coarse = direct_solution(servo, s0, deviation, t_end, DIRECT_STEP)
    fine = direct_solution(servo, s0, deviation, t_end, DIRECT_STEP / 2)
    direct_cost = (4 * fine[2] - coarse[2]) / 3  # Richardson: the transcription's leading error is O(h^2)
    direct_du = (4 * fine[1][::2] - coarse[1]) / 3
    every = int(round(DIRECT_STEP / STEP))
    servo_du = runs["servo_linear"].tau[::every] - tau0

    # the torque the path needs: inverse dynamics along the reference
    accel = np.array([c for _, _, c in samples[::2]])
    needed = arm.inverse_dynamics(nodes[:, :n], nodes[:, n:], accel)

    numbers = {"duration_s": t_end, "step_s": STEP}
    for label in ("servo", "regulator", "servo_linear", "regulator_linear"):
        e = errors(runs[label])
        for j, name in enumerate(JOINTS):
            numbers[f"{label}_max_error_{name}_rad"] = float(np.abs(e[:, j]).max())
            numbers[f"{label}_rms_error_{name}_rad"] = float(np.sqrt(np.mean(e[:, j] ** 2)))
        numbers[f"{label}_max_error_rad"] = float(np.abs(e).max())
        numbers[f"{label}_rms_error_rad"] = float(np.sqrt(np.mean(e**2)))
        numbers[f"{label}_peak_torque_nm"] = float(np.abs(runs[label].tau).max())
        numbers[f"{label}_peak_torque_ftlb"] = float(np.abs(runs[label].tau).max() / NM_PER_FT_LB)
        numbers[f"{label}_cost"] = runs[label].cost
    for j, name in enumerate(JOINTS):
        numbers[f"error_bound_{name}_rad"] = float(bound[j])
        numbers[f"servo_peak_torque_{name}_nm"] = float(np.abs(runs["servo"].tau[:, j]).max())
        numbers[f"needed_peak_torque_{name}_nm"] = float(np.abs(needed[:, j]).max())
    numbers["servo_torque_minus_needed_nm"] = float(np.abs(runs["servo"].tau - needed).max())
    numbers["needed_peak_torque_nm"] = float(np.abs(needed).max())
    numbers["residual_max"] = float(d_max.max())
    # eq 19's gravity, tau0 + dN/dtheta (theta - theta0) with dN/dtheta = -M(theta0) A_21, against N(theta)
    stiffness = -arm.mass(q0) @ A[n:, :n]
    linear_gravity = tau0 + (nodes[:, :n] - q0) @ stiffness.T
    numbers["gravity_linearisation_error_nm"] = float(np.abs(arm.gravity(nodes[:, :n]) - linear_gravity).max())
    numbers["angle_gain_min_nm_per_rad"] = float(np.diag(K[:, :n]).min())
    numbers["angle_gain_max_nm_per_rad"] = float(np.diag(K[:, :n]).max())
    poles = np.linalg.eigvals(servo.closed)
    numbers["closed_loop_slowest_real_part"] = float(poles.real.max())
    numbers["closed_loop_fastest_real_part"] = float(poles.real.min())
    numbers["servo_linear_cost_with_terminal"] = float(servo_linear_cost)
    numbers["direct_cost"] = float(direct_cost)
    numbers["direct_cost_relative_gap"] = float(abs(direct_cost - servo_linear_cost) / abs(servo_linear_cost))
    # after the first node: the transcription's first input is off by O(h) (its adjoint equation
    # there has half a step), every other one by O(h^2) before extrapolation
    numbers["direct_input_gap_nm"] = float(np.abs(direct_du - servo_du)[1:].max())
    numbers["direct_input_coarse_gap_nm"] = float(np.abs(coarse[1] - servo_du)[1:].max())

    figure = out / "fig5.png"
    plot(figure, runs, nodes, n)
    report = out / "report.md"
    hands = arm.fk(path.postures)[:, :3, 3]
    numbers.update(eq11(out, quick))
    report.write_text(markdown(numbers, lqr, path.postures, hands, quick) + eq11_markdown(numbers))
    return numbers


def eq11_markdown(x: dict) -> str:
    T = x["eq11_arrival_time_s"]
    return "\n".join(
        [
            "## Position control through rates: eq 11's remaining time",
            "",
            'The paper moves the hand to a pose "in a time interval T" by the rates of eq 11 and eqs 13-18, '
            're-planned from the current joint angles "with a new T" along the way. The PUMA 560 of '
            f"`specs/puma560_rmrc.yaml` moves {1e3 * DISTANCE:g} mm and turns {np.degrees(TURN):g} degrees, the "
            f"joints following each period's rates ({1e3 * STEP:g} ms):",
            "",
            "| | hand distance from the target at T |",
            "| --- | ---: |",
            f"| eq 11 with the remaining time, T = {T:g} s | {x['eq11_arrival_distance_at_T_m']:.2e} m |",
            f"| fixed horizon {x['eq11_horizon_s']:g} s (exponential approach) | "
            f"{x['eq11_exponential_distance_at_T_m']:.2e} m (predicted {x['eq11_exponential_predicted_m']:.2e}) |",
            "",
            f"With the remaining time the hand stays within {x['eq11_arrival_largest_distance_off_line_m']:.1e} m "
            f"of the straight line and is {1e3 * x['eq11_arrival_distance_at_half_T_m']:.2f} mm from the target "
            "at T/2 (half way).",
            "",
            "![eq 11](eq11.png)",
            "",
        ]
    )


def rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """exp([axis x] angle) by Rodrigues' formula (axis a unit vector)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def eq11(out: Path, quick: bool) -> dict:
    """Position control through rates to a target pose: the fixed horizon's exponential
    approach against eq 11 with the remaining time (arrival_step), the joints following the
    commanded rates one period at a time."""
    yaml = YAML(typ="safe")
    yaml.default_flow_style = None
    data = yaml.load(RMRC)
    name = data["name"] = "whitney_1972_puma"
    settings = data["nodes"]["rmrc"]["control"]["resolved_rate"]
    settings["horizon"] = HORIZON
    settings["arrival"] = {"minimum_remaining": STEP}
    spec = out / "module" / f"{name}.yaml"
    spec.parent.mkdir(parents=True, exist_ok=True)
    with open(spec, "w") as f:
        yaml.dump(data, f)
    if robotgen(["build", str(spec), "-o", str(out / "module" / name), "-q"]) != 0:
        raise RuntimeError(f"robotgen build {spec} failed")
    sys.path.insert(0, str(out / "module" / name))
    try:
        puma = importlib.import_module(name)
    finally:
        sys.path.pop(0)
    T = ARRIVAL_TIME[quick]
    start = puma.fk(PUMA_START)
    target = start.copy()
    target[:3, 3] += DISTANCE * DIRECTION
    target[:3, :3] = rotation(AXIS, TURN) @ start[:3, :3]
    exponential, arrival = approach_paths(puma, PUMA_START, target, T, STEP, duration=1.25 * T)
    hand = puma.fk(arrival.q)[:, :3, 3]
    along = (hand - start[:3, 3]) @ DIRECTION
    off_line = np.linalg.norm(hand - start[:3, 3] - np.outer(along, DIRECTION), axis=1)
    at_T = int(round(T / STEP))
    numbers = {
        "eq11_arrival_time_s": T,
        "eq11_horizon_s": HORIZON,
        "eq11_arrival_distance_at_T_m": float(arrival.distance()[at_T]),
        "eq11_exponential_distance_at_T_m": float(exponential.distance()[at_T]),
        "eq11_exponential_predicted_m": float(DISTANCE * np.exp(-T / HORIZON)),
        "eq11_arrival_largest_distance_off_line_m": float(off_line[: at_T + 1].max()),
        "eq11_arrival_distance_at_half_T_m": float(arrival.distance()[at_T // 2]),
    }
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4))
    for path, label in (
        (exponential, f"fixed horizon {HORIZON:g} s (position_step): exponential approach"),
        (arrival, f"eq 11 with the remaining time (arrival_step): arrives at T = {T:g} s"),
    ):
        ax.plot(path.t, 1e3 * path.distance(), label=label)
    ax.axvline(T, color="k", linestyle=":", linewidth=1)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("distance of the hand from the target [mm]")
    ax.set_title(f"PUMA 560 moved {1e3 * DISTANCE:g} mm and turned {np.degrees(TURN):g} degrees by rates")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "eq11.png", dpi=100)
    plt.close(fig)
    return numbers


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot(path: Path, runs: dict, nodes: np.ndarray, n: int) -> None:
    plt = _pyplot()

    servo, regulator = runs["servo"], runs["regulator"]
    t = servo.t
    colours = ("tab:blue", "tab:orange", "tab:green")
    fig, axes = plt.subplots(2, 2, figsize=(12, 8), sharex=True)
    ax = axes[0, 0]
    for j in range(n):
        ax.plot(t, servo.q[:, j], color=colours[j], label=f"theta{j + 1} ({JOINTS[j]})")
        ax.plot(t, nodes[:, j], color="k", linestyle=":", linewidth=1)
    ax.set_ylabel("angle [rad]")
    ax.set_title("(a) joint angles under the servo; dotted: targets")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    ax = axes[0, 1]
    for j in range(n):
        ax.plot(t, servo.tau[:, j] / NM_PER_FT_LB, color=colours[j], label=f"tau{j + 1} ({JOINTS[j]})")
        ax.plot(t, regulator.tau[:, j] / NM_PER_FT_LB, color=colours[j], linestyle="--", linewidth=1)
    ax.set_ylabel("torque [ft-lb]")
    ax.set_title("(b) joint torques; dashed: the same gains without feedforward")
    ax.legend(loc="center right", fontsize=8)
    ax.grid(alpha=0.3)
    right = ax.secondary_yaxis("right", functions=(lambda x: x * NM_PER_FT_LB, lambda x: x / NM_PER_FT_LB))
    right.set_ylabel("torque [N m]")
    for ax, label, title in (
        (axes[1, 0], "servo", "(c) tracking error, optimal linear servo"),
        (axes[1, 1], "regulator", "(d) tracking error, the same gains without feedforward"),
    ):
        run, linear = runs[label], runs[label + "_linear"]
        for j in range(n):
            ax.plot(t, 1e3 * (run.q[:, j] - nodes[:, j]), color=colours[j], label=f"theta{j + 1}")
            ax.plot(t, 1e3 * (linear.q[:, j] - nodes[:, j]), color=colours[j], linestyle="--", linewidth=1)
        title += "\n(dashed: on eq 19, the design's prediction)"
        ax.set_ylabel("error [mrad]")
        ax.set_xlabel("time [s]")
        ax.set_title(title)
        ax.legend(loc="best", fontsize=7)
        ax.grid(alpha=0.3)
    fig.suptitle(
        "Whitney 1972, Fig 5 reproduced: three-link arm under the optimal linear servo (full nonlinear dynamics)"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def markdown(x: dict, lqr: dict, postures: np.ndarray, hands: np.ndarray, quick: bool) -> str:
    def row(label, key, scale=1.0, fmt=".2f"):
        cells = [format(scale * x[f"{key}_{name}_rad"], fmt) for name in JOINTS]
        return f"| {label} | " + " | ".join(cells) + " |"

    moves = QUICK_MOVES if quick else len(POSTURES) - 1
    lines = [
        "# Whitney 1972: optimal linear servo tracking (Fig 5)",
        "",
        'The paper (section "Dynamic Control of Arms") applies the linearised model of eq 19 to the '
        "whole state, designs feedback gains and control functions by optimal linear servo theory, and "
        'runs them on simulation equations with every nonlinearity. Fig 5 ("three link arm test no. '
        '21") plots the joint angles against their targets (rad) and the torques (ft-lb). The paper '
        'gives no numbers for it, only: "Although the arm moves at a leisurely pace, the errors are '
        'quite small, as are the required torques." Its arm and path are not given either; the arm '
        "below (`whitney_1972_arm.yaml`) and the path are robotgen's choice.",
        "",
        f"Arm: shoulder sweep about the vertical, shoulder flexion and elbow about horizontal axes; upper "
        f"arm 0.30 m, 2.0 kg; forearm and hand 0.33 m, 1.5 kg; armature 0.1 kg m^2 and damping "
        f"0.5 N m s/rad per joint. Eq 19 linearised at theta0 = {lqr['nominal']} rad "
        f"(tau0 = {np.round(lqr['tau0'], 2).tolist()} N m). Servo weights: Q = diag({lqr['Q'][0]:g} "
        f"on angles, {lqr['Q'][-1]:g} on rates), R = {lqr['R'][0]:g} I; closed-loop poles' real parts "
        f"{x['closed_loop_fastest_real_part']:.1f} to {x['closed_loop_slowest_real_part']:.1f} 1/s; "
        f"controllability rank {lqr['controllability_rank']}, observability rank from the angles alone "
        f"{lqr['observability_rank_from_positions']} (of 6), as the paper states.",
        "",
        f"Path: {moves} minimum-jerk move(s) of {MOVE:g} s between postures, {REST:g} s still before and "
        f"after each ({x['duration_s']:g} s{'; quick mode' if quick else ''}). Simulation: full nonlinear "
        f"dynamics from the generated module, RK4 at {1e3 * STEP:g} ms, the law evaluated at every stage.",
        "",
        "| posture | theta [rad] | hand (x, y, z) [m], shoulder at the origin |",
        "| --- | --- | --- |",
        *(
            f"| {k} | {np.round(p, 2).tolist()} | {np.round(h, 3).tolist()} |"
            for k, (p, h) in enumerate(zip(postures, hands))
        ),
        "",
        "![Fig 5](fig5.png)",
        "",
        "| tracking error [mrad] | theta1 (sweep) | theta2 (flexion) | theta3 (elbow) |",
        "| --- | --- | --- | --- |",
        row("servo, max", "servo_max_error", 1e3),
        row("servo, RMS", "servo_rms_error", 1e3),
        row("same gains without feedforward, max", "regulator_max_error", 1e3),
        row("same gains without feedforward, RMS", "regulator_rms_error", 1e3),
        row("servo on eq 19 (the design's prediction), max", "servo_linear_max_error", 1e3),
        row("bound: prediction + peak-to-peak gain x residual", "error_bound", 1e3),
        "",
        "| torque | servo | without feedforward | inverse dynamics along the path |",
        "| --- | --- | --- | --- |",
        f"| peak [N m] | {x['servo_peak_torque_nm']:.2f} | {x['regulator_peak_torque_nm']:.2f} | "
        f"{x['needed_peak_torque_nm']:.2f} |",
        f"| peak [ft-lb] | {x['servo_peak_torque_ftlb']:.2f} | {x['regulator_peak_torque_ftlb']:.2f} | "
        f"{x['needed_peak_torque_nm'] / NM_PER_FT_LB:.2f} |",
        "",
        f"Cost int (x - r)^T Q (x - r) + (tau - tau0)^T R (tau - tau0) dt on the nonlinear arm: servo "
        f"{x['servo_cost']:.4g}, without feedforward {x['regulator_cost']:.4g}. The servo's torque stays "
        f"within {x['servo_torque_minus_needed_nm']:.3f} N m of the inverse dynamics along the path. Most of "
        f"its error is the gravity that eq 19 makes linear: off by up to "
        f"{x['gravity_linearisation_error_nm']:.3f} N m along the path, against angle gains (K's diagonal) "
        f"of {x['angle_gain_min_nm_per_rad']:.0f}-{x['angle_gain_max_nm_per_rad']:.0f} N m/rad.",
        "",
        f"Independent check: the same finite-horizon problem on eq 19 minimised directly (trapezoidal "
        f"transcription at {1e3 * DIRECT_STEP:g} and {5e2 * DIRECT_STEP:g} ms, one sparse solve each, "
        f"Richardson-extrapolated): cost {x['direct_cost']:.8g} against the servo's "
        f"{x['servo_linear_cost_with_terminal']:.8g} (relative gap {x['direct_cost_relative_gap']:.1e}; the "
        f"terminal cost s^T P s - 2 g_f^T s has no constant, hence below zero); inputs within "
        f"{x['direct_input_gap_nm']:.1e} N m after the first node ({x['direct_input_coarse_gap_nm']:.1e} at "
        f"{1e3 * DIRECT_STEP:g} ms alone).",
        "",
        'Paper\'s numbers: none for Fig 5 ("errors quite small", "torques small").',
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one move instead of three (a few seconds)")
    parser.add_argument(
        "-o",
        "--output",
        type=Path,
        default=Path("generated/papers/whitney_1972"),
        help="output directory (default generated/papers/whitney_1972)",
    )
    args = parser.parse_args(argv)
    numbers = reproduce(args.output, quick=args.quick)
    for key, value in numbers.items():
        print(f"{key:45s} {value:.6g}")
    for file in ("fig5.png", "eq11.png", "report.md"):
        print(f"wrote {args.output / file}")


if __name__ == "__main__":
    main()
