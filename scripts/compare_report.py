"""Markdown tables of the filter comparison from `codegen simulate --filters ... --json FILE` files.

`python scripts/compare_report.py FILE.json [FILE.json ...]` prints, per file (one model and one
model-error setting): the model error applied, each filter's master RMSE per state and NEES with
the band, the paired ratios derivative-free / each filter (simulate's Table VII, per seed then
averaged), the operations per node step, and for the exact model the chapter's Tables I-IV beside
the project's (the chapter gives one value per quantity, nearly constant over its rows).
"""

from __future__ import annotations

import json
import sys

# Rigatos 2011, section 7, Tables I-IV: tr P of the nodes and of the master, and the RMSE of x1,
# x2, x3 (a tracking error x - x_d, the same at both nodes and the master, nearly constant over
# the delay rows)
CHAPTER = {"trace_nodes": 2.78e-2, "trace_master": 6.7e-3, "rmse": [4.4e-3, 5.5e-3, 1.1e-2]}
NAMES = {"brunovsky": "derivative-free, the chapter's Brunovsky predictor", "ekf": "EKF", "ukf": "UKF"}


def _row(r) -> str:
    return f"({', '.join(map(str, r['d']))}, {r['p']:g})"


def _cell(mean, half) -> str:
    return f"{mean:.3e} ± {half:.0e}" if half == half else f"{mean:.3e}"


def report(path: str) -> None:
    doc = json.load(open(path, encoding="utf-8"))
    st = doc["settings"]
    NAMES["df"] = f"derivative-free, {st.get('predictor', 'brunovsky')} predictor (closed loop's)"
    n = len(doc["states"])
    rows = doc["rows"]
    xs = " | ".join(f"x{i + 1}" for i in range(n))
    print(f"#### {st['model']}, model error: {st['model_error']['describe']}, {st['runs']} runs per row "
          f"(seeds {st['seeds'][0]}–{st['seeds'][1]})\n")
    tables = {t["filter"]: t for t in doc["tables"] if t["method"].endswith("-replay")}
    print(f"| row | filter | master RMSE {xs} | master NEES (95% band) | failed |")
    print("|---|---|" + "---|" * n + "---|---|")
    for ri, r in enumerate(rows):
        for kind in st["filters"]:
            s = tables[kind]["rows"][ri]
            if not s.get("runs"):
                print(f"| {_row(r)} | {NAMES.get(kind, kind)} | " + "failed | " * n + " | all |")
                continue
            rm = s["rmse_master"]
            cells = " | ".join(_cell(m, h) for m, h in zip(rm["mean"], rm["ci95"]))
            band = s["nees_band"]
            print(f"| {_row(r)} | {NAMES.get(kind, kind)} | {cells} | {s['nees_master']['mean']:.2f} "
                  f"({band[0]:.2f}–{band[1]:.2f}) | {st['runs'] - s['runs']} |")
    print(f"\n| row | derivative-free / filter, master RMSE {xs} | pairs |")
    print("|---|" + "---|" * n + "---|")
    for e in doc.get("paired", []):
        if "mean" not in e:
            continue
        cells = " | ".join(f"{m:.3f} ± {h:.3f}" for m, h in zip(e["mean"], e["ci95"]))
        print(f"| {_row(rows[e['row']])} / {NAMES.get(e['filter'], e['filter'])} | {cells} | {e['pairs']} |")
    ops = st["operations"]
    base = sum(ops["df"].values())
    print("\nOperations per node step (one predict + one update): " +
          ", ".join(f"{NAMES.get(k, k)} {sum(v.values()):,}" + ("" if k == "df" else f" ({sum(v.values()) / base:.1f}×)")
                    for k, v in ops.items()) + "\n")
    if st["model_error"]["describe"] == "none" and n == 3:
        closed = {t["method"]: t for t in doc["tables"]}.get("replay")
        if closed:
            print("| row | tr P1 / chapter | tr P master / chapter | plant tracking RMSE x1, x2, x3 (chapter: "
                  + ", ".join(f"{v:.1e}" for v in CHAPTER["rmse"]) + ") | master estimation RMSE x1, x2, x3 |")
            print("|---|---|---|---|---|")
            for ri, r in enumerate(rows):
                s = closed["rows"][ri]
                tr = s["trace_nodes"]["mean"][0]
                print(f"| {_row(r)} | {tr:.3g} / {CHAPTER['trace_nodes']:.3g} | {s['trace_master']['mean']:.3g} / "
                      f"{CHAPTER['trace_master']:.2g} | " + ", ".join(f"{v:.2e}" for v in s["rmse_tracking"]["mean"])
                      + " | " + ", ".join(f"{v:.2e}" for v in s["rmse_master"]["mean"]) + " |")
            print()


if __name__ == "__main__":
    for arg in sys.argv[1:]:
        report(arg)
