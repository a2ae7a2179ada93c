"""Why the held filter loses to the EKF at a small q on a plant without process noise: its
constant covariance transition Φ₀, or the ETD2RK mean's one-step error? Re-filters the same
closed-loop recordings (paper scenario, the model's held filter closing the loop at `--q`) with

- `df`: the held filter as shipped (one ETD2RK step, constant Φ₀);
- `jacobian`: the same mean, its covariance through the mean map's own Jacobian at each estimate
  (an EKF on the canonical held model: what a state-dependent transition would buy);
- `substeps2`, `substeps4`: the mean by 2 or 4 ETD2RK steps of Ts/k, Φ₀ kept;
- `etd3`: the mean by one third-order step (Cox and Matthews' ETD3RK: three evaluations of
  F + G u, against ETD2RK's two), Φ₀ kept;
- `etd3jacobian`: that mean with its covariance through its own Jacobian at each estimate;

and prints each one's master RMSE divided by the EKF's (same q, same recordings, per seed then
averaged) and its master NEES, then the EKF's own RMSE and NEES. `--plant-substeps` integrates
the plant more finely than the EKF's model (the scenario's RK4 substeps) to show the EKF does
not win by sharing the plant's integrator. Usage:

    python scripts/held_mean_exactness.py [--model M] [--q Q] [--seeds N] [--row R] [--plant-substeps K]
        [--variants df,jacobian,...]
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

VARIANTS = ("df", "jacobian", "substeps2", "substeps4", "etd3", "etd3jacobian")


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


def _phi123(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, ...]:
    """e^{A h} and h φ_k(A h) B for k = 1, 2, 3, from one exponential of the augmented matrix
    [[A h, B h, 0, 0], [0, 0, I, 0], [0, 0, 0, I], [0, 0, 0, 0]] (its first block row)."""
    n, m = B.shape
    M = np.zeros((n + 3 * m, n + 3 * m))
    M[:n, :n], M[:n, n:n + m] = A * h, B * h
    M[n:n + m, n + m:n + 2 * m] = M[n + m:n + 2 * m, n + 2 * m:] = np.eye(m)
    X = sampling.expm(M)
    return X[:n, :n], X[:n, n:n + m], X[:n, n + m:n + 2 * m], X[:n, n + 2 * m:]


def third_order(model: compare.CanonicalModel, flat, ts: float) -> compare.CanonicalModel:
    """`model` with its mean taken by one ETD3RK step (Cox and Matthews 2002) of the same split
    ζ' = A ζ + B_c N(ζ), N = F + G u - L₀ ζ: a = E(h/2) ζ + Γ₁(h/2) N(ζ), b = E ζ + Γ₁ (2 N(a) -
    N(ζ)), ζ⁺ = E ζ + (Γ₁ - 3 Γ₂ + 4 Γ₃) N(ζ) + 4 (Γ₂ - 2 Γ₃) N(a) + (4 Γ₃ - Γ₂) N(b), with
    Γ_k = h φ_k(A h) B_c (Φ₀ and Q₀ unchanged)."""
    H = sampling.held_sampling(flat, ts)
    E, G1, G2, G3 = (ca.DM(a) for a in _phi123(H.A, H.Bc, ts))
    E_half, G1_half = (ca.DM(a) for a in _phi123(H.A, H.Bc, ts / 2)[:2])
    x, w = ca.SX.sym("x", model.n), ca.SX.sym("w", model.m)
    p = ca.DM(flat.param_vector)

    def N(z):
        return sampling.remainder_sx(flat, z, w, p) - ca.DM(H.L0) @ z
    n0 = N(x)
    a = E_half @ x + G1_half @ n0
    na = N(a)
    nb = N(E @ x + G1 @ (2 * na - n0))
    y = E @ x + (G1 - 3 * G2 + 4 * G3) @ n0 + 4 * (G2 - 2 * G3) @ na + (4 * G3 - G2) @ nb
    model.step_sx = ca.Function("step", [x, w], [y])
    return model


def variant_filter(kind: str, spec: str, ts: float, q) -> EKF:
    flat = ex._flat(spec)
    model = compare.CanonicalModel(flat, ts, np.array(q), "held")
    if kind.startswith("etd3"):
        model = third_order(model, flat, ts)
        return HeldJacobian(model) if kind == "etd3jacobian" else compare.DerivativeFree(model)
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
    ap.add_argument("--variants", default=",".join(VARIANTS))
    a = ap.parse_args()
    variants = tuple(a.variants.split(","))
    sc = scenario.load("paper")
    sc.q, sc.q_ekf = [a.q], [a.q]
    filter_substeps = sc.substeps
    if a.plant_substeps:
        sc.substeps = a.plant_substeps
    filters = {}
    rmse, nees = {k: [] for k in (*variants, "ekf")}, {k: [] for k in (*variants, "ekf")}
    for seed in range(a.seeds):
        cfg = plan.make_config(sc, a.model, 2, 32, "sinusoid", sc.grid[a.row], "replay", "difference", seed)
        res = ex.run(cfg)
        if not filters:    # the model's period, once the scenario's (default: the model's) is resolved
            ts = float(res.recording.ts)
            filters = {kind: variant_filter(kind, a.model, ts, [a.q] * res.recording.m) for kind in variants}
        res = dataclasses.replace(res, config=dataclasses.replace(res.config, substeps=filter_substeps))
        for kind in (*variants, "ekf"):
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
    for kind in variants:
        print(f"{kind}: {filters[kind].model.step_sx.n_instructions()} operations in the mean")
        ratio = np.mean(np.array(rmse[kind]) / ekf, axis=0)
        print(f"q = {a.q:g}, row {a.row}, {kind:>10} / EKF: " + " ".join(f"{r:.3f}" for r in ratio)
              + f"   master NEES {np.mean(nees[kind]):.3g}")
    print("EKF master RMSE " + " ".join(f"{r:.3g}" for r in ekf.mean(axis=0)) + f"   NEES {np.mean(nees['ekf']):.3g}")


if __name__ == "__main__":
    main()
