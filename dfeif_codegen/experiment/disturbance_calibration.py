"""`codegen scenario --disturbance`: the disturbance states' densities (symbolic/disturbance.py),
scaled so that the master's NEES averages n, the middle of its band (nees_match.match_nees).

Why on recordings: the held filter's estimate does not yet close the flatness controller's loop
well (reference/predictor.py: the controller computes u as if v were held), and under model
error many of those loops stop tracking before they say anything about the filter. So the
loops are closed by the chapter's Brunovsky filter, which keeps them (where it loses one, by
the held filter without disturbance states: error_loops), and the held filter with
disturbance states runs on each loop's recording, fed the applied u (experiment/compare.py: the
same data an EKF is judged on). Its q stays the one-step residual's; the densities take what
white noise on the top derivatives does not describe (a wrong parameter, the coloured part of
the residual). If the NEES is at or below n already with negligible densities (1e-6 q: the
model explains the data), q is scaled instead and the densities stay at that floor.

The d's initial spread (the scenario's `p0_std` in `[disturbance]`) is their size on the same
loops: the root mean square of what the held model misses on each chain's top derivative (the
one-step residual over Ts, first_guess). The default, the spread the density gathers in a second,
is far larger at the densities a drifting error needs (arm +-20%, integrated Gauss-Markov: 3,500
against 512 per chain), and that prior leaves the master's first information differences so
ill-conditioned that the C drifts 1.5e-9 from the reference where the budget is 1e-10 (1.0e-11
with the measured spread)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare
from dfeif_codegen.experiment.nees_match import NEES_SECONDS, match_nees
from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.symbolic.disturbance import KINDS, TIMED, Disturbance

FLOOR = 1e-6


AUTO = "auto"     # --disturbance auto: the kind chosen by measurement (disturbance_choice.py)
TAU_ONLY = f"--tau: applies to --disturbance {' or '.join((*TIMED, AUTO))} only"


def held_metrics(res, q, dist: Disturbance) -> dict:
    """compare.evaluate's metrics of the held filter with white density `q` and disturbance
    states `dist` on a loop's recording ({"failed": why} when it fails)."""
    rec = dataclasses.replace(res.recording, predictor="held", q=np.asarray(q, dtype=float))
    return compare.evaluate(dataclasses.replace(res, recording=rec), "df", disturbance=dist)


def held_nees(results: list, q, dist: Disturbance) -> float:
    """The held filter's master NEES with disturbance states `dist`, averaged over the steps and
    the recordings (inf if it fails or diverges on one)."""
    return mean_nees(results, lambda res: held_metrics(res, q, dist))


def mean_nees(results: list, evaluate) -> float:
    """The master NEES `evaluate(result)` (compare.evaluate's metrics) gives, averaged over the
    steps and the recordings (inf if it fails or diverges on one)."""
    values = []
    for res in results:
        m = evaluate(res)
        if "failed" in m:
            return math.inf
        values.append(float(np.mean(m["nees_master"])))
    return float(np.mean(values))


def with_densities(dist: Disturbance, qd) -> Disturbance:
    return Disturbance(dist.kind, tuple(float(v) for v in qd), dist.tau, dist.p0_std)


def first_guess(flat, ts: float, loops: list) -> np.ndarray:
    """Per chain, the density of a random walk that gathers in one second the variance of what
    the held model misses on the chain's top derivative along the loops: the top state's
    one-step residual over Ts, squared and averaged (the disturbance it would take)."""
    pred = predictors.make("held", flat, ts, np.ones(flat.m))
    tops = [c.offset + c.degree - 1 for c in flat.chains]
    miss = []
    for res in loops:
        z, u = res.zeta, res.recording.u
        r = np.array([z[k + 1] - pred.mean(z[k], u[k]) for k in range(len(z) - 1)])[:, tops]
        angle = np.array([c.angle and c.degree == 1 for c in flat.chains])    # a top that is an angle head
        miss.append(np.where(angle, (r + np.pi) % (2 * np.pi) - np.pi, r) / ts)
    return np.maximum(np.mean(np.concatenate(miss) ** 2, axis=0), 1e-300)


def error_loops(config, q, held, seeds: list[int], errors: list, log: list[str], say) -> tuple[list, list[str]]:
    """(the calibration's loops under the model error, one per plant of `errors`; the log):
    closed by the chapter's filter at its q (`config(q, seed, duration)` is the calibration's
    loop, its predictor the chapter's), which keeps them where the held filter's estimate does
    not (module docstring); where it loses one, by the held filter without disturbance states at
    its white q `held`, whose loop holds the plant closer to the reference. Measured on the sqrt
    motor of the tests at +-10%: the chapter's filter lets theta leave its reference by 0.6 rad
    at t = 0.94 s (amplitude 0.3 rad), or its estimate leave the model's domain (amplitude 0.5)."""
    def run(qq, predictor: str) -> list:
        return [ex.run(dataclasses.replace(config(qq, s, NEES_SECONDS), plant_error=e, predictor=predictor))
                for s, e in zip(seeds, errors)]

    say(f"the calibration's {len(errors)} loops under the model error, closed by the chapter's filter")
    try:
        return run(q, "brunovsky"), log
    except (ArithmeticError, np.linalg.LinAlgError) as exc:
        why = str(exc).split(" (")[0]
    say(f"the chapter's filter lost one ({why}): the same loops closed by the held filter")
    return run(held, "held"), log + [f"the chapter's filter lost a loop under the model error ({why}): the "
                                     f"calibration's loops closed by the held filter at q = {_text(held)} instead"]


