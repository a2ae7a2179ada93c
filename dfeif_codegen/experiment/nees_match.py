"""Scaling a scenario's q until the master's NEES averages n (`match_nees`), and raising it until
the closed loop survives the hardest delays (`close_with_delays`): the two searches of `codegen
scenario`'s calibration (experiment/starter.py), over closed loops it describes by `config(q,
seed, duration)`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex


def fmt(values) -> str:
    return "[" + ", ".join(f"{v:.3g}" for v in np.atleast_1d(values)) + "]"


DELAY_STEPS = 6    # half decades q may rise by to close the loop under the hardest delays


def links_text(links) -> str:
    """The camera links of a delay row, as the calibration's log names them."""
    return ", ".join(f"d = {lk.d} with p = {lk.p:g}" for lk in links)


def first_loss(configs) -> tuple[int, str] | None:
    """The first of the closed loops `configs` that is lost (simulate's divergence tests, when a
    config watches them): its index and why; None when every one holds. Stops at that loop."""
    for i, cfg in enumerate(configs):
        try:
            ex.run(cfg)
        except (ArithmeticError, FloatingPointError, np.linalg.LinAlgError) as exc:
            return i, str(exc)
    return None


def close_with_delays(q, config, seeds, links, log, progress=None) -> tuple[np.ndarray, list[str]]:
    """Under the hardest delays the estimate rides the model's prediction for many steps, and a q
    matched without delays can lose the loop (the maglev of the tests drifts onto its magnet).
    Run the replay loop there (simulate's divergence tests) and raise q by half a decade until it
    closes; past DELAY_STEPS keep the NEES-matched q and say so. `progress(line)` hears each q
    tried as its loops start."""
    def lost(q) -> str | None:
        loss = first_loss(dataclasses.replace(config(q, s, NEES_SECONDS), sensor=tuple(links), watch_nees=True)
                          for s in seeds)
        return loss and loss[1]

    where = links_text(links)
    say = progress or (lambda line: None)
    say(f"the replay loop under the hardest delays ({where}) at q = {fmt(q)}")
    first = lost(q)
    first = first and first.split(" (")[0]
    if first is None:
        return q, log
    for step in range(1, DELAY_STEPS + 1):
        raised = q * 10 ** (step / 2)
        say(f"the loop was lost there ({first}): q x {10 ** (step / 2):.3g} ({step} of at most {DELAY_STEPS})")
        if lost(raised) is None:
            log.append(f"under the hardest delays ({where}) the loop was lost ({first}): q x {10 ** (step / 2):.3g} "
                       f"-> {fmt(raised)} closes it")
            return raised, log
    log.append(f"WARNING: under the hardest delays ({where}) the loop is lost ({first}) up to q x "
               f"{10 ** (DELAY_STEPS / 2):.3g}; q kept")
    return q, log


# eight runs: one run's master NEES spreads widely from seed to seed (the arm at a fixed q: 2.6 to
# 11, standard deviation 2.2 around a mean of 4.8 over seeds 0-99), so two runs matched n to a
# mean 20% off on other seeds; eight halve that spread (docs/experiment.md, the exact-model NEES target)
NEES_RUNS, NEES_TOL, NEES_EVALS, NEES_SECONDS = 8, 1.1, 8, 20.0
NEES_LOST = 6      # scales of q whose closed loops were lost, at most, before giving up
# the match lowers q at most a decade below the residual: the information-difference fusion's
# Y_i - Y_pred cancels more digits the smaller q is (measured on a rotor, C against reference:
# 1e-12 at the residual's q, 6e-11 at 1e-2 of it, 2e-4 at 3e-9 of it), and a filter that trusts
# its model that much has no margin for the model's errors; a NEES below n is the safe side.
# Not when the loop was lost at the residual's q (a PVTOL's closed-loop residual overshoots by
# decades): the search then goes where loops close.
NEES_FLOOR = 0.1
NO_LOOP = "every scale of q tried"
LAST_LOSS = "; the last loop lost: "   # then its reason, in the NO_LOOP line


def _after_loss(tried, scale: float, lost: int) -> float:
    """The next log scale of q after a lost loop. Before any closed: 0, +1, -1, +2, -2, ... decades
    (a stiff plant needs more q; a PVTOL's degree-4 chains, whose residual overshoots, far less).
    After one closed: halfway back to the closest."""
    if tried:
        best = min(tried, key=lambda t: abs(t[1]))[0]
        return (scale + best) / 2
    k = (lost + 1) // 2
    return math.log(10.0) * (k if lost % 2 else -k)


