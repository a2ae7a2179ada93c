"""Build-time constants of the held-input predictor: the canonical dynamics linearized once, and
the matrices of its exact sampling (docs/mathematics.md section 3).

The plant holds u over a period, so the canonical state obeys ζ̇ = A_c ζ + B_c (F(ζ) + G(ζ) u)
with u constant. With L₀ = ∂(F + G u)/∂ζ at one nominal point and A = A_c + B_c L₀, the mean is
stepped by the second-order exponential integrator ETD2RK (Cox and Matthews 2002) on the
remainder n(ζ, u) = F(ζ) + G(ζ) u - L₀ ζ (what A leaves out; it enters through B_c only):

    a  = E ζ + Γ₁ n(ζ, u),     ζ⁺ = a + Γ₂ (n(a, u) - n(ζ, u)),

with E = e^{A Ts}, Γ₁ = Ts φ₁(A Ts) B_c, Γ₂ = Ts φ₂(A Ts) B_c. Since E = I + Ψ A with
Ψ = Ts φ₁(A Ts), the first stage is a = ζ + Ψ (A_c ζ + B_c (F(ζ) + G(ζ) u)): an increment, the
vector field through Ψ, which is how both the reference and the C compute it (E ζ and Γ₁ L₀ ζ
are large and cancel where the plant has a fast mode, which single precision cannot afford).
The covariance moves by the
constant transition Φ₀ = E and Q₀ = Σ_j q_j U_j, U_j the Van Loan integral of unit white noise
on chain j's top derivative through A. Everything here is computed once, in double, by matrix
exponentials of augmented matrices: no Jacobian at run time.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import factorial, ldexp

import casadi as ca
import numpy as np
import sympy as sp

from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic import numeric
from dfeif_codegen.symbolic.flatness import nominal_state

PREDICTORS = ("held", "scheduled", "brunovsky")
"""`held` (the default): the mean integrated with u held as the plant holds it, and the control
law that knows it (`held_input_sx`); `scheduled`: the held mean, its covariance moved by Φ(σ) at
the master's broadcast flat outputs σ (`scheduled_transition_sx`) instead of Φ₀; `brunovsky`: the chapter's exact model of the canonical chain
with v = F + G u held instead, and its law u = G⁻¹(v - F). Held, the plant's tracking error on
dc_motor_link drops 2.4x on θ, 5x on θ', 9x on θ'' without delays and up to 150x with them
(docs/experiment.md)."""
DEFAULT = "held"


def for_method(predictor: str | None, oosm: str) -> str:
    """`predictor`, or when None the one a late-measurement method works with: Brunovsky for
    retrodiction (the only one it can use), else the default."""
    return predictor or ("brunovsky" if oosm == "retrodict" else DEFAULT)


def expm(M: np.ndarray) -> np.ndarray:
    """e^M of a small matrix by scaling and squaring a Taylor series: the argument is scaled to a
    norm below 1/8, where 18 terms leave a truncation error below 1e-30 of the result, then
    squared back. Rounding is that of the squarings (~ 2^s ε), ample for build-time constants
    of the sizes used here (tests compare with scipy.linalg.expm)."""
    M = np.asarray(M, dtype=float)
    norm = np.max(np.sum(np.abs(M), axis=1)) if M.size else 0.0
    s = max(0, int(np.ceil(np.log2(norm * 8.0))) if norm > 0 else 0)
    X = M * ldexp(1.0, -s)
    out, term = np.eye(len(M)), np.eye(len(M))
    for k in range(1, 19):
        term = term @ X / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out


def phi_matrices(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """E = e^{A h}, h φ₁(A h) B and h φ₂(A h) B from one exponential of the augmented matrix
    [[A, B, 0], [0, 0, I], [0, 0, 0]] h: its blocks (0,1) and (0,2) are ∫₀ʰ e^{A(h-s)} B ds =
    h φ₁ B and ∫₀ʰ e^{A(h-s)} B s ds = h² φ₂ B."""
    n, m = B.shape
    M = np.zeros((n + 2 * m, n + 2 * m))
    M[:n, :n], M[:n, n:n + m], M[n:n + m, n + m:] = A, B, np.eye(m)
    X = expm(M * h)
    return X[:n, :n], X[:n, n:n + m], X[:n, n + m:] / h


def van_loan(A: np.ndarray, b: np.ndarray, h: float) -> np.ndarray:
    """∫₀ʰ e^{A s} b bᵀ e^{Aᵀ s} ds for unit white noise entering through the column b: Van
    Loan's exponential over a span t = h / 2^s short enough that ‖A t‖ ≤ 1, then s doublings
    Q(2t) = Q(t) + e^{A t} Q(t) e^{Aᵀ t}. Van Loan over the whole span would exponentiate -A h,
    which a fast stable mode makes huge (e^{500 · 0.32} for the motor's current over 32 periods),
    and lose every digit of Q to cancellation; the doublings only add positive terms."""
    n = len(A)
    norm = np.max(np.sum(np.abs(A), axis=1)) * h
    s = max(0, int(np.ceil(np.log2(norm)))) if norm > 0 else 0
    t = h * ldexp(1.0, -s)
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -A, np.outer(b, b), A.T
    X = expm(M * t)
    Q, E = X[n:, n:].T @ X[:n, n:], X[n:, n:].T
    for _ in range(s):
        Q = Q + E @ Q @ E.T
        E = E @ E
    return (Q + Q.T) / 2


@dataclass(frozen=True)
class HeldSampling:
    """The constants of the held-input predictor at one period `ts` (see the module docstring).
    `zeta0`, `u0`: the point L₀ was taken at."""

    ts: float
    zeta0: np.ndarray
    u0: np.ndarray
    L0: np.ndarray         # (m, n)
    Bc: np.ndarray         # (n, m)
    Ac: np.ndarray         # the linear part without L₀: A_c (with disturbance states, their drift too)
    A: np.ndarray          # A_c + B_c L₀
    E: np.ndarray          # e^{A Ts} = Φ₀
    Psi: np.ndarray        # Ts φ₁(A Ts): E = I + Ψ A
    G1: np.ndarray         # Ts φ₁(A Ts) B_c = Ψ B_c
    G2: np.ndarray         # Ts φ₂(A Ts) B_c
    U: np.ndarray          # (m [+ m], N, N): Q₀ per unit density of each chain [and disturbance]
    noise: np.ndarray      # (N, m [+ m]): the columns the white noises enter through
    steps: int = 1         # ETD2RK steps the mean takes per period (the model's mean_substeps)
    sub: "HeldSampling | None" = None   # the constants at ts / steps that each of them uses

    def Q(self, q, qd=None) -> np.ndarray:
        """Q₀ for densities q (a scalar or one per chain) and qd, the disturbance states' (if any)."""
        m = self.Bc.shape[1]
        qs = np.broadcast_to(np.asarray(q, dtype=float), (m,))
        if len(self.U) > m:
            qs = np.concatenate([qs, np.broadcast_to(np.asarray(qd, dtype=float), (len(self.U) - m,))])
        return np.einsum("j,jab->ab", qs, self.U)

    def ahead(self, steps: int) -> "HeldSampling":
        """The same linearization over `steps` periods: E = Φ₀^steps and the noise of that span."""
        return assemble(self.Ac, self.Bc, self.L0, self.zeta0, self.u0, steps * self.ts, self.noise)


def assemble(Ac, Bc, L0, zeta0, u0, ts, noise=None, steps: int = 1) -> HeldSampling:
    """The constants for the linear part A = A_c + B_c L₀ at period ts; white noise of unit
    density enters through each column of `noise` (default B_c: each chain's top derivative);
    with `steps` > 1 the mean's ETD2RK steps' at ts / steps too."""
    A = Ac + Bc @ L0
    noise = Bc if noise is None else noise
    E, G1, G2 = phi_matrices(A, Bc, ts)
    Psi = phi_matrices(A, np.eye(len(A)), ts)[1]
    U = np.array([van_loan(A, noise[:, j], ts) for j in range(noise.shape[1])])
    sub = assemble(Ac, Bc, L0, zeta0, u0, ts / steps, noise) if steps > 1 else None
    return HeldSampling(float(ts), np.asarray(zeta0, float), np.asarray(u0, float), L0, Bc, Ac, A, E, Psi, G1, G2, U,
                        noise, steps, sub)


def augmented(flat, L0, dist) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(A_c, B_c, L₀, noise columns) of the canonical state followed by the disturbance states
    (symbolic/disturbance.py): the first m enter the chains' top derivatives, the white noise
    drives the last m (the d's themselves, or the integrated random walk's rates); without
    `dist`, the plain ones."""
    Ac, Bc, _ = flat.canonical()
    if dist is None:
        return Ac, Bc, L0, Bc
    n, m = Bc.shape
    nd = dist.order * m
    A = np.zeros((n + nd, n + nd))
    A[:n, :n], A[:n, n:n + m], A[n:, n:] = Ac, Bc, dist.drift(m)
    B = np.vstack([Bc, np.zeros((nd, m))])
    L = np.hstack([L0, np.zeros((m, nd))])
    noise = np.hstack([B, np.vstack([np.zeros((n + nd - m, m)), np.eye(m)])])
    return A, B, L, noise


def remainder_sx(flat, z, u, p, trig=None) -> ca.SX:
    """F(ζ) + G(ζ) u at z (`trig`: how sin and cos are computed, numeric.to_casadi)."""
    table = {s: z[i] for i, s in enumerate(flat.zeta)} | {s: p[i] for i, s in enumerate(flat.params)}
    F = ca.vertcat(*[numeric.to_casadi(flat.F[j], table, f"F-bar[{j}]", trig=trig) for j in range(flat.m)])
    G = ca.SX(flat.m, flat.m)
    for i in range(flat.m):
        for j in range(flat.m):
            G[i, j] = numeric.to_casadi(flat.G[i, j], table, f"G-bar[{i},{j}]", trig=trig)
    return F + ca.mtimes(G, u)


def remainder_function(flat) -> ca.Function:
    """(ζ, u, p) -> F(ζ) + G(ζ) u, and its Jacobian in ζ, as one CasADi function."""
    z, u, p = ca.SX.sym("z", flat.n), ca.SX.sym("u", flat.m), ca.SX.sym("p", len(flat.params))
    top = remainder_sx(flat, z, u, p)
    return ca.Function("top", [z, u, p], [top, ca.jacobian(top, z)])


class TrigCarry:
    """sin and cos in ETD2RK's second stage from the first stage's, by angle addition:
    sin(α + δ) = sin α cos δ + cos α sin δ (cos alike), α an argument at the stage's start z,
    α + δ the same argument at a = z + d, and sin δ, cos δ by their Taylor polynomials through
    δ¹¹ and δ¹². Why: a trigonometric model otherwise pays two libm calls per argument and step
    (97 instructions each for the motor's sincos on x86-64 glibc, more in software on a
    Cortex-M4F) where these polynomials cost 24 operations. δ is the argument's change over
    one period's first stage: the truncation, below |δ|¹³/13! (2.4e-18 at |δ| ≤ 0.25 rad, below
    rounding; 2e-13 at 0.6 rad, a rotation sampled 10 times a turn), is far below ETD2RK's own
    local error at such steps. Both stages go through this one graph, so the reference and the
    C compute the same thing (docs/mathematics.md section 3)."""

    SIN = tuple((-1) ** k / factorial(2 * k + 1) for k in range(6))   # δ, δ³, ..., δ¹¹
    COS = tuple((-1) ** k / factorial(2 * k) for k in range(7))       # 1, δ², ..., δ¹²

    def __init__(self, states):
        self.states = set(states)
        self.at_start: dict = {}    # sympy argument -> (α, sin α, cos α)
        self.at_end: dict = {}      # sympy argument -> (sin(α + δ), cos(α + δ))

    def starting_from(self, values: ca.SX) -> "TrigCarry":
        """A carry for a second stage evaluated apart from the first (the bench's model
        function peer_v2): this carry's arguments, their sines and cosines read from `values`
        (sin, cos per argument, in the order the first stage met them)."""
        out = TrigCarry(self.states)
        out.at_start = {arg: (alpha, values[2 * k], values[2 * k + 1])
                        for k, (arg, (alpha, _, _)) in enumerate(self.at_start.items())}
        return out

    def values(self) -> ca.SX:
        """The first stage's sines and cosines, (sin, cos) per argument (`starting_from`'s order)."""
        return ca.vertcat(*[ca.vertcat(s, c) for _, s, c in self.at_start.values()])

    def first(self, func, arg, value):
        if arg not in self.at_start:
            self.at_start[arg] = (value, ca.sin(value), ca.cos(value))
        return self.at_start[arg][1 if func is sp.sin else 2]

    def second(self, func, arg, value):
        alpha, s, c = self.at_start[arg]
        if not arg.free_symbols & self.states:      # no state in it: the same at both stages
            return s if func is sp.sin else c
        if arg not in self.at_end:
            delta = value - alpha
            t = delta * delta
            sin_d, cos_d = _horner(self.SIN, t) * delta, _horner(self.COS, t)
            self.at_end[arg] = (s * cos_d + c * sin_d, c * cos_d - s * sin_d)
        return self.at_end[arg][0 if func is sp.sin else 1]


def _horner(coefficients, t):
    """Σ_k coefficients[k] t^k."""
    out = coefficients[-1]
    for a in reversed(coefficients[:-1]):
        out = a + t * out
    return out


def held_increment_sx(flat, H: HeldSampling, x: ca.SX, z: ca.SX, u: ca.SX, p) -> ca.SX:
    """x⁺ - x over one period with u held: H.steps ETD2RK steps of H.sub's length (one of the
    period's when steps is 1), each from where the last ended."""
    if H.steps == 1:
        return _etd2rk_increment(flat, H, x, z, u, p)
    inc = _etd2rk_increment(flat, H.sub, x, z, u, p)
    for _ in range(1, H.steps):
        inc = inc + _etd2rk_increment(flat, H.sub, x + inc, z + inc, u, p)
    return inc


