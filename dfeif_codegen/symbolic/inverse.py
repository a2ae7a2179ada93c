"""Phi^-1: solving `Phi(x) = zeta` for the state, in forms defined where the robot operates.

Sympy solves `v cos(th) = x_1, v sin(th) = y_1` in half-angle forms, `th = -2 atan((x_1 -
sqrt(x_1^2 + y_1^2))/y_1)`, which are 0/0 at heading 0 and lose every digit in float32 near it.
A pair of equations in which an unknown angle appears only through its sine and cosine is
therefore solved for (sin, cos) first, with sin^2 + cos^2 = 1, and the angle taken as atan2 of
the two, the modulus as a square root of squares (printed as hypot). Every candidate branch is
kept only if it round-trips at states drawn from the declared domain, the nominal state among
them, in double precision and then in float32.
"""

from __future__ import annotations

import itertools

import numpy as np
import sympy as sp

from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic import numeric
from dfeif_codegen.symbolic.given_inverse import given_entries
from dfeif_codegen.symbolic.lie import domain_samples, interval, nominal_state
from dfeif_codegen.symbolic.model import Model


def node_count(expr, cap: int) -> int:
    """Nodes of expr's tree, counted up to `cap` (count_ops walks all of a huge one: stop there)."""
    for k, _ in enumerate(sp.preorder_traversal(expr)):
        if k >= cap:
            return cap
    return k + 1



def small_simplify(expr: sp.Expr, limit: int = 30) -> sp.Expr:
    """Simplify what is cheap to simplify; large expressions are left for CasADi's CSE. A tree of
    more than 40 nodes per allowed operation is large without counting its operations."""
    if node_count(expr, 40 * limit + 1) > 40 * limit or sp.count_ops(expr) > limit:
        return expr
    out = sp.simplify(expr)
    # simplify writes sign(x) as Piecewise((0, Eq(x, 0)), (x/Abs(x), True)): longer, and a
    # division by |x| that reads as a singular set where the model has none
    return expr if out.has(sp.Piecewise) and not expr.has(sp.Piecewise) else out


BRANCH_POINTS = 48  # round-trip test points on the domain for every candidate branch of Phi^-1
ROUND_TRIP = 1e-7   # |Phi^-1(Phi(x)) - x| <= 1e-7 (1 + |x|): a few hundred ulps of the composition,
                     # far above double rounding and far below a wrong branch's O(|x|) error


def evaluate(args: list, expr: sp.Expr, columns: np.ndarray) -> np.ndarray:
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
        got = evaluate(list(zeta), sp.sympify(expr).subs(params), zeta_rows)
        want = rows[:, index[var]]
        ok &= np.isfinite(got) & (np.abs(got - want) <= ROUND_TRIP * (1 + np.abs(want)))
    return ok


EPS32 = 2.0 ** -23   # float32 machine epsilon
NEAR_NOMINAL = 8     # test points within 1e-4 of the domain's width of the nominal state: where a 0/0
                     # form at the nominal point loses its digits


def _float32_trips(cand: dict, rows: np.ndarray, zeta_rows: np.ndarray, zeta: list, params: dict,
                   index: dict) -> np.ndarray:
    """Per test point: does this candidate, computed in float32 (every operation rounded), give
    back the state it came from as well as the problem allows? The allowance is 10 times how far
    rounding zeta to float32 alone moves the double result (the conditioning no form escapes) plus
    100 float32 ulps; a cancelling form (half-angle atan near heading 0) misses it by orders."""
    ok = np.ones(len(rows), dtype=bool)
    table = {z: np.asarray(c, dtype=np.float32) for z, c in zip(zeta, zeta_rows.T)}
    rng = np.random.default_rng(7)
    shaken = [zeta_rows * (1 + EPS32 * rng.uniform(-1, 1, zeta_rows.shape)) for _ in range(3)]
    for var, expr in cand.items():
        expr_p = sp.sympify(expr).subs(params)
        values = evaluate(list(zeta), expr_p, np.vstack([zeta_rows, *shaken])).reshape(len(shaken) + 1, -1)
        moved = np.max(np.abs(values[1:] - values[0]), axis=0)
        try:
            with np.errstate(all="ignore"):
                got = numeric.to_casadi(expr_p, table, str(var), numeric.Float32)
        except (ModelError, TypeError, ValueError):
            return np.zeros(len(rows), dtype=bool)
        got = np.broadcast_to(np.asarray(got, dtype=np.float32), (len(rows),))
        want = rows[:, index[var]]
        allowed = 10 * np.nan_to_num(moved, nan=np.inf) + 100 * EPS32 * (1 + np.abs(want))
        ok &= np.isfinite(got) & (np.abs(got.astype(float) - want) <= allowed)
    return ok


