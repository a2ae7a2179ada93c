"""The master's fusion kernels of a long chain as C loops (`Loop`), without straight-line parts.

Their work is symmetric inversions (`linalg.spd_inverse`: Cholesky, L^-1 by substitution,
L^-T L^-1) and products with them, Theta(n^3) operations: straight-line code of Theta(n^3) bytes
(the master's kernels grew as n^2.6 over n = 2..12). Above their limits in the orchestrator's
LOOP_OPS they are printed as loops instead, each around one sum written out: O(n^2) code that
does the straight-line code's operations in its order (each sum in CasADi's order, from its
first product; no structural zero multiplied): the same results bit for bit, without
-ffp-contract (tests). What they cost: a loop counter and loads instead of registers, about a
third more instructions than the straight-line code (docs/algorithms.md, looped kernels).
"""

from __future__ import annotations

import casadi as ca

from dfeif_codegen.codegen.kernels.chains import Chains
from dfeif_codegen.codegen.kernels.csource import Loop, for_lines


def _plus(expr: str, k: int) -> str:
    """expr + k, or expr when k is 0 (MISRA 2.2: no operation without effect)."""
    return f"{expr} + {k}" if k else expr


def _at(n: int, row: int | str, col: int | str) -> str:
    """Entry (row, col) of an n x n array stored row by row, as a subscript (`_index`)."""
    return f"[{_index(n, row, col)}]"


def _index(n: int, row: int | str, col: int | str) -> str:
    """The index of entry (row, col) of an n x n array stored row by row, either a number or a
    loop variable, with no operation without effect (MISRA 2.2)."""
    if isinstance(row, int) and isinstance(col, int):
        return str(row * n + col)
    if isinstance(row, int):
        return _plus(str(col), row * n)
    return _plus(f"({row} * {n})", int(col)) if isinstance(col, int) else f"({row} * {n}) + {col}"


def _cholesky(n: int, S: str, piv: int, L: str = "L") -> list[str]:
    """S's Cholesky factor by rows into the work array L, its pivots into piv[piv + j], by
    linalg.chol's operations: S read as CasADi stores it (column by column: entry (i, j) at
    j n + i, the diagonal and below). One loop per column j of L (rows i >= j), its sum written
    out."""
    out: list[str] = []
    for j in range(n):   # L's column j: row j (the pivot) and the rows below
        sums = [f"s = s - ({L}[{_plus(f'(i * {n})', k)}] * {L}[{j * n + k}]);" for k in range(j)]
        out += for_lines(f"i = {j}; i < {n}; i++", [f"s = {S}[{_plus('i', j * n)}];"] + sums + [
            "if (i == " + f"{j}) {{", f"    piv[{piv + j}] = s;", f"    {L}[{j * n + j}] = sqrt(s);",
            "} else {", f"    {L}[{_plus(f'(i * {n})', j)}] = s / {L}[{j * n + j}];", "}"])
    return out


def _inverse(n: int, S: str, piv: int, Y: str, L: str = "L") -> list[str]:
    """Y = S^-1 (both halves, n x n) and S's Cholesky pivots into piv[piv + j] by spd_inverse's
    operations: the factor (`_cholesky`) into the work array L, then the strictly lower
    part of L^-1 by columns into L's upper triangle (column j as row j), then the upper triangle
    of L^-T L^-1, mirrored. As CasADi simplifies the straight-line expressions: a product with
    a diagonal entry 1 / L_jj of L^-1 is a division by L_jj (except its square on Y's
    diagonal), and the negations it moves about are exact.
    Each sum is written out (one statement per product, O(n) code) inside one loop over the
    entries that share its length: column j of L (rows i >= j), diagonal d of L^-1 (entries
    (j + d, j), which need only diagonals before d) and column j of Y (rows i <= j), so O(n^2)
    code in all, with registers for the sums and no inner loop to count."""
    out = _cholesky(n, S, piv, L)
    for d in range(1, n):   # L^-1's entries (i, j), i = j + d, stored at (j, i)
        sums = [f"s = s - ({L}[(i * {n}) + j + {m}] * {L}[(j * {n}) + j + {m}]);" for m in range(1, d)]
        out += for_lines(f"j = 0; j < {n - d}; j++", [f"i = j + {d};", f"s = -({L}[(i * {n}) + j] / {L}[(j * {n}) + j]);"]
                         + sums + [f"{L}[(j * {n}) + i] = s / {L}[(i * {n}) + i];"])
    for j in range(n):   # Y's column j, rows i <= j
        sums = [f"s = s + ({L}[{_plus(f'(i * {n})', k)}] * {L}[{j * n + k}]);" for k in range(j + 1, n)]
        out += for_lines(f"i = 0; i <= {j}; i++", [
            f"if (i == {j}) {{", f"    s = (casadi_real)1 / {L}[{j * n + j}];", "    s = s * s;", "} else {",
            f"    s = {L}[{_plus(f'(i * {n})', j)}] / {L}[{j * n + j}];", "}"] + sums
            + [f"{Y}[{_plus(f'(i * {n})', j)}] = s;", f"{Y}[{_plus('i', j * n)}] = s;"])
    return out


