"""Markdown tables of the restated acceptance figures from scripts/acceptance.py's files.

`python scripts/acceptance_report.py MODEL [--real FILE.npy] [--filters FILE.npy|FILE.jsonl[,FILE2...] [--rows 0,1,5[/2,3,4...]]] [--matched FILE.npy[,FILE2...]] [--plot DIR]`
(several files are merged: e.g. the rows of one sweep and the other rows of another, same seeds).
Every interval is a 95% Student-t interval over the seeds; ratios and differences are formed per
seed first (the rows and methods of one seed share their random numbers), then averaged.
"""

from __future__ import annotations

import sys

import numpy as np

from dfeif_codegen.experiment import bounds, plan, scenario, stats
from dfeif_codegen.experiment import closed_loop as ex

SC = scenario.load("paper")
LABELS = [f"({', '.join(map(str, r.d))}, {r.p:g})" for r in SC.grid]


def load(path, rows=None):
    """A scripts/acceptance.py file, or a `codegen simulate --filters df,ekf,ukf --results FILE.jsonl`
    file (its row numbers mapped to the paper grid's by `rows` when the scenario had fewer)."""
    if not str(path).endswith(".jsonl"):
        return np.load(path, allow_pickle=True)[0]
    import json

    from dfeif_codegen.experiment import sweep
    names = {"df-replay": "replay", "ekf-replay": "ekf", "ukf-replay": "ukf"}
    data: dict = {}
    for line in open(path, encoding="utf-8"):
        rec = json.loads(line)
        m = sweep.decode(rec["metrics"])
        for ref, label, _, ri, seed in rec["runs"]:
            if label in names:
                key = (rows[ri] if rows else ri, seed)
                data.setdefault(key, {})[names[label]] = {"failed": m} if isinstance(m, str) else m
    return data


def seeds_of(data, rows):
    """Seeds with every row present."""
    seeds = sorted({s for (_, s) in data})
    return [s for s in seeds if all((ri, s) in data for ri in rows)]


def ci(values):
    mean, half = stats.mean_ci(np.asarray(values, dtype=float))
    return mean, half


def fmt(mean, half, digits=3):
    return f"{mean:.{digits}f} ± {half:.{digits}f}" if np.isfinite(half) else f"{mean:.{digits}f}"


def efmt(mean, half):
    return f"{mean:.3e} ± {half:.0e}"


def bound_ratios(model, seeds):
    """Exact centralized bound per row over `seeds`: RMSE (rows, n)."""
    out = []
    for row in SC.grid:
        cfgs = [plan.make_config(SC, model, 2, 32, "sinusoid", row, "replay", "difference", s) for s in seeds]
        out.append(bounds.row_bound(cfgs))
    return out