def _angles(eq_pair: list[sp.Expr], unknown: list[sp.Symbol]) -> sp.Symbol | None:
    """The unknown that appears in both equations only as sin(it) and cos(it), if any."""
    for th in unknown:
        if all(e.has(th) for e in eq_pair):
            trig = {f for e in eq_pair for f in e.atoms(sp.sin, sp.cos) if f.has(th)}
            bare = [e.subs({f: sp.Dummy() for f in trig}) for e in eq_pair]
            if trig and all(f.args[0] == th for f in trig) and not any(b.has(th) for b in bare):
                return th
    return None


def _squares(expr: sp.Expr) -> list[sp.Expr] | None:
    """Bases b_i with expr = sum b_i^2, found by completing the square one variable at a time
    (x^2 + z^2 + 2 g z + g^2 -> [x, z + g]); None when expr is not such a sum."""
    expr, bases = sp.expand(expr), []
    for v in sorted(expr.free_symbols, key=str):
        poly = sp.Poly(expr, v)
        if poly.degree() != 2:
            continue
        a, b, c = (poly.coeff_monomial(v**k) for k in (2, 1, 0))
        if a != 1:
            return None
        bases.append(v + b / 2)
        expr = sp.expand(c - b**2 / 4)
    return bases if expr == 0 and bases else None


def sum_of_squares_roots(expr: sp.Expr) -> sp.Expr:
    """Every sqrt(sum of squares) written as such, so that it is printed as hypot (no overflow or
    underflow of the squares in float32) and known to be non-negative."""
    def rewrite(e):
        bases = _squares(e.base)
        return sp.sqrt(sp.Add(*[b**2 for b in bases], evaluate=False)) if bases and len(bases) == 2 else e
    return expr.replace(lambda e: isinstance(e, sp.Pow) and abs(e.exp) == sp.Rational(1, 2),
                        lambda e: rewrite(e) if e.exp > 0 else 1 / rewrite(1 / e))


def _atan2(s: sp.Expr, c: sp.Expr) -> sp.Expr:
    """atan2(s, c) with a common positive denominator cancelled (atan2 is invariant under it)."""
    (sn, sd), (cn, cd) = sp.fraction(sp.together(s)), sp.fraction(sp.together(c))
    root = isinstance(sd, sp.Pow) and sd.exp == sp.Rational(1, 2)   # a principal square root: >= 0
    if sd == cd and (root or sd.is_nonnegative):
        return sp.atan2(sn, cn)
    if sd == cd and (-sd).is_nonnegative:
        return sp.atan2(-sn, -cn)
    return sp.atan2(s, c)


def polar_candidates(pair: list[sp.Expr], unknown: list[sp.Symbol], real: dict) -> list[dict] | None:
    """Branches of a pair of equations in an angle th (through sin/cos only) and at most one
    other unknown r: solved for (sin th, cos th, r) with sin^2 + cos^2 = 1, th = atan2(sin, cos).
    None when the pair has another shape. `real` maps symbols to real dummies (so that
    sqrt(a^2 + b^2) is known to be non-negative)."""
    th = _angles(pair, unknown)
    if th is None:
        return None
    others = [v for v in unknown if v != th and any(e.has(v) for e in pair)]
    if len(others) > 1:
        return None
    S, C = sp.Dummy("S", real=True), sp.Dummy("C", real=True)
    eqs = [e.subs({sp.sin(th): S, sp.cos(th): C}).subs(real) for e in pair] + [S**2 + C**2 - 1]
    try:
        roots = sp.solve(eqs, [S, C, *[real[v] for v in others]], dict=True)
    except NotImplementedError:
        return None
    back = {d: s for s, d in real.items()}
    out = []
    for r in roots:
        if S not in r or C not in r:
            continue
        cand = {th: sum_of_squares_roots(_atan2(r[S], r[C]).subs(back))}
        cand.update({v: sum_of_squares_roots(r[real[v]].subs(back)) for v in others if real[v] in r})
        if len(cand) == 1 + len(others):
            out.append(cand)
    return out or None


