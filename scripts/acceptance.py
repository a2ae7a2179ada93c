"""Per-run figures behind docs/experiment.md, "The acceptance figures, restated".

`python scripts/acceptance.py MODEL RUNS OUT.npy [--seed S] [--rows 0,1,5] [--filters [--compiled]] [--matched] [--reference]`: for every
seed and delay row of the paper scenario (sinusoid reference), the closed loop with replay +
difference, with discard and with retrodict; `--filters` instead runs replay + difference only and
the EKF and UKF nodes on its recording (experiment/compare.py), with the cost per step of each;
`--compiled` evaluates the three filters' CasADi functions as compiled C (the same figures to
the bit, 3-5x less time per EKF/UKF predict; the cost column then measures compiled code);
`--matched` runs the matched linear plant (experiment/matched.py) instead of the real one. Stores
per-run metrics (so ratios get paired intervals) and per-step master NEES. Runs in 2 processes; the closed loops in compiled C
(check/closed_loop_c.py, the same Result as the numpy engine) unless `--reference`.
"""

from __future__ import annotations

import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from dfeif_codegen.check import closed_loop_c
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import plan, scenario

METHODS = ("replay", "discard", "retrodict")
ENGINE = "reference" if "--reference" in sys.argv else "c"    # the compiled closed loop by default
COMPILED = "--compiled" in sys.argv     # EKF/UKF/df functions as compiled C (the same figures, less time)


def matched_one(model, ri, seed):
    """The matched linear plant (experiment/matched.py) with replay + difference, and the gap
    between the master's covariance and the centralized Riccati recursion of the same arrivals."""
    from dfeif_codegen.experiment import bounds, matched
    sc = scenario.load("paper")
    cfg = plan.make_config(sc, model, 2, 32, "sinusoid", sc.grid[ri], "replay", "difference", seed)
    out = matched.run(cfg)
    m = matched.metrics(cfg, out)
    flat = ex._flat(model)
    A, Q, R, P0, _ = bounds.matched_model(cfg)
    C = np.zeros((flat.m, flat.n))
    C[np.arange(flat.m), flat.heads] = 1.0
    H = np.array([C.T @ np.linalg.solve(Ri, C) for Ri in R])
    central = bounds.posterior_covariances(A, Q, H, P0, bounds.arrivals(bounds.network_of(cfg, out["x"].shape[0]), 32))
    m["P_gap"] = float(np.max(np.abs(out["P"] - central) / np.abs(central).max(axis=(1, 2))[:, None, None]))
    return {"matched": m}


def one(args):
    model, ri, seed, with_filters = args
    if with_filters == "matched":
        return model, ri, seed, matched_one(model, ri, seed)
    sc = scenario.load("paper")
    row = sc.grid[ri]
    out = {}
    for method in (("replay",) if with_filters else METHODS):
        if ri == 0 and method != "replay":
            continue
        cfg = plan.make_config(sc, model, 2, 32, "sinusoid", row, method, "difference", seed)
        try:
            res = closed_loop_c.run(cfg) if ENGINE == "c" else ex.run(cfg)
        except (ArithmeticError, FloatingPointError, np.linalg.LinAlgError) as exc:
            out[method] = {"failed": str(exc)}
            continue
        m = dict(res.metrics)
        flat = ex._flat(model)
        rec = res.recording
        k0 = int(round(cfg.metrics_from / rec.ts))
        xd = np.array([ex.state_of_flags(flat, r) for r in rec.ref[k0:]])
        m["rmse_est_track_master"] = np.sqrt((ex._errors(flat, rec.x[k0:], xd) ** 2).mean(0))
        m["rmse_est_track_nodes"] = np.sqrt((ex._errors(flat, rec.node_x[:, k0:], xd[None]) ** 2).mean(1))
        m["nees_nodes"] = m["nees_nodes"].mean(axis=-1)          # keep per-step NEES only for the master
        out[method] = m
        if with_filters and method == "replay":
            from dfeif_codegen.experiment import compare
            m["us_per_step"] = compare.evaluate(res, "df", COMPILED)["us_per_step"]   # same driver as the EKF/UKF
            for kind in compare.FILTERS:
                out[kind] = compare.evaluate(res, kind, COMPILED)
    return model, ri, seed, out


def main():
    model, runs, path = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    with_filters = "matched" if "--matched" in sys.argv else "--filters" in sys.argv
    first = int(sys.argv[sys.argv.index("--seed") + 1]) if "--seed" in sys.argv else 0
    rows = range(len(scenario.load("paper").grid))
    if "--rows" in sys.argv:
        rows = [int(r) for r in sys.argv[sys.argv.index("--rows") + 1].split(",")]
    jobs = [(model, ri, s, with_filters) for s in range(first, first + runs) for ri in rows]
    started = time.monotonic()
    results = {}
    with ProcessPoolExecutor(max_workers=2) as pool:
        for done, (mdl, ri, seed, out) in enumerate(pool.map(one, jobs, chunksize=1), 1):
            results[(ri, seed)] = out
            if done % 12 == 0:
                print(f"{done}/{len(jobs)} in {time.monotonic() - started:.0f} s", flush=True)
                np.save(path, np.array([results], dtype=object), allow_pickle=True)
    np.save(path, np.array([results], dtype=object), allow_pickle=True)
    print(f"done: {len(jobs)} jobs in {time.monotonic() - started:.0f} s")


if __name__ == "__main__":
    main()
