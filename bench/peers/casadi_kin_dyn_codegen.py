"""casadi_kin_dyn's functions for one robot, as CasADi's generated C (run by
bench/peers/casadi_kin_dyn_peer.py inside the virtual environment that holds casadi_kin_dyn, whose
Pinocchio and CasADi are older than robotgen's).

    python casadi_kin_dyn_codegen.py URDF OUT.c OUT.json

casadi_kin_dyn traces Pinocchio's algorithms on CasADi SX symbols: crba (M), rnea (tau) and
aba (ddq). It offers no derivatives of the joint-space dynamics, so those are CasADi's
automatic differentiation of its SX graphs, as a user of it would take them; so is M^-1 (the
Jacobian of aba in tau). A second forward dynamics and M^-1 solve with M's L D L^T factors
(CasADi's ldl, ldl_solve): the CasADi analogue of Pinocchio's traced CRBA + Cholesky. Every
output matrix is generated transposed, so that CasADi's column-major storage is the row-major
layout robotgen writes, and dense (a structural zero written as 0). OUT.json lists each
function: name, what it computes, its work sizes.
"""

from __future__ import annotations

import json
import sys

import casadi as cs
import casadi_kin_dyn


def functions(urdf: str) -> list[tuple[str, str, cs.Function]]:
    """(kernel, variant, Function) for every variant; inputs q[, v, a or tau]."""
    kd = casadi_kin_dyn.CasadiKinDyn(urdf)
    n = kd.nv()
    crba, rnea, aba = (cs.Function.deserialize(f.serialize()) for f in (kd.crba(), kd.rnea(), kd.aba()))
    q, v, u = cs.SX.sym("q", n), cs.SX.sym("v", n), cs.SX.sym("u", n)
    mass = crba(q)
    mass = cs.triu(mass) + cs.triu(mass, False).T  # crba fills M's upper triangle (Pinocchio's convention)
    bias = rnea(q, v, cs.SX.zeros(n))
    d, lt, p = cs.ldl(mass)
    ddq_aba = aba(q, v, u)
    ddq_ldl = cs.ldl_solve(u - bias, d, lt, p)
    minv_ldl = cs.ldl_solve(cs.SX.eye(n), d, lt, p)
    tau = rnea(q, v, u)
    out = [
        ("mass", "crba", cs.Function("ckd_crba", [q], [mass.T])),
        ("inverse_dynamics", "rnea", cs.Function("ckd_rnea", [q, v, u], [tau])),
        ("forward_dynamics", "aba", cs.Function("ckd_aba", [q, v, u], [ddq_aba])),
        ("forward_dynamics", "crba_ldl", cs.Function("ckd_crba_ldl_fd", [q, v, u], [ddq_ldl])),
        (
            "mass_inverse",
            "aba_jacobian",
            cs.Function(
                "ckd_aba_jacobian_minv",
                [q],
                [cs.substitute(cs.jacobian(ddq_aba, u), cs.vertcat(v, u), cs.SX.zeros(2 * n)).T],
            ),
        ),
        ("mass_inverse", "crba_ldl", cs.Function("ckd_crba_ldl_minv", [q], [minv_ldl.T])),
        (
            "inverse_dynamics_derivatives",
            "rnea_jacobian",
            cs.Function("ckd_rnea_jacobian", [q, v, u], [cs.jacobian(tau, q).T, cs.jacobian(tau, v).T]),
        ),
        (
            "forward_dynamics_derivatives",
            "aba_jacobian",
            cs.Function(
                "ckd_aba_jacobian",
                [q, v, u],
                [cs.jacobian(ddq_aba, q).T, cs.jacobian(ddq_aba, v).T, cs.jacobian(ddq_aba, u).T],
            ),
        ),
        (
            "forward_dynamics_derivatives",
            "crba_ldl_jacobian",
            cs.Function(
                "ckd_crba_ldl_jacobian", [q, v, u], [cs.jacobian(ddq_ldl, q).T, cs.jacobian(ddq_ldl, v).T, minv_ldl.T]
            ),
        ),
    ]
    return out


def main(argv: list[str]) -> int:
    urdf, c_file, json_file = argv
    generated = functions(open(urdf).read())
    gen = cs.CodeGenerator(
        c_file.rsplit("/", 1)[-1], {"with_header": False, "casadi_real": "double", "casadi_int": "long long int"}
    )
    listing = []
    for kernel, variant, f in generated:
        ins = f.sx_in()
        f = cs.Function(f.name(), ins, [cs.densify(y) for y in f.call(ins)])
        gen.add(f)
        listing.append(
            {
                "kernel": kernel,
                "variant": variant,
                "function": f.name(),
                "n_in": f.n_in(),
                "n_out": f.n_out(),
                "sz_arg": f.sz_arg(),
                "sz_res": f.sz_res(),
                "sz_iw": f.sz_iw(),
                "sz_w": f.sz_w(),
                "out_sizes": [f.numel_out(i) for i in range(f.n_out())],
                "operations": f.n_nodes(),
            }
        )
    gen.generate(c_file.rsplit("/", 1)[0] + "/" if "/" in c_file else "./")
    with open(json_file, "w") as fh:
        json.dump({"casadi": cs.__version__, "functions": listing}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
