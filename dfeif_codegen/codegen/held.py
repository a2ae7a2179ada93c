"""The held-input predictor's kernels (docs/mathematics.md section 3; the reference's is
reference/predictor.py): the node's and the master's prediction, and the covariance-only step a
node's replay carries its checkpoints with.

The C stores the chain heads relative to a centre (docs/algorithms.md, "Centred storage"). The
Brunovsky A maps a vector that is zero off the heads to itself, so its prediction commutes with
the centre; E = e^{(A_c + B_c L₀) Ts} does not (L₀ has entries in the heads' columns), and F, G
need the absolute state. So these kernels take the centre c (one value per head, Hc its
embedding) and add the reference's increment (sampling.held_increment_sx, evaluated at the
absolute state z = x + Hc) to the relative x: the ETD2RK step of the reference minus Hc, the
stored values keeping their resolution in single precision.
The model's parameters are baked in at their values: L₀ is taken with them at build time.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from dfeif_codegen.symbolic import sampling


class HeldKernels:
    """Kernel builders for one flat system and period; `b` is the kernel builder whose packing
    helpers (pack, unpack, symmetric) the node's storage uses."""

    def __init__(self, flat, ts: float, b):
        self.flat, self.b = flat, b
        self.n, self.m = flat.n, flat.m
        self.H = sampling.held_sampling(flat, ts)
        self.p = ca.DM(flat.param_vector)
        self.embed = np.zeros((self.n, self.m))
        self.embed[flat.heads, np.arange(self.m)] = 1.0

    def mean(self, x: ca.SX, u: ca.SX, c: ca.SX) -> ca.SX:
        """x⁺ relative to the centre c from x relative to it (module docstring)."""
        return x + sampling.held_increment_sx(self.flat, self.H, x, x + ca.mtimes(sampling.constant(self.embed), c), u, self.p)

    def noise(self, q: ca.SX) -> ca.SX:
        """Q₀ = Σ_j q_j U_j."""
        out = ca.SX(self.n, self.n)
        for j in range(self.m):
            out = out + q[j] * sampling.constant(self.H.U[j])
        return out

    def covariance(self, P: ca.SX, q: ca.SX) -> ca.SX:
        """Φ₀ P Φ₀ᵀ + Q₀ from the upper triangle of P."""
        E = sampling.constant(self.H.E)
        return ca.mtimes(ca.mtimes(E, self.b.symmetric(P)), E.T) + self.noise(q)

    def node_predict(self, name: str) -> ca.Function:
        """The node's prediction of its state (x, then P packed: one argument) with the applied u."""
        n, m, npp = self.n, self.m, self.n * (self.n + 1) // 2
        post, u, q, c = ca.SX.sym("post", n + npp), ca.SX.sym("u", m), ca.SX.sym("q", m), ca.SX.sym("centre", m)
        x1 = self.mean(post[:n], u, c)
        P1 = self.covariance(self.b.unpack(post[n:], n), q)
        return ca.Function(name, [post, u, q, c], [x1, self.b.pack(P1)], ["post", "u", "q", "centre"], ["x1", "P1"])

    def node_predict_P(self, name: str) -> ca.Function:
        """The covariance alone (a replay's checkpoints: P reads neither x nor u)."""
        npp = self.n * (self.n + 1) // 2
        P, q = ca.SX.sym("P", npp), ca.SX.sym("q", self.m)
        return ca.Function(name, [P, q], [self.b.pack(self.covariance(self.b.unpack(P, self.n), q))], ["P", "q"],
                           ["P1"])

    def predict(self, name: str) -> ca.Function:
        """The master's prediction (x, P full): printed as node_predict on packed copies."""
        n, m = self.n, self.m
        x, P, u = ca.SX.sym("x", n), ca.SX.sym("P", n, n), ca.SX.sym("u", m)
        q, c = ca.SX.sym("q", m), ca.SX.sym("centre", m)
        P1 = self.b.symmetric(self.covariance(self.b.symmetric(P), q))
        return ca.Function(name, [x, P, u, q, c], [self.mean(x, u, c), P1], ["x", "P", "u", "q", "centre"],
                           ["x1", "P1"])
