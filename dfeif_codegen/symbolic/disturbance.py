"""Disturbance states for model error (scenario `[disturbance]`, docs/algorithms.md "Disturbance
states"): a state d_i per chain entering its top derivative, y_i^(r_i) = F_i + G_i u + d_i,
so that what the model gets wrong (a parameter, an unmodelled force) is estimated instead of
biasing the chain. `random_walk`: ḋ = w; `gauss_markov`: ḋ = -d / tau + w (first order);
`integrated_random_walk`: d̈ = w, a second state per chain for its rate ḋ (after the m d's),
so that an error that drifts as the state moves (the motor's m g l sin θ / J under a wrong
mass) is followed without the random walk's lag; `integrated_gauss_markov`: d̈ = -ḋ / tau + w,
the integrated walk whose rate forgets over tau, so that through a gap in the measurements the
predicted d stops ramping after about tau instead of extrapolating its last rate for the whole
gap; w white with density q_i per chain. Only the held and scheduled predictors carry them
(their transition is the exponential of the augmented A; the Brunovsky chain has no place for
them).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

KINDS = ("random_walk", "gauss_markov", "integrated_random_walk", "integrated_gauss_markov")
SECOND_ORDER = ("integrated_random_walk", "integrated_gauss_markov")     # d and its rate per chain
TIMED = ("gauss_markov", "integrated_gauss_markov")                      # with a time constant tau
TAU_ONLY_TIMED = "--tau: applies to --disturbance " + " or ".join(TIMED) + " only"   # the one wording
KEYS = {"kind", "q", "tau", "p0_std"}


def brunovsky_refusal(oosm: str) -> str:
    """What disturbance states need when the predictor is the Brunovsky chain (the one wording
    of the build option and the scenario table): with retrodiction, replay as well."""
    if oosm == "retrodict":
        return ("needs --oosm replay and the held or scheduled predictor (retrodiction runs only the brunovsky "
                "predictor, which has no disturbance states)")
    return "needs --predictor held or scheduled (the brunovsky predictor has no disturbance states)"


@dataclass(frozen=True)
class Disturbance:
    kind: str
    q: tuple                 # density per chain (1 value: every chain)
    tau: float | None = None     # Gauss-Markov time constant [s] (of d, or of its rate)
    p0_std: tuple | None = None  # initial std per chain (integrated walk: of d, or of d then its
                                 # rate); None: the stationary one (Gauss-Markov) or the spread one
                                 # second of the walk gathers (initial_std)

    @property
    def order(self) -> int:
        """Disturbance states per chain: d, and its rate for the integrated kinds."""
        return 2 if self.kind in SECOND_ORDER else 1

    def densities(self, m: int) -> np.ndarray:
        return np.broadcast_to(np.asarray(self.q, dtype=float), (m,)).copy()

    def drift(self, m: int) -> np.ndarray:
        """ḋ = D d over the order * m disturbance states: 0 for the random walk, -1/tau for
        Gauss-Markov; for the integrated kinds each d driven by its rate, the rate's own -1/tau
        (integrated Gauss-Markov) or 0 (integrated random walk)."""
        decay = np.eye(m) * (-1.0 / self.tau if self.kind in TIMED else 0.0)
        if self.order == 2:
            return np.block([[np.zeros((m, m)), np.eye(m)], [np.zeros((m, m)), decay]])
        return decay

    def initial_std(self, m: int) -> np.ndarray:
        """The order * m states' initial std: p0_std when given (the integrated random walk's:
        the d's, or the d's then the rates'), otherwise the spread the density gathers (over
        tau / 2 for Gauss-Markov, 1 s else: d ~ sqrt(q) for the random walk; for the integrated
        ones, d sqrt(q / 3) and its rate sqrt(q), the integrals of a white d̈ over 1 s, or the
        rate's stationary sqrt(q tau / 2) when it forgets over tau)."""
        q = self.densities(m)
        given = None if self.p0_std is None else np.asarray(self.p0_std, dtype=float)
        if self.order == 2:
            if given is not None and len(given) == 2 * m:
                return given.copy()
            d = np.sqrt(q / 3) if given is None else np.broadcast_to(given, (m,))
            return np.concatenate([d, np.sqrt(q * (self.tau / 2 if self.kind in TIMED else 1.0))])
        if given is not None:
            return np.broadcast_to(given, (m,)).copy()
        span = self.tau / 2 if self.kind == "gauss_markov" else 1.0
        return np.sqrt(q * span)

    def to_json(self) -> str:
        """One line a Recording stores (and `from_json` reads back)."""
        return json.dumps({"kind": self.kind, "q": list(self.q), "tau": self.tau,
                           "p0_std": None if self.p0_std is None else list(self.p0_std)})

    @staticmethod
    def from_json(text: str) -> "Disturbance | None":
        """The disturbance `to_json` wrote; None for "" (a recording without disturbance states)."""
        if not text:
            return None
        d = json.loads(text)
        return Disturbance(d["kind"], tuple(d["q"]), d["tau"], None if d["p0_std"] is None else tuple(d["p0_std"]))

    def check(self, m: int, fail) -> None:
        """q and p0_std sized for a model of m chains; `fail(key, message)` raises the error."""
        if len(self.q) not in (1, m):
            fail("disturbance.q", f"needs 1 or {m} values (one density per flat output), got {len(self.q)}"
                 if m > 1 else f"needs 1 value (the density of the one flat output), got {len(self.q)}")
        sizes = sorted({1, m, 2 * m} if self.order == 2 else {1, m})
        if self.p0_std is not None and len(self.p0_std) not in sizes:
            fail("disturbance.p0_std", f"needs {' or '.join(map(str, sizes))} values, got {len(self.p0_std)}"
                 + (" (the d's, then their rates')" if self.order == 2 else ""))
        if self.order == 2 and 0.0 in self.q and (self.p0_std is None or len(self.p0_std) != 2 * m):
            fail("disturbance.p0_std", f"needs {2 * m} values (the d's, then their rates') when a density is 0: a "
                                       "constant rate's initial std cannot come from a zero density")

    def scaled(self, factor: float) -> "Disturbance":
        """The same disturbance with every density times `factor` (calibration)."""
        return Disturbance(self.kind, tuple(float(v) * factor for v in self.q), self.tau, self.p0_std)


