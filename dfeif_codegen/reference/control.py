"""Flatness-based tracking control (docs/mathematics.md section 6, docs/algorithms.md "Flatness-based
control"): a linear tracking law on each canonical chain gives `v`, and `u = G^-1 (v - F)` makes
the plant's `y^(r) = F + G u` equal to it, so the tracking error obeys a chosen linear ODE.
With the held-input predictor the law knows the plant holds u, not v, over a period: u is the
input whose held value gives each chain's top derivative the increment Ts v
(symbolic/sampling.py `held_input_sx`).
"""

from __future__ import annotations

from math import comb

import casadi as ca
import numpy as np

from dfeif_codegen.reference.linalg import wrap
from dfeif_codegen.symbolic import numeric, sampling


def hurwitz_gains(degree: int, lam: float) -> np.ndarray:
    """k_1..k_r of s^r + k_1 s^(r-1) + ... + k_r = (s + lam)^r, i.e. k_i = C(r, i) lam^i."""
    return np.array([comb(degree, i) * float(lam) ** i for i in range(1, degree + 1)])


class SingularControl(ArithmeticError):
    """G(x) is too close to singular for u = G^-1 (v - F) to mean anything (the C's ERR_SINGULAR)."""


SINGULAR_RTOL = 1e-6  # default of the build option --singular-rtol: same threshold as the C


class FlatController:
    """`poles`: one lam > 0 per chain (a scalar is broadcast), every pole of the chain's error
    ODE at -lam. Or explicit `gains`, length n, chain by chain `[k_1, ..., k_r]` (k_1 multiplies
    the highest derivative's error, k_r the output's error): the order the C kernel takes.
    Like the C: refuses (SingularControl) when |det G(x)| < singular_rtol * |det G(nominal)|, and
    clamps u to the inputs' declared limits, counting clamped inputs in `saturations`.
    `held`: the held predictor's constants (sampling.HeldSampling): u is then the input to hold
    over the period (module docstring); None: the chapter's u = G^-1 (v - F)."""

    def __init__(self, flat, poles=5.0, gains=None, singular_rtol=SINGULAR_RTOL, held=None):
        self.flat = flat
        self._held = None if held is None else _held_law(flat, held)
        self.singular_rtol = float(singular_rtol)
        self.saturations = 0
        self._det_nominal = None
        inputs = flat.model.inputs
        self.u_min = np.array([-np.inf if w.min is None else w.min for w in inputs])
        self.u_max = np.array([np.inf if w.max is None else w.max for w in inputs])
        if gains is None:
            lams = np.broadcast_to(np.asarray(poles, dtype=float), (flat.m,))
            if np.any(lams <= 0):
                raise ValueError("poles are lam > 0 (every pole at -lam)")
            gains = np.concatenate([hurwitz_gains(c.degree, lam) for c, lam in zip(flat.chains, lams)])
        self.gains = np.asarray(gains, dtype=float)
        if self.gains.shape != (flat.n,):
            raise ValueError(f"gains must have length n = {flat.n}, got shape {self.gains.shape}")

    def __call__(self, x, ref_flags, params=None, disturbance=None) -> tuple[np.ndarray, np.ndarray]:
        """(u, v) for the estimate `x` and reference flags, chain by chain [y_d, ..., y_d^(r)].
        `disturbance`: the filters' estimate d of what the model misses on each chain's top
        derivative (symbolic/disturbance.py), which enters where F does: u - G⁻¹ d then gives the
        plant's top derivatives what u gives the model (the offset cancelled, as an integral
        action would). In the held law too: its first stage sees d through S Γ₁ (G u + d), so the
        same shift cancels it there (not v - d, which S Γ₁ would scale)."""
        x, ref = np.asarray(x, dtype=float), np.asarray(ref_flags, dtype=float)
        if ref.shape != (self.flat.n + self.flat.m,):
            raise ValueError(f"ref_flags must have length n + m = {self.flat.n + self.flat.m}")
        v = np.empty(self.flat.m)
        for j, c in enumerate(self.flat.chains):
            flags = ref[c.offset + j:c.offset + j + c.degree + 1]
            e = x[c.offset:c.offset + c.degree] - flags[:c.degree]
            e[0] = wrap(e[0], c.angle)
            v[j] = flags[c.degree] - self.gains[c.offset:c.offset + c.degree][::-1] @ e
        G, F = self.flat.G_num(x, params), self.flat.F_num(x, params)
        if self._det_nominal is None:
            self._det_nominal = self.flat.nominal_det()
        if not np.all(np.isfinite(x)):
            raise SingularControl(f"x = {np.array2string(x, precision=4)}: the estimate the law is given has diverged")
        if not (np.all(np.isfinite(G)) and np.all(np.isfinite(F))):
            raise SingularControl(f"F(x), G(x) are not finite at x = {np.array2string(x, precision=4)}: the estimate "
                                  "the law is given has left the model's domain (its inverse transform is undefined "
                                  "there)")
        det = np.linalg.det(G)
        if not np.isfinite(det):
            raise SingularControl(f"det G(x) = {det:.3g} at x = {np.array2string(x, precision=4)}: the estimate the "
                                  "law is given has diverged")
        if not abs(det) >= self.singular_rtol * self._det_nominal:
            raise SingularControl(f"det G(x) = {det:.3g} is below {self.singular_rtol:g} of its nominal "
                                  f"{self._det_nominal:.3g} at x = {np.array2string(x, precision=4)}")
        if self._held is None:
            u = np.linalg.solve(G, v - F)
        else:
            u = np.array(self._held(x, v, self.flat.param_vector if params is None else params), dtype=float).reshape(-1)
        if disturbance is not None:
            u = u - np.linalg.solve(G, np.asarray(disturbance, dtype=float))
        if np.isfinite(self.u_min).any() or np.isfinite(self.u_max).any():
            clamped = np.clip(u, self.u_min, self.u_max)
            self.saturations += int(np.count_nonzero((u < self.u_min) | (u > self.u_max)))
            u, v = clamped, F + G @ clamped
        return u, v


_LAWS: dict[tuple, tuple] = {}


def _held_law(flat, H) -> numeric.Numeric:
    """(z, v, p) -> u of the held-input law, one CasADi function per flat system and period."""
    key = (id(flat), H.ts)
    if key not in _LAWS or _LAWS[key][0] is not flat:
        z, v, p = ca.SX.sym("z", flat.n), ca.SX.sym("v", flat.m), ca.SX.sym("p", len(flat.params))
        u, _ = sampling.held_input_sx(flat, H, z, v, p)
        _LAWS[key] = (flat, numeric.Numeric(ca.Function("held_input", [z, v, p], [u], {"cse": True})))
    return _LAWS[key][1]