class _Lost(float):
    """inf, and why the run was lost: a calibration that loses every loop says what ended them."""

    reason: str

    def __new__(cls, reason: str) -> "_Lost":
        lost = super().__new__(cls, math.inf)
        lost.reason = reason
        return lost


def _master_nees(config, q, seeds) -> float:
    """The master's NEES averaged over the steps and the runs (inf when a run fails: `_Lost`)."""
    values = []
    for s in seeds:
        try:
            values.append(float(np.mean(ex.run(config(q, s, NEES_SECONDS)).metrics["nees_master"])))
        except (ArithmeticError, FloatingPointError, np.linalg.LinAlgError) as exc:
            return _Lost(str(exc))
    return float(np.mean(values)) if np.all(np.isfinite(values)) else math.inf


def match_nees(flat, q, config, seeds, log, nees=None, floor: float | None = NEES_FLOOR,
               progress=None) -> tuple[np.ndarray, list[str]]:
    """Scale q (every chain alike, keeping the residual's proportions) until the master's NEES,
    averaged over `seeds` closed loops without delays of NEES_SECONDS (the length of a
    scenario's runs: the NEES of a filter with little process noise drifts over a run, so a
    shorter run would match another q), is n within a factor NEES_TOL: the middle of its 95%
    band for any number of runs. A secant on log NEES against log scale (NEES falls as q
    grows); at most NEES_EVALS evaluations, keeping the closest. The residual alone does not get
    there: it is coloured (correlated from step to step), which white noise of the same variance
    does not describe, and the estimate's own error feeds back through u. `nees(q)`: another
    measure of the master's NEES at q than `seeds` closed loops of `config`; `floor`: how far
    below the start q may go when the first loop closed (None: no floor, for a filter whose
    start is not the residual's scale and which does not close the loop); `progress(line)` hears
    each evaluation's NEES."""
    n = flat.n
    nees_at = nees or (lambda qq: _master_nees(config, qq, seeds))
    tried = []                                   # (log scale, log NEES / n)
    lost = 0
    scale = 0.0
    floored = False
    why = ""                                     # the last lost loop's reason, if it gave one
    while len(tried) < NEES_EVALS and lost <= NEES_LOST:
        value = nees_at(q * math.exp(scale))
        why = getattr(value, "reason", why)
        if progress:
            progress(f"master NEES at q = {fmt(q * math.exp(scale))}: " + (
                f"{value:.3g} ({len(tried) + 1} of at most {NEES_EVALS})" if math.isfinite(value)
                else f"a loop lost ({lost + 1} of at most {NEES_LOST + 1} losses)"))
        if not math.isfinite(value):
            lost += 1
            scale = _after_loss(tried, scale, lost)
            continue
        tried.append((scale, math.log(value / n)))
        if abs(tried[-1][1]) <= math.log(NEES_TOL):
            break
        if len(tried) < 2 or tried[-1][0] == tried[-2][0]:
            slope = -1.0                         # NEES ~ 1/q, the first guess
        else:
            (s0, e0), (s1, e1) = tried[-2], tried[-1]
            slope = (e1 - e0) / (s1 - s0) if s1 != s0 else -1.0
            slope = min(slope, -0.05)            # NEES falls with q; a flat stretch takes large steps
        step = max(-3.0, min(3.0, tried[-1][1] / slope))                   # within e^+-3 per step
        scale = tried[-1][0] - step
        if floor is not None and tried[0][0] >= math.log(floor):  # closed near the residual: keep the floor
            scale = max(scale, min(math.log(floor), tried[-1][0]))
            floored = scale == tried[-1][0]
            if floored:
                break                            # at the floor, and NEES still asks for less q
    if not tried:
        log.append(f"master NEES: {NO_LOOP} (x1e-{NEES_LOST // 2} to x1e{(NEES_LOST + 1) // 2}) lost a closed loop; "
                   "q kept from the residual" + (f"{LAST_LOSS}{why}" if why else ""))
        return q, log
    best = min(tried, key=lambda t: abs(t[1]))
    q = q * math.exp(best[0])
    inside = abs(best[1]) <= math.log(NEES_TOL)
    log.append(f"master NEES over {len(seeds)} runs without delays: {n * math.exp(best[1]):.3g} at q = {fmt(q)} "
               f"(x{math.exp(best[0]):.3g}; target n = {n}"
               + ("" if inside else f", not reached in {len(tried)} tries")
               + (f", q lowered at most x{floor:g}" if floored else "") + ")")
    return q, log
