"""The held filter's disturbance states at other densities and kinds than a scenario's, on the
same recordings (docs/experiment.md, "The comparison under model error"). Loops closed by the
held filter with the scenario's q and [disturbance] (what `codegen simulate` runs), on a plant
whose parameters are drawn per seed; on each recording the EKF at the scenario's q_ekf and the
held filter re-run with each variant KIND:FACTOR[:TAU] (the scenario's densities times FACTOR,
of kind KIND, with time constant TAU or the scenario's, and the scenario's initial spread of the
d's). Prints, per delay row, the master RMSE over the EKF's (per seed, then averaged) and the
master NEES. Why: which densities the calibration should land on is a question of accuracy as
much as of NEES, and re-filtering one set of loops answers it without closing new ones.
Usage:

    codegen scenario two_link_arm --disturbance random_walk --param-error 0.2 --amplitude 1,1 --offset 0,0 --out F
    python scripts/density_sweep.py --scenario F --model two_link_arm --runs 16 \\
        --variants random_walk:1,random_walk:0.5,integrated_random_walk:10
"""

from __future__ import annotations

import argparse
import multiprocessing

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare, model_error, plan, scenario
from dfeif_codegen.symbolic.disturbance import KINDS, SECOND_ORDER, TIMED, Disturbance


def variant(dist: Disturbance, text: str, m: int) -> Disturbance:
    """KIND:FACTOR[:TAU]: the scenario's densities times FACTOR, of kind KIND, with the time
    constant TAU (a timed kind's; default the scenario's own) and the scenario's p0_std (for a
    kind without rates, only the d's of a d-then-rates p0_std); m chains. ValueError says what
    is wrong with `text`."""
    kind, *rest = text.split(":")
    if kind not in KINDS or len(rest) not in (1, 2):
        raise ValueError(f"KIND:FACTOR[:TAU], KIND one of {', '.join(KINDS)}")
    try:
        factor, tau = float(rest[0]), float(rest[1]) if len(rest) == 2 else dist.tau
    except ValueError:
        raise ValueError("FACTOR and TAU are numbers") from None
    if kind in TIMED and tau is None:
        raise ValueError(f"{kind} needs a time constant: {text}:TAU")
    p0 = dist.p0_std
    if p0 is not None and len(p0) == 2 * m and kind not in SECOND_ORDER:
        p0 = p0[:m]
    return Disturbance(kind, tuple(float(v) * factor for v in dist.q), tau if kind in TIMED else None, p0)


def one(job) -> dict:
    """Metrics of the EKF and of each variant on one seed's loop of one delay row."""
    a, seed, row = job
    sc = scenario.load(a.scenario)
    sc.model_error = model_error.from_option(a.param_error)
    cfg = plan.make_config(sc, a.model, 2, 32, sc.references[0], sc.grid[row], "replay", "difference", seed, "held")
    res = ex.run(cfg)
    out = {"ekf": compare.evaluate(res, "ekf")}
    for v in a.variants.split(","):
        out[v] = compare.evaluate(res, "df", disturbance=variant(sc.disturbance, v, ex._flat(a.model).m))
    return {k: None if "failed" in m else (np.asarray(m["rmse_master"]), float(np.mean(m["nees_master"])))
            for k, m in out.items()}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenario", required=True, help="a scenario with [disturbance] (codegen scenario)")
    ap.add_argument("--model", default="two_link_arm")
    ap.add_argument("--runs", type=int, default=16)
    ap.add_argument("--param-error", default="0.2")
    ap.add_argument("--rows", default=None, help="delay rows by index, e.g. 0,3 (default every row)")
    ap.add_argument("--variants", default="random_walk:1,random_walk:0.5,integrated_random_walk:10")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    sc = scenario.load(a.scenario)
    if sc.disturbance is None:
        ap.error(f"--scenario {a.scenario}: has no [disturbance] (codegen scenario --disturbance KIND)")
    for v in a.variants.split(","):
        try:
            variant(sc.disturbance, v, ex._flat(a.model).m)
        except ValueError as exc:
            ap.error(f"--variants {v}: {exc}")
    rows = range(len(sc.grid)) if a.rows is None else [int(r) for r in a.rows.split(",")]
    jobs = [(a, s, r) for r in rows for s in range(a.runs)]
    with multiprocessing.Pool(a.workers) as pool:
        results = pool.map(one, jobs)
    for r in rows:
        mine = [res for (_, _, row), res in zip(jobs, results) if row == r]
        print(f"row {r}")
        for v in a.variants.split(","):
            kept = [res for res in mine if res["ekf"] is not None and res[v] is not None]
            ratio = np.mean([res[v][0] / res["ekf"][0] for res in kept], axis=0)
            nees = np.mean([res[v][1] for res in kept])
            print(f"  {v:28s} {len(kept)}/{len(mine)} seeds; master RMSE / EKF's "
                  f"{' '.join(f'{x:.3f}' for x in ratio)}; NEES {nees:.2f}")


if __name__ == "__main__":
    main()
