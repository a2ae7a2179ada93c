"""The master's fusion kernels of a long chain as C loops (`Loop`), without straight-line parts.

Their work is symmetric inversions (`linalg.spd_inverse`: Cholesky, L^-1 by substitution,
L^-T L^-1) and products with them, Theta(n^3) operations: straight-line code of Theta(n^3) bytes
(the master's kernels grew as n^2.5 over n = 2..12). Above their limits in the orchestrator's
LOOP_OPS they are printed as loop nests instead, O(1) code in n, that do the straight-line
code's operations in its order (each sum in CasADi's order, from its first product; no
structural zero multiplied): the same results bit for bit, without -ffp-contract (tests).
What they cost: loads, stores and loop counting instead of registers (docs/algorithms.md,
looped kernels).
"""

from __future__ import annotations

import casadi as ca

from dfeif_codegen.codegen.kernels.csource import Loop, for_lines


def _at(n: int, row: str, col: str) -> str:
    """Entry (row, col) of an n x n array stored row by row."""
    return f"[({row} * {n}) + {col}]"


def _inverse(n: int, S: str, piv: int, Y: str) -> list[str]:
    """Y = S^-1 (both halves, n x n) and S's Cholesky pivots into piv[piv + j] by spd_inverse's
    operations: S read as CasADi stores it (column by column: entry (i, j) at j n + i, the
    diagonal and below), the factor L by rows into the work array L, then the strictly lower
    part of L^-1 by columns into L's upper triangle (column j as row j), then the upper triangle
    of L^-T L^-1, mirrored. As CasADi simplifies the straight-line expressions: a product with
    a diagonal entry 1 / L_jj of L^-1 is a division by L_jj (except its square on Y's
    diagonal), and the negations it moves about are exact."""
    a = lambda r, c: _at(n, r, c)  # noqa: E731
    chol = for_lines(f"j = 0; j < {n}; j++", [f"s = {S}{a('j', 'j')};"]
                     + for_lines("k = 0; k < j; k++", [f"s = s - (L{a('j', 'k')} * L{a('j', 'k')});"])
                     + [f"piv[{piv} + j] = s;" if piv else "piv[j] = s;", f"L{a('j', 'j')} = sqrt(s);"]
                     + for_lines(f"i = j + 1; i < {n}; i++", [f"s = {S}{a('j', 'i')};"]
                                 + for_lines("k = 0; k < j; k++", [f"s = s - (L{a('i', 'k')} * L{a('j', 'k')});"])
                                 + [f"L{a('i', 'j')} = s / L{a('j', 'j')};"]))
    inv = for_lines(f"j = 0; j < {n}; j++", for_lines(
        f"i = j + 1; i < {n}; i++", [f"s = -(L{a('i', 'j')} / L{a('j', 'j')});"]
        + for_lines("k = j + 1; k < i; k++", [f"s = s - (L{a('i', 'k')} * L{a('j', 'k')});"])
        + [f"L{a('j', 'i')} = s / L{a('i', 'i')};"]))
    prod = for_lines(f"i = 0; i < {n}; i++", [f"s = (casadi_real)1 / L{a('i', 'i')};", "s = s * s;"]
                     + for_lines(f"k = i + 1; k < {n}; k++", [f"s = s + (L{a('i', 'k')} * L{a('i', 'k')});"])
                     + [f"{Y}{a('i', 'i')} = s;"]
                     + for_lines(f"j = i + 1; j < {n}; j++", [f"s = L{a('i', 'j')} / L{a('j', 'j')};"]
                                 + for_lines(f"k = j + 1; k < {n}; k++", [f"s = s + (L{a('i', 'k')} * L{a('j', 'k')});"])
                                 + [f"{Y}{a('i', 'j')} = s;", f"{Y}{a('j', 'i')} = s;"]))
    return chol + inv + prod


def _times(n: int, Y: str, d: str, out: str, first: str = "") -> list[str]:
    """out = first + Y d (CasADi's mtimes: each sum from its first product, in column order)."""
    return for_lines(f"i = 0; i < {n}; i++", [f"s = {Y}{_at(n, 'i', '0')} * {d}[0];"]
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
    """fusion.fuse_finish_difference: P_c^-1 + dY into P (Y_c's upper entry plus dY's, both
    halves), then `_finish`."""
    body = (_inverse(n, "Pc", 0, "P")
            + _packed_rows(n, [f"s = P{_at(n, 'i', 'j')} + dY[k];", f"P{_at(n, 'i', 'j')} = s;",
                               f"P{_at(n, 'j', 'i')} = s;"])
            + _finish(n, "dy", n))
    return Loop([], _decls(n, ()), body)


LOOPS = {"master_info": master_info_loop, "master_gain": master_gain_loop, "fuse_finish": fuse_finish_loop,
         "fuse_finish_difference": fuse_finish_difference_loop}


def loop_of(kind: str, f: ca.Function) -> Loop:
    """The loops of fusion kernel `kind` (a key of LOOPS) for f, whose inputs are n long."""
    return LOOPS[kind](f.numel_in(f.n_in() - 1))
