"""The flatness transform, derived from the model: Lie derivatives, relative degrees, the
decoupling matrix, the diffeomorphism `zeta = Phi(x)` and its inverse, and the canonical
(block-Brunovsky) form `y^(r) = F(zeta) + G(zeta) u` that every filter here runs on.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import sympy as sp

from dfeif_codegen.symbolic import discretize, numeric
from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic.model import Model

_ZERO_TOL = 1e-9


@dataclass(frozen=True)
class Chain:
    """One flat output's chain of integrators inside the canonical state."""

    output: str
    degree: int
    offset: int
    angle: bool


def _lie(expr: sp.Expr, field: sp.Matrix, x: sp.Matrix) -> sp.Expr:
    return sum((sp.diff(expr, xi) * fi for xi, fi in zip(x, field)), sp.Integer(0))


def _numeric_points(model: Model, count: int = 6) -> list[dict]:
    """Random states inside the declared domain (moderate magnitudes where none is declared),
    the parameters at their defaults."""
    values = model.param_values
    box = domain_samples(model, count)
    return [{**values, **dict(zip(model.x, row))} for row in box]


def _interval(var) -> tuple[float, float]:
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
        lo, hi = _interval(v)
        out.append(v.nominal if v.nominal is not None else 0.0 if not v.bounded else 0.5 * (lo + hi))
    return np.array(out, dtype=float)


def domain_samples(model: Model, count: int, seed: int = 1234) -> np.ndarray:
    """`count` states drawn uniformly from the declared domain (the nominal state first)."""
    rng = np.random.default_rng(seed)
    lo, hi = np.array([_interval(v) for v in model.states]).T
    rows = lo + (hi - lo) * rng.random((max(count, 1), model.n))
    if any(v.nominal is not None for v in model.states):
        rows[0] = nominal_state(model)
    return rows


def _is_zero(expr: sp.Expr, points: list[dict]) -> bool:
    """Identically zero? Exact for the easy cases, else probabilistic identity testing."""
    expr = sp.sympify(expr)
    if expr == 0:
        return True
    if not expr.free_symbols:
        return sp.simplify(expr) == 0
    for point in points:
        try:
            value = complex(expr.evalf(subs=point))
        except (TypeError, ValueError, ZeroDivisionError):
            return False
        if not np.isfinite(value) or abs(value) > _ZERO_TOL:
            return False
    return True


def _small_simplify(expr: sp.Expr, limit: int = 30) -> sp.Expr:
    """Simplify what is cheap to simplify; large expressions are left for CasADi's CSE."""
    return sp.simplify(expr) if sp.count_ops(expr) <= limit else expr


BRANCH_POINTS = 48  # round-trip test points on the domain for every candidate branch of Phi^-1
_ROUND_TRIP = 1e-7   # |Phi^-1(Phi(x)) - x| <= 1e-7 (1 + |x|): a few hundred ulps of the composition,
                     # far above double rounding and far below a wrong branch's O(|x|) error


def _evaluate(args: list, expr: sp.Expr, columns: np.ndarray) -> np.ndarray:
    """A sympy expression at many points at once (one row per point), through the one
    sympy -> CasADi bridge; nan where undefined (a square root of a negative number, a log of
    zero) or where the expression is not real (a candidate branch with I in it)."""
    try:
        f = numeric.sx_function("candidate", [list(args)], [expr])
    except (ModelError, TypeError, ValueError):
        return np.full(len(columns), np.nan)
    with np.errstate(all="ignore"):
        value = np.asarray(f.map(len(columns))(np.asarray(columns, dtype=float).T), dtype=float)
    return value.reshape(-1)


def _round_trips(cand: dict, rows: np.ndarray, zeta_rows: np.ndarray, zeta: list, params: dict,
                 index: dict) -> np.ndarray:
    """Per test point: does this candidate give back the state it came from?"""
    ok = np.ones(len(rows), dtype=bool)
    for var, expr in cand.items():
        got = _evaluate(list(zeta), sp.sympify(expr).subs(params), zeta_rows)
        want = rows[:, index[var]]
        ok &= np.isfinite(got) & (np.abs(got - want) <= _ROUND_TRIP * (1 + np.abs(want)))
    return ok


