"""Lie derivatives, relative degrees and the decoupling matrix, decided on numbers.

Whether `L_g L_f^k h` vanishes and what rank the decoupling matrix has are questions about
functions of the state; answering them symbolically (a determinant, `simplify(...) == 0`) can take
longer than everything else together for a fully coupled arm. Here they are answered in double
precision at states drawn from the declared domain (the nominal state first), the parameters at
their values; the symbolic expressions are formed only where they are used (Phi, f-bar, g-bar).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic import numeric
from dfeif_codegen.symbolic.model import Model

DECIDE_POINTS = 16   # sampled states at which relative degrees and the decoupling rank are decided
ZERO_TOL = 1e-9      # |value| <= ZERO_TOL at every sampled state: identically zero. A function that is
                     # zero evaluates to rounding noise (~1e-16 times its terms' size, far below 1e-9 for
                     # a declared domain's magnitudes); one that is not exceeds 1e-9 at 16 random states
                     # except on a set of measure zero
RANK_RTOL = 1e-9     # singular values below RANK_RTOL * the largest count as zero (same reasoning)


def lie(expr: sp.Expr, field: sp.Matrix, x: sp.Matrix) -> sp.Expr:
    """The Lie derivative of `expr` along the vector field `field`."""
    return sum((sp.diff(expr, xi) * fi for xi, fi in zip(x, field)), sp.Integer(0))


def interval(var) -> tuple[float, float]:
    """Where to sample a state: its declared [min, max] (a one-sided bound gets a width of 2.6,
    or twice the distance to the nominal point), else [-1.3, 1.3]."""
    lo, hi = var.min, var.max
    if lo is None and hi is None:
        return -1.3, 1.3
    width = 2.6 if var.nominal is None else max(2.6, 2 * abs(var.nominal - (lo if lo is not None else hi)))
    lo = hi - width if lo is None else lo
    hi = lo + width if hi is None else hi
    pad = 1e-6 * (hi - lo)  # stay off the boundary, where a square root's argument is 0
    return lo + pad, hi - pad


def nominal_state(model: Model) -> np.ndarray:
    """The declared nominal state; a state without one sits at its domain's centre (0 if free)."""
    out = []
    for v in model.states:
        lo, hi = interval(v)
        out.append(v.nominal if v.nominal is not None else 0.0 if not v.bounded else 0.5 * (lo + hi))
    return np.array(out, dtype=float)


def domain_samples(model: Model, count: int, seed: int = 1234) -> np.ndarray:
    """`count` states drawn uniformly from the declared domain (the nominal state first)."""
    rng = np.random.default_rng(seed)
    lo, hi = np.array([interval(v) for v in model.states]).T
    rows = lo + (hi - lo) * rng.random((max(count, 1), model.n))
    if any(v.nominal is not None for v in model.states):
        rows[0] = nominal_state(model)
    return rows


class Sampler:
    """Expressions in a model's states and parameters evaluated at DECIDE_POINTS sampled states
    (row 0 the nominal state), the parameters at their values, in double precision."""

    def __init__(self, model: Model, count: int = DECIDE_POINTS):
        self.model = model
        self.rows = domain_samples(model, count)
        self.rows[0] = nominal_state(model)
        self.params = np.array([q.value for q in model.parameters], dtype=float)

    def values(self, exprs) -> np.ndarray:
        """(points, len(exprs)) values; nan where an expression is undefined."""
        exprs = [sp.sympify(e) for e in exprs]
        f = numeric.sx_function("decide", [list(self.model.x), list(self.model.p)], exprs)
        with np.errstate(all="ignore"):
            out = np.asarray(f.map(len(self.rows))(self.rows.T, self.params), dtype=float)
        return out.reshape(len(exprs), len(self.rows)).T

    @staticmethod
    def zero(values: np.ndarray) -> np.ndarray:
        """Per point (row): every entry finite and within ZERO_TOL."""
        return np.all(np.isfinite(values) & (np.abs(values) <= ZERO_TOL), axis=-1)


def rank(matrix: np.ndarray) -> int:
    """Numeric rank of one matrix (singular values above RANK_RTOL times the largest); -1 where it
    is not finite (undefined at that state)."""
    if not np.all(np.isfinite(matrix)):
        return -1
    sv = np.linalg.svd(matrix, compute_uv=False)
    return int(np.sum(sv > RANK_RTOL * max(sv[0], ZERO_TOL))) if sv.size else 0


@dataclass
class IOStructure:
    """Per flat output its derivatives up to the relative degree, and the decoupling matrix."""

    degrees: list[int]
    derivs: list[list[sp.Expr]]   # per output [h, L_f h, ..., L_f^(r-1) h]
    top: list[sp.Expr]            # per output L_f^r h
    decoupling: sp.Matrix         # row i: L_g L_f^(r_i - 1) h_i
    samples: np.ndarray           # the decoupling matrix at the sampled states, (points, m, m)
    rank: int                     # its rank at generic states (the largest seen)
    nominal: np.ndarray           # the sampled states' row 0: the nominal state

    def check_nominal(self, model: Model) -> None:
        """Refuse an output whose input row vanishes at the nominal state (but not elsewhere):
        its relative degree is not defined there."""
        for out, deg, row in zip(model.outputs, self.degrees, self.samples[0]):
            if np.all(np.isfinite(row) & (np.abs(row) <= ZERO_TOL)):
                at = ", ".join(f"{s.name} = {v:g}" for s, v in zip(model.states, self.nominal))
                raise ModelError(f"{model.where('outputs')}: the relative degree of '{out.name}' is not defined "
                                 f"at the nominal state ({at}): the inputs enter its derivative {deg} elsewhere "
                                 "but not there; declare a 'nominal' where they do")


def structure(model: Model, sampler: Sampler, say=lambda text: None) -> IOStructure:
    """Relative degrees and the decoupling matrix, each decided at the sampled states (an input
    enters a derivative when it does at any of them)."""
    x, f, g, n = model.x, model.f, model.g, model.n
    degrees, derivs, top, rows, samples = [], [], [], [], []
    for out in model.outputs:
        chain = [sp.sympify(out.expr)]
        while True:
            say(f"differentiating flat output '{out.name}' ({model.where('outputs')}) {len(chain)} time(s)")
            row = [lie(chain[-1], g.col(j), x) for j in range(model.m)]
            say(f"testing whether input enters '{out.name}' at derivative {len(chain)} "
                f"({len(sampler.rows)} sampled states)")
            values = sampler.values(row)
            zero = Sampler.zero(values)
            if not zero.all():
                break
            if len(chain) >= n:
                raise ModelError(f"{model.where('outputs')}: output '{out.name}' has no input in its first {n} "
                                 "derivatives (relative degree too high / g-bar identically zero): not flat")
            chain.append(lie(chain[-1], f, x))
        degrees.append(len(chain))
        derivs.append(chain)
        top.append(lie(chain[-1], f, x))
        rows.append(row)
        samples.append(values)
    stack = np.stack(samples, axis=1)  # (points, m, m)
    say(f"testing the decoupling matrix's rank at {len(sampler.rows)} sampled states")
    generic = max(rank(a) for a in stack)
    return IOStructure(degrees, derivs, top, sp.Matrix(rows), stack, generic, sampler.rows[0])
