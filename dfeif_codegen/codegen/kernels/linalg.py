"""Symbolic linear algebra on small CasADi SX matrices, written out entry by entry.

Why by hand: CasADi prints exactly the expressions built here, so each primitive is shaped for
the C it becomes (one division per column, each distinct entry of a symmetric result once, no
work for structural zeros). Nothing here knows the model; the kernels build on it.
"""

from __future__ import annotations

import casadi as ca
import numpy as np


def sym(name: str, rows: int = 1, cols: int = 1) -> ca.SX:
    return ca.SX.sym(name, rows, cols)


def dm(a: np.ndarray) -> ca.DM:
    """Constant matrix with zeros structural, so CasADi emits no work for them."""
    return ca.sparsify(ca.DM(np.atleast_2d(a)))


def powers(t: ca.SX, top: int) -> list[ca.SX]:
    out = [ca.SX(1.0)]
    for _ in range(top):
        out.append(out[-1] * t)
    return out


def chol(S: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Lower Cholesky factor and the pivots before the square root (<= 0: not positive definite)."""
    n = S.shape[0]
    L = ca.SX(n, n)
    piv = ca.SX(n, 1)
    for j in range(n):
        d = S[j, j]
        for k in range(j):
            d = d - L[j, k] * L[j, k]
        piv[j] = d
        L[j, j] = ca.sqrt(d)
        for i in range(j + 1, n):
            s = S[i, j]
            for k in range(j):
                s = s - L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    return L, piv


def chol_reciprocal(S: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """Cholesky S = L L' as its strictly lower part, the reciprocals r_j = 1 / L_jj and the pivots
    (<= 0: not positive definite). Why r = sqrt(1 / d) and not 1 / sqrt(d): CasADi rewrites
    s * (1 / x) into s / x, so only this form keeps one division per column and multiplies the
    column by it (n divisions instead of n^2 / 2)."""
    n = S.shape[0]
    L, r, piv = ca.SX(n, n), ca.SX(n, 1), ca.SX(n, 1)
    for j in range(n):
        d = S[j, j]
        for k in range(j):
            d = d - L[j, k] * L[j, k]
        piv[j] = d
        r[j] = ca.sqrt(1 / d)
        for i in range(j + 1, n):
            s = S[i, j]
            for k in range(j):
                s = s - L[i, k] * L[j, k]
            L[i, j] = s * r[j]
    return L, r, piv


def spd_inverse(S: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Inverse of a symmetric positive definite matrix by Cholesky, and its pivots.
    A 1x1 matrix is a division: the scalar innovation of a single output needs no factorisation.
    The fusion kernels use this form (their float CI master is at its tolerance); the node's
    information uses `spd_inverse_once`."""
    n = S.shape[0]
    if n == 1:
        return 1 / S, S
    L, piv = chol(S)
    Li = lower_inverse(L)
    return ca.mtimes(Li.T, Li), piv


def spd_inverse_once(S: ca.SX) -> tuple[ca.SX, ca.SX]:
    """`spd_inverse` with each distinct entry computed once: L^-1 by forward substitution with
    one division per column (multiplications by 1 / L_jj), then the upper triangle of L^-T L^-1
    mirrored. About half the operations of the plain form at n = 10."""
    n = S.shape[0]
    if n == 1:
        return 1 / S, S
    L, r, piv = chol_reciprocal(S)
    Li = ca.SX(n, n)
    for j in range(n):
        Li[j, j] = r[j]
        for i in range(j + 1, n):
            s = L[i, j] * Li[j, j]
            for k in range(j + 1, i):
                s = s + L[i, k] * Li[k, j]
            Li[i, j] = -s * r[i]
    Y = ca.SX(n, n)
    for a in range(n):
        for b in range(a, n):
            y = Li[b, a] * Li[b, b]
            for k in range(b + 1, n):
                y = y + Li[k, a] * Li[k, b]
            Y[a, b] = y
            Y[b, a] = y
    return Y, piv


def right_divide(B: ca.SX, S: ca.SX) -> tuple[ca.SX, ca.SX]:
    """B S^-1 for SPD S (a division when S is 1x1), and S's pivots."""
    if S.shape[0] == 1:
        return B / S, S
    Si, piv = spd_inverse(S)
    return ca.mtimes(B, Si), piv


def normalized_square(e: ca.SX, S: ca.SX) -> ca.SX:
    """e' S^-1 e for SPD S: an innovation's squared Mahalanobis length (the innovation gate's test)."""
    w, _ = right_divide(e.T, S)
    return ca.mtimes(w, e)


def trace_of_product(A: ca.SX, B: ca.SX) -> ca.SX:
    """tr(A B) = sum_ab A_ab B_ba: n^2 products instead of the n^3 of forming A B."""
    n = A.shape[0]
    out = ca.SX(0)
    for a in range(n):
        for b in range(n):
            out = out + A[a, b] * B[b, a]
    return out


def lower_inverse(L: ca.SX) -> ca.SX:
    """L^-1 of a lower-triangular L by forward substitution, column by column (lower again)."""
    n = L.shape[0]
    Li = ca.SX(n, n)
    for j in range(n):
        Li[j, j] = 1 / L[j, j]
        for i in range(j + 1, n):
            s = ca.SX(0)
            for k in range(j, i):
                s = s - L[i, k] * Li[k, j]
            Li[i, j] = s / L[i, i]
    return Li


def chol_solve(L: ca.SX, b: ca.SX) -> ca.SX:
    """(L L')^-1 b by a forward and a backward substitution."""
    n = L.shape[0]
    z = [None] * n
    for i in range(n):
        s = b[i]
        for k in range(i):
            s = s - L[i, k] * z[k]
        z[i] = s / L[i, i]
    out = [None] * n
    for i in reversed(range(n)):
        s = z[i]
        for k in range(i + 1, n):
            s = s - L[k, i] * out[k]
        out[i] = s / L[i, i]
    return ca.vertcat(*out)


# --- symmetric matrices: each distinct entry stored, read and computed once -------------------

def packed_index(i: int, j: int) -> int:
    """Where entry (i, j), i <= j, of a symmetric matrix sits in the node's packed storage: the
    upper triangle column by column (LAPACK's "U" packed layout)."""
    return j * (j + 1) // 2 + i


def unpack(p: ca.SX, n: int) -> ca.SX:
    """The symmetric n x n matrix of a packed upper triangle (packed_index order): each
    distinct entry of the node's P stored, read and computed once."""
    out = ca.SX(n, n)
    for j in range(n):
        for i in range(j + 1):
            out[i, j] = p[packed_index(i, j)]
            out[j, i] = p[packed_index(i, j)]
    return out


def pack(P: ca.SX) -> ca.SX:
    """The upper triangle of a symmetric result, column by column: only these entries are
    computed (CasADi drops the expressions of the lower triangle)."""
    n = P.shape[0]
    return ca.vertcat(*[P[i, j] for j in range(n) for i in range(j + 1)])


def symmetric(P: ca.SX) -> ca.SX:
    """P from its upper triangle: each distinct entry of a symmetric result computed once (the
    lower triangle reuses the same expressions), and of an input read once."""
    n = P.shape[0]
    out = ca.SX(n, n)
    for i in range(n):
        for j in range(i, n):
            out[i, j] = P[i, j]
            out[j, i] = P[i, j]
    return out


def packed_rows(Y: ca.SX) -> ca.SX:
    """The upper triangle of a symmetric matrix, row by row (the master's packed form):
    n(n+1)/2 numbers."""
    n = Y.shape[0]
    return ca.vertcat(*[Y[i, j] for i in range(n) for j in range(i, n)])


def unpacked_rows(v: ca.SX, n: int) -> ca.SX:
    """The symmetric n x n matrix whose upper triangle, row by row (`packed_rows`), is v."""
    out, at = ca.SX(n, n), 0
    for i in range(n):
        for j in range(i, n):
            out[i, j] = v[at]
            out[j, i] = v[at]
            at += 1
    return out
