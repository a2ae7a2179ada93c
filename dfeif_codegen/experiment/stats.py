"""The statistics of `codegen simulate`: means with 95% confidence intervals and the NEES band.

Without scipy at runtime: Student-t and chi-square quantiles from the normal quantile
(Cornish-Fisher expansion; Wilson-Hilferty), accurate to well under 1% where they are used.
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np


def t_quantile(p: float, dof: int) -> float:
    """Student-t quantile: exact for 1 and 2 degrees of freedom, Cornish-Fisher beyond."""
    if dof == 1:
        return math.tan(math.pi * (p - 0.5))
    if dof == 2:
        return (2 * p - 1) / math.sqrt(2 * p * (1 - p))
    z, v = NormalDist().inv_cdf(p), float(dof)
    g1 = (z ** 3 + z) / 4
    g2 = (5 * z ** 5 + 16 * z ** 3 + 3 * z) / 96
    g3 = (3 * z ** 7 + 19 * z ** 5 + 17 * z ** 3 - 15 * z) / 384
    g4 = (79 * z ** 9 + 776 * z ** 7 + 1482 * z ** 5 - 1920 * z ** 3 - 945 * z) / 92160
    return z + g1 / v + g2 / v ** 2 + g3 / v ** 3 + g4 / v ** 4


def chi2_quantile(p: float, dof: float) -> float:
    """Chi-square quantile by Wilson-Hilferty (cube of a normal)."""
    z, c = NormalDist().inv_cdf(p), 2.0 / (9.0 * dof)
    return dof * max(1 - c + z * math.sqrt(c), 0.0) ** 3


def mean_ci(samples) -> tuple[np.ndarray, np.ndarray]:
    """Mean over axis 0 and the half-width of its 95% confidence interval (NaN for one sample)."""
    a = np.asarray(samples, dtype=float)
    mean = a.mean(axis=0)
    if a.shape[0] < 2:
        return mean, np.full_like(mean, np.nan)
    return mean, t_quantile(0.975, a.shape[0] - 1) * a.std(axis=0, ddof=1) / math.sqrt(a.shape[0])


def nees_band(n: int, runs: int) -> tuple[float, float]:
    """95% band of the NEES averaged over `runs` independent runs at one step (Bar-Shalom)."""
    return chi2_quantile(0.025, n * runs) / runs, chi2_quantile(0.975, n * runs) / runs


METRICS = ("trace_nodes", "trace_master", "rmse_nodes", "rmse_master", "rmse_tracking",
           "rmse_est_tracking_nodes", "rmse_est_tracking_master", "late_applied", "late_rejected", "us_per_step",
           "saturated_steps", "outliers")


def summarize(runs: list[dict], n: int) -> dict:
    """Mean and 95% CI of each metric over the successful runs; NEES averaged over runs per step,
    then over time, with the band and the fraction of steps inside it."""
    out: dict = {"runs": len(runs)}
    if not runs:
        return out
    for key in METRICS:
        if any(key not in r for r in runs):     # e.g. records resumed from an older version
            continue
        mean, half = mean_ci([r[key] for r in runs])
        out[key] = {"mean": mean.tolist(), "ci95": half.tolist()}
    lo, hi = nees_band(n, len(runs))
    out["nees_band"] = [lo, hi]
    for key in ("nees_nodes", "nees_master"):
        per_step = np.mean([r[key] for r in runs], axis=0)           # run-averaged NEES per step
        out[key] = {"mean": per_step.mean(axis=-1).tolist(),
                    "in_band": ((per_step >= lo) & (per_step <= hi)).mean(axis=-1).tolist()}
    return out
