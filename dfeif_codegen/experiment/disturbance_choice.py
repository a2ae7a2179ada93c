"""`codegen scenario --disturbance auto [--tau S]`: which disturbance kind a model's error needs,
measured.

Why: a random walk suits an error that changes little between frames, an integrated random walk
one that drifts as the state moves, the Gauss–Markov kinds an error that forgets over a time
constant; which a model needs does not show in its equations. Measured on the built-ins at ±20%
(docs/experiment.md, "Disturbance kinds under model error"): the integrated walk takes the
motor's θ'' error to a third of the random walk's; on the arm its loop is lost on a corner of
the error at every pole the check tries, and an integrated Gauss–Markov at τ 0.3 s meets the
RMSE target there but loses a corner too, where the random walk holds them all. So the
calibration calibrates every candidate on the same loops (the two walks, and with --tau the two
Gauss–Markov kinds at that τ: a time constant is the user's knowledge of the error, not a thing
these few loops can fit), ranks them by their held filter's accuracy there (the loops are
simulations: the truth is known; a simpler kind first unless BETTER), and keeps the first in rank
whose loop holds the error's corners under the hardest delays (pole_margin).
"""

from __future__ import annotations

import math

import numpy as np

from dfeif_codegen.experiment import disturbance_calibration, pole_margin
from dfeif_codegen.symbolic.disturbance import TIMED, Disturbance

WALKS = ("random_walk", "integrated_random_walk")
# A kind with more states, or a time constant, ranks ahead of a simpler one only when it is this
# much more accurate on the calibration loops; below it the simpler is kept: it costs less per
# step (the motor's node step: random walk 377 operations, integrated walk 510), and without model
# error, where every kind lands within 0.1% of the others (the motor), the choice would be rounding's.
BETTER = 0.02


def candidates(tau: float | None) -> list[Disturbance]:
    """The kinds `auto` calibrates: the two walks, and the Gauss–Markov kinds when a τ is given."""
    kinds = [Disturbance(kind, (1.0,)) for kind in WALKS]
    return kinds + ([Disturbance(kind, (1.0,), tau) for kind in TIMED] if tau is not None else [])


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


def rank(kinds: list[Disturbance], ratios: list[float]) -> list[int]:
    """Candidates' indices, best first: the simplest (fewest states, then no time constant) of
    those within BETTER of the most accurate, then the others by accuracy."""
    best = min(ratios)
    simple = lambda i: (kinds[i].order, kinds[i].kind in TIMED, i)   # noqa: E731
    alike = sorted((i for i, r in enumerate(ratios) if r <= best * (1 + BETTER)), key=simple)
    return alike[:1] + sorted((i for i in range(len(kinds)) if i not in alike[:1]), key=lambda i: (ratios[i], i))


def choose(flat, q, loops: list, match, tol: float, log: list[str], hold, tau: float | None = None):
    """(q, log, the calibrated Disturbance, poles): every candidate (`candidates(tau)`) calibrated
    on `loops` (disturbance_calibration.densities, `match` and `tol` as there) and ranked by its
    master RMSE against the random walk's (`ratio`, `rank`; a failed calibration loop last); `hold(q,
    dist, log)` is the pole check (pole_margin.hold for that filter): (poles, log), its last line
    a WARNING when no pole it tried holds. The first in rank that holds is kept; when none does,
    the first."""
    kinds = candidates(tau)
    tried = [disturbance_calibration.densities(flat, q, loops, kind, match, tol, []) for kind in kinds]
    rmse = [master_rmse(loops, qk, dk) for qk, _, dk in tried]
    ratios = [1.0] + [ratio([rmse[0], r]) for r in rmse[1:]]
    order = rank(kinds, ratios)
    log = log + [f"disturbance kind: {kinds[order[0]].kind} (the held filter's master RMSE on the calibration "
                 "loops, geometric mean over the states, against random_walk's: "
                 + ", ".join(f"{k.kind} x{r:.3g}" for k, r in zip(kinds[1:], ratios[1:])) + ")"]
    first = None
    for i in order:
        qk, lines, dk = tried[i]
        poles, out = hold(qk, dk, log + lines)
        if not out[-1].startswith(pole_margin.WARNING):
            if first is not None:
                out.append(f"disturbance kind: {kinds[i].kind} instead: with {kinds[order[0]].kind} no pole tried "
                           "held the error's corners, with it they hold")
            return qk, out, dk, poles
        first = first or (qk, out, dk, poles)
    return first
