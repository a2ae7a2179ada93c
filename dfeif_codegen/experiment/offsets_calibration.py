"""`codegen scenario --offsets NAME,...`: the [offsets] table of the comparison's offset filter
(reference/offsets.py), tuned on the loops the disturbance calibration runs under the model
error (disturbance_calibration.py).

Each named offset's prior std is the drawn error's own; the chains' white density is scaled
until the offset filter's master NEES on those loops is n (nees_match.match_nees). Why its own
density: with the parameters estimated, what is left for the chains' noise is less than the held
filter's white part (q = 1 left the motor's NEES at 1.4 where n = 3).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.experiment import compare
from dfeif_codegen.experiment.disturbance_calibration import mean_nees
from dfeif_codegen.experiment.nees_match import NO_LOOP
from dfeif_codegen.reference.offsets import Offsets


def from_option(flat, names: str, plant_error) -> Offsets:
    """--offsets NAME,...: an Offsets for those parameters of `flat`'s model, each one's prior std
    the relative error `plant_error` gives it (the draw's std, or its fixed offset's size);
    ScenarioError naming a parameter the model lacks or the error leaves alone (nothing to
    calibrate on)."""
    params = [p.strip() for p in names.split(",")]
    if not all(params) or len(set(params)) != len(params):
        raise ScenarioError(f"--offsets {names}: give distinct parameter names separated by commas")
    try:
        where = Offsets(tuple(params), (1.0,)).indices(flat)
    except ValueError as exc:
        raise ScenarioError(f"--offsets: {exc}") from None
    size = plant_error.stds(flat.model)
    std = [float(f"{size[i]:.4g}") for i in where]
    still = [p for p, s in zip(params, std) if s <= 0]
    if still:
        raise ScenarioError(f"--offsets: --param-error leaves {', '.join(still)} at the model's value: "
                            "no error of it to calibrate on")
    return Offsets(tuple(params), tuple(std))


def nees(results: list, offsets: Offsets) -> float:
    """The offset filter's master NEES over the recordings (inf if it fails on one)."""
    return mean_nees(results, lambda res: compare.evaluate(res, compare.OFFSETS, offsets=offsets))


def chains_q(q, loops: list, offsets: Offsets, match, log: list[str]) -> tuple[Offsets, list[str]]:
    """(the Offsets with `chains_q` calibrated, log): scaled from the held filter's white `q`
    until the offset filter's master NEES on `loops` is n; `match(q, log, nees)` is
    nees_match.match_nees with its NEES measure."""
    def at(cq):
        return dataclasses.replace(offsets, chains_q=tuple(float(v) for v in np.atleast_1d(cq)))
    cq, log = match(np.asarray(q, dtype=float), log, lambda cq: nees(loops, at(cq)))
    if NO_LOOP in log[-1]:
        raise ScenarioError(f"--offsets {','.join(offsets.params)}: the offset filter failed or diverged on the "
                            "calibration's loops at every scale of its chains' q tried; estimate fewer parameters")
    log[-1] = "the offset filter's chains: " + log[-1]
    return at(cq), log


def table(offsets: Offsets, model, plant_error) -> list[str]:
    """The scenario's [offsets] lines, with a comment naming the parameters the error moves that
    no offset estimates (their part stays in chains_q, on average only)."""
    left = [q.name for q, e in zip(model.parameters, plant_error.stds(model)) if e > 0 and q.name not in offsets.params]
    note = [f"# NOTE: the error also moves {', '.join(left)}, which no offset estimates: that part",
            "# stays in chains_q, and a run drawn far off there is over-confident (docs/experiment.md)"] if left else []
    return ["# the offset filter of simulate --filters offsets (reference only): the named parameters'",
            "# relative offsets as constant states, prior std their error's; chains_q: the",
            "# chains' white density, scaled so that its master's NEES averages n", *note,
            "[offsets]", f"params = {json.dumps(list(offsets.params))}", f"std = {_numbers(offsets.std)}",
            f"q = {offsets.q:g}", f"chains_q = {_numbers(offsets.chains_q)}", ""]


def _numbers(values) -> str:
    """A TOML list of numbers to four significant digits."""
    return json.dumps([float(f"{v:.4g}") for v in values])
