"""The adaptive step's identification (eq 37) and one-step control (eq 39) as loops, and the
reset's discretisation (eqs 29-32) (init_schedule).

Straight-line, the step's RLS update and one-step control are four of its five thousand
operations (19 x 19 covariance, 12 rows of 19 parameters, 12 x 6 products and two 6 x 6 grams),
and a Cortex-M build of it was 75 kB of code. Here the feedforward, the perturbation dx and
the copies of the trajectory stay the straight-line prologue, and the rest repeats small
bodies (robotgen.symbolic.schedule) that read the controller's state in place:

  Pphi_i = P_i . phi_old                          rows of P (RANGE n)
  g, eps g, scale                                 once (resolved_adaptive.identify's gain)
  theta_i += (dx_i - theta_i . phi_old) g         the rows of Theta = [A B c] (RANGE 12)
  P_ij = (P_ij - Pphi_i eps g_j) scale            the diagonal (RANGE n), then i < j (ABOVE),
                                                  written to (i, j) and (j, i)
  (A dx)_i, (Q B)_i, (Q B0)_i                     rows (RANGE 12)
  (B^T Q B)_ab, kappa (B0^T Q B0)_ab              the diagonal, then a < b (ABOVE)
  (QB^T A dx)_a, (QB^T c)_a                       columns (RANGE 6)
  du, tau                                         once: the two Cholesky solves of eq 39

Each body is resolved_adaptive's formula for one row or entry, so the step computes what its
straight-line form (resolved_adaptive.step_graph) computes. The weights, run-time parameters
or constants, are copied into local arrays by the prologue (a loop body reads arrays, not the
parameter struct)."""

from __future__ import annotations

import casadi as ca

from robotgen.symbolic.root_laws.hand import Linearisation, acceleration_row
from robotgen.symbolic.root_laws.resolved_adaptive import (
    NU,
    NX,
    covariance_entry,
    one_step_torque,
    parameter_row,
    rls_gain,
    trace_factor,
)
from robotgen.symbolic.schedule import ABOVE, INPUT, LOCAL, ONCE, OUTPUT, RANGE, ScheduleBuilder, Slice, body

TAU, DX, STATE_NEXT = 0, 1, 2  # the step's outputs
STATE, ADAPT = 5, 6  # the step's inputs: q, qd, pose_d, twist_d, accel_d, state, adapt