def augment(x0, P0, dist: Disturbance | None, m: int) -> tuple[np.ndarray, np.ndarray]:
    """(x0, P0) of the canonical state extended by the disturbances (mean 0, independent)."""
    if dist is None:
        return np.asarray(x0, dtype=float), np.asarray(P0, dtype=float)
    n, std = len(x0), dist.initial_std(m)
    P = np.zeros((n + len(std), n + len(std)))
    P[:n, :n], P[n:, n:] = P0, np.diag(std ** 2)
    return np.concatenate([x0, np.zeros(len(std))]), P


def from_table(table: dict, fail) -> Disturbance:
    """The scenario's [disturbance] table; `fail(key, message)` raises the one-line error."""
    for key in table:
        if key not in KEYS:
            fail(f"disturbance.{key}", f"unknown field (expected one of {', '.join(sorted(KEYS))})")
    kind = table.get("kind")
    if kind not in KINDS:
        fail("disturbance.kind", f"must be one of {', '.join(KINDS)}, got {kind!r}")
    q = numbers(table.get("q"), "disturbance.q", fail, allow_zero=True)
    tau = table.get("tau")
    if kind in TIMED:
        if not finite_number(tau) or tau <= 0:
            fail("disturbance.tau", f"the Gauss-Markov time constant must be a number > 0 [s], got {tau!r}")
        tau = float(tau)
    elif tau is not None:
        fail("disturbance.tau", "applies to kind = \"gauss_markov\" or \"integrated_gauss_markov\" only")
    p0 = numbers(table["p0_std"], "disturbance.p0_std", fail, allow_zero=False) if "p0_std" in table else None
    if p0 is None and 0.0 in q:
        # the default initial spread is the one the density gathers: none for q = 0, which would
        # leave that state's covariance singular (the information-form fusion inverts it)
        fail("disturbance.p0_std", "needed when a density in disturbance.q is 0 (a constant disturbance: "
                                   "its initial std cannot come from a zero density)")
    return Disturbance(kind, q, tau, p0)


def finite_number(v) -> bool:
    """A finite TOML number (a bool is an int to Python, not a number to a scenario)."""
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(v)
    except OverflowError:       # a TOML integer beyond a double's range
        return False


def numbers(value, key: str, fail, allow_zero: bool, per: str = "chain") -> tuple:
    """A scenario field holding one number or a non-empty list of them (one per `per`), each > 0
    (or >= 0); `fail(key, message)` raises the one-line error."""
    items = value if isinstance(value, list) else [value]
    bound = ">= 0" if allow_zero else "> 0"
    if not items or not all(finite_number(v) and (v > 0 or (allow_zero and v == 0)) for v in items):
        fail(key, f"must be a number {bound} or a non-empty list of them (one per {per}), got {value!r}")
    return tuple(float(v) for v in items)
