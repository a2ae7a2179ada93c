"""Parameter-offset states: a candidate extension of the held filter for parameter error, measured
in the comparison (`codegen simulate --filters df,offsets,ekf` with an [offsets] table), not yet
generated as C.

Why: under parameter error the held filter's per-chain disturbance state has to follow an error
that moves with the state (the motor's m g l sin θ / J), and its acceleration error stops at a
floor (docs/experiment.md, "The comparison under model error"). Estimating the relative offsets δ
of the parameters the user is unsure of, p = p0 (1 + δ), constant or a slow random walk, removes
the cause instead of chasing it.

The filter's state is (ζ, δ). The mean is the held predictor's ETD2RK step at p; the covariance
moves by Φ_k = [[Φ₀, S_k], [0, I]], S_k = ∂ζ⁺/∂δ at the estimate and the applied input: a
parameter sensitivity, the one derivative evaluated at run time (Φ₀ stays the build-time
transition of the canonical block). S_k is taken at the master's fused estimate, which the master
would broadcast with u: nodes and master then share one covariance recursion, so the nodes' replay
and the information-difference fusion stay exact. A node's mean is linearized about that point
in δ, ζ⁺ = step(ζ, δ̂) + S_k (δ - δ̂) with δ̂ the master's offsets, the linearization its
covariance already uses: from one camera the offsets are weakly observable, and a node stepping
at its own δ drifted to non-physical values (the arm's k_d offset to -1.15) until its step
exploded and took the master with it. The master steps at its own estimate, exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.reference.ekf import EKF
from dfeif_codegen.reference.physical import CanonicalMaps
from dfeif_codegen.symbolic.disturbance import finite_number, numbers

KEYS = {"params", "std", "q", "chains_q"}


@dataclass(frozen=True)
class Offsets:
    params: tuple            # names of the parameters whose relative offsets are estimated
    std: tuple               # prior std of each relative offset (1 value: every parameter)
    q: float = 0.0           # random-walk density of each offset [1/s]; 0: constants
    chains_q: tuple = ()     # the chains' white density; (): the scenario's q

    def stds(self) -> np.ndarray:
        return np.broadcast_to(np.asarray(self.std, dtype=float), (len(self.params),)).copy()

    def indices(self, flat) -> list[int]:
        """The parameters' positions in the model's parameter vector; ValueError naming an unknown one."""
        names = [str(s) for s in flat.params]
        unknown = [p for p in self.params if p not in names]
        if unknown:
            raise ValueError(f"{', '.join(unknown)}: not a parameter of model {flat.model.name} "
                             f"(its parameters: {', '.join(names)})")
        return [names.index(p) for p in self.params]


def from_table(table: dict, fail) -> Offsets:
    """The scenario's [offsets] table; `fail(key, message)` raises the one-line error."""
    for key in table:
        if key not in KEYS:
            fail(f"offsets.{key}", f"unknown field (expected one of {', '.join(sorted(KEYS))})")
    params = table.get("params")
    if not (isinstance(params, list) and params and all(isinstance(p, str) and p for p in params)) \
            or len(set(params)) != len(params):
        fail("offsets.params", f"must be a non-empty list of distinct parameter names, got {params!r}")
    stds = numbers(table.get("std", 0.2), "offsets.std", fail, allow_zero=False, per="parameter")
    if len(stds) not in (1, len(params)):
        fail("offsets.std", f"needs 1 or {len(params)} values (one per parameter), got {len(stds)}")
    q = table.get("q", 0.0)
    if not (finite_number(q) and q >= 0):
        fail("offsets.q", f"must be a number >= 0 (the offsets' random-walk density), got {q!r}")
    chains = numbers(table["chains_q"], "offsets.chains_q", fail, allow_zero=False) if "chains_q" in table else ()
    return Offsets(tuple(params), stds, float(q), chains)


class OffsetModel(CanonicalMaps):
    """The held filter's model with offset states, in the shape of compare.CanonicalModel (the
    filter's own state, h, Q; Phi the identity on the canonical part) so that it runs on the
    comparison's driver. What `predict` takes is (u, x̂): the applied input and the master's
    estimate after its fusion, the point S_k is taken at, so that every node and the master
    propagate their covariances by the same Φ_k (the information-difference fusion and the
    nodes' replay then stay exact, as with the constant Φ₀); each mean steps its own ζ at the
    point's offsets plus S_k times its own offsets' distance from them."""

    def __init__(self, flat, ts: float, q, offsets: Offsets):
        which, p0 = offsets.indices(flat), flat.param_vector
        n, k, m = flat.n, len(which), flat.m
        self.offsets, self.canonical_n = offsets, n
        self.n, self.m, self.ts = n + k, m, float(ts)
        self.inputs = m + self.n
        self.angle_out = np.array([c.angle for c in flat.chains])
        H = predictors.held_constants(flat, ts)
        x, w = ca.SX.sym("x", self.n), ca.SX.sym("w", self.inputs)
        u, point = w[:m], w[m:]
        p = ca.SX(ca.DM(p0))
        for j, i in enumerate(which):
            p[i] = p0[i] * (1 + x[n + j])
        mean = predictors.held_mean_sx(flat, H, x[:n], u, p)
        sensitivity = ca.Function("sensitivity", [x, w], [ca.jacobian(mean, x[n:])])
        Phi = ca.SX.eye(self.n)
        Phi[:n, :n] = ca.DM(H.E)
        Phi[:n, n:] = sensitivity(point, w)
        held = ca.Function("held", [x, w], [mean])
        at_point = held(ca.vertcat(x[:n], point[n:]), w) + Phi[:n, n:] @ (x[n:] - point[n:])
        self.step_sx = ca.Function("step", [x, w], [ca.vertcat(at_point, x[n:])])
        self.transition_sx = ca.Function("transition", [w], [Phi])
        Q = np.zeros((self.n, self.n))
        Q[:n, :n], Q[n:, n:] = H.Q(np.asarray(q, dtype=float)), np.eye(k) * offsets.q * ts
        self.Qd = Q
        C = np.hstack([flat.discrete(ts)[2], np.zeros((m, k))])
        self.h_sx = ca.Function("h", [x], [ca.DM(C) @ x])
        self.Qx_sx = ca.Function("Qx", [x], [ca.DM(Q)])

    def input(self, u, master_x) -> np.ndarray:
        """What `predict` takes at a step: the applied input and the master's fused estimate."""
        return np.concatenate([np.atleast_1d(np.asarray(u, float)), np.asarray(master_x, float)])

    def start(self, x0, P0):
        """(ζ0, 0) and P0 with the offsets' prior spread, independent of ζ."""
        n, k = self.canonical_n, self.n - self.canonical_n
        P = np.zeros((self.n, self.n))
        P[:n, :n], P[n:, n:] = P0, np.diag(self.offsets.stds() ** 2)
        return np.concatenate([np.asarray(x0, float), np.zeros(k)]), P


class OffsetFilter(EKF):
    """The Kalman update (C is constant) with the offset model's prediction: the held mean at the
    estimated parameters and Φ_k P Φ_kᵀ + Q."""

    def predict_sx(self, x, P, w):
        Phi = self.model.transition_sx(w)
        return self.model.step_sx(x, w), Phi @ P @ Phi.T + ca.DM(self.model.Qd)
