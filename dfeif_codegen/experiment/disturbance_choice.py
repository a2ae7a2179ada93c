"""`codegen scenario --disturbance auto`: which disturbance kind a model's error needs, measured.

Why: a random walk suits an error that changes little between frames, an integrated random walk
one that drifts as the state moves; which of the two a model needs does not show in its
equations. Measured on the built-ins at ±20% (docs/experiment.md, "Disturbance kinds under
model error"): the integrated walk takes the motor's θ'' error to a third of the random walk's,
and on the arm its loop is lost on a corner of the error at every pole the check tries. So the
calibration calibrates both on the same loops, keeps the one whose held filter is the more
accurate there (the loops are simulations: the truth is known), and takes the other when the
chosen one's loop does not hold the error's corners under the hardest delays (pole_margin).
"""

from __future__ import annotations

import math

import numpy as np

from dfeif_codegen.experiment import disturbance_calibration, pole_margin
from dfeif_codegen.symbolic.disturbance import Disturbance

CANDIDATES = ("random_walk", "integrated_random_walk")


def master_rmse(results: list, q, dist: Disturbance) -> np.ndarray:
    """The held filter's master RMSE per canonical state with `dist`, root mean square over the
    recordings; inf where it fails on one."""
    out = []
    for res in results:
        m = disturbance_calibration.held_metrics(res, q, dist)
        if "failed" in m:
            return np.full(res.recording.n, math.inf)
        out.append(np.asarray(m["rmse_master"], dtype=float))
    return np.sqrt(np.mean(np.square(out), axis=0))


def ratio(rmse: list[np.ndarray]) -> float:
    """The second kind's RMSE over the first's, geometric mean over the states (inf: it failed)."""
    with np.errstate(all="ignore"):
        r = float(np.exp(np.mean(np.log(rmse[1] / rmse[0]))))
    return r if math.isfinite(r) else (0.0 if np.all(np.isfinite(rmse[1])) else math.inf)


def choose(flat, q, loops: list, match, tol: float, log: list[str], hold):
    """(q, log, the calibrated Disturbance, poles): both CANDIDATES calibrated on `loops`
    (disturbance_calibration.densities, `match` and `tol` as there), the more accurate kept;
    `hold(q, dist, log)` is the pole check (pole_margin.hold for that filter): (poles, log), its
    last line a WARNING when no pole it tried holds. The other kind is taken when it holds where
    the first does not."""
    tried = [disturbance_calibration.densities(flat, q, loops, Disturbance(kind, (1.0,)), match, tol, [])
             for kind in CANDIDATES]
    r = ratio([master_rmse(loops, qk, dk) for qk, _, dk in tried])
    order = (1, 0) if r < 1 else (0, 1)
    log = log + [f"disturbance kind: {CANDIDATES[order[0]]} (the held filter's master RMSE on the calibration "
                 f"loops with integrated_random_walk x{r:.3g} of its RMSE with random_walk, geometric mean over the "
                 "states)"]
    first = None
    for i in order:
        qk, lines, dk = tried[i]
        poles, out = hold(qk, dk, log + lines)
        if not out[-1].startswith(pole_margin.WARNING):
            if first is not None:
                out.append(f"disturbance kind: {CANDIDATES[i]} instead: with {CANDIDATES[order[0]]} no pole tried "
                           "held the error's corners, with it they hold")
            return qk, out, dk, poles
        first = first or (qk, out, dk, poles)
    return first
