"""Master RMSE and NEES of the held-input filter, the chapter's Brunovsky filter and the EKF on the
same closed-loop recordings (docs/experiment.md, "The held-input predictor").

The closed loop runs with the held filter (reference engine); on each recording the Brunovsky
filter (with the v = F + G u the master computed) and the EKF re-filter open loop through the
same driver (experiment/compare.py). For reference, the Brunovsky filter's own closed loop (the
chapter's setting, where its noisier estimate drives the plant) and the EKF on its recordings.
Usage:

    python scripts/predictor_comparison.py [MODEL] [--seeds N] [--rows 0,2] [--q Q]
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare, scenario, simulate


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("model", nargs="?", default="dc_motor_link")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--rows", default="0,2")
    ap.add_argument("--q", type=float, default=None, help="process-noise density (default: the scenario's)")
    a = ap.parse_args()
    sc = scenario.load("paper")
    flat = ex._flat(a.model)
    for row in map(int, a.rows.split(",")):
        out = {"held": [], "brunovsky": [], "ekf": [], "brunovsky, own loop": [], "ekf on that loop": []}
        for seed in range(a.seeds):
            cfg = simulate.make_config(sc, a.model, 2, 32, "sinusoid", sc.grid[row], "replay", "difference", seed)
            if a.q is not None:
                cfg = dataclasses.replace(cfg, q=(a.q,))
            res = ex.run(cfg)
            out["held"].append(res.metrics)
            bru = dataclasses.replace(res, recording=dataclasses.replace(res.recording, predictor="brunovsky"))
            out["brunovsky"].append(compare.evaluate(bru, "df"))
            out["ekf"].append(compare.evaluate(res, "ekf"))
            own = ex.run(dataclasses.replace(cfg, predictor="brunovsky"))
            out["brunovsky, own loop"].append(own.metrics)
            out["ekf on that loop"].append(compare.evaluate(own, "ekf"))
        d = sc.grid[row]
        print(f"{a.model} row {row} (d = {d.d}, p = {d.p}), {a.seeds} seeds, q = {cfg.q[0]:g}:")
        for name, ms in out.items():
            ok = [m for m in ms if "failed" not in m]
            rmse = np.mean([m["rmse_master"] for m in ok], axis=0)
            nees = np.mean([np.mean(m["nees_master"]) for m in ok])
            print(f"  {name:20s} RMSE " + " / ".join(f"{r:.3g}" for r in rmse) + f"  NEES {nees:.2f}"
                  + (f"  ({len(ms) - len(ok)} failed)" if len(ok) < len(ms) else ""))
    ops = {p: compare.operations(a.model, flat.model.ts, [a.q or sc.q[0]] * flat.m, predictor=p)
           for p in ("held", "brunovsky")}
    print("operations per predict/update (CasADi instructions): " + ", ".join(
        f"{p} {o['df']['predict']}/{o['df']['update']}" for p, o in ops.items())
          + f", EKF {ops['held']['ekf']['predict']}/{ops['held']['ekf']['update']}")


if __name__ == "__main__":
    main()
