"""Paired comparison of filters run on the same recordings (`simulate --filters`).

Every filter of one seed saw the same frames, delays, inputs and (with model error) the same
plant, so their errors are strongly correlated: the ratio of two filters' RMSE is formed per
seed first, then averaged over the seeds with a 95% Student-t interval. That interval is far
tighter than one from the two filters' separate means, and it is the honest one for "who wins
by how much". A seed where either filter failed or diverged is left out of that pair (counted).
"""

from __future__ import annotations

import numpy as np

from dfeif_codegen.experiment.compare import FILTERS
from dfeif_codegen.experiment.stats import mean_ci

REFERENCE = "df"


def _by_seed(per_run, ref: str, label: str, ri: int) -> dict:
    return {seed: m for r, lab, _, row, seed, m in per_run if r == ref and lab == label and row == ri}


def ratios(per_run, ref: str, ri: int, kind: str, key: str = "rmse_master", numerator: str = REFERENCE) -> dict:
    """`numerator`'s `key` over `kind`'s, per seed, then mean and 95% half-width per component;
    also both filters' mean master NEES over the same seeds."""
    mine, theirs = _by_seed(per_run, ref, f"{numerator}-replay", ri), _by_seed(per_run, ref, f"{kind}-replay", ri)
    seeds = sorted(s for s in mine if s in theirs and isinstance(mine[s], dict) and isinstance(theirs[s], dict))
    out: dict = {"numerator": numerator, "pairs": len(seeds), "unpaired": len(set(mine) | set(theirs)) - len(seeds)}
    if not seeds:
        return out
    ratio = [np.asarray(mine[s][key], float) / np.asarray(theirs[s][key], float) for s in seeds]
    mean, half = mean_ci(ratio)
    out.update(mean=mean.tolist(), ci95=half.tolist(),
               nees=[float(np.mean([np.mean(d[s]["nees_master"]) for s in seeds])) for d in (mine, theirs)])
    return out


def entries(per_run, refs, rows, kinds) -> list[dict]:
    """Every other filter against REFERENCE, per reference and delay row (the JSON's "paired"),
    then each other candidate (not df, not one of compare.FILTERS) against the EKF when both ran:
    the comparison a user choosing between a candidate and the EKF reads."""
    pairs = [(REFERENCE, kind) for kind in kinds if kind != REFERENCE]
    if "ekf" in kinds:
        pairs += [(kind, "ekf") for kind in kinds if kind not in (REFERENCE, *FILTERS)]
    return [{"reference": ref, "row": ri, "filter": kind, **ratios(per_run, ref, ri, kind, numerator=top)}
            for top, kind in pairs for ref in refs for ri in range(len(rows))]


def print_ratios(out, paired: list[dict], rows, operations, row_label, n: int) -> None:
    """Table VII: the paired ratios, every row and state, and the operations per node step."""
    if not paired:
        return
    print(f"Table VII: master RMSE, derivative-free ({REFERENCE}) / each filter on the same recordings, "
          "formed per seed then averaged (mean ± 95% CI; below 1: the first more accurate); master NEES of "
          "both over the same seeds; pairs (seeds where both ran; unpaired: either failed). Then each other "
          "candidate / ekf alike", file=out)
    head = "".join(f"{f'x{i + 1}':>19}" for i in range(n))
    for ref in dict.fromkeys(e["reference"] for e in paired):
        print(f"  {ref}", file=out)
        print(f"  {'row':>14}  {'first / filter':24s}{head}   NEES first / filter   pairs", file=out)
        for e in (e for e in paired if e["reference"] == ref):
            label, who = row_label(rows[e["row"]]), f"{e['numerator']} / {e['filter']}"
            if not e["pairs"]:
                print(f"  {label:>14}  {who:24s}  no pair (every run of one filter failed)", file=out)
                continue
            cells = "".join(f"{m:>11.3f} ± {h:5.3f}" if np.isfinite(h) else f"{m:>19.3f}"
                            for m, h in zip(e["mean"], e["ci95"]))
            extra = f" ({e['unpaired']} unpaired)" if e["unpaired"] else ""
            print(f"  {label:>14}  {who:24s}{cells}   {e['nees'][0]:7.2f} / {e['nees'][1]:<8.2f}"
                  f"   {e['pairs']}{extra}", file=out)
    base = sum(operations[REFERENCE].values())
    ops = ", ".join(f"{k} {sum(v.values()):,}" + ("" if k == REFERENCE else f" ({sum(v.values()) / base:.1f}x)")
                    for k, v in operations.items())
    print(f"  operations per node step (one predict + one update, CasADi SX instructions): {ops}\n", file=out)
