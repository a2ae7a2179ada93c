"""A covariance transition scheduled on the master's flat outputs, as a candidate in the
comparison (`codegen simulate --filters df,scheduled,ekf`, on the comparison's driver); the same
filter is the build option `--predictor scheduled` (reference/predictor.py `Scheduled`, and the
generated C).

Why: the held filter propagates its covariance by one constant Φ₀, the canonical dynamics
linearized at the nominal state. On a model whose inertia and gravity move with the configuration
(the two-link arm over ±1 rad) that transition is wrong away from the nominal, and the filter
is consistent only at a q where its second joint is 10–17% behind the EKF (docs/experiment.md).

What changes: the mean is the held filter's, unchanged. The covariance moves by

    Φ(σ) = Φ₀ + Γ₁ (L(σ) - L₀),   L(σ) = ∂(F + G u₀)/∂ζ at ζ₀ with its flat-output entries set to σ,

Γ₁ = Ts φ₁(A Ts) B_c the build-time input matrix of the exponential step, ζ₀, u₀ the point L₀
was taken at, and σ the master's fused flat outputs, which the master would broadcast with u
(m more numbers on the wire). Φ(σ) is the Jacobian of the exponential-Euler step
ζ + Ψ (A_c ζ + B_c (F + G u₀)) at that point: Φ₀ itself at the nominal, and measured as accurate
as the Jacobian of the held mean's own second-order step at a third of its operations (the arm:
predict 2,205 against 5,273). Every node and the master propagate by the same matrix, so a
node's replay is still the filter re-run with the frame on time and the information-difference
fusion still gives the centralized filter, as with Φ₀. L(σ) is a closed-form function of the m
configuration numbers, derived at build time: a node evaluates it and differentiates nothing.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.reference.ekf import EKF
from dfeif_codegen.reference.physical import CanonicalMaps
from dfeif_codegen.symbolic import sampling
from dfeif_codegen.symbolic.disturbance import augment


class ScheduledModel(CanonicalMaps):
    """The held filter's model with the scheduled transition, in the shape of
    compare.CanonicalModel so that it runs on the comparison's driver. What `predict` takes is
    (u, σ): the applied input and the master's fused flat outputs after its fusion."""

    def __init__(self, flat, ts: float, q, disturbance=None):
        """`disturbance` (symbolic/disturbance.py): the state extended by the disturbance
        states, as the held filter's (compare.CanonicalModel); `phi` reports the canonical part."""
        pred = predictors.make("scheduled", flat, ts, np.asarray(q, dtype=float), disturbance=disturbance)
        H, m = pred.H, flat.m                           # with the point L₀ was taken at
        self.n, self.m, self.ts, self.canonical_n = len(H.A), m, float(ts), flat.n
        self.disturbance, self.inputs = disturbance, 2 * m
        self.outputs_at = np.array(flat.heads)                          # σ's entries in ζ
        self.angle_out = np.array([c.angle for c in flat.chains])
        x, w = ca.SX.sym("x", self.n), ca.SX.sym("w", self.inputs)
        p = ca.DM(flat.param_vector)
        self.step_sx = ca.Function("step", [x, w], [predictors.held_mean_sx(flat, H, x, w[:m], p)])
        self.transition_sx = ca.Function("transition", [w], [sampling.scheduled_transition_sx(flat, H, w[m:], p)])
        self.Qd = pred.Q
        C = np.hstack([flat.discrete(ts)[2], np.zeros((m, self.n - flat.n))])
        self.h_sx = ca.Function("h", [x], [ca.DM(C) @ x])
        self.Qx_sx = ca.Function("Qx", [x], [ca.DM(self.Qd)])

    def start(self, x0, P0):
        """The filter's initial (x, P) from the canonical ones (disturbances at 0, their spread)."""
        return augment(x0, P0, self.disturbance, self.m)

    def input(self, u, master_x) -> np.ndarray:
        """What `predict` takes at a step: the applied input and the master's fused flat outputs."""
        return predictors.with_flat_outputs(u, master_x, self.outputs_at)


class ScheduledFilter(EKF):
    """The Kalman update (C is constant) with the held mean and Φ(σ) P Φ(σ)ᵀ + Q."""

    def predict_sx(self, x, P, w):
        Phi = self.model.transition_sx(w)
        return self.model.step_sx(x, w), Phi @ P @ Phi.T + ca.DM(self.model.Qd)
