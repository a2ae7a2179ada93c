"""The flatness transform, derived from the model: Lie derivatives, relative degrees, the
decoupling matrix, the diffeomorphism `zeta = Phi(x)` and its inverse, and the canonical
(block-Brunovsky) form `y^(r) = F(zeta) + G(zeta) u` that every filter here runs on.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import sympy as sp

from dfeif_codegen import angles
from dfeif_codegen.symbolic import conditioning, discretize, extension, lie, numeric
from dfeif_codegen.symbolic.inverse import ROUND_TRIP, small_simplify, solve_inverse
from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic.lie import domain_samples, nominal_state  # noqa: F401  (re-exported)
from dfeif_codegen.symbolic.model import Model


@dataclass(frozen=True)
class Chain:
    """One flat output's chain of integrators inside the canonical state."""

    output: str
    degree: int
    offset: int
    angle: bool


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
    decoupling_x: sp.Matrix  # the same matrix in the (extended) states
    physical: Model | None = None          # the model as written (model is its dynamic extension)
    extension: "extension.Extension | None" = None  # the integrators added; none when steps is empty

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
                             f"nominal state ({', '.join(f'{v:g}' for v in nominal_state(self.model))}): declare a 'nominal' where it is not")
        return det

    def undefined_at(self, zeta_rows, singular_rtol: float = 1e-6) -> tuple[int, str] | None:
        """First row where Phi^-1 is undefined (not finite) or leaves the declared domain, saying so
        with the Phi^-1 entry responsible, or where the decoupling matrix is singular (|det G| below
        singular_rtol times its nominal value, where the C control refuses); None when every row
        maps to a state in the domain with G invertible. det G changing sign between two rows is
        a singular set crossed between them, however small |det G| is on either side: the row
        after the crossing is named."""
        zeta_rows = np.atleast_2d(np.asarray(zeta_rows, dtype=float))
        with np.errstate(all="ignore"):
            x = np.array([self.phi_inv_num(z) for z in zeta_rows])
        for i, var in enumerate(self.model.states):
            lo = -np.inf if var.min is None else var.min
            hi = np.inf if var.max is None else var.max
            bad = ~np.isfinite(x[:, i]) | (x[:, i] < lo) | (x[:, i] > hi)
            if bad.any():
                k = int(np.argmax(bad))
                return k, (f"Phi^-1 is undefined: {var.name} = {self.phi_inv[i]} = {x[k, i]:.6g} "
                           f"(domain [{lo:g}, {hi:g}])")
        with np.errstate(all="ignore"):
            signed = np.array([np.linalg.det(self.G_num(z)) for z in zeta_rows])
        det = np.abs(signed)
        bad = ~np.isfinite(det) | (det < singular_rtol * self.nominal_det())
        crossed = np.append(False, np.sign(signed[1:]) * np.sign(signed[:-1]) < 0)
        if bad.any() or crossed.any():
            k = int(np.argmax(bad | crossed))
            if crossed[k] and not bad[k]:
                return k, (f"the decoupling matrix is singular between this sample and the one before (det G "
                           f"changes sign, {signed[k - 1]:.3g} to {signed[k]:.3g}; see the singular sets in "
                           "`codegen inspect`)")
            return k, (f"the decoupling matrix is singular (|det G| = {det[k]:.3g}, below {singular_rtol:g} "
                       f"times its nominal {self.nominal_det():.3g}; see the singular sets in `codegen inspect`)")
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


def _say(model: Model, progress):
    """progress(text) with the model's largest expression named (the likely culprit of a stop)."""
    if not progress:
        return lambda text: None
    named = {f"dynamics.f.{v.name}": e for v, e in zip(model.states, model.f)}
    named |= {f"dynamics.g.{u.name}.{v.name}": model.g[i, j] for j, u in enumerate(model.inputs)
              for i, v in enumerate(model.states) if model.g[i, j] != 0}
    named |= {f"outputs.{o.name}": o.expr for o in model.outputs}
    worst = max(named, key=lambda k: sp.count_ops(named[k]))
    return lambda text: progress(f"{text}; largest expression {model.where(worst)}")