def real(model, data):
    flat = ex._flat(model)
    n = flat.n
    rows = list(range(len(SC.grid)))
    seeds = seeds_of(data, rows)
    R = len(seeds)
    get = lambda ri, s, meth, key: np.asarray(data[(ri, s)][meth][key], dtype=float)  # noqa: E731
    bnd = bound_ratios(model, seeds)
    print(f"\n### {model}, real plant, replay + difference, {R} runs (seeds {seeds[0]}–{seeds[-1]}), sinusoid\n")
    # delay ratio
    print("| row | master x1 RMSE | ratio to (0,0,0) | exact filter's ratio | met (≤ exact) |")
    print("|---|---|---|---|---|")
    for ri in rows:
        r1 = [get(ri, s, "replay", "rmse_master")[0] for s in seeds]
        ratio = [get(ri, s, "replay", "rmse_master")[0] / get(0, s, "replay", "rmse_master")[0] for s in seeds]
        b = bnd[ri].rmse_central[0] / bnd[0].rmse_central[0]
        m, h = ci(ratio)
        print(f"| {LABELS[ri]} | {efmt(*ci(r1))} | {fmt(m, h)} | {b:.3f} | {'yes' if m + h <= b else ('no' if m - h > b else 'within CI')} |")
    # replay vs discard
    print("\n| row | discard − replay, master RMSE x1 | x2 | x3 | replay better at every state? |")
    print("|---|---|---|---|---|")
    for ri in rows[1:]:
        d = np.array([get(ri, s, "discard", "rmse_master")[:3] - get(ri, s, "replay", "rmse_master")[:3] for s in seeds])
        cells = [ci(d[:, i]) for i in range(3)]
        better = all(m - h > 0 for m, h in cells)
        print(f"| {LABELS[ri]} | " + " | ".join(efmt(m, h) for m, h in cells) + f" | {'yes' if better else 'no'} |")
    # fusion gain
    limits = [0.85, 0.88, 0.95]
    print("\n| row | master / better node x1 (≤ 0.85) | x2 (≤ 0.88) | x3 (≤ 0.95) | exact filter x1 / x2 / x3 |")
    print("|---|---|---|---|---|")
    for ri in rows:
        g = np.array([get(ri, s, "replay", "rmse_master")[:3] / get(ri, s, "replay", "rmse_nodes")[:, :3].min(axis=0)
                      for s in seeds])
        cells = [ci(g[:, i]) for i in range(3)]
        eb = bnd[ri].rmse_central[:3] / bnd[ri].rmse_nodes[:, :3].min(axis=0)
        print(f"| {LABELS[ri]} | " + " | ".join(f"{fmt(m, h)} {'met' if m + h <= lim else 'missed'}"
                                               for (m, h), lim in zip(cells, limits))
              + f" | {' / '.join(f'{v:.3f}' for v in eb)} |")
    # tracking and estimated tracking
    print("\n| row | plant x − x_d, x1 (ratio to (0,0,0)) | x̂ − x_d node 1 | node 2 | master (ratio to (0,0,0)) |")
    print("|---|---|---|---|---|")
    for ri in rows:
        tr = [get(ri, s, "replay", "rmse_tracking")[0] for s in seeds]
        trr = [get(ri, s, "replay", "rmse_tracking")[0] / get(0, s, "replay", "rmse_tracking")[0] for s in seeds]
        en = np.array([get(ri, s, "replay", "rmse_est_track_nodes")[:, 0] for s in seeds])
        em = [get(ri, s, "replay", "rmse_est_track_master")[0] for s in seeds]
        emr = [get(ri, s, "replay", "rmse_est_track_master")[0] / get(0, s, "replay", "rmse_est_track_master")[0]
               for s in seeds]
        print(f"| {LABELS[ri]} | {efmt(*ci(tr))} ({fmt(*ci(trr))}) | {efmt(*ci(en[:, 0]))} | {efmt(*ci(en[:, 1]))} "
              f"| {efmt(*ci(em))} ({fmt(*ci(emr))}) |")
    # NEES
    lo, hi = stats.nees_band(n, R)
    print(f"\n| row | master NEES, time average (n = {n}, band [{lo:.2f}, {hi:.2f}] for {R} runs) | steps in band | met |")
    print("|---|---|---|---|")
    for ri in rows:
        per_step = np.mean([get(ri, s, "replay", "nees_master") for s in seeds], axis=0)
        avg, share = per_step.mean(), np.mean((per_step >= lo) & (per_step <= hi))
        print(f"| {LABELS[ri]} | {avg:.2f} | {100 * share:.0f}% | {'yes' if lo <= avg <= hi else 'no'} |")
    # retrodiction
    print("\n| row | retrodict: late frames applied per run | rejected per run | rejected share | "
          "master x1 RMSE retrodict / replay |")
    print("|---|---|---|---|---|")
    for ri in rows[1:]:
        app = [get(ri, s, "retrodict", "late_applied") for s in seeds]
        rej = [get(ri, s, "retrodict", "late_rejected") for s in seeds]
        share = [100 * r / (a + r) if a + r else 0.0 for a, r in zip(app, rej)]
        rr = [get(ri, s, "retrodict", "rmse_master")[0] / get(ri, s, "replay", "rmse_master")[0] for s in seeds]
        print(f"| {LABELS[ri]} | {fmt(*ci(app), digits=0)} | {fmt(*ci(rej), digits=0)} | "
              f"{fmt(*ci(share), digits=1)}% | {fmt(*ci(rr))} |")