def _etd2rk_increment(flat, H: HeldSampling, x: ca.SX, z: ca.SX, u: ca.SX, p) -> ca.SX:
    """x⁺ - x for one ETD2RK step of length H.ts with u held, from the absolute state z (x may
    be z relative to a centre on the chain heads: A_c never reads a head). In the increment form
    of the module docstring of sampling.py: d = Ψ (A_c x + B_c v(z)), a = z + d, and
    x⁺ - x = d + Γ₂ (v(a) - v(z) - L₀ d), v = F + G u: no large terms that cancel; v(a)'s sines
    and cosines carried from v(z)'s (`TrigCarry`)."""
    n, carry = flat.n, TrigCarry(flat.zeta)
    v0 = remainder_sx(flat, z[:n], u, p, carry.first)
    d = ca.mtimes(constant(H.Psi), ca.mtimes(constant(H.Ac), x) + ca.mtimes(constant(H.Bc), v0))
    v1 = remainder_sx(flat, (z + d)[:n], u, p, carry.second)
    return d + ca.mtimes(constant(H.G2), v1 - v0 - ca.mtimes(constant(H.L0), d))


def held_input_sx(flat, H: HeldSampling, z: ca.SX, v: ca.SX, p) -> tuple[ca.SX, ca.SX]:
    """The input to hold over the next period so that each chain's top derivative gains Ts·v,
    the increment v held would give it (docs/algorithms.md "Control with the input held"), and
    G(z). The plant holds u, not v: where it has a mode fast against Ts (the motor's current),
    u = G⁻¹(v - F) computed at the period's start drives the top derivative somewhere else and
    the loop tracks 15x worse. The increment is the predictor's (ETD2RK, `held_increment_sx`):
    u₀ solves its first, affine stage S Ψ (A_c z + B_c (F + G u)) = Ts v, S the chains' top rows,
    and one step u₁ = u₀ + (S Γ₁ G)⁻¹ (Ts v - S Δ(z, u₀)) takes the second stage in (measured: a
    second step changes the tracking error by < 1e-6). With A = A_c, S Ψ A_c z = 0 and S Γ₁ = Ts I:
    the law is the chapter's u = G⁻¹(v - F) when the dynamics have no such mode."""
    top = remainder_function(flat)
    Ac, _, _ = flat.canonical()
    tops = [c.offset + c.degree - 1 for c in flat.chains]
    if not np.linalg.cond(H.G1[tops]) < 1e12:
        raise ModelError(f"{flat.model.where('inputs')}: held over Ts = {H.ts:g} s the inputs do not move the chains' "
                         f"top derivatives independently (S Γ₁ singular); use --predictor brunovsky")
    SG1, SPsiAc = constant(H.G1[tops]), constant((H.Psi @ Ac)[tops])
    w = ca.SX.sym("w", flat.m)                    # F + G w is affine in w: G is its Jacobian
    F = top(z, ca.SX.zeros(flat.m), p)[0]
    G = ca.substitute(ca.jacobian(top(z, w, p)[0], w), w, ca.SX.zeros(flat.m))
    M = ca.mtimes(SG1, G)
    solve = (lambda b: b / M) if flat.m == 1 else (lambda b: ca.solve(M, b))  # noqa: E731
    goal = H.ts * v
    u_first = within_limits(flat, solve(goal - ca.mtimes(SPsiAc, z) - ca.mtimes(SG1, F)))
    step = held_increment_sx(flat, H, z, z, u_first, p)
    u = u_first + solve(goal - ca.vertcat(*[step[i] for i in tops]))
    return u, G


