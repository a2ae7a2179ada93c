"""node_predict and info of a long chain as C loops over small straight-line parts (`Loop`).

Straight-line code of Theta(n^3) operations is Theta(n^3) bytes: above the orchestrator's
LOOP_OPS, these two node kernels are printed as loops over static parts of O(n^2) code instead,
the same work in a fraction of the bytes (docs/algorithms.md, looped kernels).
"""

from __future__ import annotations

import casadi as ca

from dfeif_codegen.codegen.kernels.chains import Chains
from dfeif_codegen.codegen.kernels.csource import Loop, for_lines
from dfeif_codegen.codegen.kernels.linalg import pack, sym


def node_predict_loop(s: Chains, name: str) -> Loop:
    """node_predict as loops: G = A P column by column, then row i of A P A' = A (row i of G)',
    both by the part `A c` (O(nnz A) code); then x1 = A x + B v and P1 = A P A' + Q packed
    (O(n^2) code). Twice the multiplications of the straight-line code (no symmetry in the
    products), none of its Theta(n^3) bytes."""
    n, m, npp = s.n, s.m, s.n * (s.n + 1) // 2
    c = sym("col", n)
    a = ca.Function(f"{name}_a", [c], [ca.mtimes(s.A, c)], ["col"], ["Acol"])
    post, v, q, M = sym("post", n + npp), sym("v", m), sym("q", m), sym("APA", n * n)
    x1 = ca.mtimes(s.A, post[:n]) + ca.mtimes(s.B, v)
    P1 = ca.reshape(M, n, n) + s.Q_of(q)
    end = ca.Function(f"{name}_end", [post, v, q, M], [x1, pack(P1)], ["post", "v", "q", "APA"],
                      ["x1", "P1"])
    unpack = ["k = 0;"] + for_lines(f"j = 0; j < {n}; j++", for_lines("i = 0; i <= j; i++", [
        f"P[(j * {n}) + i] = post[{n} + k];", f"P[(i * {n}) + j] = post[{n} + k];", "k++;"]))
    body = (unpack + for_lines(f"j = 0; j < {n}; j++", [f"(void){name}_a(&P[j * {n}], &G[j * {n}]);"])
            + for_lines(f"i = 0; i < {n}; i++", for_lines(f"j = 0; j < {n}; j++", [f"g[j] = G[(j * {n}) + i];"])
                        + [f"(void){name}_a(g, &P[i * {n}]);"])
            + [f"(void){name}_end(post, v, q, P, x1, P1);"])
    decls = [f"casadi_real P[{n * n}]; /* P, then A P A' */", f"casadi_real G[{n * n}]; /* A P */",
             f"casadi_real g[{n}]; /* a row of A P */", "int i;", "int j;", "int k;"]
    return Loop([a, end], decls, body)


def _forward(n: int, L: ca.SX, r: ca.SX, b: ca.SX) -> list:
    """z = L^-1 b for the lower-triangular L of `info_loop` (row k at L[k n ...], 1 / L_kk in r),
    in linalg.chol_reciprocal's order of operations; a row whose r is still 0 gives z = 0."""
    z = []
    for k in range(n):
        s = b[k]
        for j in range(k):
            s = s - L[k * n + j] * z[j]
        z.append(s * r[k])
    return z


def _info_parts(n: int, name: str) -> list[ca.Function]:
    """info_loop's parts: `row` (one row of the Cholesky factor) and `solve` (P^-1 b)."""
    L, r, b, bii = sym("L", n * n), sym("r", n), sym("b", n), sym("bii")
    z = _forward(n, L, r, b)
    d = bii
    for zk in z:
        d = d - zk * zk
    row = ca.Function(f"{name}_row", [L, r, b, bii], [ca.vertcat(*z), d, ca.sqrt(1 / d)],
                      ["L", "r", "b", "bii"], ["z", "d", "rd"])
    w = [None] * n
    z = _forward(n, L, r, b)
    for k in reversed(range(n)):
        s = z[k]
        for j in range(k + 1, n):
            s = s - L[j * n + k] * w[j]
        w[k] = s * r[k]
    solve = ca.Function(f"{name}_solve", [L, r, b], [ca.vertcat(*w)], ["L", "r", "b"], ["sol"])
    return [row, solve]


def info_loop(s: Chains, name: str) -> Loop:
    """info as loops: the Cholesky factor row by row (part `row`: a forward substitution with
    the rows above, the pivot and 1 / sqrt of it; the same operations as the straight-line
    factorisation), then each column of Y = P^-1 and y = P^-1 (x - c) by two substitutions
    (part `solve`). Each part O(n^2) code; the solves take about twice the straight-line
    code's operations."""
    n = s.n
    body = (for_lines(f"i = 0; i < {n * n}; i++", ["L[i] = (casadi_real)0;"])
            + for_lines(f"i = 0; i < {n}; i++", ["r[i] = (casadi_real)0;", "e[i] = (casadi_real)0;"])
            + for_lines(f"i = 0; i < {n}; i++", [
                f"(void){name}_row(L, r, &P[i * {n}], &P[(i * {n}) + i], z, &piv[i], &rd);", "r[i] = rd;"]
                + for_lines("j = 0; j < i; j++", [f"L[(i * {n}) + j] = z[j];"]))
            + for_lines(f"j = 0; j < {n}; j++", ["e[j] = (casadi_real)1;", f"(void){name}_solve(L, r, e, z);",
                                                "e[j] = (casadi_real)0;"]
                        + for_lines("i = 0; i <= j; i++", [f"Y[(j * {n}) + i] = z[i];", f"Y[(i * {n}) + j] = z[i];"]))
            + for_lines(f"i = 0; i < {n}; i++", ["e[i] = x[i] - c[i];"])
            + [f"(void){name}_solve(L, r, e, y);"])
    decls = [f"casadi_real L[{n * n}]; /* the Cholesky factor's rows, 0 until computed */",
             f"casadi_real r[{n}]; /* 1 / L_ii, 0 until computed */", f"casadi_real e[{n}];",
             f"casadi_real z[{n}];", "casadi_real rd;", "int i;", "int j;"]
    return Loop(_info_parts(n, name), decls, body)
