"""The step in which the C moves the flat outputs' centre (docs/algorithms.md, "Centred storage").

The C stores each flat output relative to a centre that moves in exact steps, so that single
precision resolves the output to the step's size rather than to its distance from 0. A step of
1/8 suits outputs that swing over radians or metres; an output that lives on millimetres (a
levitated ball's gap of 5-30 mm) stored within 1/16 of its centre is resolved no finer than it
would be absolutely, and the filter turns that resolution into derivative noise (measured: a
float master 1.9e-4 from the reference at 1/8, 4.2e-5 at 1/1024). So each output's step follows
the range the model declares for it: the largest power of two at most 1/16 of it, and never
above 1/8. A power of two keeps every shift exact.
"""

from __future__ import annotations

import math

import numpy as np
import sympy as sp

from dfeif_codegen.symbolic.lie import Sampler

COARSEST = 0.125     # the step of an output without a declared range (and the largest)
FINEST = 2.0 ** -40  # a range narrower than 16 of these is taken as a typo, not a scale
PARTS = 16           # the step is at most this fraction of the output's declared range


def output_ranges(model) -> list[float | None]:
    """Per flat output, the width of its values over the declared domain (sampled), or None
    where a state it depends on lacks a min or a max."""
    states = {sp.Symbol(s.name): s for s in model.states}
    sampler = Sampler(model, 256)
    values = sampler.values([o.expr for o in model.outputs])
    out: list[float | None] = []
    for j, o in enumerate(model.outputs):
        expr = sp.sympify(o.expr)
        used = [states[s] for s in expr.free_symbols if s in states]
        if not used or any(s.min is None or s.max is None for s in used):
            out.append(None)
            continue
        if expr in states:    # the state itself: its declared range, exactly
            width = float(used[0].max - used[0].min)
        else:
            v = values[:, j][np.isfinite(values[:, j])]
            width = float(v.max() - v.min()) if v.size else 0.0
        out.append(width if width > 0 else None)
    return out


def centre_steps(model) -> list[float]:
    """Per flat output, its centre's step: a power of two, at most COARSEST and at most
    1/PARTS of its declared range (never below FINEST, which single precision still holds as a
    normal number with room to spare). Each output has its own, so that a spinning angle beside
    a millimetre-scale gap keeps its coarse step and its 2^20 steps of centred range."""
    out = []
    for width in output_ranges(model):
        step = COARSEST if width is None else min(COARSEST, 2.0 ** math.floor(math.log2(width / PARTS)))
        out.append(max(step, FINEST))
    return out