def scheduled_transition_sx(flat, H: HeldSampling, sigma: ca.SX, p) -> ca.SX:
    """Φ(σ) = Φ₀ + Γ₁ (L(σ) - L₀): the exponential-Euler step's Jacobian at the nominal point
    with its flat-output entries set to σ (the `scheduled` predictor; docs/mathematics.md
    section 3). L(σ) is a closed form of the m numbers σ: whoever evaluates it differentiates
    nothing. Φ(σ₀) = Φ₀ at the nominal outputs σ₀. With disturbance states (H of the extended
    state, `augmented`) L(σ) has zero columns for them, as L₀ has: they enter through B_c, which
    A carries, and F + G u does not read them. Where the point is not a state of the model
    (`_schedulable`), L is taken at the nominal point: Φ₀."""
    point = ca.SX(ca.DM(H.zeta0))
    for j, c in enumerate(flat.chains):
        point[c.offset] = sigma[j]
    inside = _schedulable(flat, point, p)
    for j, c in enumerate(flat.chains):     # the nominal point where σ's is not a state
        point[c.offset] = inside * sigma[j] + (1 - inside) * float(H.zeta0[c.offset])
    L = remainder_function(flat)(point, ca.DM(H.u0), p)[1]
    L = ca.horzcat(L, ca.SX(flat.m, len(H.A) - flat.n))
    return constant(H.E) + ca.mtimes(constant(H.G1), L - constant(H.L0))


