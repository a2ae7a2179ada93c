"""The filters' prediction step, one class per `--predictor` (docs/mathematics.md section 3):

- `held` (the default): the mean integrated over the period with the applied input u held, as
  the plant holds it (ETD2RK on the canonical dynamics, symbolic/sampling.py), the covariance by
  the constant Φ₀, Q₀ of the dynamics linearized once at build time. Takes u.
- `scheduled`: the held mean; the covariance by Φ(σ) = Φ₀ + Γ₁ (L(σ) - L₀), L linearized at the
  master's broadcast flat outputs σ (symbolic/sampling.py). Takes (u, σ).
- `brunovsky` (the chapter's): the exact model of the canonical chain with v = F + G u held.
  Linear, so a packet N steps old is brought forward in one step of length N. Takes v.

All keep the covariance recursion independent of the filters' own states, so a node's replay and the master's
information-difference fusion stay exact (the nodes' information gains do not depend on the mean).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from dfeif_codegen.symbolic import disturbance as disturbance_states, numeric, sampling
from dfeif_codegen.symbolic.sampling import DEFAULT, PREDICTORS, for_method  # noqa: F401 (re-exported)


def check(name: str, oosm: str = "replay", disturbance=None) -> None:
    """ValueError naming the options for an unknown predictor or one retrodiction cannot use."""
    if name not in PREDICTORS:
        raise ValueError(f"predictor must be one of {', '.join(PREDICTORS)}, not {name!r}")
    if disturbance is not None and name == "brunovsky":
        raise ValueError(f"[disturbance] {disturbance_states.brunovsky_refusal(oosm)}")
    if oosm == "retrodict" and name != "brunovsky":
        raise ValueError(f"--oosm retrodict needs --predictor brunovsky (Xia's retrodiction inverts the transition "
                         f"over the lag, ill-conditioned for the {name} predictor's); use --oosm replay")


def held_mean_sx(flat, H: sampling.HeldSampling, x: ca.SX, u: ca.SX, p) -> ca.SX:
    """One ETD2RK step of the canonical dynamics with u held (the C prints the same increment)."""
    return x + sampling.held_increment_sx(flat, H, x, x, u, p)


class Brunovsky:
    """x⁺ = A_d x + B_d v, P⁺ = A_d P A_dᵀ + Q_d (closed forms, discretize.py)."""

    name = "brunovsky"
    # Φ (P Φᵀ) instead of (Φ P) Φᵀ: the same filter with other roundings, the second double
    # implementation `codegen verify` judges a double mismatch by (FilterBank's right_first)
    right_first = False

    def __init__(self, flat, ts: float, q, dtype=np.float64):
        self.flat, self.ts, self.q, self.dtype = flat, float(ts), q, np.dtype(dtype)
        A, self.B, _ = flat.discrete(ts)
        self.Phi, self.B = A.astype(self.dtype), self.B.astype(self.dtype)
        self.Q = flat.process_noise(ts, q).astype(self.dtype)
        self._ahead: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def mean(self, x, v) -> np.ndarray:
        return self.Phi @ x + self.B @ v

    def ahead(self, N: int) -> tuple[np.ndarray, np.ndarray]:
        """Φ over N periods and the noise of N periods (A_d(N Ts), Q_d(N Ts): closed forms)."""
        if N not in self._ahead:
            self._ahead[N] = (self.flat.discrete(N * self.ts)[0], self.flat.process_noise(N * self.ts, self.q))
        return self._ahead[N]

    @staticmethod
    def input(u, v, x_master) -> np.ndarray:
        """What the master broadcasts for this predictor at a step: v."""
        return np.atleast_1d(v)

    def sandwich(self, A, P) -> np.ndarray:
        """A P Aᵀ, associated as `right_first` says."""
        return A @ (P @ A.T) if self.right_first else A @ P @ A.T

    def covariance(self, P, w) -> np.ndarray:
        """P one step on (the transition does not depend on the input)."""
        return self.sandwich(self.Phi, P) + self.Q

    def carry(self, Ps: list[np.ndarray], inputs: list[np.ndarray]) -> list[np.ndarray]:
        """Covariances brought over len(inputs) steps in one step of that length (closed forms,
        equal to len(inputs) one-step predictions)."""
        A, Q = (a.astype(self.dtype, copy=False) for a in self.ahead(len(inputs)))
        return [self.sandwich(A, P) + Q for P in Ps]

    def bring(self, xs: list[np.ndarray], inputs: list[np.ndarray]) -> list[np.ndarray]:
        """Means predicted over len(inputs) steps: A(N Ts) x plus the inputs' effect (linear)."""
        effect = np.zeros_like(xs[0])
        for v in inputs:
            effect = self.Phi @ effect + self.B @ v
        A = self.ahead(len(inputs))[0]
        return [A @ x + effect for x in xs]


