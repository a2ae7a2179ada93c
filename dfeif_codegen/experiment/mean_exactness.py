"""How exact the held predictor's mean is along a scenario's reference, at the model's
`mean_substeps` and at twice and four times as many: `codegen scenario` logs it, so a user sees
when one ETD2RK step per period, not the model, limits an exact model's filter
(docs/mathematics.md section 3, "More steps per period").

The error of a state is the root mean square, over the reference's states, of the mean's
one-step prediction minus the plant's (the plant started on the reference state and driven one
period by its feedforward input, as the residual of `codegen scenario`'s q), divided by the
root mean square of the plant's own change over that period: the fraction of each period's
change the mean gets wrong. The worst state's is reported.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import shapes
from dfeif_codegen.experiment.trajectory import flags
from dfeif_codegen.reference import predictor as predictors

POINTS = 400    # reference states the mean is tried from, spread over the reference's period
# Above this fraction of a period's change the mean is the exact model's main error: a
# parameter known to 1% moves the top derivative's change over a period by about 1%
ADVISE = 1e-2


class Steps(NamedTuple):
    """The plant's periods along a reference: started on each reference state, driven one
    period by that state's feedforward (rows: the reference's steps over its period)."""
    starts: np.ndarray    # canonical states
    tops: np.ndarray      # the feedforward's top derivatives v
    inputs: np.ndarray    # the feedforward's u
    ends: np.ndarray      # canonical states one period later


def reference_steps(flat, spec: str, ts: float, substeps: int, shape: shapes.Shape) -> Steps:
    """One period of the plant (`substeps` RK4 steps) from every reference state of `shape`:
    what `codegen scenario`'s residual q and this module's errors are measured on."""
    plant = ex._plant(spec, ts, substeps)
    refs = ex.references(ex.Config(model=spec, **shape.config()), flat.m)
    p = flat.param_vector
    rows = []
    for tk in np.arange(int(round(shape.period / ts)) + 1) * ts:
        z, top, u = shapes.feedforward(flat, flags(refs, flat.degrees, tk), p)
        rows.append((z, top, u, flat.phi_num(plant.step(flat.phi_inv_num(z, p), u), p)))
    return Steps(*(np.array(column) for column in zip(*rows)))


def with_substeps(flat, steps: int):
    """The same flat system with its mean in `steps` ETD2RK steps per period (no re-derivation)."""
    return dataclasses.replace(flat, model=dataclasses.replace(flat.model, mean_substeps=steps))


def one_step_errors(flat, ts: float, steps: Steps, counts) -> dict[int, float]:
    """Per number of ETD2RK steps in `counts`, the worst state's one-step error over a period's
    change (module docstring), from at most POINTS of `steps`."""
    pick = slice(None, None, max(1, len(steps.starts) // POINTS))
    starts, inputs, ends = steps.starts[pick], steps.inputs[pick], steps.ends[pick]
    change = np.sqrt(np.mean((ends - starts) ** 2, axis=0))
    out = {}
    for n in counts:
        mean = predictors.make("held", with_substeps(flat, n), ts, np.ones(flat.m)).mean
        miss = np.array([mean(z, u) for z, u in zip(starts, inputs)]) - ends
        rms = np.sqrt(np.mean(miss ** 2, axis=0))
        out[n] = float(np.max(rms / np.maximum(change, np.finfo(float).tiny)))
    return out


def line(flat, ts: float, steps: Steps) -> str:
    """The calibration log's line: the errors at the model's mean_substeps N, 2N and 4N, and
    advice where N's is above ADVISE."""
    n = flat.model.mean_substeps
    errors = one_step_errors(flat, ts, steps, (n, 2 * n, 4 * n))
    text = ("held mean's worst one-step error along the reference, as a fraction of a period's change: "
            + ", ".join(f"{e:.2g} at mean_substeps = {k}" for k, e in errors.items()))
    if errors[n] > ADVISE:
        better = [k for k, e in errors.items() if e <= ADVISE]
        text += (f" (above {ADVISE:g}: the mean limits the filter on an exact model; set [model] mean_substeps = "
                 f"{better[0] if better else 4 * n} in the model and run this command again)")
    return text