def densities(flat, q, loops: list, dist: Disturbance, match, tol: float, log: list[str]):
    """(q, log, the Disturbance with calibrated densities) from the results of the loops closed
    by the Brunovsky filter; `match(q, log, nees)` is nees_match.match_nees with its NEES measure
    `nees(q)`, `tol` its factor."""
    floor = with_densities(dist, FLOOR * np.asarray(q, dtype=float))
    if held_nees(loops, q, floor) <= flat.n * tol:
        log.append(f"held filter's NEES at or below n with disturbance q = {_text(floor.q)}: the model needs none")
        q, log = match(q, log, lambda qq: held_nees(loops, qq, floor))
        return q, log, floor
    # an integrated random walk's d spreads q T^3 / 3 in T = 1 s where a random walk's spreads q T
    size = first_guess(flat, loops[0].recording.ts, loops)
    guess = size * (3.0 if dist.order == 2 else 1.0)
    if dist.p0_std is None:     # the d's initial spread: their size on these loops (module docstring)
        dist = Disturbance(dist.kind, dist.q, dist.tau, tuple(float(f"{v:.4g}") for v in np.sqrt(size)))
    log.append(f"disturbance q from what the held model misses on the top derivatives: {_text(guess)}")
    qd, log = match(guess, log, lambda qd: held_nees(loops, q, with_densities(dist, qd)))
    log[-1] = log[-1].replace(" at q = ", f" at q = {_text(q)}, disturbance q = ")
    return q, log, with_densities(dist, qd)


def settle(flat, q, dist: Disturbance, poles, hold, config, errors: list, seeds: list[int], log: list[str],
           progress=None):
    """(dist, poles, log): the densities matched again on the held filter's own loops
    (on_own_loops), closed at the poles `hold` gave for `dist` (where none held, those that lost
    the fewest corners: a loop too fast for the model error tracks badly whatever the densities,
    measured on the arm at +-20%: one of the 16 loops at NEES 100 at -0.1/Ts), then the poles
    checked again at the new densities. `hold(q, dist, log)` -> (poles, log) is the pole check
    from the scenario's own poles (pole_margin.hold). Skipped at the floor: the model needs no
    densities."""
    if np.allclose(dist.q, FLOOR * np.asarray(q, dtype=float)):
        return dist, poles, log
    closed = lambda qq, seed, duration: dataclasses.replace(config(qq, seed, duration), poles=tuple(poles))  # noqa: E731
    new, log = on_own_loops(flat, q, dist, closed, errors, seeds, log, progress)
    if new == dist:
        return dist, poles, log
    poles, log = hold(q, new, log)
    return new, poles, log


def on_own_loops(flat, q, dist: Disturbance, config, errors: list, seeds: list[int], log: list[str],
                 progress=None) -> tuple[Disturbance, list[str]]:
    """(the Disturbance, log): its densities re-matched so that the master NEES of loops the held
    filter closes itself, with them and white q `q`, on the plants `errors` (one per seed in
    `seeds`), is n; `config(q, seed, duration)` is the calibration's closed loop. Why: the first
    match re-filters loops the chapter's filter closed, whose noisier voltage drives the plant
    harder, so the model error in them is larger. Measured on the arm at +-20% with an integrated
    Gauss-Markov disturbance (tau 0.3 s): the first match asks for 6.7 times the densities that
    put the held filter's own loops at n, and at those densities no pole the check tries holds
    the error's corners. The NEES moves little with the densities (6.3 to 4.8 over that factor),
    so this match keeps the first densities whenever their NEES is within its tolerance."""
    def loop(qd, seed, duration):
        return dataclasses.replace(config(q, seed, duration), predictor="held", disturbance=with_densities(dist, qd),
                                   plant_error=errors[seeds.index(seed)])
    qd, lines = match_nees(flat, np.asarray(dist.q, dtype=float), loop, seeds, [], floor=None, progress=progress)
    line = lines[-1].replace(" at q = ", f" at q = {_text(q)}, disturbance q = ")
    return with_densities(dist, qd), log + ["on loops the held filter closes itself with them: " + line]


def _text(values) -> str:
    return "[" + ", ".join(f"{v:.3g}" for v in np.atleast_1d(values)) + "]"


def from_options(kind: str | None, tau: float | None) -> Disturbance | None:
    """--disturbance KIND [--tau S], checked before any work."""
    if kind is None:
        if tau is not None:
            raise ScenarioError(TAU_ONLY)
        return None
    if kind not in (*KINDS, AUTO):
        raise ScenarioError(f"--disturbance {kind}: choose from {', '.join(KINDS)}, or auto (the calibration "
                            "measures random_walk against integrated_random_walk, and with --tau the "
                            "Gauss-Markov kinds too)")
    if kind == AUTO and tau is not None:
        if not math.isfinite(tau) or tau <= 0:
            raise ScenarioError(f"--tau {tau}: --disturbance auto needs a time constant > 0 [s] for its "
                                "Gauss-Markov candidates")
    elif kind in TIMED:
        if tau is None or not math.isfinite(tau) or tau <= 0:
            raise ScenarioError(f"--tau {tau}: --disturbance {kind} needs a time constant > 0 [s]")
    elif tau is not None:
        raise ScenarioError(TAU_ONLY)
    return Disturbance(kind, (1.0,), tau)
