"""The node's retrodiction kernels (`--oosm retrodict`): a late measurement applied at the
present step by Xia et al.'s correction instead of replaying the steps since it was taken.

`retro_step` is one step of the backward recursion over the window (the loop is C in the node
template); `retro_finish` applies the correction from its sums (docs/mathematics.md section 4).
"""

from __future__ import annotations

import casadi as ca

from dfeif_codegen.codegen.kernels.chains import Chains
from dfeif_codegen.codegen.kernels.linalg import (normalized_square, pack, right_divide, spd_inverse, sym, symmetric,
                                                  unpack)


def retro_step(s: Chains, name: str) -> ca.Function:
    """One step n (slot k-n) of the backward recursion of the retrodiction (algorithms.md):
    adds slot k-n's terms to the sums and carries T(n)(A L_n)' and E(n-1) = L_n A E(n)."""
    n, m = s.n, s.m
    nn, Tp, E = sym("n"), sym("Tp", n, n), sym("E", n, n)
    npp = n * (n + 1) // 2
    xm, Pp, z, used, R = sym("xm", n), sym("Pm", npp), sym("z", m), sym("used"), sym("R", m, m)
    Pm = unpack(Pp, n)
    v, q = sym("v", m), sym("q", m)
    sw, sQ, sX, su = sym("sw", n), sym("sQ", n, n), sym("sX", n, n), sym("su", n)
    t = nn * s.opts.ts
    An = s.A_of(t)
    e = s.wrap(z - s.head_rows(xm))
    S, K, piv = s.gain(Pm, R, used)
    Si, _ = spd_inverse(S)
    T = ca.mtimes(An, s.Q_of(q)) + Tp
    Ct = s.head_cols(T)                       # C~(n) = T(n) C'
    D = s.head_rows(ca.mtimes(s.A, E))        # D(n) = C A E(n)
    CtSi = ca.mtimes(Ct, Si)
    sw1 = sw + used * ca.mtimes(CtSi, e)
    sQ1 = sQ + used * ca.mtimes(CtSi, Ct.T)
    sX1 = sX + used * ca.mtimes(ca.mtimes(D.T, Si), Ct.T)
    su1 = su + ca.mtimes(ca.mtimes(An, s.B), v)   # A^n B v(k-1-n): the known input
    L = s.I - ca.mtimes(K, s.C)
    AL = ca.mtimes(s.A, L)
    Tp1 = ca.mtimes(T, AL.T)
    E1 = ca.mtimes(ca.mtimes(L, s.A), E)
    return ca.Function(name, [nn, Tp, E, xm, Pp, z, used, R, v, q, sw, sQ, sX, su],
                       [Tp1, E1, sw1, sQ1, sX1, su1, piv],
                       ["n", "Tp", "E", "xm", "Pm", "z", "used", "R", "v", "q", "sw", "sQ", "sX", "su"],
                       ["Tp1", "E1", "sw1", "sQ1", "sX1", "su1", "piv"])


def retro_finish(s: Chains, name: str) -> ca.Function:
    """Xia et al.'s correction (docs/mathematics.md section 4) from the sums of the recursion."""
    n, m = s.n, s.m
    npp = n * (n + 1) // 2
    N, x, Pp, PmNp, usedN = sym("N"), sym("x", n), sym("P", npp), sym("PmN", npp), sym("usedN")
    P, PmN = unpack(Pp, n), unpack(PmNp, n)
    z, R, q = sym("z", m), sym("R", m, m), sym("q", m)
    sw, sQ, sX, su = sym("sw", n), sym("sQ", n, n), sym("sX", n, n), sym("su", n)
    Phi1 = s.A_of(-N * s.opts.ts)
    AN = s.A_of(N * s.opts.ts)
    _, KN, _ = s.gain(PmN, R, usedN)
    PN = s.posterior(PmN, KN, R, usedN)        # P(k-N|k-N)
    wa = -ca.mtimes(Phi1, sw)
    # Q* = Phi1 (Q_d(N Ts) - sum) Phi1': the two nearly cancel, so subtract before Phi1
    # amplifies them (as the reference does), and keep both symmetric (the upper triangle
    # mirrored): in single precision the other order lost digits
    Dq = s.Q_of(q, N * s.opts.ts) - sQ
    Qs = symmetric(ca.mtimes(ca.mtimes(Phi1, symmetric(Dq)), Phi1.T))
    Pxw = ca.mtimes(ca.mtimes(ca.mtimes(AN, PN), sX), Phi1.T) - ca.mtimes(AN, Qs)
    xr = ca.mtimes(Phi1, x - su) + wa
    PhiPxw = ca.mtimes(Phi1, Pxw)
    inner = ca.mtimes(ca.mtimes(Phi1, P), Phi1.T) + PhiPxw + PhiPxw.T + Qs
    W = s.head_cols(s.head_rows(inner)) + R
    Mg, piv = right_divide(s.head_cols(ca.mtimes(P, Phi1.T) + Pxw), W)
    e = s.wrap(z - s.head_rows(xr))
    xs = x + ca.mtimes(Mg, e)
    Ps = P - ca.mtimes(ca.mtimes(Mg, W), Mg.T)
    Ps = (Ps + Ps.T) / 2          # symmetric again: see algorithms.md, retrodict
    _, pivP = spd_inverse(Ps)     # with a stale history P* can lose definiteness: reject then
    outs, names = [xs, pack(Ps), piv, pivP], ["xs", "Ps", "piv", "pivP"]
    if s.opts.gate is not None:   # the gate's test: the late innovation against its covariance W
        outs, names = outs + [normalized_square(e, W)], names + ["nis"]
    return ca.Function(name, [N, x, Pp, PmNp, usedN, z, R, q, sw, sQ, sX, su], outs,
                       ["N", "x", "P", "PmN", "usedN", "z", "R", "q", "sw", "sQ", "sX", "su"], names)
