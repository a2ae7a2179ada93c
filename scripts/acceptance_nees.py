"""Why the master's NEES is above its band (docs/experiment.md): the canonical model's residual
against the filter's Q_d, the correlation of the two nodes' errors, and a scan of q.

`python scripts/acceptance_nees.py MODEL RUNS Q[,Q...]`: for rows (0,0,0) and (25,30,0.6) of the
paper scenario (sinusoid, replay + difference, compiled closed loop), prints the run-averaged master
and node NEES with the 95% band, the master x1 RMSE, the one-step residual
`w = zeta(k+1) - A zeta(k) - B v(k)` of the true canonical state whitened by Q_d (`L^-1 w`,
`L L' = Q_d`: unit variance and no autocorrelation if the model were right): its variance and lag-1
autocorrelation per component; and, on a third of the seeds, the correlation of node 1's and node 2's
errors on the real plant and on the matched linear plant (experiment/matched.py), first 30 seeds.
"""

from __future__ import annotations

import sys

import numpy as np

from dfeif_codegen.check import closed_loop_c
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import matched, plan, scenario, stats


def node_correlation(node_x, zeta) -> np.ndarray:
    e = node_x[:, 100:] - zeta[None, 100:]
    return np.array([np.corrcoef(e[0, :, j], e[1, :, j])[0, 1] for j in range(e.shape[2])])


def main():
    model, runs, qs = sys.argv[1], int(sys.argv[2]), [float(q) for q in sys.argv[3].split(",")]
    sc = scenario.load("paper")
    flat = ex._flat(model)
    A, B, _ = flat.discrete(flat.model.ts)
    lo, hi = stats.nees_band(flat.n, runs)
    for q in qs:
        for ri in (0, len(sc.grid) - 1):
            nm, nn, var, ac, rm, c_real, c_matched = [], [], [], [], [], [], []
            for s in range(runs):
                cfg = plan.make_config(sc, model, 2, 32, "sinusoid", sc.grid[ri], "replay", "difference", s)
                cfg = ex.Config(**{**cfg.__dict__, "q": (q,) * len(cfg.q)})
                res = closed_loop_c.run(cfg)
                nm.append(res.metrics["nees_master"])
                nn.append(res.metrics["nees_nodes"].mean(axis=-1))
                rm.append(res.metrics["rmse_master"][0])
                z, v = res.zeta, res.recording.v
                w = (z[1:] - z[:-1] @ A.T - v[:-1] @ B.T)[100:]
                e = np.linalg.solve(np.linalg.cholesky(flat.process_noise(flat.model.ts, ex._per_chain(cfg.q, flat.m))), w.T).T
                var.append((e ** 2).mean(axis=0))
                ac.append([np.corrcoef(e[:-1, j], e[1:, j])[0, 1] for j in range(e.shape[1])])
                if s < 30:
                    c_real.append(node_correlation(res.recording.node_x, res.zeta))
                    out = matched.run(cfg)
                    c_matched.append(node_correlation(out["node_x"], out["zeta"]))
            per_step = np.mean(nm, axis=0)
            print(f"{model} q={q:g} row {ri + 1}: master NEES {per_step.mean():.2f} "
                  f"({np.mean((per_step >= lo) & (per_step <= hi)):.0%} of steps in [{lo:.2f}, {hi:.2f}]), "
                  f"nodes {np.round(np.mean(nn, axis=0), 2)}, master x1 RMSE {np.mean(rm):.3e}; "
                  f"whitened residual variance {np.round(np.mean(var, axis=0), 3)}, "
                  f"lag-1 autocorrelation {np.round(np.mean(ac, axis=0), 3)}; "
                  f"node error correlation real {np.round(np.mean(c_real, axis=0), 3)} "
                  f"matched {np.round(np.mean(c_matched, axis=0), 3)}", flush=True)


if __name__ == "__main__":
    main()