def domain_points(model: Model) -> np.ndarray:
    """BRANCH_POINTS states of the declared domain, the nominal state first (the point the robot
    is declared to operate at is always tested), then NEAR_NOMINAL states next to it."""
    rows = domain_samples(model, BRANCH_POINTS)
    nominal = rows[0] = nominal_state(model)
    lo, hi = np.array([interval(v) for v in model.states]).T
    near = nominal + 1e-4 * (hi - lo) * np.random.default_rng(5).uniform(-1, 1, (NEAR_NOMINAL, model.n))
    return np.vstack([rows, np.clip(near, lo, hi)])


SHOWN_LIMIT = 160   # characters of Phi^-1 a message quotes: a cubic's closed form runs to thousands


def _brief(text: str) -> str:
    """`text`, cut to SHOWN_LIMIT characters (marked) so that a message stays one readable line."""
    return text if len(text) <= SHOWN_LIMIT else text[:SHOWN_LIMIT - 4] + " ..."


def _declared_at(model: Model, i: int) -> tuple[str, str]:
    """Where the user declared state i (`file:line: key`) and its name."""
    return model.state_declared_at(i), model.states[i].name


def solve_inverse(model: Model, phi: sp.Matrix, zeta: list[sp.Symbol]) -> sp.Matrix:
    """Solve `Phi(x) = zeta` for x: one unknown at a time where the map is triangular, jointly
    otherwise. Where sympy returns several branches (a square root, an arcsine), keep the one
    that round-trips at every one of BRANCH_POINTS states of the declared domain; on an undeclared
    domain, refuse when more than one branch is valid somewhere (the sign would be a coin toss).
    Entries given in the model's [inverse] table are solved first (checked by the same round
    trips) and kept as written; the equations they answer are tried last."""
    x = list(model.x)
    pending = [sp.expand_func(phi_i - z) for phi_i, z in zip(phi, zeta)]
    rows = domain_points(model)
    real = {s: sp.Dummy(str(s), real=True) for s in list(x) + list(zeta) + list(model.p)}
    zeta_rows = np.column_stack([evaluate(x, e.subs(model.param_values), rows) for e in phi])
    index = {v: i for i, v in enumerate(x)}
    declared = {v: s.bounded for v, s in zip(x, model.states)}
    trip = (rows, zeta_rows, zeta, model.param_values, index)
    given = given_entries(model, zeta, rows, zeta_rows, lambda c: _round_trips(c, *trip),
                          lambda c: _float32_trips(c, *trip))
    solved: dict = {v: v for v in given}   # known, but kept a symbol until the end: the equations stay small

    def pick(candidates: list[dict]) -> dict:
        closed = [{v: sp.sympify(e).subs(solved).subs(given) for v, e in c.items()} for c in candidates]
        exact = [_round_trips(c, *trip) for c in closed]
        valid = [ok & _float32_trips(c, *trip) if ok.all() else ok for c, ok in zip(closed, exact)]
        everywhere = [c for c, ok in zip(candidates, valid) if ok.all()]
        somewhere = [c for c, ok in zip(candidates, valid) if ok.any()]
        names = ", ".join(sorted(str(v) for v in candidates[0])) if candidates else "?"
        shown = _brief(" | ".join(", ".join(f"{v} = {e}" for v, e in c.items()) for c in candidates))
        free = [str(v) for v in candidates[0] if not declared[v]] if candidates else []
        if free and len(somewhere) > 1:
            spots = [_declared_at(model, index[v]) for v in candidates[0] if not declared[v]]
            others = "".join(f" ({name}: {at})" for at, name in spots[1:])
            raise ModelError(f"{spots[0][0]}: Phi^-1 has several branches for {names} ({shown}) and "
                             f"{' and '.join(name for _, name in spots)} {'has' if len(spots) == 1 else 'have'} "
                             f"no declared domain{others}: add min/max to choose one")
        if everywhere:
            return everywhere[0]
        where_ = "its declared domain" if not free else "the test box [-1.3, 1.3]"
        at = model.where(f"states#{index[next(iter(candidates[0]))]}") if candidates else model.where("outputs")
        if any(ok.all() for ok in exact):   # exact in double: single precision's rounding is the trouble
            raise ModelError(f"{at}: Phi^-1 for {names} ({shown}) is exact in double precision but loses the "
                             f"state in single precision somewhere on {where_}: give {names} in a "
                             "better-conditioned form in [inverse]")
        raise ModelError(f"{at}: no branch of Phi^-1 for {names} ({shown}) is valid on all of "
                         f"{where_}: the flat outputs do not determine the state there")

    progress = True
    while pending and progress:
        progress = False
        for eq in sorted(pending, key=lambda e: bool(e.free_symbols & set(given))):  # given answer these: last
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
        if not progress:
            progress = _polar_step(pending, solved, x, real, pick)
    rest = [v for v in x if v not in solved]
    if rest:
        roots = _linear_roots([eq.subs(solved) for eq in pending], rest)
        try:
            roots = roots if roots is not None else sp.solve([eq.subs(solved) for eq in pending], rest, dict=True)
        except NotImplementedError:
            roots = []
        roots = [r for r in roots if all(v in r for v in rest)]
        if not roots:
            raise ModelError(f"{model.where('outputs')}: cannot invert Phi symbolically for "
                             f"{', '.join(map(str, rest))}")
        solved.update(pick(roots))
    return _back_substitute(x, solved | given, set(given))


