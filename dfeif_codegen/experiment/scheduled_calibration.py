"""`codegen scenario --scheduled`: the q of the scheduled predictor (`--predictor scheduled`,
and the comparison's `--filters scheduled`), `q_scheduled` in [filter].

Two stages. First, scaled from the held filter's calibrated q until the scheduled filter's master
NEES, re-filtering the calibration's loops without delays (closed by the held filter at its q),
is n: cheap, one set of loops. Then, from there, until the master NEES of loops the scheduled
filter closes itself (as `simulate --predictor scheduled` and the generated C run it) is n: what
the product runs. On the two-link arm the two agree (the loops barely depend on which filter
closes them: the same NEES to three digits), so the second stage accepts the first's q at its
first evaluation. Why its own q: a transition that follows the configuration leaves less for q
to cover (on the arm about 300 times less: docs/experiment.md). With disturbance states
(`--disturbance`, under model error) one stage, on the loops their densities were matched on
(`under_model_error`).

Whether a model wants the scheduled predictor at all (`transition_swing`, `advice`, `note`):
`codegen scenario` says so when the transition moves along the reference by more than half of
its own step, as the arm's does and the motor's does not, and the scheduled predictor holds the
scenario's loops.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare
from dfeif_codegen.experiment.disturbance_calibration import mean_nees
from dfeif_codegen.experiment.nees_match import NEES_SECONDS, NO_LOOP, first_loss, match_nees


def nees(loops: list, q, disturbance=None) -> float:
    """The scheduled filter's master NEES at `q` over the recordings (inf if it fails on one);
    with `disturbance`, its disturbance states at their calibrated densities."""
    qs = tuple(float(v) for v in np.atleast_1d(q))
    return mean_nees(loops, lambda res: compare.evaluate(
        dataclasses.replace(res, config=dataclasses.replace(res.config, q_scheduled=qs)), compare.SCHEDULED,
        disturbance=disturbance))


def under_model_error(flat, q, loops: list, seeds, disturbance, log: list[str], say) -> tuple[np.ndarray, list[str]]:
    """(the scheduled filter's white q, log) with disturbance states: scaled from the held
    filter's calibrated white `q`, the disturbances' densities kept, until the scheduled filter's
    master NEES re-filtering the calibration's loops under the model error (`loops`, of `seeds`)
    is n. Those loops are the ones the densities were matched on; a second stage on loops the
    scheduled filter closes would draw the model error again (the held filter's own densities
    are matched on re-filtered loops alike). When the densities dominate, q moves the NEES
    little and match_nees keeps the closest it found, saying so."""
    say(f"the scheduled filter: white q scaled until its NEES on those {len(loops)} loops is n")
    found, log = match_nees(flat, np.asarray(q, dtype=float), None, seeds, log,
                            lambda qq: nees(loops, qq, disturbance), floor=None, progress=say)
    if NO_LOOP in log[-1]:
        raise ScenarioError(f"--scheduled: the scheduled filter failed or diverged on the calibration's loops at "
                            f"every scale of q tried (from {list(np.atleast_1d(q))})")
    log[-1] = "the scheduled filter, with the disturbance states: " + log[-1]
    return found, log


def q_scheduled(flat, q, config, seeds, log: list[str], say) -> tuple[np.ndarray, list[str]]:
    """(the scheduled filter's q, log): a q scaled from the held filter's `q` until the master's
    NEES is n, first re-filtering the held filter's loops `config(q, seed, NEES_SECONDS)` of
    `seeds`, then on loops the scheduled filter closes at each q tried (module docstring; no
    floor: the start is not the residual's scale)."""
    say(f"the scheduled filter: q scaled until its NEES on {len(seeds)} loops of the held filter is n")
    loops = [ex.run(config(q, s, NEES_SECONDS)) for s in seeds]
    found, log = match_nees(flat, np.asarray(q, dtype=float), None, seeds, log, lambda qq: nees(loops, qq),
                            floor=None, progress=say)
    if NO_LOOP not in log[-1]:
        log[-1] = "the scheduled filter: " + log[-1]
        say(f"the scheduled filter: q scaled until its NEES on {len(seeds)} loops it closes itself is n")
        found, log = match_nees(flat, found, closed_by_scheduled(config), seeds, log, floor=None, progress=say)
    if NO_LOOP in log[-1]:
        raise ScenarioError(f"--scheduled: the scheduled filter failed or diverged on the calibration's loops at "
                            f"every scale of q tried (from {list(np.atleast_1d(q))})")
    log[-1] = "the scheduled filter, on its own loops: " + log[-1]
    return found, log


def closed_by_scheduled(config):
    """`config` with the loops closed by the scheduled predictor at the q given."""
    return lambda q, seed, duration: dataclasses.replace(config(q, seed, duration), predictor="scheduled")


SWING_ADVICE = 0.5
"""`codegen scenario` advises `--predictor scheduled` where the covariance transition moves along
the reference by more than this fraction of its own step, max |Φ(σ) - Φ₀| / |Φ₀ - I| (Frobenius):
the constant Φ₀ then describes a step only near the nominal outputs. Measured: two_link_arm 1.45
on the reference `codegen scenario` picks (2.0 on the 1 rad one of docs/experiment.md, where the
scheduled filter was 0.37-0.85 of the EKF's error with 30-90% of the frames lost and the held one
1.07-3.6, and its q2 1.006 against 1.14 with none lost); dc_motor_link 0.12, where the two
filters agree; unicycle and pvtol 0 (their L does not depend on σ)."""


def transition_swing(flat, ts: float, sigmas) -> float:
    """max over the flat outputs `sigmas` (rows) of |Φ(σ) - Φ₀| / |Φ₀ - I|: how far the scheduled
    predictor's transition leaves the held one's over those outputs, in units of the held one's
    own step (0 where L does not depend on σ)."""
    from dfeif_codegen.reference import predictor as predictors

    pred = predictors.make("scheduled", flat, ts, np.ones(flat.m))
    phi0 = np.asarray(pred.H.E, dtype=float)
    step = np.linalg.norm(phi0 - np.eye(len(phi0)))
    u = np.zeros(flat.m)
    return max(float(np.linalg.norm(np.asarray(pred.transition(np.concatenate([u, s])), dtype=float) - phi0)) / step
               for s in np.atleast_2d(sigmas))


def advice(swing: float) -> str:
    """What `codegen scenario` says of a transition that swings past SWING_ADVICE (else "")."""
    if swing <= SWING_ADVICE:
        return ""
    return (f"the covariance transition moves along this reference by up to {swing:.2g} times its own step (|Phi(sigma)"
            " - Phi0| / |Phi0 - I|): the held predictor's constant Phi0 follows it only near the nominal outputs; "
            "build with --predictor scheduled (and run codegen scenario --scheduled for its q): on the two-link arm "
            "(2.0) it was 0.37-0.85 of an EKF's error with camera frames lost, where the held one lost to the EKF")


def swing_along_reference(flat, spec: str, ts: float, shape=None) -> float:
    """transition_swing over the flat outputs of 24 instants of one period of the reference."""
    from dfeif_codegen.experiment import shapes

    heads = list(flat.heads)
    return transition_swing(flat, ts, [z[heads] for z, _ in shapes.along_reference(flat, spec, 24, shape)])


HOLD_SEEDS = 2   # closed loops the scheduled predictor must hold before it is advised


def lost_loop(loop) -> str | None:
    """Why the scheduled predictor loses one of the closed loops `loop(seed)` describes (seeds
    0 to HOLD_SEEDS - 1, simulate's divergence watch), or None where it holds them all."""
    loss = first_loss(dataclasses.replace(loop(s), predictor="scheduled", watch_nees=True) for s in range(HOLD_SEEDS))
    return loss and loss[1]


def note(flat, spec: str, ts: float, shape, progress, loop) -> list[str]:
    """A starting scenario's header note advising the scheduled predictor where its transition
    swings along the reference (`advice`) and it holds the scenario's own loops (`loop(seed)`:
    their settings, at the calibrated q), also said on `progress`; else nothing. Why the loops:
    a large swing says Φ₀ is wrong along the reference, not that Φ(σ), linearized at the nominal
    derivatives, is right (the tests' reluctance motor: it swings 4.4, and the scheduled filter's
    covariance grows threefold a step near θ = 0.07 and the loop is lost)."""
    said = advice(swing_along_reference(flat, spec, ts, shape))
    lost = said and lost_loop(loop)
    if lost:
        said = ""
        if progress:
            progress(f"note: the scheduled predictor lost its loop on this reference ({lost}): not advised")
    if said and progress:
        progress(f"note: {said}")
    return [f"# NOTE: {said}."] if said else []