def _check_recover(model: Model) -> None:
    """[measurement.recover] must give each flat output back from what the cameras observe:
    recover(observe(x)) = h(x) at sampled states of the domain (modulo 2 pi for an angle), to
    the inverse's round-trip tolerance. A wrong one builds and runs, and every filter then
    fuses a measurement of something else and diverges with no hint why."""
    meas = model.measurement
    if meas is None:
        return
    seen = {sp.Symbol(k): e for k, e in meas.observe.items()}
    sampler = lie.Sampler(model)
    got = sampler.values([sp.sympify(meas.recover[o.name]).xreplace(seen) for o in model.outputs])
    want = sampler.values([o.expr for o in model.outputs])
    for j, out in enumerate(model.outputs):
        diff = got[:, j] - want[:, j]
        diff = angles.wrap_np(diff) if out.angle else diff
        bad = np.isfinite(want[:, j]) & ~(np.abs(diff) <= ROUND_TRIP * (1 + np.abs(want[:, j])))
        if bad.any():
            k = int(np.argmax(bad))
            state = ", ".join(f"{v.name} = {sampler.rows[k, i]:.4g}" for i, v in enumerate(model.states))
            raise ModelError(f"{model.where(f'measurement.recover.{out.name}')}: does not give the flat output "
                             f"{out.name} back from the observed channels: at {state} it gives {got[k, j]:.6g}, "
                             f"{out.name} = {want[k, j]:.6g}")


def derive(model: Model, progress=None) -> FlatSystem:
    """Derive the canonical form, or say in one line why the model is not flat in this sense.
    A singular decoupling matrix is cured by a dynamic extension where one exists (see
    extension.py); the flat system is then that of the extended model. `progress(text)` is told
    each stage (the budget in dfeif_codegen.budget names it on a stop)."""
    say = _say(model, progress)
    _check_denominators(model, {f"dynamics.f.{s.name}": e for s, e in zip(model.states, model.f)}
                        | {f"dynamics.g.{u.name}": sum(model.g.col(j)) for j, u in enumerate(model.inputs)})
    physical = model
    model, ext, io = extension.extend(physical, say)
    _check_recover(physical)   # after the relative degrees: an output that is not flat says that first
    x = model.x
    chains, zeta, offset = [], [], 0
    for out, degree in zip(model.outputs, io.degrees):
        chains.append(Chain(out.name, degree, offset, out.angle))
        zeta += [sp.Symbol(f"{out.name}_{k}") for k in range(degree)]
        offset += degree
    clash = {str(z) for z in zeta} & {s.name for s in model.states + model.parameters}
    if clash:
        raise ModelError(f"{model.where('outputs')}: canonical state names {sorted(clash)} clash with model names")
    phi = sp.Matrix([d for chain in io.derivs for d in chain])
    say("solving Phi(x) = zeta for the state (Phi^-1)")
    phi_inv = solve_inverse(model, phi, zeta)
    say("substituting Phi^-1 into F-bar and G-bar")
    back = dict(zip(x, phi_inv))
    # xreplace: one structural pass (subs pattern-matches every node: minutes on a coupled arm)
    F = sp.Matrix([small_simplify(sp.sympify(r).xreplace(back)) for r in io.top])
    G = io.decoupling.xreplace(back).applyfunc(small_simplify)
    say("choosing the forms of F-bar and G-bar that single precision computes best")
    points = conditioning.canonical_points(model, phi, chains)
    F, G = (part.applyfunc(lambda e: conditioning.better_conditioned(e, zeta, model, points)) for part in (F, G))
    _check_denominators(model, {f"Phi^-1.{s.name}": e for s, e in zip(model.states, phi_inv)}
                        | {"F-bar": sum(F), "G-bar": sum(G)})
    return FlatSystem(model, chains, zeta, phi, phi_inv, F, G, io.decoupling, physical, ext)