def _back_substitute(x: list, solved: dict, given: set) -> sp.Matrix:
    """Phi^-1 with every entry a function of zeta only: the solved entries substituted into each
    other; simplified where small, except the given ones, kept as the user wrote them."""
    inverse, unknowns = [solved[v] for v in x], set(x)
    for _ in range(len(x)):   # only entries that still hold a state: subs walks the whole tree
        todo = [i for i, e in enumerate(inverse) if sp.sympify(e).free_symbols & unknowns]
        if not todo:
            break
        for i in todo:
            inverse[i] = sp.sympify(inverse[i]).subs(solved)
    return sp.Matrix([e if v in given else small_simplify(e) for v, e in zip(x, inverse)])


LINEAR_NODES = 2000  # equations larger than this (tree nodes) that are linear in the unknowns: LU


def _linear_roots(eqs: list, rest: list) -> list[dict] | None:
    """The one root of equations linear in the unknowns (A(known) rest = b), by an LU solve that
    forms no inverse and simplifies nothing (a fully coupled arm's currents from its accelerations:
    sympy's general solve took minutes where this takes milliseconds); None when not linear or
    not square. The round-trip test of the caller checks the result."""
    if len(eqs) != len(rest) or node_count(sp.Add(*eqs), LINEAR_NODES + 1) <= LINEAR_NODES:
        return None   # small systems: sympy's solve, whose simplified forms the built-ins' C keeps
    E = sp.Matrix(eqs)
    A = E.jacobian(rest)
    if any(a.has(r) for a in A for r in rest):
        return None
    try:
        sol = A.LUsolve(-E.subs({r: 0 for r in rest}))
    except (ValueError, ZeroDivisionError, sp.matrices.common.NonInvertibleMatrixError):
        return None
    return [dict(zip(rest, sol))]


def _polar_step(pending: list, solved: dict, x: list, real: dict, pick) -> bool:
    """Solve the first pair of pending equations that polar_candidates can; True if one was."""
    for e1, e2 in itertools.combinations(list(pending), 2):
        pair = [e1.subs(solved), e2.subs(solved)]
        unknown = [v for v in x if v not in solved and any(e.has(v) for e in pair)]
        candidates = polar_candidates(pair, unknown, real)
        if candidates:
            solved.update(pick(candidates))
            pending.remove(e1)
            pending.remove(e2)
            return True
    return False



