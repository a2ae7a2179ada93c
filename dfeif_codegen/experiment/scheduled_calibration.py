"""`codegen scenario --scheduled`: the q of the comparison's scheduled filter
(reference/scheduled.py), `q_scheduled` in [filter].

Scaled from the held filter's calibrated q until the scheduled filter's master NEES, re-filtering
the calibration's loops without delays (closed by the held filter at its q, as simulate's are),
is n. Why its own q: a transition that follows the configuration leaves less for q to cover
(on the two-link arm a q about 300 times smaller: docs/experiment.md).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare
from dfeif_codegen.experiment.disturbance_calibration import mean_nees
from dfeif_codegen.experiment.nees_match import NEES_SECONDS, NO_LOOP, match_nees


def check_option(scheduled: bool, disturbance) -> None:
    """--scheduled with the other options: the scheduled filter has no disturbance states."""
    if scheduled and disturbance is not None:
        raise ScenarioError("--scheduled: not with --disturbance (the scheduled filter has no disturbance states)")


def nees(loops: list, q) -> float:
    """The scheduled filter's master NEES at `q` over the recordings (inf if it fails on one)."""
    qs = tuple(float(v) for v in np.atleast_1d(q))
    return mean_nees(loops, lambda res: compare.evaluate(
        dataclasses.replace(res, config=dataclasses.replace(res.config, q_scheduled=qs)), compare.SCHEDULED))


def q_scheduled(flat, q, config, seeds, log: list[str], say) -> tuple[np.ndarray, list[str]]:
    """(the scheduled filter's q, log): the loops `config(q, seed, NEES_SECONDS)` of `seeds`,
    re-filtered at a q scaled from the held filter's `q` until the master's NEES is n (no floor:
    this filter closes no loop)."""
    say(f"the scheduled filter: q scaled until its NEES on {len(seeds)} loops of the held filter is n")
    loops = [ex.run(config(q, s, NEES_SECONDS)) for s in seeds]
    found, log = match_nees(flat, np.asarray(q, dtype=float), None, seeds, log, lambda qq: nees(loops, qq),
                            floor=None, progress=say)
    if NO_LOOP in log[-1]:
        raise ScenarioError(f"--scheduled: the scheduled filter failed or diverged on the calibration's loops at "
                            f"every scale of q tried (from {list(np.atleast_1d(q))})")
    log[-1] = "the scheduled filter: " + log[-1]
    return found, log