def _times(n: int, Y: str, d: str, out: str, first: str = "") -> list[str]:
    """out = first + Y d (CasADi's mtimes: each sum from its first product, in column order)."""
    return for_lines(f"i = 0; i < {n}; i++", [f"s = {Y}[i * {n}] * {d}[0];"]
                     + for_lines(f"j = 1; j < {n}; j++", [f"s = s + ({Y}{_at(n, 'i', 'j')} * {d}[j]);"])
                     + [f"{out}[i] = {first}s;"])


def _packed_rows(n: int, body: list[str]) -> list[str]:
    """`body` for each entry (i, j), i <= j, k its place in the master's packed rows."""
    return ["k = 0;"] + for_lines(f"i = 0; i < {n}; i++", for_lines(f"j = i; j < {n}; j++", body + ["k++;"]))


def _decls(n: int, full: tuple[str, ...]) -> list[str]:
    return ([f"casadi_real L[{n * n}]; /* the Cholesky factor by rows, then its inverse's columns */"]
            + [f"casadi_real {name}[{n * n}];" for name in full] + ["casadi_real s;", "int i;", "int j;", "int k;"])


def master_info_loop(n: int) -> Loop:
    """fusion.master_info: Y = P^-1 (packed rows), y = Y (x - c), the pivots."""
    body = (_inverse(n, "P", 0, "Yf") + for_lines(f"i = 0; i < {n}; i++", ["e[i] = x[i] - c[i];"])
            + _times(n, "Yf", "e", "y") + _packed_rows(n, [f"Y[k] = Yf{_at(n, 'i', 'j')};"]))
    return Loop([], _decls(n, ("Yf",)) + [f"casadi_real e[{n}];"], body)


def master_gain_loop(n: int) -> Loop:
    """fusion.master_gain: the update's information into the outputs, then less the prediction's."""
    body = (_inverse(n, "P", 0, "Yf") + for_lines(f"i = 0; i < {n}; i++", ["e[i] = x[i] - c[i];"])
            + _times(n, "Yf", "e", "dy") + _packed_rows(n, [f"dY[k] = Yf{_at(n, 'i', 'j')};"])
            + _inverse(n, "Pp", n, "Yf") + for_lines(f"i = 0; i < {n}; i++", ["e[i] = xp[i] - c[i];"])
            + _times(n, "Yf", "e", "z") + for_lines(f"i = 0; i < {n}; i++", ["dy[i] = dy[i] - z[i];"])
            + _packed_rows(n, [f"dY[k] = dY[k] - Yf{_at(n, 'i', 'j')};"]))
    return Loop([], _decls(n, ("Yf",)) + [f"casadi_real e[{n}];", f"casadi_real z[{n}];"], body)


def _finish(n: int, y: str, piv: int) -> list[str]:
    """x = c + P y, P = S^-1 for S in the output P (`_inverse` reads the diagonal and below)."""
    return _inverse(n, "P", piv, "P") + _times(n, "P", y, "x", "c[i] + ")


def fuse_finish_loop(n: int) -> Loop:
    """fusion.fuse_finish: the packed Y unpacked into P, then `_finish`."""
    body = _packed_rows(n, [f"P{_at(n, 'i', 'j')} = Y[k];", f"P{_at(n, 'j', 'i')} = Y[k];"]) + _finish(n, "y", 0)
    return Loop([], _decls(n, ()), body)