def _solve_inverse(model: Model, phi: sp.Matrix, zeta: list[sp.Symbol]) -> sp.Matrix:
    """Solve `Phi(x) = zeta` for x: one unknown at a time where the map is triangular, jointly
    otherwise. Where sympy returns several branches (a square root, an arcsine), keep the one
    that round-trips at every one of BRANCH_POINTS states of the declared domain; on an undeclared
    domain, refuse when more than one branch is valid somewhere (the sign would be a coin toss)."""
    x = list(model.x)
    equations = [sp.expand_func(phi_i - z) for phi_i, z in zip(phi, zeta)]
    solved: dict[sp.Symbol, sp.Expr] = {}
    pending = list(equations)
    rows = domain_samples(model, BRANCH_POINTS)
    zeta_rows = np.column_stack([_evaluate(x, e.subs(model.param_values), rows) for e in phi])
    index = {v: i for i, v in enumerate(x)}
    declared = {v: s.bounded for v, s in zip(x, model.states)}

    def pick(candidates: list[dict]) -> dict:
        closed = [{v: sp.sympify(e).subs(solved) for v, e in c.items()} for c in candidates]
        valid = [_round_trips(c, rows, zeta_rows, zeta, model.param_values, index) for c in closed]
        everywhere = [c for c, ok in zip(candidates, valid) if ok.all()]
        somewhere = [c for c, ok in zip(candidates, valid) if ok.any()]
        names = ", ".join(sorted(str(v) for v in candidates[0])) if candidates else "?"
        shown = " | ".join(", ".join(f"{v} = {e}" for v, e in c.items()) for c in candidates)
        free = [str(v) for v in candidates[0] if not declared[v]] if candidates else []
        if free and len(somewhere) > 1:
            at = model.where(f"states#{index[next(iter(candidates[0]))]}")
            raise ModelError(f"{at}: Phi^-1 has several branches for {names} ({shown}) and "
                             f"{', '.join(free)} has no declared domain: add min/max to the state to choose one")
        if everywhere:
            return everywhere[0]
        where_ = "its declared domain" if not free else "the test box [-1.3, 1.3]"
        at = model.where(f"states#{index[next(iter(candidates[0]))]}") if candidates else model.where("outputs")
        raise ModelError(f"{at}: no branch of Phi^-1 for {names} ({shown}) is valid on all of "
                         f"{where_}: the flat outputs do not determine the state there")

    progress = True
    while pending and progress:
        progress = False
        for eq in list(pending):
            eq_sub = eq.subs(solved)
            unknown = [v for v in x if v not in solved and eq_sub.has(v)]
            if len(unknown) == 1:
                var = unknown[0]
                try:
                    roots = sp.solve(eq_sub, var, dict=True)
                except NotImplementedError:
                    continue
                if roots:
                    solved[var] = pick([{var: r[var]} for r in roots if var in r])[var]
                    pending.remove(eq)
                    progress = True
            elif not unknown:
                pending.remove(eq)
                progress = True
    rest = [v for v in x if v not in solved]
    if rest:
        try:
            roots = sp.solve([eq.subs(solved) for eq in pending], rest, dict=True)
        except NotImplementedError:
            roots = []
        roots = [r for r in roots if all(v in r for v in rest)]
        if not roots:
            raise ModelError(f"{model.where('outputs')}: cannot invert Phi symbolically for "
                             f"{', '.join(map(str, rest))}")
        solved.update(pick(roots))
    # back-substitute until every entry is a function of zeta only
    inverse = sp.Matrix([solved[v] for v in x])
    for _ in range(len(x)):
        inverse = inverse.subs(solved)
    return inverse.applyfunc(_small_simplify)


def _check_denominators(model: Model, named: dict[str, sp.Expr]) -> None:
    """A parameter value that zeroes a denominator is reported with the parameter and the field."""
    values = model.param_values
    for key, expr in named.items():
        for sub in sp.preorder_traversal(expr):
            if isinstance(sub, sp.Pow) and sub.exp.is_negative:
                base = sub.base
                if base.free_symbols and base.free_symbols <= set(values) and float(base.subs(values)) == 0.0:
                    params = ", ".join(f"{s} = {values[s]:g}" for s in sorted(base.free_symbols, key=str))
                    raise ModelError(f"{model.where(key)}: parameter value(s) {params} make the "
                                     f"denominator {base} zero")


