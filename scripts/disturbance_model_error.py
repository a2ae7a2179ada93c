"""Held filter with and without disturbance states against the EKF under model error, on the
same recordings (docs/mathematics.md section 3, "Disturbance states"). Loops of a scenario's
first delay row, closed by the chapter's Brunovsky filter (the held estimate does not yet close
the controller's loop reliably under model error), on a plant whose parameters are drawn per
seed (`--param-error`, as `codegen simulate`'s); on each recording: the EKF (the scenario's q),
the held filter with the scenario's q and no disturbance states, and the held filter with the q
and [disturbance] of a scenario written by `codegen scenario --disturbance ...`. Usage:

    codegen scenario dc_motor_link --disturbance random_walk --param-error 0.2 --out motor_d.toml
    python scripts/disturbance_model_error.py --disturbed motor_d.toml [--runs 10] [--param-error 0.2]
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare, model_error, scenario, simulate, stats


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--model", default="dc_motor_link")
    ap.add_argument("--scenario", default="paper", help="the loops' and the EKF's (default paper)")
    ap.add_argument("--disturbed", required=True, help="a scenario with [disturbance] (codegen scenario)")
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--param-error", default="0.2")
    a = ap.parse_args()
    sc, sd = scenario.load(a.scenario), scenario.load(a.disturbed)
    sc.model_error = model_error.from_option(a.param_error)
    filters = {"EKF": ("ekf", None, None),
               f"held, q = {sc.q}": ("df", np.asarray(sc.q), None),
               f"held + {sd.disturbance.kind}, q = {list(sd.q)}, q_d = {list(sd.disturbance.q)}":
                   ("df", np.asarray(sd.q), sd.disturbance)}
    rows: dict[str, list] = {k: [] for k in filters}
    for s in range(a.runs):
        cfg = simulate.make_config(sc, a.model, 2, 32, sc.references[0], sc.grid[0], "replay", "difference", s,
                                   "brunovsky")
        res = ex.run(cfg)
        for name, (kind, q, dist) in filters.items():
            run = res if kind == "ekf" else dataclasses.replace(
                res, recording=dataclasses.replace(res.recording, predictor="held", q=q))
            rows[name].append(compare.evaluate(run, kind, disturbance=dist))
    lo, hi = stats.nees_band(ex._flat(a.model).n, a.runs)
    ekf = np.array([m["rmse_master"] for m in rows["EKF"]])
    print(f"{a.model}, --param-error {a.param_error}, {a.runs} seeds, row {sc.grid[0].label}, the same recordings; "
          f"NEES band of {a.runs} runs [{lo:.2f}, {hi:.2f}]")
    for name, ms in rows.items():
        ok = [i for i, m in enumerate(ms) if "failed" not in m]
        if not ok:
            print(f"{name}: failed on every recording")
            continue
        rmse = np.mean([ms[i]["rmse_master"] for i in ok], axis=0)
        ratio = np.mean([np.asarray(ms[i]["rmse_master"]) / ekf[i] for i in ok], axis=0)
        nees = np.mean([np.mean(ms[i]["nees_master"]) for i in ok])
        print(f"{name}: {len(ok)}/{len(ms)} runs kept; master RMSE {' / '.join(f'{v:.3g}' for v in rmse)}, "
              f"per run / the EKF's {' / '.join(f'{v:.2f}' for v in ratio)}; NEES {nees:.3g}")


if __name__ == "__main__":
    main()