def _schedulable(flat, point: ca.SX, p) -> ca.SX:
    """1 where the scheduling point is a state of the model, Φ⁻¹(point) inside every declared
    [min, max]; 0 elsewhere (a NaN compares false), where Φ(σ) is then taken at the nominal point:
    Φ₀. Why: the point holds the nominal derivatives, so it can leave the domain where the
    reference does not: on a reluctance motor whose current is sqrt((J θ'' + c θ' + ks θ)/k), the
    reference reaches θ = 0 with θ'' = 0.79 and the point, with θ'' = 0, a current of 0 and an
    infinite slope (the filter's NaN ended the loop). A product of comparisons, not a logical
    AND or a select: the C stays free of floating-point conditions (clang -Wfloat-conversion)."""
    table = {s: point[i] for i, s in enumerate(flat.zeta)} | {s: p[i] for i, s in enumerate(flat.params)}
    inside = ca.SX(1)
    for i, state in enumerate(flat.model.states):
        if state.min is None and state.max is None:
            continue
        x = numeric.to_casadi(flat.phi_inv[i], table, f"Phi^-1[{i}]")
        inside = inside if state.min is None else inside * (x >= state.min)
        inside = inside if state.max is None else inside * (x <= state.max)
    return inside


def within_limits(flat, u: ca.SX) -> ca.SX:
    """u clamped to the inputs' declared limits (the generated control's clamp too). The held
    law's correction step evaluates the predictor at u₀: far outside the limits it can reach
    states where the canonical model folds back (a tank model's level from a squared root:
    measured, u₀ = -0.04 against limits [0, 1e-3] gave a correction of the wrong sign and the
    tank overflowed), while the plant only ever sees u clamped."""
    parts = []
    for i, w in enumerate(flat.model.inputs):
        ui = u[i]
        if w.min is not None:
            ui = ca.fmax(ui, float(w.min))
        if w.max is not None:
            ui = ca.fmin(ui, float(w.max))
        parts.append(ui)
    return ca.vertcat(*parts)


