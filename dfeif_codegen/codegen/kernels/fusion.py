"""The master's fusion kernels (difference and paper rules) and its prediction of stale packets.

Each packet becomes information about the master's prior (`master_info`, or with the difference
rule the gain of its update over its prediction, `master_gain`); the C sums them and
`fuse_finish` turns the sum back into an estimate. Symmetric results are computed once and
packed row by row (`linalg.packed_rows`); the master keeps these kernels' work in locals.
The covariance-intersection weights are in `ci`.
"""

from __future__ import annotations

import casadi as ca

from dfeif_codegen.codegen.kernels.chains import Chains
from dfeif_codegen.codegen.kernels.linalg import chol, packed_rows, spd_inverse, sym, symmetric, unpacked_rows


def _info_of(x: ca.SX, P: ca.SX, c: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """Y = P^-1 (its upper triangle only: the lower reuses it) and y = Y (x - c), about the
    master's prior c: the same fused x in exact arithmetic, without the cancellation of Y x
    terms that |x| / sigma of several hundred causes in single precision."""
    Yi, piv = spd_inverse(P)
    Y = symmetric(Yi)
    return Y, ca.mtimes(Y, x - c), piv


def _finish_of(Y: ca.SX, y: ca.SX, c: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    Pi, piv = spd_inverse(Y)
    P = symmetric(Pi)
    return c + ca.mtimes(P, y), P, piv


def master_info(s: Chains, name: str) -> ca.Function:
    """One packet's information (paper and ci rules), Y packed."""
    n = s.n
    x, P, c = sym("x", n), sym("P", n, n), sym("c", n)
    Y, y, piv = _info_of(x, P, c)
    return ca.Function(name, [x, P, c], [packed_rows(Y), y, piv], ["x", "P", "c"], ["Y", "y", "piv"])


def master_gain(s: Chains, name: str) -> ca.Function:
    """One packet's information gain (difference rule): its update's information less its
    prediction's, packed, with both factorisations' pivots."""
    n = s.n
    x, P, xp, Pp, c = sym("x", n), sym("P", n, n), sym("xp", n), sym("Pp", n, n), sym("c", n)
    Y, y, piv = _info_of(x, P, c)
    Yp, yp, pivp = _info_of(xp, Pp, c)
    return ca.Function(name, [x, P, xp, Pp, c], [packed_rows(Y - Yp), y - yp, ca.vertcat(piv, pivp)],
                       ["x", "P", "xp", "Pp", "c"], ["dY", "dy", "piv"])


def fuse_finish(s: Chains, name: str) -> ca.Function:
    """x = c + P y, P = Y^-1 from the fused information (Y packed)."""
    n = s.n
    Y, y, c = sym("Y", n * (n + 1) // 2), sym("y", n), sym("c", n)
    x, P, piv = _finish_of(unpacked_rows(Y, n), y, c)
    return ca.Function(name, [Y, y, c], [x, P, piv], ["Y", "y", "c"], ["x", "P", "piv"])


def fuse_finish_difference(s: Chains, name: str) -> ca.Function:
    """The difference rule's end: the fused Y = P_c^-1 + D (P_c, c the estimate the gains add
    to: the prediction, or an earlier call's result in the step; D the sum of the gains,
    packed), y = 0 + the sum of their dy; then x = c + P y with P = Y^-1 in the factor
    P_c = L L': P = L (I + L' D L)^-1 L'. The same P in exact arithmetic as inverting
    P_c^-1 + D, without inverting twice: where the packets bring little information
    (D small, or 0 before the first measurement arrives) P is P_prior to the rounding of its
    factor, where the double inversion lost cond(P_prior) * eps (a float master 1.7e-4 from the
    reference at a user model's second step, docs/algorithms.md). Every sum is written out from
    its first product, in the order `fusion_loops` repeats."""
    n = s.n
    Pc, dY, dy, c = sym("Pc", n, n), sym("dY", n * (n + 1) // 2), sym("dy", n), sym("c", n)
    L, pivc = chol(Pc)
    D = unpacked_rows(dY, n)
    W = ca.SX(n, n)   # D L (L lower: the sum over rows a >= j)
    for k in range(n):
        for j in range(n):
            W[k, j] = _sum([D[k, a] * L[a, j] for a in range(j, n)])
    M = ca.SX(n, n)   # I + L' W, upper triangle mirrored
    for i in range(n):
        for j in range(i, n):
            m = _sum([L[k, i] * W[k, j] for k in range(i, n)])
            M[i, j] = M[j, i] = 1 + m if i == j else m
    Mi, piv = spd_inverse(M)
    Mi = symmetric(Mi)
    V = ca.SX(n, n)   # L Mi
    for i in range(n):
        for b in range(n):
            V[i, b] = _sum([L[i, a] * Mi[a, b] for a in range(i + 1)])
    P = ca.SX(n, n)   # V L', upper triangle mirrored
    for i in range(n):
        for j in range(i, n):
            P[i, j] = P[j, i] = _sum([V[i, b] * L[j, b] for b in range(j + 1)])
    x = c + ca.mtimes(P, dy)
    return ca.Function(name, [Pc, dY, dy, c], [x, P, ca.vertcat(pivc, piv)], ["Pc", "dY", "dy", "c"],
                       ["x", "P", "piv"])


def _sum(terms: list[ca.SX]) -> ca.SX:
    """terms[0] + terms[1] + ..., left to right (the loops' order)."""
    out = terms[0]
    for t in terms[1:]:
        out = out + t
    return out


def advance(s: Chains, name: str) -> ca.Function:
    """A stale packet's estimate brought N steps forward at once: x1 = A(N Ts) x + effect and
    P1 = A(N Ts) P A(N Ts)' + Q_d(N Ts), `effect` the stored inputs' effect over those steps
    (`input_step`). Exactly the N one-step predictions (sum_i A^i Q A^i' = Q_d(N Ts) for the
    chains' white-noise model), in the work of one: a packet N_max steps old costs the master
    one kernel call instead of N_max."""
    n, m = s.n, s.m
    N, x, P, e, q = sym("N"), sym("x", n), sym("P", n, n), sym("effect", n), sym("q", m)
    t = N * s.opts.ts
    A = s.A_of(t)
    P1 = symmetric(ca.mtimes(ca.mtimes(A, symmetric(P)), A.T) + s.Q_of(q, t))
    return ca.Function(name, [N, x, P, e, q], [ca.mtimes(A, x) + e, P1], ["N", "x", "P", "effect", "q"],
                       ["x1", "P1"])


def input_step(s: Chains, name: str) -> ca.Function:
    """One stored input's step of that effect: A effect + B v (from 0 at the packet's step)."""
    e, v = sym("effect", s.n), sym("v", s.m)
    return ca.Function(name, [e, v], [ca.mtimes(s.A, e) + ca.mtimes(s.B, v)], ["effect", "v"],
                       ["effect1"])