def fuse_finish_difference_loop(n: int) -> Loop:
    """fusion.fuse_finish_difference: L = chol(P_c) by rows, D (the packed gains) unpacked into
    the output P, W = D L, M = I + L' W into D (upper sums, mirrored), M^-1 into P (W its work
    array), V = L M^-1 into D, P = V L' (upper sums, mirrored), x = c + P dy. Each sum over the
    rows or columns L's triangle leaves, in the straight line's order, inside one loop over the
    entries that share its length."""
    at = lambda a, r, c: a + _at(n, r, c)  # noqa: E731
    body = _cholesky(n, "Pc", 0) + _packed_rows(n, [f"{at('P', 'i', 'j')} = dY[k];", f"{at('P', 'j', 'i')} = dY[k];"])
    for j in range(n):   # W's column j: D's row k times L's column j (rows a >= j)
        sums = [f"s = s + ({at('P', 'k', a)} * L[{a * n + j}]);" for a in range(j + 1, n)]
        body += for_lines(f"k = 0; k < {n}; k++", [f"s = {at('P', 'k', j)} * L[{j * n + j}];"] + sums
                          + [f"{at('W', 'k', j)} = s;"])
    for i in range(n):   # M's row i, columns j >= i: L's column i (rows k >= i) times W's column j
        sums = [f"s = s + (L[{k * n + i}] * {at('W', k, 'j')});" for k in range(i + 1, n)]
        body += for_lines(f"j = {i}; j < {n}; j++", [f"s = L[{i * n + i}] * {at('W', i, 'j')};"] + sums + [
            f"if (j == {i}) {{", "    s = (casadi_real)1 + s;", "}", f"{at('D', i, 'j')} = s;",
            f"{at('D', 'j', i)} = s;"])
    body += _inverse(n, "D", n, "P", "W")
    for i in range(n):   # V's row i: L's row i (columns a <= i) times M^-1's column b
        sums = [f"s = s + (L[{i * n + a}] * {at('P', a, 'j')});" for a in range(1, i + 1)]
        body += for_lines(f"j = 0; j < {n}; j++", [f"s = L[{i * n}] * P[j];"] + sums + [f"{at('D', i, 'j')} = s;"])
    for j in range(n):   # P's column j, rows i <= j: V's row i times L's row j (columns b <= j)
        sums = [f"s = s + ({at('D', 'i', b)} * L[{j * n + b}]);" for b in range(1, j + 1)]
        body += for_lines(f"i = 0; i <= {j}; i++", [f"s = {at('D', 'i', 0)} * L[{j * n}];"] + sums + [
            f"{at('P', 'i', j)} = s;", f"{at('P', j, 'i')} = s;"])
    body += _times(n, "P", "dy", "x", "c[i] + ")
    return Loop([], _decls(n, ("D", "W")), body)


LOOPS = {"master_info": master_info_loop, "master_gain": master_gain_loop, "fuse_finish": fuse_finish_loop,
         "fuse_finish_difference": fuse_finish_difference_loop}


def loop_of(kind: str, f: ca.Function) -> Loop:
    """The loops of fusion kernel `kind` (a key of LOOPS) for f, whose inputs are n long."""
    return LOOPS[kind](f.numel_in(f.n_in() - 1))


def advance_loop(s: Chains, f: ca.Function) -> Loop:
    """fusion.advance: A(N Ts) and Q_d(N Ts) by one part (`at`, O(n^2) code, dense), then
    x1 = A x + effect and the upper triangle of A P A' + Q_d (P's upper triangle, mirrored) as
    loops over A's upper triangle (A is block upper triangular with a unit diagonal): the
    straight-line sums' products in their order, with the zeros between chains added exactly."""
    n, name = s.n, f.name()
    N, q = ca.SX.sym("N"), ca.SX.sym("q", s.m)
    t = N * s.opts.ts
    at = ca.Function(f"{name}_at", [N, q], [ca.densify(s.A_of(t)), ca.densify(s.Q_of(q, t))], ["N", "q"],
                     ["A", "Q"])
    a = lambda r, c: _at(n, r, c)  # noqa: E731  (column-major (i, j) is [j n + i])
    body = ([f"(void){name}_at(N, q, A, Q);"]
            + for_lines(f"j = 0; j < {n}; j++", for_lines("i = 0; i <= j; i++", [
                f"P1{a('j', 'i')} = P{a('j', 'i')};", f"P1{a('i', 'j')} = P{a('j', 'i')};"]))
            + for_lines(f"i = 0; i < {n}; i++", for_lines(f"j = 0; j < {n}; j++", [
                f"s = A{a('i', 'i')} * P1{a('j', 'i')};"]
                + for_lines(f"k = i + 1; k < {n}; k++", [f"s = s + (A{a('k', 'i')} * P1{a('j', 'k')});"])
                + [f"G{a('j', 'i')} = s;"]))
            + for_lines(f"i = 0; i < {n}; i++", [f"s = A{a('i', 'i')} * x[i];"]
                        + for_lines(f"k = i + 1; k < {n}; k++", [f"s = s + (A{a('k', 'i')} * x[k]);"])
                        + ["x1[i] = s + effect[i];"])
            + for_lines(f"j = 0; j < {n}; j++", for_lines("i = 0; i <= j; i++", [
                f"s = G{a('j', 'i')} * A{a('j', 'j')};"]
                + for_lines(f"k = j + 1; k < {n}; k++", [f"s = s + (G{a('k', 'i')} * A{a('k', 'j')});"])
                + [f"s = s + Q{a('j', 'i')};", f"P1{a('j', 'i')} = s;", f"P1{a('i', 'j')} = s;"])))
    decls = [f"casadi_real A[{n * n}];", f"casadi_real Q[{n * n}];", f"casadi_real G[{n * n}]; /* A P */",
             "casadi_real s;", "int i;", "int j;", "int k;"]
    return Loop([at], decls, body)
