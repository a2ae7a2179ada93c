"""The master's NEES per chain (each flat output's block of the canonical state, its own
covariance block) beside the whole state's, and the held filter's master RMSE divided by the
EKF's per state (both at the same q, on the same closed-loop recordings, per seed then averaged,
with 95% intervals): whether one white q per chain can put the master's NEES in its band and keep
every state's RMSE near the EKF's. Row `--row` of the scenario's grid, replay, information-
difference fusion, seeds 0 .. N-1 (the reference engine, the loop closed by the held filter).
Usage:

    python scripts/chain_nees.py --scenario FILE --q Q1,Q2,... [--model M] [--seeds N] [--row R]
"""

from __future__ import annotations

import argparse

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare, plan, scenario
from dfeif_codegen.experiment.metrics import _errors, _nees


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--model", default="two_link_arm")
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--q", required=True, help="white densities per chain, comma-separated")
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--row", type=int, default=0)
    a = ap.parse_args()
    sc = scenario.load(a.scenario)
    sc.q = sc.q_ekf = [float(v) for v in a.q.split(",")]
    flat = ex._flat(a.model)
    blocks = [slice(c.offset, c.offset + c.degree) for c in flat.chains]
    nees, ratio = [], []
    for seed in range(a.seeds):
        cfg = plan.make_config(sc, a.model, 2, 32, "sinusoid", sc.grid[a.row], "replay", "difference", seed)
        res = ex.run(cfg)
        rec, k0 = res.recording, int(round(cfg.metrics_from / res.recording.ts))
        err, P = _errors(flat, rec.x[k0:], res.zeta[k0:]), rec.P[k0:]
        nees.append([np.mean(_nees(err, P))] + [np.mean(_nees(err[:, b], P[:, b, b])) for b in blocks])
        ratio.append(np.sqrt(np.mean(err ** 2, axis=0)) / compare.evaluate(res, "ekf")["rmse_master"])
    nees, ratio = np.array(nees), np.array(ratio)
    ci = 1.96 * ratio.std(axis=0, ddof=1) / np.sqrt(len(ratio)) if len(ratio) > 1 else np.zeros(flat.n)
    print(f"q = {a.q}, row {a.row}, {a.seeds} seeds: master NEES {nees[:, 0].mean():.2f} (n = {flat.n}), per chain "
          + " ".join(f"{v:.2f}" for v in nees[:, 1:].mean(axis=0)))
    print("held / EKF master RMSE: " + " ".join(f"{r:.3f} ± {c:.3f}" for r, c in zip(ratio.mean(axis=0), ci)))


if __name__ == "__main__":
    main()
