"""F-bar and G-bar in the form single precision computes best (used by symbolic/flatness.py).

F-bar is the plant's top derivative with Phi^-1(zeta) substituted for the state. Where Phi^-1
gives a state as a flat output plus a small correction (a flexible joint's motor angle
q2 = (I q1'' + k q1 + MgL sin q1) / k), the plant's spring term k (q1 - q2) becomes a difference
of two nearly equal numbers: it keeps the rounding of q1 and loses the spring's deflection, and
k^2 / (I Jm) multiplies what is left (measured on the flexible joint of tests/test_user_models.py:
F-bar 6.3e-6 of its largest value from its double value in float32, the float build's node
estimates 2.5e-3 from the double reference's; rewritten, 1.3e-7 and 2.8e-4, and the double
build's master 3.8e-11 -> 2.4e-12; on a two-link elastic arm F-bar 3.4e-5 and 8.5e-5 -> 2.7e-7
and 4.2e-7 for 4% and 7% more instructions, its double build's nodes 1.4e-10 -> 1.8e-12).

The rewriting (`cancel_sums`) visits every sum of the tree from the leaves up and replaces it by
its expansion, or by the expansion of its numerator over a common denominator, where that is
shorter: a cancellation the symbols can do shows as a shorter sum (q1 - (I q1'' + k q1 + MgL sin
q1) / k -> -(I q1'' + MgL sin q1) / k), and a sum that nothing cancels in gets longer and is
kept. Expanding the whole entry instead would do it too, at 2.5-3.3 times the instructions on a
two-link elastic arm (the arm's F-bar grows six-fold). The rewritten entry is kept only where it
is measured better: computed in float32, every operation rounded, at canonical states at least
GAIN times nearer its double value, and at most GROWTH times as many CasADi instructions.

The canonical states: Phi of states drawn from the declared domain (inverse.domain_points), and
the same flat outputs with every derivative drawn from [-1, 1] (near-steady motion, where the
flexible joint's spring deflection is small against its angle; states from the domain swing the
motor and the link apart by radians, where nothing cancels).
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from dfeif_codegen.symbolic import numeric
from dfeif_codegen.symbolic.inverse import domain_points, evaluate, node_count

GAIN = 4.0            # float32 error of the form substituted over the rewritten one's, at least
GROWTH = 1.5          # CasADi instructions of the rewritten form over the substituted one's, at most
SUM_MAX_NODES = 400   # larger sums are not rewritten (their expansion is what grows an arm's F-bar)


def canonical_points(model, phi, chains, seed: int = 11) -> list[np.ndarray]:
    """The two sets of canonical states of the module docstring (rows with a non-finite entry
    dropped): `phi` (Phi, in the states of `model`) at the domain's states, and their flat
    outputs with derivatives from [-1, 1]."""
    rows = domain_points(model)
    zeta_rows = np.column_stack([evaluate(list(model.x), e.subs(model.param_values), rows) for e in phi])
    slow = np.array(zeta_rows, dtype=float)
    rng = np.random.default_rng(seed)
    for c in chains:
        slow[:, c.offset + 1:c.offset + c.degree] = rng.uniform(-1.0, 1.0, (len(slow), c.degree - 1))
    return [z[np.all(np.isfinite(z), axis=1)] for z in (zeta_rows, slow)]


def float32_error(expr: sp.Expr, zeta: list, model, point_sets: list[np.ndarray]) -> float:
    """The largest distance of expr computed in float32 (parameters as float32 numbers, as the
    float build's constants) from its double value, relative to the largest |value| of each set
    of canonical states; 0 where it is nowhere finite."""
    params = list(model.p)
    values = [model.param_values[p] for p in params]
    worst = 0.0
    for rows in point_sets:
        if not len(rows):
            continue
        exact = evaluate(list(zeta) + params, expr, np.hstack([rows, np.tile(values, (len(rows), 1))]))
        table = {z: rows[:, i].astype(np.float32) for i, z in enumerate(zeta)}
        table.update({p: np.full(len(rows), v, dtype=np.float32) for p, v in zip(params, values)})
        with np.errstate(all="ignore"):
            single = np.broadcast_to(np.asarray(numeric.to_casadi(expr, table, "F-bar", numeric.Float32),
                                                dtype=float), (len(rows),))
        ok = np.isfinite(exact) & np.isfinite(single)
        scale = np.max(np.abs(exact[ok]), initial=0.0)
        if scale > 0:
            worst = max(worst, float(np.max(np.abs(single[ok] - exact[ok]))) / scale)
    return worst


def cancel_sums(expr: sp.Expr) -> sp.Expr:
    """expr with each sum of at most SUM_MAX_NODES nodes replaced, from the leaves up, by its
    expansion or its numerator's expansion over the common denominator, whichever has the
    fewest nodes when fewer than the sum's (module docstring)."""
    done: dict = {}

    def visit(e: sp.Expr) -> sp.Expr:
        if e in done:
            return done[e]
        out = e
        if e.args:
            args = [visit(a) for a in e.args]
            if any(a is not b for a, b in zip(args, e.args)):
                out = e.func(*args)
            size = node_count(out, SUM_MAX_NODES + 1) if out.is_Add else SUM_MAX_NODES + 1
            if size <= SUM_MAX_NODES:
                num, den = sp.fraction(sp.together(out))
                for form in (sp.expand(out), sp.expand(num) / den):
                    shorter = node_count(form, size)
                    if shorter < size:
                        out, size = form, shorter
        done[e] = out
        return out
    return visit(expr)


def instructions(expr: sp.Expr, zeta: list, model) -> int:
    """CasADi instructions of expr after common-subexpression elimination (what the C runs)."""
    return numeric.sx_function("form", [list(zeta), list(model.p)], [expr]).n_instructions()


def better_conditioned(expr: sp.Expr, zeta: list, model, point_sets: list[np.ndarray]) -> sp.Expr:
    """expr, or `cancel_sums(expr)` where that is measured better in float32 (module docstring)."""
    if expr.is_Number:
        return expr
    rewritten = cancel_sums(expr)
    if rewritten == expr or instructions(rewritten, zeta, model) > GROWTH * instructions(expr, zeta, model):
        return expr
    before, after = (float32_error(e, zeta, model, point_sets) for e in (expr, rewritten))
    return rewritten if before > 0 and after * GAIN <= before else expr
