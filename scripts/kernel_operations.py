"""Operations of one node step, counted on what a node runs and on the comparison's filters
(docs/experiment.md, "The comparison under model error"). `codegen simulate` counts each
filter's predict and update as the comparison builds them in the reference: full n x n
matrices in, symmetrized full matrices out, and a generic update. A generated node runs the
kernels of `codegen build` instead (`<p>_kern_node_predict` and `<p>_kern_update`: the upper
triangle in and out, the update reading only the heads' rows). This prints both counts for the
derivative-free filter and, for a like-for-like ratio, the EKF's predict and update rebuilt with
the upper triangle in and out (its Jacobian and RK4 substeps unchanged). Every count is CasADi's
instruction count after common-subexpression elimination. Usage:

    python scripts/kernel_operations.py two_link_arm --disturbance integrated_gauss_markov --tau 0.3
"""

from __future__ import annotations

import argparse

import casadi as ca

from dfeif_codegen.codegen import kernels
from dfeif_codegen.codegen.kernels.linalg import pack, symmetric, unpack
from dfeif_codegen.codegen.options import Options
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare
from dfeif_codegen.symbolic.disturbance import Disturbance


def ekf_packed(spec: str, ts: float, substeps: int) -> dict[str, ca.Function]:
    """The comparison's EKF predict (x, P, u) and update (x, P, z, R) with the upper triangle of
    P in and out (q of 1 per chain: the count moves by under 0.1% with q)."""
    f = compare.filter_of(spec, ts, (1.0,), substeps, "ekf")
    m, n = f.model, f.model.n
    x, pp, u = ca.SX.sym("x", n), ca.SX.sym("pp", n * (n + 1) // 2), ca.SX.sym("u", m.inputs)
    z, R = ca.SX.sym("z", m.m), ca.SX.sym("R", m.m, m.m)
    P = symmetric(unpack(pp, n))
    (xn, Pn), (xu, Pu) = f.predict_sx(x, P, u), f.update_sx(x, P, z, R)
    return {"predict": ca.Function("predict", [x, pp, u], [xn, pack(Pn)], {"cse": True}),
            "update": ca.Function("update", [x, pp, z, R], [xu, pack(Pu)], {"cse": True})}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", help="built-in model name or a model .toml")
    ap.add_argument("--ts", type=float, default=None, help="sampling period [s] (default: the model's)")
    ap.add_argument("--disturbance", default=None, help="the disturbance states' kind (symbolic/disturbance.KINDS)")
    ap.add_argument("--tau", type=float, default=None, help="their time constant [s] (a timed kind's)")
    ap.add_argument("--predictor", default=None, help="held (default) or scheduled")
    ap.add_argument("--substeps", type=int, default=10, help="the EKF's RK4 substeps per period (the comparison's)")
    a = ap.parse_args()
    flat = ex._flat(a.model)
    ts = a.ts or flat.model.ts
    opts = Options(ts=ts, predictor=a.predictor, disturbance=a.disturbance, tau=a.tau)
    made = {f.name(): f.n_instructions() for f in kernels.build(flat, opts, "p").all()}
    node = {"predict": made["p_kern_node_predict"], "update": made["p_kern_update"]}
    dist = None if a.disturbance is None else Disturbance(a.disturbance, (1.0,) * flat.m, a.tau)
    kind = compare.own_kind("df", opts.predictor)
    ops = compare.operations(a.model, ts, (1.0,) * flat.m, a.substeps, kinds=(kind, "ekf"),
                             predictor=opts.predictor, disturbance=dist)
    rows = [("derivative-free, generated kernels", node), ("derivative-free, the comparison's", ops[kind]),
            ("EKF, the comparison's", ops["ekf"]), ("EKF, upper triangle in and out",
             {k: f.n_instructions() for k, f in ekf_packed(a.model, ts, a.substeps).items()})]
    step = lambda c: c["predict"] + c["update"]  # noqa: E731
    for label, c in rows:
        print(f"{label:38s} predict {c['predict']:6,d}  update {c['update']:5,d}  step {step(c):6,d}")
    print(f"EKF / derivative-free per node step: {step(rows[3][1]) / step(node):.2f}x on the generated kernels and "
          f"the packed EKF, {step(ops['ekf']) / step(ops[kind]):.2f}x as the comparison counts both")


if __name__ == "__main__":
    main()