SINGULAR_OPS = 400  # symbolic det for `inspect` only when the decoupling matrix is this small (display only)


def singular_sets(flat) -> list[str]:
    """Where the transform stops being defined, for `inspect`: the decoupling matrix's determinant
    (when it is small enough to form), atan2's with both arguments zero and denominators of
    Phi^-1, f-bar and g-bar. Display only: nothing is decided on these expressions."""
    out = []
    dec = flat.decoupling_x
    if dec.shape[0] <= 3 and sum(sp.count_ops(e) for e in dec) <= SINGULAR_OPS:
        det = sp.factor(sp.simplify(dec.det(method="berkowitz")))
        if sp.fraction(sp.together(det))[0].free_symbols & set(flat.model.x):
            out.append(f"decoupling matrix singular where det = {det} = 0")
    seen, variables = set(), set(flat.zeta) | set(flat.model.x)
    named = [(f"Phi^-1.{s.name}", e) for s, e in zip(flat.model.states, flat.phi_inv)]
    named += [(f"f_bar[{c.output}]", e) for c, e in zip(flat.chains, flat.F)]
    named += [(f"g_bar[{i},{j}]", flat.G[i, j]) for i in range(flat.m) for j in range(flat.m)]
    for key, expr in named:
        for sub in sp.preorder_traversal(sp.sympify(expr)):
            if isinstance(sub, sp.atan2) and ("atan2", sub.args) not in seen:
                seen.add(("atan2", sub.args))
                out.append(f"{key} undefined where {sub.args[0]} = {sub.args[1]} = 0 ({sub})")
            elif isinstance(sub, sp.Pow) and sub.exp.is_negative and sub.base.free_symbols & variables \
                    and ("den", sub.base) not in seen:
                seen.add(("den", sub.base))
                out.append(f"{key} undefined where {sub.base} = 0")
    return out


NEAR_SINGULAR = 1e-3   # inspect warns where |det G| falls below this fraction of its nominal value
DOMAIN_POINTS = 512    # states of the declared domain the warning looks at


def near_singular(flat) -> list[str]:
    """Warnings for `inspect`: where inside the declared domain the decoupling matrix's
    determinant (g-bar for one input) changes sign, is undefined, or falls below NEAR_SINGULAR
    of its nominal value, with the worst sampled state. Sampled, so a warning is certain and its
    absence is evidence only."""
    from dfeif_codegen.symbolic.lie import Sampler

    sampler = Sampler(flat.model, DOMAIN_POINTS)
    values = sampler.values(list(flat.decoupling_x)).reshape(-1, flat.m, flat.m)
    with np.errstate(all="ignore"):
        det = np.array([np.linalg.det(a) if np.all(np.isfinite(a)) else np.nan for a in values])
    name = "g_bar" if flat.m == 1 else "det G"
    nominal, out = abs(det[0]), []
    if not np.isfinite(nominal) or nominal == 0:
        return [f"{name} is zero or undefined at the nominal state"]

    def at(k: int) -> str:
        return ", ".join(f"{s.name} = {v:.4g}" for s, v in zip(flat.model.states, sampler.rows[k]))
    bad = ~np.isfinite(det)
    if bad.any():
        out.append(f"{name} is undefined inside the declared domain, e.g. at {at(int(np.argmax(bad)))}")
    finite = np.where(bad, np.nan, det)
    if np.nanmin(finite) < 0 < np.nanmax(finite):
        k = int(np.nanargmin(np.abs(finite)))
        out.append(f"{name} changes sign inside the declared domain, so it is zero somewhere in it; smallest "
                   f"|{name}| = {abs(finite[k]):.3g} (nominal {nominal:.3g}) at {at(k)}")
    elif np.nanmin(np.abs(finite)) < NEAR_SINGULAR * nominal:
        k = int(np.nanargmin(np.abs(finite)))
        out.append(f"|{name}| = {abs(finite[k]):.3g} at {at(k)}, below {NEAR_SINGULAR:g} of its nominal "
                   f"{nominal:.3g}: the control is near singular there")
    return out