def step_schedule(
    inputs: list[ca.SX],
    sizes: list[int],
    offsets: dict[str, tuple[int, int, int]],
    prologue: dict[str, ca.SX],
    weights: dict,
) -> ScheduleBuilder:
    """The step as a prologue and loops. ``prologue``: values of the inputs alone (u_n, dx,
    q_d, qd_d, qdd_d); ``weights``: Q's diagonal (12) or Q row-major (144), R row-major (36)
    or None (then kappa B0^T Q B0), kappa and mu, each SX of the run-time parameters or
    constant (the prologue copies them into local arrays); the trace limit or None,
    directional, affine."""
    b = ScheduleBuilder(inputs, sizes)
    n = offsets["phi"][1]
    affine = weights["affine"]

    def state(name: str, i_stride: int = 0, j_stride: int = 0, offset: int = 0, step: int = 1) -> Slice:
        return Slice(INPUT, STATE, offsets[name][0] + offset, i_stride, j_stride, step)

    def new(name: str, i_stride: int = 0, j_stride: int = 0, offset: int = 0, step: int = 1) -> Slice:
        return Slice(OUTPUT, STATE_NEXT, offsets[name][0] + offset, i_stride, j_stride, step)

    def local(index: int, i_stride: int = 0, j_stride: int = 0, offset: int = 0, step: int = 1) -> Slice:
        return Slice(LOCAL, index, offset, i_stride, j_stride, step)

    # the prologue: the trajectory, dx, and phi's new head and constant
    u_n = b.local(prologue["u_n"])
    dx = b.local(prologue["dx"])
    scalars = b.local(ca.vertcat(inputs[ADAPT], weights["mu"], weights["kappa"]))  # adapt, mu, kappa
    b.prologue(Slice(OUTPUT, DX), prologue["dx"])
    b.prologue(new("phi"), prologue["dx"])
    if affine:
        b.prologue(new("phi", offset=NX + NU), ca.SX(1))
    for name in ("q_d", "qd_d", "qdd_d"):
        b.prologue(new(name), prologue[name])
    row6, x = ca.SX.sym("row", NU), ca.SX.sym("x", NX)
    b.loop(body("copy", [row6], [row6]), RANGE, NX, [state("B0", NU)], [new("B0", NU)])

    # eq 37: P phi, the gain, the rows of Theta, P's update
    p_row, phi = ca.SX.sym("p_row", n), ca.SX.sym("phi", n)
    p_phi = b.local(size=n)
    b.loop(
        body("p_phi", [p_row, phi], [ca.dot(p_row, phi)]), RANGE, n, [state("P", n), state("phi")], [local(p_phi, 1)]
    )
    pp, adapt, mu = ca.SX.sym("pp", n), ca.SX.sym("adapt"), ca.SX.sym("mu")
    g, eg, scale = rls_gain(pp, phi, adapt, mu, weights["directional"])
    gain, e_gain = b.local(size=n), b.local(size=n)
    scaling = b.local(size=1) if scale is not None else -1
    b.loop(
        body("gain", [pp, phi, adapt, mu], [g, eg, *((scale,) if scale is not None else ())]),
        ONCE,
        1,
        [local(p_phi), state("phi"), local(scalars), local(scalars, offset=1)],
        [local(gain), local(e_gain), *((local(scaling),) if scale is not None else ())],
    )
    a_row, b_row, c_i, dx_i, gg = (ca.SX.sym(k, m) for k, m in (("a", NX), ("b", NU), ("c", 1), ("dx", 1), ("g", n)))
    theta = parameter_row(ca.vertcat(a_row, b_row, *((c_i,) if affine else ())), phi, dx_i, gg)
    rows = [state("A", NX), state("B", NU), *((state("c", 1),) if affine else ())]
    b.loop(
        body(
            "theta",
            [a_row, b_row, *((c_i,) if affine else ()), phi, dx_i, gg],
            [theta[:NX], theta[NX : NX + NU], *((theta[NX + NU],) if affine else ())],
        ),
        RANGE,
        NX,
        [*rows, state("phi"), local(dx, 1), local(gain)],
        [new("A", NX), new("B", NU), *((new("c", 1),) if affine else ())],
    )
    p_ij, pp_i, eg_j, sc = (ca.SX.sym(k) for k in ("p_ij", "pp_i", "eg_j", "scale"))
    scaled = scale is not None
    value = covariance_entry(p_ij, pp_i, eg_j, sc if scaled else None)
    ins = [p_ij, pp_i, eg_j, *((sc,) if scaled else ())]
    entry = body("covariance", ins, [value])
    both = body("covariance_pair", ins, [value] * 2)
    limit = weights["limit"]
    if limit is None:
        upper, lower, diagonal = new("P", n, 1), new("P", 1, n), new("P", n + 1)
    else:
        unlimited = b.local(size=n * n)
        upper, lower, diagonal = local(unlimited, n, 1), local(unlimited, 1, n), local(unlimited, n + 1)
    by = [local(scaling)] if scaled else []
    b.loop(entry, RANGE, n, [state("P", n + 1), local(p_phi, 1), local(e_gain, 1), *by], [diagonal])
    b.loop(both, ABOVE, n, [state("P", n, 1), local(p_phi, 1), local(e_gain, 0, 1), *by], [upper, lower])
    if limit is not None:
        d = ca.SX.sym("d", n)
        factor = b.local(size=1)
        b.loop(
            body("trace", [d], [trace_factor(d, limit)]),
            ONCE,
            1,
            [local(unlimited, step=n + 1)],
            [local(factor)],
        )
        r, f = ca.SX.sym("r", n), ca.SX.sym("f")
        b.loop(body("limited", [r, f], [r * f]), RANGE, n, [local(unlimited, n), local(factor)], [new("P", n)])

    # eq 39: A dx, Q B (and Q B0), the grams, QB^T A dx and QB^T c, then the solves
    a_dx = b.local(size=NX)
    b.loop(body("a_dx", [a_row, x], [ca.dot(a_row, x)]), RANGE, NX, [new("A", NX), local(dx)], [local(a_dx, 1)])
    q = b.local(weights["q"])  # Q's diagonal, or Q row-major

    def times_q(source: Slice, name: str) -> int:
        out = b.local(size=NX * NU)
        if weights["q"].numel() == NX:
            q_i, row = ca.SX.sym("q_i"), ca.SX.sym("row", NU)
            b.loop(body(name, [q_i, row], [q_i * row]), RANGE, NX, [local(q, 1), source], [local(out, NU)])
        else:
            q_row, whole = ca.SX.sym("q_row", NX), ca.SX.sym("whole", NX * NU)
            matrix = ca.reshape(whole, NU, NX).T
            b.loop(
                body(name, [q_row, whole], [(q_row.T @ matrix).T]),
                RANGE,
                NX,
                [local(q, NX), _whole(source)],
                [local(out, NU)],
            )
        return out

    qb = times_q(new("B", NU), "q_b")
    column_a, column_b, kappa = ca.SX.sym("column_a", NX), ca.SX.sym("column_b", NX), ca.SX.sym("kappa")

    def gram(matrix: Slice, product: int, name: str, scaled: bool = False) -> int:
        """B^T (Q B) as resolved_adaptive._gram forms it, each entry once, mirrored; times kappa."""
        out = b.local(size=NU * NU)
        value = ca.dot(column_a, column_b) * kappa if scaled else ca.dot(column_a, column_b)
        ins = [column_a, column_b, *((kappa,) if scaled else ())]
        extra = [local(scalars, offset=2)] if scaled else []
        b.loop(
            body(name, ins, [value]),
            RANGE,
            NU,
            [_column(matrix, 1, 0), local(product, 1, step=NU), *extra],
            [local(out, NU + 1)],
        )
        b.loop(
            body(name + "_pair", ins, [value] * 2),
            ABOVE,
            NU,
            [_column(matrix, 1, 0), local(product, 0, 1, step=NU), *extra],
            [local(out, NU, 1), local(out, 1, NU)],
        )
        return out

    h = gram(new("B", step=NU), qb, "gram")
    if weights["r"] is None:
        qb0 = times_q(state("B0", NU), "q_b0")
        weight = gram(state("B0", step=NU), qb0, "torque_weight", scaled=True)
    else:
        weight = b.local(weights["r"])
    column = ca.SX.sym("column", NX)
    qb_a_dx = b.local(size=NU)
    b.loop(
        body("qb_a_dx", [column, x], [ca.dot(column, x)]),
        RANGE,
        NU,
        [local(qb, 1, step=NU), local(a_dx)],
        [local(qb_a_dx, 1)],
    )
    solves = [local(h), local(weight), local(qb_a_dx), local(u_n)]
    hh, rr, v, un = ca.SX.sym("h", NU * NU), ca.SX.sym("r", NU * NU), ca.SX.sym("v", NU), ca.SX.sym("u_n", NU)
    H, R = ca.reshape(hh, NU, NU).T, ca.reshape(rr, NU, NU).T
    arguments = [hh, rr, v, un]
    w = None
    if affine:
        qb_c = b.local(size=NU)
        b.loop(
            body("qb_c", [column, x], [ca.dot(column, x)]),
            RANGE,
            NU,
            [local(qb, 1, step=NU), new("c")],
            [local(qb_c, 1)],
        )
        w = ca.SX.sym("w", NU)
        solves.append(local(qb_c))
        arguments.append(w)
    du = one_step_torque(H, R, v, w)
    b.loop(body("control", arguments, [un + du, du]), ONCE, 1, solves, [Slice(OUTPUT, TAU), new("phi", offset=NX)])
    return b