class Held:
    """x⁺ by ETD2RK with u held, P⁺ = Φ₀ P Φ₀ᵀ + Q₀ (symbolic/sampling.py)."""

    name = "held"

    def __init__(self, flat, ts: float, q, dtype=np.float64, disturbance=None):
        """`disturbance` (symbolic/disturbance.py): the state is extended by its disturbance
        states (one or two per chain), after the canonical ones."""
        self.flat, self.ts, self.q, self.dtype = flat, float(ts), q, np.dtype(dtype)
        self.drift = None if disturbance is None else (disturbance.kind, disturbance.tau)
        self.qd = None if disturbance is None else disturbance.densities(flat.m)
        self.H = _cached(("sampling", id(flat), self.ts, self.drift), flat,
                         lambda: sampling.held_sampling(flat, ts, disturbance=disturbance))
        self.Phi = self.H.E.astype(self.dtype)
        self.Q = self.H.Q(q, self.qd).astype(self.dtype)
        self._step = _mean_function(flat, self.H, self.drift)
        if self.dtype == np.float32:      # the float build's rounding inside the step, not only of its result
            function = self._step.function
            self._step = _cached(("mean32", id(flat), self.ts, self.drift), flat,
                                 lambda: numeric.SinglePrecision(function))
        self._p = flat.param_vector
        self._ahead: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def mean(self, x, u) -> np.ndarray:
        return self._step(x, u, self._p).astype(self.dtype)

    def ahead(self, N: int) -> tuple[np.ndarray, np.ndarray]:
        """Φ₀^N and the noise of N periods (the Van Loan integral over N Ts)."""
        if N not in self._ahead:
            H = self.H.ahead(N)
            self._ahead[N] = (H.E, H.Q(self.q, self.qd))
        return self._ahead[N]

    right_first = False
    sandwich = Brunovsky.sandwich
    covariance = Brunovsky.covariance
    carry = Brunovsky.carry

    @staticmethod
    def input(u, v, x_master) -> np.ndarray:
        """What the master broadcasts for this predictor at a step: u."""
        return np.atleast_1d(u)

    def bring(self, xs: list[np.ndarray], inputs: list[np.ndarray]) -> list[np.ndarray]:
        """Means predicted step by step with the stored inputs (the map is nonlinear)."""
        return _stepped(xs, inputs, self.mean)


class Scheduled(Held):
    """The held mean with u = w[:m]; P⁺ = Φ(σ) P Φ(σ)ᵀ + Q₀ with σ = w[m:], the master's flat
    outputs it broadcast with u (symbolic/sampling.py, `scheduled_transition_sx`)."""

    name = "scheduled"

    def __init__(self, flat, ts: float, q, dtype=np.float64, disturbance=None):
        super().__init__(flat, ts, q, dtype, disturbance)
        self.m = flat.m
        self._transition = _cached(("transition", id(flat), self.ts, self.drift), flat,
                                   lambda: _transition_function(flat, self.H))

    def mean(self, x, w) -> np.ndarray:
        return super().mean(x, w[:self.m])

    def input(self, u, v, x_master) -> np.ndarray:
        """What the master broadcasts at a step: u, then its fused flat outputs."""
        return with_flat_outputs(u, x_master, self.flat.heads)

    def transition(self, w) -> np.ndarray:
        """Φ(σ) of the step whose input is w = (u, σ), computed in double and then rounded (as
        the C's float build, whose Φ(σ) entries are each a few operations on σ)."""
        return self._transition(w[self.m:]).astype(self.dtype)

    def covariance(self, P, w) -> np.ndarray:
        return self.sandwich(self.transition(w), P) + self.Q

    def carry(self, Ps: list[np.ndarray], inputs: list[np.ndarray]) -> list[np.ndarray]:
        """Covariances predicted step by step (each step's Φ(σ) its own)."""
        return _stepped(Ps, inputs, self.covariance)

    def ahead(self, N: int):
        """Refused: Φ₀^N would silently be the held filter's; each step has its own Φ(σ)."""
        raise NotImplementedError("the scheduled transition has no N-step closed form: carry step by step")


def _stepped(values: list, inputs: list, step) -> list:
    """Each value taken through `step(value, input)` for the inputs in turn."""
    out = []
    for value in values:
        for w in inputs:
            value = step(value, w)
        out.append(value)
    return out


_CACHE: dict[tuple, tuple] = {}


def with_flat_outputs(u, x, heads) -> np.ndarray:
    """The scheduled predictor's input (u, σ): u, then the flat outputs x[heads] of the master's
    estimate; of one step (vectors) or of a whole recording ((K, m) and (K, n) arrays)."""
    return np.concatenate([np.atleast_1d(np.asarray(u, float)), np.asarray(x, float)[..., list(heads)]], axis=-1)


def _transition_function(flat, H) -> numeric.Numeric:
    """σ -> Φ(σ) with the model's parameters at their values."""
    sigma = ca.SX.sym("sigma", flat.m)
    return numeric.Numeric(ca.Function("transition", [sigma], [ca.densify(
        sampling.scheduled_transition_sx(flat, H, sigma, ca.DM(flat.param_vector)))], {"cse": True}))


def held_constants(flat, ts: float) -> sampling.HeldSampling:
    """The held predictor's build-time constants, computed once per flat system and period."""
    return _cached(("sampling", id(flat), float(ts), None), flat, lambda: sampling.held_sampling(flat, ts))


def _cached(key: tuple, flat, make_value):
    """One value per flat system and period (a sweep builds hundreds of filters of one model)."""
    if key not in _CACHE or _CACHE[key][0] is not flat:
        _CACHE[key] = (flat, make_value())
    return _CACHE[key][1]


def _mean_function(flat, H, drift=None) -> numeric.Numeric:
    """The ETD2RK step as one CasADi function (x, u, p) -> x⁺."""
    def make():
        x, u, p = ca.SX.sym("x", len(H.A)), ca.SX.sym("u", flat.m), ca.SX.sym("p", len(flat.params))
        return numeric.Numeric(ca.Function("held_mean", [x, u, p], [held_mean_sx(flat, H, x, u, p)], {"cse": True}))
    return _cached(("mean", id(flat), H.ts, drift), flat, make)


def make(name: str, flat, ts: float, q, dtype=np.float64, disturbance=None):
    """The predictor called `name` (one of PREDICTORS); `disturbance` needs the held or the
    scheduled one."""
    check(name, disturbance=disturbance)
    if name == "held":
        return Held(flat, ts, q, dtype, disturbance)
    if name == "scheduled":
        return Scheduled(flat, ts, q, dtype, disturbance)
    return Brunovsky(flat, ts, q, dtype)