def filters(model, data):
    flat = ex._flat(model)
    n = flat.n
    rows = sorted({ri for (ri, _) in data})
    seeds = seeds_of(data, rows)
    print(f"\n### {model}: derivative-free filter against EKF and UKF, {len(seeds)} runs per row, same recordings\n")
    print("| row | filter | master RMSE " + " | ".join(f"x{i + 1}" for i in range(n)) +
          " | master NEES | diverged / rejected frames per run | CPU µs per step (2 nodes + master) |")
    print("|---|---|" + "---|" * n + "---|---|---|")
    series = {}
    for ri in rows:
        for kind, label in (("replay", "derivative-free"), ("ekf", "EKF"), ("ukf", "UKF")):
            runs = [data[(ri, s)][kind] for s in seeds]
            ok = [r for r in runs if "failed" not in r]
            if not ok:
                print(f"| {LABELS[ri]} | {label} | " + " | ".join("failed" for _ in range(n)) + f" | | {len(runs)} / - | |")
                continue
            rm = np.array([r["rmse_master"] for r in ok])
            cells = [ci(rm[:, i]) for i in range(n)]
            series.setdefault(label, ([], []))
            series[label][0].append([c[0] for c in cells])
            series[label][1].append([c[1] for c in cells])
            nees = np.mean([np.mean(r["nees_master"]) for r in ok])
            cost = ci([r["us_per_step"] for r in ok])
            rej = np.mean([r["late_rejected"] for r in ok])
            print(f"| {LABELS[ri]} | {label} | " + " | ".join(efmt(*c) for c in cells) +
                  f" | {nees:.2f} | {len(runs) - len(ok)} / {rej:.0f} | {cost[0]:.0f} ± {cost[1]:.0f} |")
    # paired ratio EKF / DF
    print("\n| row | master RMSE ratio EKF / derivative-free, " + " | ".join(f"x{i + 1}" for i in range(n)) + " |")
    print("|---|" + "---|" * n)
    for ri in rows:
        pairs = [(data[(ri, s)]["ekf"], data[(ri, s)]["replay"]) for s in seeds if "failed" not in data[(ri, s)]["ekf"]]
        r = np.array([np.asarray(e["rmse_master"]) / np.asarray(d["rmse_master"]) for e, d in pairs])
        print(f"| {LABELS[ri]} | " + " | ".join(fmt(*ci(r[:, i])) for i in range(n)) + " |")
    print("\n| row | CPU time per step, EKF / derivative-free | UKF / derivative-free |")
    print("|---|---|---|")
    for ri in rows:
        cells = []
        for kind in ("ekf", "ukf"):
            r = [data[(ri, s)][kind]["us_per_step"] / data[(ri, s)]["replay"]["us_per_step"] for s in seeds
                 if "failed" not in data[(ri, s)][kind]]
            cells.append(fmt(*ci(r), digits=2))
        print(f"| {LABELS[ri]} | {cells[0]} | {cells[1]} |")
    return rows, series


def matched_report(model, data):
    flat = ex._flat(model)
    n = flat.n
    rows = list(range(len(SC.grid)))
    seeds = seeds_of(data, rows)
    R = len(seeds)
    bnd = bound_ratios(model, seeds)
    lo, hi = stats.nees_band(n, R)
    print(f"\n### {model}, matched linear plant, replay + difference, {R} runs\n")
    print("| row | master RMSE / exact bound " + " | ".join(f"x{i + 1}" for i in range(n)) +
          " | within ±5%? | max rel. gap master P vs centralized Riccati | "
          f"NEES avg (band [{lo:.2f}, {hi:.2f}]) | steps in band |")
    print("|---|" + "---|" * n + "---|---|---|---|")
    for ri in rows:
        mse = np.array([data[(ri, s)]["matched"]["mse_master"] for s in seeds])      # (R, n)
        rms = np.sqrt(mse.mean(axis=0))
        # delta method for the interval of sqrt(mean mse) / bound
        half = stats.t_quantile(0.975, R - 1) * mse.std(axis=0, ddof=1) / np.sqrt(R) / (2 * rms)
        ratio, rh = rms / bnd[ri].rmse_central, half / bnd[ri].rmse_central
        ok = all(abs(ratio[i] - 1) + rh[i] <= 0.05 for i in range(n))
        gap = max(data[(ri, s)]["matched"]["P_gap"] for s in seeds)
        per_step = np.mean([data[(ri, s)]["matched"]["nees_master"] for s in seeds], axis=0)
        print(f"| {LABELS[ri]} | " + " | ".join(fmt(ratio[i], rh[i]) for i in range(n)) +
              f" | {'yes' if ok else 'no'} | {gap:.1e} | {per_step.mean():.2f} | "
              f"{100 * np.mean((per_step >= lo) & (per_step <= hi)):.0f}% |")


def main():
    model = sys.argv[1]
    args = sys.argv[2:]

    def opt(name):
        return args[args.index(name) + 1] if name in args else None

    if opt("--matched"):        # several files (e.g. different rows of the same seeds): comma-separated
        merged = {}
        for part in opt("--matched").split(","):
            merged.update(load(part))
        matched_report(model, merged)
    if opt("--real"):
        real(model, load(opt("--real")))
    if opt("--filters"):        # several files: comma-separated, with their --rows maps separated by "/"
        files = opt("--filters").split(",")
        maps = opt("--rows").split("/") if opt("--rows") else [None] * len(files)
        if len(maps) != len(files):
            sys.exit("--rows: one row map per --filters file, separated by '/'")
        merged = {}
        for part, rows_of in zip(files, maps):
            merged.update(load(part, [int(r) for r in rows_of.split(",")] if rows_of else None))
        rows, series = filters(model, merged)
        if opt("--plot"):
            from dfeif_codegen.experiment import figures
            figures.comparison_figure(opt("--plot"), f"{model}: master RMSE per filter (95% intervals), "
                                      "same recordings", ex._flat(model), [LABELS[r] for r in rows],
                                      {k: (np.array(m), np.array(h)) for k, (m, h) in series.items()})


if __name__ == "__main__":
    main()