def _column(matrix: Slice, i_stride: int, j_stride: int) -> Slice:
    """Column i (or j) of a 12 x 6 row-major matrix slice: 12 elements NU apart."""
    return Slice(matrix.kind, matrix.index, matrix.offset, i_stride, j_stride, NU)


def _whole(row: Slice) -> Slice:
    """The whole matrix whose rows ``row`` walks (the same elements at every iteration)."""
    return Slice(row.kind, row.index, row.offset)


def init_schedule(
    inputs: list[ca.SX],
    size: int,
    offsets: dict[str, tuple[int, int, int]],
    values: dict,
    parts: Linearisation,
    T: float,
    terms: int,
) -> ScheduleBuilder:
    """The reset's state with F's acceleration rows, A = exp(F T) and B = int_0^T exp(F s) ds L
    (hand.discretise's series to ``terms`` terms) as loops: each acceleration row of F
    (hand.acceleration_row, a 6 x 12 and three 6 x 6 products), then each row of each term
    of the series as the row of the term before times F times T/k (one loop over the rows of
    the terms laid end to end), then each entry of A and of S = sum_k term_k T/(k+1), then
    each row of B = S L (S's last six columns times J D^-1: L's first rows are zero). The prologue writes the
    linearisation's ``parts`` (hand.linearisation_parts), the trajectory and P_0's diagonal;
    c and phi stay 0. ``values``: q_d, qd_d, qdd_d and P0 (its diagonal)."""
    b = ScheduleBuilder(inputs, [size])
    n = offsets["P"][1]

    def new(name: str, i_stride: int = 0, offset: int = 0) -> Slice:
        return Slice(OUTPUT, 0, offsets[name][0] + offset, i_stride)

    for name in ("q_d", "qd_d", "qdd_d"):
        b.prologue(new(name), values[name])
    b.prologue(Slice(OUTPUT, 0, offsets["P"][0], 0, 0, n + 1), values["P0"])
    f = b.local(size=NX * NX)  # F row-major: (p, Phi)'s rows here, the acceleration rows by the loop
    b.prologue(Slice(LOCAL, f), ca.densify(parts.top).T)
    read = (parts.dadz, parts.J_Minv, parts.dtaudz, parts.W, parts.Jinv, parts.E)
    matrices = [b.local(ca.densify(m).T) for m in read]  # row-major
    dadz_row, jm_row = ca.SX.sym("dadz_row", NX), ca.SX.sym("jm_row", NU)
    dtaudz, w, jinv, e = (
        ca.SX.sym(name, size) for name, size in (("dtaudz", NU * NX), ("W", NU * NU), ("Jinv", NU * NU), ("E", 9))
    )
    row_of_f = acceleration_row(
        dadz_row.T,
        jm_row.T,
        ca.reshape(dtaudz, NX, NU).T,
        ca.reshape(w, NU, NU).T,
        ca.reshape(jinv, NU, NU).T,
        ca.reshape(e, 3, 3).T,
    )
    b.loop(
        body("acceleration_row", [dadz_row, jm_row, dtaudz, w, jinv, e], [row_of_f.T]),
        RANGE,
        NU,
        [Slice(LOCAL, matrices[0], 0, NX), Slice(LOCAL, matrices[1], 0, NU), *(Slice(LOCAL, m) for m in matrices[2:])],
        [Slice(LOCAL, f, NU * NX, NX)],
    )
    series = b.local(ca.vertcat(ca.vec(ca.DM.eye(NX)), ca.SX.zeros((terms - 1) * NX * NX)))  # term_0 = I, then 0
    # row r of term k + 1 is row 12 k + r of the terms laid end to end: one RANGE over i = 12 k + r
    factors = b.local(ca.DM([T / k for k in range(1, terms) for _ in range(NX)]))
    row, whole, factor = ca.SX.sym("row", NX), ca.SX.sym("f", NX * NX), ca.SX.sym("factor")
    b.loop(
        body("series_term", [row, whole, factor], [(row.T @ ca.reshape(whole, NX, NX).T).T * factor]),
        RANGE,
        (terms - 1) * NX,
        [Slice(LOCAL, series, 0, NX), Slice(LOCAL, f), Slice(LOCAL, factors, 0, 1)],
        [Slice(LOCAL, series, NX * NX, NX)],
    )
    t = ca.SX.sym("t", terms)
    a_entry, s_entry = t[0], t[0] * T
    for k in range(1, terms):
        a_entry, s_entry = a_entry + t[k], s_entry + t[k] * (T / (k + 1))
    s_matrix = series  # S takes term_0's place, entry by entry as the sums read it
    b.loop(
        body("series_sums", [t], [a_entry, s_entry]),
        RANGE,
        NX * NX,
        [Slice(LOCAL, series, 0, 1, 0, NX * NX)],
        [new("A", 1), Slice(LOCAL, s_matrix, 0, 1)],
    )
    # B = S L = S's last six columns times J D^-1 (L's first six rows are zero)
    s_row, jm = ca.SX.sym("s_row", NU), ca.SX.sym("jm", NU * NU)
    b_row = (s_row.T @ ca.reshape(jm, NU, NU).T).T
    b.loop(
        body("input_matrix", [s_row, jm], [b_row, b_row]),
        RANGE,
        NX,
        [Slice(LOCAL, s_matrix, NU, NX), Slice(LOCAL, matrices[1])],
        [new("B", NU), new("B0", NU)],
    )
    return b
