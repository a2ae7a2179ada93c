"""The node filter's kernels: prediction, measurement update and information form.

Each is one step of work on one node's estimate; the loops over the late-measurement window are
plain C in the templates. The node keeps its state as one vector, x then P packed
(`linalg.packed_index`), so these kernels read and write that form.
"""

from __future__ import annotations

import casadi as ca

from dfeif_codegen.codegen.kernels.chains import Chains
from dfeif_codegen.codegen.kernels.linalg import normalized_square, pack, spd_inverse_once, sym, symmetric, unpack


def predict(s: Chains, name: str) -> ca.Function:
    """x1 = A x + B v, P1 = A P A' + Q on full matrices (the master's predict)."""
    n, m = s.n, s.m
    x, P, v, q = sym("x", n), sym("P", n, n), sym("v", m), sym("q", m)
    x1 = ca.mtimes(s.A, x) + ca.mtimes(s.B, v)
    Ps = symmetric(P)
    P1 = symmetric(ca.mtimes(ca.mtimes(s.A, Ps), s.A.T) + s.Q_of(q))
    return ca.Function(name, [x, P, v, q], [x1, P1], ["x", "P", "v", "q"], ["x1", "P1"])


def update(s: Chains, name: str) -> ca.Function:
    """The node's update with a measurement on its packed prior (npp = n (n + 1) / 2 reals),
    posterior packed. A step without one keeps its prior as it is (the node copies it): no
    gamma factor in the gain, so none of its multiplications.
    Prior and posterior are each one vector, x then P (the node stores them so): fewer
    arguments, all in registers on the host. The innovation e comes wrapped from the node,
    whose wrap skips the fmod in the common case (a branch, which straight-line
    code cannot take). With an innovation gate (`--gate`) it also returns e' S^-1 e, which the
    node compares with the gate's square before it keeps the posterior."""
    n, m, npp = s.n, s.m, s.n * (s.n + 1) // 2
    prior, e, R = sym("prior", n + npp), sym("e", m), sym("R", m, m)
    Pm = unpack(prior[n:], n)
    S, K, piv = s.gain(Pm, R, 1)
    x, P = prior[:n] + ca.mtimes(K, e), s.posterior(Pm, K, R)
    outs, names = [ca.vertcat(x, pack(P)), piv], ["post", "piv"]
    if s.opts.gate is not None:
        outs, names = outs + [normalized_square(e, S)], names + ["nis"]
    return ca.Function(name, [prior, e, R], outs, ["prior", "e", "R"], names)


def node_predict(s: Chains, name: str) -> ca.Function:
    """The node's prediction of its state (x, then P packed: one argument)."""
    n, m, npp = s.n, s.m, s.n * (s.n + 1) // 2
    post, v, q = sym("post", n + npp), sym("v", m), sym("q", m)
    x1 = ca.mtimes(s.A, post[:n]) + ca.mtimes(s.B, v)
    # A P A' + Q from the upper triangle of P (the posterior as the node stores it)
    P1 = ca.mtimes(ca.mtimes(s.A, symmetric(unpack(post[n:], n))), s.A.T) + s.Q_of(q)
    return ca.Function(name, [post, v, q], [x1, pack(P1)], ["post", "v", "q"], ["x1", "P1"])


def info(s: Chains, name: str) -> ca.Function:
    """Information form about a centre c: Y = P^-1, y = Y (x - c). The master centres on its
    prior: the same fused x in exact arithmetic, without the cancellation of Y x terms
    that |x| / sigma of several hundred causes in single precision."""
    n = s.n
    x, P, c = sym("x", n), sym("P", n, n), sym("c", n)
    Y, piv = spd_inverse_once(P)
    return ca.Function(name, [x, P, c], [Y, ca.mtimes(Y, x - c), piv], ["x", "P", "c"], ["Y", "y", "piv"])
