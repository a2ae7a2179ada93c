"""The held-input predictor's kernels (`--predictor held`, the default; docs/mathematics.md
section 3; the reference's is reference/predictor.py): the node's and the master's prediction,
and the covariance-only step a node's replay carries its checkpoints with.

The C stores the chain heads relative to a centre (docs/algorithms.md, "Centred storage"). The
Brunovsky A maps a vector that is zero off the heads to itself, so its prediction commutes with
the centre; E = e^{(A_c + B_c L₀) Ts} does not (L₀ has entries in the heads' columns), and F, G
need the absolute state. So these kernels take the centre c (one value per head, Hc its
embedding) and add the reference's increment (sampling.held_increment_sx, evaluated at the
absolute state z = x + Hc) to the relative x: the ETD2RK step of the reference minus Hc, the
stored values keeping their resolution in single precision. The model's parameters are baked in
at their values: L₀ is taken with them at build time.

With disturbance states (`codegen build --disturbance`, symbolic/disturbance.py) the state is the
canonical one followed by one disturbance per chain, q the chains' densities followed by the
disturbances': the same increment and E, U of the extended A (sampling.augmented).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from dfeif_codegen.codegen.kernels.linalg import dm, pack, sym, symmetric, unpack
from dfeif_codegen.symbolic import sampling


class Held:
    """The held predictor's constants for one flat system and period, and its SX pieces."""

    def __init__(self, flat, ts: float, disturbance=None):
        self.flat, self.m = flat, flat.m
        self.H = sampling.held_sampling(flat, ts, disturbance=disturbance)
        self.n, self.nq = len(self.H.A), len(self.H.U)     # state and densities, disturbances included
        # the control law's constants: the canonical model's (the reference's law)
        self.law = self.H if disturbance is None else sampling.held_sampling(flat, ts)
        self.p = ca.DM(flat.param_vector)
        self.embed = np.zeros((self.n, self.m))
        self.embed[flat.heads, np.arange(self.m)] = 1.0

    def mean(self, x: ca.SX, u: ca.SX, c: ca.SX) -> ca.SX:
        """x⁺ relative to the centre c from x relative to it (module docstring)."""
        return x + sampling.held_increment_sx(self.flat, self.H, x, x + ca.mtimes(dm(self.embed), c), u, self.p)

    def covariance(self, P: ca.SX, q: ca.SX) -> ca.SX:
        """Φ₀ P Φ₀ᵀ + Q₀ (Q₀ = Σ_j q_j U_j) from the upper triangle of P."""
        E = dm(self.H.E)
        out = ca.mtimes(ca.mtimes(E, symmetric(P)), E.T)
        for j in range(self.nq):
            out = out + q[j] * dm(self.H.U[j])
        return out


def node_predict(h: Held, name: str) -> ca.Function:
    """The node's prediction of its state (x, then P packed: one argument) with the applied u."""
    n, m, npp = h.n, h.m, h.n * (h.n + 1) // 2
    post, u, q, c = sym("post", n + npp), sym("u", m), sym("q", h.nq), sym("centre", m)
    P1 = h.covariance(unpack(post[n:], n), q)
    return ca.Function(name, [post, u, q, c], [h.mean(post[:n], u, c), pack(P1)], ["post", "u", "q", "centre"],
                       ["x1", "P1"])


def node_predict_P(h: Held, name: str) -> ca.Function:
    """The covariance alone (a replay's checkpoints: P reads neither x nor u)."""
    P, q = sym("P", h.n * (h.n + 1) // 2), sym("q", h.nq)
    return ca.Function(name, [P, q], [pack(h.covariance(unpack(P, h.n), q))], ["P", "q"], ["P1"])


def predict(h: Held, name: str) -> ca.Function:
    """The master's prediction (x, P full): printed as node_predict on packed copies."""
    x, P, u, q, c = sym("x", h.n), sym("P", h.n, h.n), sym("u", h.m), sym("q", h.nq), sym("centre", h.m)
    P1 = symmetric(h.covariance(symmetric(P), q))
    return ca.Function(name, [x, P, u, q, c], [h.mean(x, u, c), P1], ["x", "P", "u", "q", "centre"], ["x1", "P1"])
