"""Covariance intersection (`--fusion ci`): the kernels of one Newton step on the weights.

The master minimises tr((sum w_i Y_i)^-1) over the simplex; the iteration, the free set and the
regulariser are C (master_ci.c.j2), each step's symbolic work is here: the gradient and Hessian
(`ci_grad`), the step direction (`ci_dir`) and (H + rho I) d (`ci_hd`). The Hessian is carried
as itself (M x M) or as its factor G (H = G G', M x n^2), whichever step costs fewer operations
(`ci_kernels`).
"""

from __future__ import annotations

import math

import casadi as ca

from dfeif_codegen.codegen.kernels.chains import Chains
from dfeif_codegen.codegen.kernels.linalg import (chol, chol_solve, lower_inverse, sym, symmetric,
                                                  trace_of_product, unpacked_rows)


def ci_grad(s: Chains, name: str, lowrank: bool) -> ca.Function:
    """Covariance intersection, first half of a Newton step (algorithms.md, master "ci"):
    gradient of tr((sum w_i Y_i)^-1) and the Hessian H, each Y_i packed; absent nodes have
    w_i = 0 and Y_i = 0. With S = sum w_i Y_i = L L', P = S^-1 = L^-T L^-1 and
    W_i = L^-1 Y_i P: g_i = -tr(P Y_i P) = -<L^-1, W_i> and H_ij = 2 tr(P Y_i P Y_j P) =
    2 <W_i, W_j> (Frobenius), a Gram matrix. `F` carries H itself (M x M), or with `lowrank`
    its factor G (row i = sqrt(2) vec W_i, H = G G'), which the step uses without forming H:
    O(M n^4) instead of O(M^2 n^2). `hd` is H's diagonal (for the regulariser, master_ci.c.j2)."""
    n, M = s.n, s.opts.nodes
    d = n * (n + 1) // 2
    w = sym("w", M)
    Y = sym("Y", M * d)     # node i's packed Y_i at entries i d .. (i + 1) d - 1
    Ys = [unpacked_rows(Y[i * d:(i + 1) * d], n) for i in range(M)]
    Sp = w[0] * Y[0:d]
    for i in range(1, M):
        Sp = Sp + w[i] * Y[i * d:(i + 1) * d]
    L, piv = chol(unpacked_rows(Sp, n))
    Li = lower_inverse(L)
    P = symmetric(ca.mtimes(Li.T, Li))
    W = [ca.mtimes(ca.mtimes(Li, Yi), P) for Yi in Ys]
    g = ca.vertcat(*[-trace_of_product(Li, Wi.T) for Wi in W])
    if lowrank:
        G = ca.vertcat(*[math.sqrt(2) * ca.reshape(Wi, 1, n * n) for Wi in W])
        hd = ca.vertcat(*[ca.dot(G[i, :], G[i, :]) for i in range(M)])
        F = ca.reshape(G.T, M * n * n, 1)                       # row by row
    else:
        H = ca.SX(M, M)
        for i in range(M):
            for j in range(i, M):
                H[i, j] = 2 * trace_of_product(W[i], W[j].T)
                H[j, i] = H[i, j]
        hd = ca.diag(H)
        F = ca.reshape(H, M * M, 1)
    return ca.Function(name, [w, Y], [g, F, hd, piv], ["wt", "Y"], ["g", "F", "hd", "piv"])


def ci_dir(s: Chains, name: str, lowrank: bool) -> ca.Function:
    """Second half: the step d_F of `[H_FF + rho I, 1; 1', 0] [d; mu] = [-g_F; 0]` over the
    free set F (mask f), d_i = 0 off F, by the Schur complement: u1 = Hf^-1 (f g),
    u2 = Hf^-1 f, mu = -f'u1 / f'u2, d = -(u1 + mu u2), with Hf the regularised H on F and
    the identity off it (there the right-hand sides are 0, so d_i is exactly 0). Hf^-1 by a
    Cholesky solve of the M x M matrix, or with `lowrank` by Woodbury's identity through the
    n^2 x n^2 matrix I + G_F' G_F / rho (Hf = D + G_F G_F', D = rho on F and 1 off it; its
    eigenvalues are >= 1, so it factors in any precision): O(M n^4 + n^6), linear in M."""
    n, M = s.n, s.opts.nodes
    g, f, rho = sym("g", M), sym("free", M), sym("rho")
    if lowrank:
        q = n * n
        Fs = sym("F", M * q)
        G = ca.reshape(Fs, q, M).T                                  # row i = node i
        c = f / rho                 # D^-1 on F (the mask is 0 or 1); rows off F drop out
        cG = ca.diag(c) @ G
        C = ca.SX(q, q)             # I + G_F' D^-1 G_F, its lower triangle (all chol reads)
        for a in range(q):
            for b in range(a + 1):
                C[a, b] = (1 if a == b else 0) + ca.dot(cG[:, a], G[:, b])
        L, piv = chol(C)

        def solve(bv):              # bv is 0 off F: D^-1 bv = c bv
            return c * bv - ca.mtimes(cG, chol_solve(L, ca.mtimes(cG.T, bv)))
    else:
        Fs = sym("F", M * M)
        H = ca.reshape(Fs, M, M)
        Hf = ca.SX(M, M)
        for i in range(M):
            for j in range(M):
                Hf[i, j] = f[i] * f[j] * H[i, j]
            Hf[i, i] = Hf[i, i] + f[i] * rho + (1 - f[i])
        L, piv = chol(Hf)

        def solve(bv):
            return chol_solve(L, bv)
    u1, u2 = solve(f * g), solve(f)
    mu = -ca.dot(f, u1) / ca.dot(f, u2)
    return ca.Function(name, [g, Fs, f, rho], [-(u1 + mu * u2), piv], ["g", "F", "fmask", "rho"], ["d", "piv"])


def ci_hd(s: Chains, name: str, lowrank: bool) -> ca.Function:
    """(H + rho I) d, for the model's gradient along a pivot: G (G' d) + rho d with `lowrank`."""
    n, M = s.n, s.opts.nodes
    d, rho = sym("d", M), sym("rho")
    if lowrank:
        Fs = sym("F", M * n * n)
        G = ca.reshape(Fs, n * n, M).T
        hd = ca.mtimes(G, ca.mtimes(G.T, d))
    else:
        Fs = sym("F", M * M)
        hd = ca.mtimes(ca.reshape(Fs, M, M), d)
    return ca.Function(name, [d, Fs, rho], [hd + rho * d], ["d", "F", "rho"], ["hd"])


def ci_kernels(s: Chains, name) -> list[ca.Function]:
    """ci_grad, ci_dir and ci_hd in the form whose Newton step costs fewer operations for this
    model and node count (CasADi's count; the M x M form on a tie): the low-rank one once M
    outgrows n^2, roughly. `name(kernel)` gives a kernel's C name."""
    forms = [(ci_grad(s, name("ci_grad"), lowrank), ci_dir(s, name("ci_dir"), lowrank), lowrank)
             for lowrank in (False, True)]
    grad, step, lowrank = min(forms, key=lambda f: f[0].n_instructions() + f[1].n_instructions())
    return [grad, step, ci_hd(s, name("ci_hd"), lowrank)]