def constant(a) -> ca.DM:
    """A constant matrix with its exact zeros structural (no work emitted for them)."""
    return ca.sparsify(ca.DM(np.atleast_2d(a)))


def nominal_point(flat, x=None, u=None) -> tuple[np.ndarray, np.ndarray]:
    """ζ₀ = Φ(x) at the model's nominal state (or `x`), and u₀: given, else the input that holds
    the flat outputs' top derivatives at 0 there (F + G u₀ = 0, the equilibrium input when the
    nominal state is an equilibrium)."""
    x = nominal_state(flat.model) if x is None else np.asarray(x, dtype=float)
    zeta0 = flat.phi_num(x)
    if u is None:
        with np.errstate(all="ignore"):
            try:
                u = np.linalg.solve(flat.G_num(zeta0), -flat.F_num(zeta0))
            except np.linalg.LinAlgError:
                u = np.full(flat.m, np.nan)
    u = np.asarray(u, dtype=float).reshape(flat.m)
    if not (np.all(np.isfinite(zeta0)) and np.all(np.isfinite(u))):
        raise ModelError(f"{flat.model.where('states')}: the canonical model cannot be linearized at the nominal "
                         f"state ({', '.join(f'{v:g}' for v in np.ravel(x))}): declare a 'nominal' where Phi and G are defined and G is regular")
    return zeta0, u


def held_sampling(flat, ts: float, x=None, u=None, disturbance=None) -> HeldSampling:
    """The held-input predictor's constants at period `ts`, linearized at the nominal point (or
    at the physical state `x` and input `u`, to measure the sensitivity to that choice); with
    `disturbance`, for the state extended by its disturbance states."""
    zeta0, u0 = nominal_point(flat, x, u)
    _, jac = remainder_function(flat)(zeta0, u0, flat.param_vector)
    L0 = np.array(jac, dtype=float).reshape(flat.m, flat.n)
    if not np.all(np.isfinite(L0)):
        raise ModelError(f"{flat.model.where('states')}: dF/dzeta + dG/dzeta u is not finite at the nominal state")
    Ac, Bc, L0, noise = augmented(flat, L0, disturbance)
    return assemble(Ac, Bc, L0, zeta0, u0, ts, noise, flat.model.mean_substeps)