@dataclass
class FlatSystem:
    """The model in canonical coordinates. `zeta` is ordered chain by chain:
    [y1, y1', ..., y1^(r1-1), y2, ...], named `<output>_<k>` (k-th derivative)."""

    model: Model
    chains: list[Chain]
    zeta: list[sp.Symbol]
    phi: sp.Matrix          # zeta = Phi(x), in the states and parameters
    phi_inv: sp.Matrix      # x = Phi^-1(zeta)
    F: sp.Matrix            # y^(r) = F(zeta) + G(zeta) u  (f-bar, one row per output)
    G: sp.Matrix            # decoupling matrix in zeta (g-bar)
    decoupling_x: sp.Matrix  # the same matrix in the physical states

    @property
    def n(self) -> int:
        return len(self.zeta)

    @property
    def m(self) -> int:
        return len(self.chains)

    @property
    def degrees(self) -> list[int]:
        return [c.degree for c in self.chains]

    @property
    def heads(self) -> list[int]:
        """Index in zeta of each measured flat output (C = e_head per chain)."""
        return [c.offset for c in self.chains]

    @property
    def params(self) -> list[sp.Symbol]:
        return self.model.p

    @property
    def param_vector(self) -> np.ndarray:
        return np.array([q.value for q in self.model.parameters], dtype=float)

    # continuous and discrete canonical matrices ----------------------------------------------
    def canonical(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return discretize.brunovsky(self.degrees)

    def discrete(self, ts: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A_d, B_d, C_d of the exact zero-order-hold discretization."""
        return discretize.discrete(self.degrees, ts)

    def process_noise(self, ts: float, q) -> np.ndarray:
        """Q_d for white noise of density q (scalar or one per chain) on each chain's input."""
        return discretize.process_noise(self.degrees, ts, q)

    # numeric functions (numpy), parameters as a vector in model order -------------------------
    @cached_property
    def _numeric(self) -> dict[str, numeric.Numeric]:
        """F, G, Phi, Phi^-1 through the CasADi bridge the generated C is printed from."""
        z, p, x = self.zeta, self.params, list(self.model.x)
        return {"F": numeric.Numeric.of("F", [z, p], self.F), "G": numeric.Numeric.of("G", [z, p], self.G),
                "phi": numeric.Numeric.of("phi", [x, p], self.phi),
                "phi_inv": numeric.Numeric.of("phi_inv", [z, p], self.phi_inv)}

    def F_num(self, zeta, p=None) -> np.ndarray:
        return self._numeric["F"](zeta, self._p(p)).reshape(self.m)

    def G_num(self, zeta, p=None) -> np.ndarray:
        return self._numeric["G"](zeta, self._p(p)).reshape(self.m, self.m)

    def phi_num(self, x, p=None) -> np.ndarray:
        return self._numeric["phi"](x, self._p(p)).reshape(self.n)

    def phi_inv_num(self, zeta, p=None) -> np.ndarray:
        return self._numeric["phi_inv"](zeta, self._p(p)).reshape(self.n)

    def nominal_det(self) -> float:
        """|det G| at the model's nominal state and parameters: the scale 'near singular' is
        measured against (the C control and the reference refuse below a fraction of it)."""
        zeta = self.phi_num(nominal_state(self.model))
        with np.errstate(all="ignore"):
            det = abs(float(np.linalg.det(self.G_num(zeta)))) if np.all(np.isfinite(zeta)) else float("nan")
        if not np.isfinite(det) or det == 0.0:
            raise ModelError(f"{self.model.where('states')}: the decoupling matrix G is singular or undefined at the "
                             f"nominal state {list(nominal_state(self.model))}: declare a 'nominal' where it is not")
        return det

    def undefined_at(self, zeta_rows) -> tuple[int, str] | None:
        """First row where Phi^-1 is undefined (not finite) or leaves the declared domain, with the
        Phi^-1 entry responsible; None when every row maps to a state in the domain."""
        zeta_rows = np.atleast_2d(np.asarray(zeta_rows, dtype=float))
        with np.errstate(all="ignore"):
            x = np.array([self.phi_inv_num(z) for z in zeta_rows])
        for i, var in enumerate(self.model.states):
            lo = -np.inf if var.min is None else var.min
            hi = np.inf if var.max is None else var.max
            bad = ~np.isfinite(x[:, i]) | (x[:, i] < lo) | (x[:, i] > hi)
            if bad.any():
                k = int(np.argmax(bad))
                return k, f"{var.name} = {self.phi_inv[i]} = {x[k, i]:.6g} (domain [{lo:g}, {hi:g}])"
        return None

    def _p(self, p) -> np.ndarray:
        """Parameters as a vector in model order: None or {} are the defaults, a dict overrides
        by name (python-control's flatsys passes `params={}`), a sequence is taken as it is."""
        if p is None or isinstance(p, dict):
            given = dict(p or {})
            unknown = set(given) - {q.name for q in self.model.parameters}
            if unknown:
                raise ValueError(f"unknown parameter(s) {', '.join(sorted(unknown))} of model {self.model.name}")
            return np.array([float(given.get(q.name, q.value)) for q in self.model.parameters])
        return np.asarray(p, dtype=float)

    # python-control flatsys form --------------------------------------------------------------
    def forward(self, x, u, params=None) -> list[np.ndarray]:
        """State and input to flat flags: per output [y, y', ..., y^(r)] (python-control's
        `flatsys` convention)."""
        zeta = self.phi_num(x, params)
        top = self.F_num(zeta, params) + self.G_num(zeta, params) @ np.atleast_1d(u)
        return [np.append(zeta[c.offset:c.offset + c.degree], top[j]) for j, c in enumerate(self.chains)]

    def reverse(self, zflag, params=None) -> tuple[np.ndarray, np.ndarray]:
        """Flat flags to state and input: `u = G^-1 (y^(r) - F)`."""
        zeta = np.concatenate([np.asarray(zflag[j], float)[:c.degree] for j, c in enumerate(self.chains)])
        top = np.array([float(zflag[j][c.degree]) for j, c in enumerate(self.chains)])
        u = np.linalg.solve(self.G_num(zeta, params), top - self.F_num(zeta, params))
        return self.phi_inv_num(zeta, params), u


def derive(model: Model, progress=None) -> FlatSystem:
    """Derive the canonical form, or say in one line why the model is not flat in this sense.
    `progress(text)` is told each stage (the budget in dfeif_codegen.budget names it on a stop)."""
    x, f, g, n = model.x, model.f, model.g, model.n
    if progress:  # a stop on the budget names the model's largest expression, the likely culprit
        named = {f"dynamics.f.{v.name}": e for v, e in zip(model.states, f)}
        named |= {f"outputs.{o.name}": o.expr for o in model.outputs}
        worst = max(named, key=lambda k: sp.count_ops(named[k]))
        say = lambda text: progress(f"{text}; largest expression {model.where(worst)}")  # noqa: E731
    else:
        say = lambda text: None  # noqa: E731
    points = _numeric_points(model)
    _check_denominators(model, {f"dynamics.f.{s.name}": e for s, e in zip(model.states, f)}
                        | {f"dynamics.g.{u.name}": sum(g.col(j)) for j, u in enumerate(model.inputs)})
    chains, phi_rows, top_rows, decoupling, zeta = [], [], [], [], []
    offset = 0
    for out in model.outputs:
        derivs = [sp.sympify(out.expr)]
        while True:
            say(f"differentiating flat output '{out.name}' ({model.where('outputs')}) {len(derivs)} time(s)")
            row = [_lie(derivs[-1], g.col(j), x) for j in range(model.m)]
            if not all(_is_zero(e, points) for e in row):
                break
            if len(derivs) >= n:
                raise ModelError(f"{model.where('outputs')}: output '{out.name}' has no input in its first {n} "
                                 "derivatives (relative degree too high / g-bar identically zero): not flat")
            derivs.append(_lie(derivs[-1], f, x))
        degree = len(derivs)
        chains.append(Chain(out.name, degree, offset, out.angle))
        phi_rows += derivs
        top_rows.append(_lie(derivs[-1], f, x))
        decoupling.append(row)
        zeta += [sp.Symbol(f"{out.name}_{k}") for k in range(degree)]
        offset += degree
    if offset != n:
        raise ModelError(f"{model.where('outputs')}: relative degrees {[c.degree for c in chains]} sum to "
                         f"{offset}, not n = {n}: the flat outputs leave internal dynamics (not flat)")
    clash = {str(z) for z in zeta} & {s.name for s in model.states + model.parameters}
    if clash:
        raise ModelError(f"{model.where('outputs')}: canonical state names {sorted(clash)} clash with model names")
    dec_x = sp.Matrix(decoupling)
    det = dec_x.det(method="berkowitz") if model.m > 1 else dec_x[0, 0]
    if _is_zero(det, points):
        raise ModelError(f"{model.where('dynamics.g')}: the decoupling matrix is singular (det = 0): "
                         "the inputs cannot steer the flat outputs independently (not flat)")
    phi = sp.Matrix(phi_rows)
    say("solving Phi(x) = zeta for the state (Phi^-1)")
    phi_inv = _solve_inverse(model, phi, zeta)
    say("substituting Phi^-1 into F-bar and G-bar")
    back = dict(zip(x, phi_inv))
    F = sp.Matrix([_small_simplify(r.subs(back)) for r in top_rows])
    G = dec_x.subs(back).applyfunc(_small_simplify)
    _check_denominators(model, {f"Phi^-1.{s.name}": e for s, e in zip(model.states, phi_inv)}
                        | {"F-bar": sum(F), "G-bar": sum(G)})
    return FlatSystem(model, chains, zeta, phi, phi_inv, F, G, dec_x)
