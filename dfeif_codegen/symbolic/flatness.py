"""The flatness transform, derived from the model: Lie derivatives, relative degrees, the
decoupling matrix, the diffeomorphism `zeta = Phi(x)` and its inverse, and the canonical
(block-Brunovsky) form `y^(r) = F(zeta) + G(zeta) u` that every filter here runs on.
"""

from __future__ import annotations

import random
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
    """Random states (moderate magnitudes) with the parameters at their defaults."""
    rng = random.Random(1234)
    values = model.param_values
    return [{**values, **{xi: rng.uniform(-1.3, 1.3) for xi in model.x}} for _ in range(count)]


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


def _solve_inverse(model: Model, phi: sp.Matrix, zeta: list[sp.Symbol]) -> sp.Matrix:
    """Solve `Phi(x) = zeta` for x: one unknown at a time where the map is triangular, jointly
    otherwise; among several branches keep the one that round-trips at a test point."""
    x = list(model.x)
    equations = [sp.expand_func(phi_i - z) for phi_i, z in zip(phi, zeta)]
    solved: dict[sp.Symbol, sp.Expr] = {}
    pending = list(equations)
    point = _numeric_points(model, 1)[0]
    zeta_point = {z: phi_i.subs(point) for z, phi_i in zip(zeta, phi)}
    zeta_point.update(model.param_values)

    def pick(candidates: list[dict]) -> dict:
        for cand in candidates:
            ok = True
            for var, expr in cand.items():
                value = complex(sp.sympify(expr).evalf(subs=zeta_point))
                if not np.isfinite(value) or abs(value - complex(point[var])) > 1e-7 * (1 + abs(point[var])):
                    ok = False
            if ok:
                return cand
        raise ModelError(f"{model.where('outputs')}: Phi(x) = zeta has no solution branch through a "
                         "test point: the flat outputs do not determine the state")

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

    def _p(self, p) -> np.ndarray:
        return self.param_vector if p is None else p

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


def derive(model: Model) -> FlatSystem:
    """Derive the canonical form, or say in one line why the model is not flat in this sense."""
    x, f, g, n = model.x, model.f, model.g, model.n
    points = _numeric_points(model)
    _check_denominators(model, {f"dynamics.f.{s.name}": e for s, e in zip(model.states, f)}
                        | {f"dynamics.g.{u.name}": sum(g.col(j)) for j, u in enumerate(model.inputs)})
    chains, phi_rows, top_rows, decoupling, zeta = [], [], [], [], []
    offset = 0
    for out in model.outputs:
        derivs = [sp.sympify(out.expr)]
        while True:
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
    phi_inv = _solve_inverse(model, phi, zeta)
    back = dict(zip(x, phi_inv))
    F = sp.Matrix([_small_simplify(r.subs(back)) for r in top_rows])
    G = dec_x.subs(back).applyfunc(_small_simplify)
    _check_denominators(model, {f"Phi^-1.{s.name}": e for s, e in zip(model.states, phi_inv)}
                        | {"F-bar": sum(F), "G-bar": sum(G)})
    return FlatSystem(model, chains, zeta, phi, phi_inv, F, G, dec_x)
