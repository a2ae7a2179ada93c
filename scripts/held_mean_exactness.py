"""Why the held filter loses to the EKF at a small q on a plant without process noise: its
constant covariance transition Φ₀, or the ETD2RK mean's one-step error? Re-filters the same
closed-loop recordings (paper scenario, the model's held filter closing the loop at `--q`) with

- `df`: the held filter as shipped (one ETD2RK step, constant Φ₀);
- `jacobian`: the same mean, its covariance through the mean map's own Jacobian at each estimate
  (an EKF on the canonical held model: what a state-dependent transition would buy);
- `substeps2`, `substeps4`: the mean by 2 or 4 ETD2RK steps of Ts/k, Φ₀ kept;

and prints each one's master RMSE divided by the EKF's (same q, same recordings, per seed then
averaged) and its master NEES, then the EKF's own RMSE and NEES. `--plant-substeps` integrates
the plant more finely than the EKF's model (the scenario's RK4 substeps) to show the EKF does
not win by sharing the plant's integrator. Usage:

    python scripts/held_mean_exactness.py [--model M] [--q Q] [--seeds N] [--row R] [--plant-substeps K]
"""

from __future__ import annotations

import argparse
import dataclasses

import casadi as ca
import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare, plan, scenario
from dfeif_codegen.reference.ekf import EKF
from dfeif_codegen.symbolic import sampling

VARIANTS = ("df", "jacobian", "substeps2", "substeps4")


class HeldJacobian(EKF):
    """The held mean with P propagated through its Jacobian at the estimate."""

    def predict_sx(self, x, P, u):
        mean = self.model.step_sx(x, u)
        F = ca.jacobian(mean, x)
        return mean, F @ P @ F.T + ca.DM(self.model.Qd)


def substepped(model: compare.CanonicalModel, flat, ts: float, k: int) -> compare.CanonicalModel:
    """`model` with its mean taken by k ETD2RK steps of ts/k (its Φ₀ and Q₀ unchanged)."""
    H = sampling.held_sampling(flat, ts / k)
    x, w = ca.SX.sym("x", model.n), ca.SX.sym("w", model.m)
    y = x
    for _ in range(k):
        y = y + sampling.held_increment_sx(flat, H, y, y, w, ca.DM(flat.param_vector))
    model.step_sx = ca.Function("step", [x, w], [y])
    return model


def variant_filter(kind: str, spec: str, ts: float, q) -> EKF:
    flat = ex._flat(spec)
    model = compare.CanonicalModel(flat, ts, np.array(q), "held")
    if kind == "jacobian":
        return HeldJacobian(model)
    if kind.startswith("substeps"):
        return compare.DerivativeFree(substepped(model, flat, ts, int(kind[len("substeps"):])))
    return compare.DerivativeFree(model)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--model", default="dc_motor_link")
    ap.add_argument("--q", type=float, default=7e-4)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--row", type=int, default=0)
    ap.add_argument("--plant-substeps", type=int, default=None)
    a = ap.parse_args()
    sc = scenario.load("paper")
    sc.q, sc.q_ekf = [a.q], [a.q]
    filter_substeps = sc.substeps
    if a.plant_substeps:
        sc.substeps = a.plant_substeps
    filters = {}
    rmse, nees = {k: [] for k in (*VARIANTS, "ekf")}, {k: [] for k in (*VARIANTS, "ekf")}
    for seed in range(a.seeds):
        cfg = plan.make_config(sc, a.model, 2, 32, "sinusoid", sc.grid[a.row], "replay", "difference", seed)
        res = ex.run(cfg)
        if not filters:    # the model's period, once the scenario's (default: the model's) is resolved
            ts = float(res.recording.ts)
            filters = {kind: variant_filter(kind, a.model, ts, [a.q] * res.recording.m) for kind in VARIANTS}
        res = dataclasses.replace(res, config=dataclasses.replace(res.config, substeps=filter_substeps))
        for kind in (*VARIANTS, "ekf"):
            original = compare.filter_of
            if kind != "ekf":
                compare.filter_of = lambda *args, kind=kind, **kw: filters[kind]   # noqa: E731
            try:
                m = compare.evaluate(res, "df" if kind != "ekf" else "ekf")
            finally:
                compare.filter_of = original
            rmse[kind].append(m["rmse_master"])
            nees[kind].append(float(np.mean(m["nees_master"])))
    ekf = np.array(rmse["ekf"])
    for kind in VARIANTS:
        ratio = np.mean(np.array(rmse[kind]) / ekf, axis=0)
        print(f"q = {a.q:g}, row {a.row}, {kind:>10} / EKF: " + " ".join(f"{r:.3f}" for r in ratio)
              + f"   master NEES {np.mean(nees[kind]):.3g}")
    print("EKF master RMSE " + " ".join(f"{r:.3g}" for r in ekf.mean(axis=0)) + f"   NEES {np.mean(nees['ekf']):.3g}")


if __name__ == "__main__":
    main()
