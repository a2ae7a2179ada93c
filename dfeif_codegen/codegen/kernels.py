"""The filter, fusion and control math as CasADi SX functions, and their C source.

Why CasADi: it turns the symbolic model into straight-line C with shared subexpressions and the
known structure folded away (Brunovsky A_d is constant and sparse, C = e_head picks entries), so
no generic matrix code ships to the microcontroller. Every kernel is one step of work; loops over
the late-measurement window, over nodes and over the CI iterations are plain C in the templates.
Straight-line code of Theta(n^3) operations is Theta(n^3) bytes, so above LOOP_OPS operations,
node_predict and info are printed as C loops over static straight-line parts of O(n^2) code
(`Loop`): the same work, a fraction of the bytes.

The sympy model is converted by `symbolic.numeric.to_casadi`, the one sympy -> CasADi bridge.
The C that CasADi prints is post-processed (`c_source`) into one file per group: internal helpers
made `static` and named per file, each entry point a typed function `<model>_kern_<name>` whose
named, sized parameters come from the kernel's signature (so callers never fill `arg[]`/`res[]`
by position), statements spaced as the style file asks, the real type named, and, for single
precision, `f` math calls and `f` literals so that no double arithmetic hides in a float build.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from math import factorial

import casadi as ca
import numpy as np

from dfeif_codegen import angles
from dfeif_codegen.symbolic import discretize
from dfeif_codegen.symbolic.numeric import to_casadi
from dfeif_codegen.codegen import layout
from dfeif_codegen.codegen.options import Options

# --- symbolic linear algebra on small matrices ------------------------------------------------

def _sym(name: str, rows: int = 1, cols: int = 1) -> ca.SX:
    return ca.SX.sym(name, rows, cols)


def _dm(a: np.ndarray) -> ca.DM:
    """Constant matrix with zeros structural, so CasADi emits no work for them."""
    return ca.sparsify(ca.DM(np.atleast_2d(a)))


def _powers(t: ca.SX, top: int) -> list[ca.SX]:
    out = [ca.SX(1.0)]
    for _ in range(top):
        out.append(out[-1] * t)
    return out


def _chol(S: ca.SX) -> tuple[ca.SX, ca.SX]:
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


def _chol_reciprocal(S: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
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
    L, piv = _chol(S)
    Li = _lower_inverse(L)
    return ca.mtimes(Li.T, Li), piv


def spd_inverse_once(S: ca.SX) -> tuple[ca.SX, ca.SX]:
    """`spd_inverse` with each distinct entry computed once: L^-1 by forward substitution with
    one division per column (multiplications by 1 / L_jj), then the upper triangle of L^-T L^-1
    mirrored. About half the operations of the plain form at n = 10."""
    n = S.shape[0]
    if n == 1:
        return 1 / S, S
    L, r, piv = _chol_reciprocal(S)
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


def _right_divide(B: ca.SX, S: ca.SX) -> tuple[ca.SX, ca.SX]:
    """B S^-1 for SPD S (a division when S is 1x1), and S's pivots."""
    if S.shape[0] == 1:
        return B / S, S
    Si, piv = spd_inverse(S)
    return ca.mtimes(B, Si), piv


def _trace_of_product(A: ca.SX, B: ca.SX) -> ca.SX:
    """tr(A B) = sum_ab A_ab B_ba: n^2 products instead of the n^3 of forming A B."""
    n = A.shape[0]
    out = ca.SX(0)
    for a in range(n):
        for b in range(n):
            out = out + A[a, b] * B[b, a]
    return out


def _lower_inverse(L: ca.SX) -> ca.SX:
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


def _chol_solve(L: ca.SX, b: ca.SX) -> ca.SX:
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


# --- the kernels ------------------------------------------------------------------------------

@dataclass
class KernelSet:
    """The CasADi functions of one model, grouped by the C file they go into."""

    groups: dict[str, list[ca.Function]] = field(default_factory=dict)
    local_work: set[str] = field(default_factory=set)   # groups whose kernels keep work locally
    # kernel -> the kernel it calls on packed copies of its n x n arguments (`packed_wrapper`)
    wrappers: dict[str, str] = field(default_factory=dict)
    # kernel -> the C loops that compute it instead of its straight-line code (`Loop`)
    loops: dict[str, "Loop"] = field(default_factory=dict)

    def all(self) -> list[ca.Function]:
        return [f for fs in self.groups.values() for f in fs]


@dataclass
class Loop:
    """A kernel printed as C loops over straight-line parts (`parts`, static in its file, each
    O(n^2) code) instead of its own straight-line code, which is Theta(n^3) bytes for Theta(n^3)
    operations. `decls` and `body`: the C between the parameters and the return (`casadi_real`
    names the real type); the kernel's own ca.Function still gives its signature."""

    parts: list[ca.Function]
    decls: list[str]
    body: list[str]


def _for(head: str, body: list[str]) -> list[str]:
    """A C for loop as lines: `for (head) {`, the body indented, `}`."""
    return [f"for ({head}) {{"] + [INDENT + line for line in body] + ["}"]


class _Builder:
    def __init__(self, flat, opts: Options):
        self.flat, self.opts = flat, opts
        self.n, self.m = flat.n, flat.m
        self.degrees = flat.degrees
        self.heads = flat.heads
        self.angles = [c.angle for c in flat.chains]
        A, B, C = flat.discrete(opts.ts)
        self.A, self.B, self.C = _dm(A), _dm(B), _dm(C)
        self.Qunit = [discretize.chain_Q(r, opts.ts, 1.0) for r in self.degrees]
        self.I = ca.DM.eye(self.n)

    # chain-structured constants with a runtime factor -------------------------------------
    def A_of(self, t: ca.SX) -> ca.SX:
        """A_d(t) = exp(A_c t) for symbolic t: A^n = A_of(n Ts), A^-N = A_of(-N Ts)."""
        out = ca.SX(self.n, self.n)
        pw = _powers(t, max(self.degrees))
        at = 0
        for r in self.degrees:
            for i in range(r):
                for j in range(i, r):
                    out[at + i, at + j] = pw[j - i] / factorial(j - i) if j > i else ca.SX(1.0)
            at += r
        return out

    def Q_of(self, q: ca.SX, t: ca.SX | None = None) -> ca.SX:
        """Q_d for densities q (one per chain) over Ts, or over a symbolic period t."""
        out = ca.SX(self.n, self.n)
        pw = _powers(t, 2 * max(self.degrees)) if t is not None else None
        at = 0
        for c, r in enumerate(self.degrees):
            for i in range(1, r + 1):
                for j in range(1, r + 1):
                    if pw is None:
                        value = q[c] * self.Qunit[c][i - 1, j - 1]
                    else:
                        power = 2 * r - i - j + 1
                        value = q[c] * pw[power] / (factorial(r - i) * factorial(r - j) * power)
                    out[at + i - 1, at + j - 1] = value
            at += r
        return out

    def head_rows(self, X: ca.SX) -> ca.SX:
        return ca.vertcat(*[X[h, :] for h in self.heads])

    def head_cols(self, X: ca.SX) -> ca.SX:
        return ca.horzcat(*[X[:, h] for h in self.heads])

    def wrap(self, e: ca.SX) -> ca.SX:
        """Angle outputs' innovations into (-pi, pi]."""
        out = []
        for j in range(self.m):
            ej = e[j]
            if self.angles[j]:
                ej = angles.wrap_sx(ej)
            out.append(ej)
        return ca.vertcat(*out)

    def gain(self, Pm: ca.SX, R: ca.SX, scale: ca.SX):
        """Innovation covariance, gain K = scale P C' S^-1 and the pivots of S."""
        S = self.head_cols(self.head_rows(Pm)) + R
        K, piv = _right_divide(self.head_cols(Pm), S)
        return S, scale * K, piv

    @staticmethod
    def unpack(p: ca.SX, n: int) -> ca.SX:
        """The symmetric n x n matrix of a packed upper triangle (packed_index order): each
        distinct entry of the node's P stored, read and computed once."""
        out = ca.SX(n, n)
        for j in range(n):
            for i in range(j + 1):
                out[i, j] = p[packed_index(i, j)]
                out[j, i] = p[packed_index(i, j)]
        return out

    @staticmethod
    def pack(P: ca.SX) -> ca.SX:
        """The upper triangle of a symmetric result, column by column: only these entries are
        computed (CasADi drops the expressions of the lower triangle)."""
        n = P.shape[0]
        return ca.vertcat(*[P[i, j] for j in range(n) for i in range(j + 1)])

    @staticmethod
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

    def posterior(self, Pm: ca.SX, K: ca.SX, R: ca.SX, used: ca.SX | float = 1) -> ca.SX:
        """P+ = P - K C P (algorithms.md, node update), each entry (i <= j) computed once and
        mirrored; an entry in a head's row or column as R K' (= (I - P_HH S^-1) C P exactly),
        which a precise measurement does not cancel. `used` 0 (and K = 0) gives P back."""
        n, KCP, RK = self.n, ca.mtimes(K, self.head_rows(Pm)), ca.mtimes(R, K.T)
        out = ca.SX(n, n)
        for j in range(n):
            for i in range(j + 1):
                if j in self.heads:
                    a, b = self.heads.index(j), i
                elif i in self.heads:
                    a, b = self.heads.index(i), j
                else:
                    out[i, j] = Pm[i, j] - KCP[i, j]
                    out[j, i] = out[i, j]
                    continue
                out[i, j] = RK[a, b] if isinstance(used, int) else RK[a, b] + (1 - used) * Pm[i, j]
                out[j, i] = out[i, j]
        return out

    # kernels ---------------------------------------------------------------------------------
    def predict(self, name: str) -> ca.Function:
        n, m = self.n, self.m
        x, P, v, q = _sym("x", n), _sym("P", n, n), _sym("v", m), _sym("q", m)
        x1 = ca.mtimes(self.A, x) + ca.mtimes(self.B, v)
        Ps = self.symmetric(P)
        P1 = self.symmetric(ca.mtimes(ca.mtimes(self.A, Ps), self.A.T) + self.Q_of(q))
        return ca.Function(name, [x, P, v, q], [x1, P1], ["x", "P", "v", "q"], ["x1", "P1"])

    def update(self, name: str) -> ca.Function:
        """The node's update with a measurement on its packed prior (npp = n (n + 1) / 2 reals),
        posterior packed. A step without one keeps its prior as it is (the node copies it): no
        gamma factor in the gain, so none of its multiplications.
        Prior and posterior are each one vector, x then P (the node stores them so): fewer
        arguments, all in registers on the host. The innovation e comes wrapped from the node,
        whose wrap skips the fmod in the common case (a branch, which straight-line
        code cannot take)."""
        n, m, npp = self.n, self.m, self.n * (self.n + 1) // 2
        prior, e, R = _sym("prior", n + npp), _sym("e", m), _sym("R", m, m)
        Pm = self.unpack(prior[n:], n)
        _, K, piv = self.gain(Pm, R, 1)
        x, P = prior[:n] + ca.mtimes(K, e), self.posterior(Pm, K, R)
        return ca.Function(name, [prior, e, R], [ca.vertcat(x, self.pack(P)), piv], ["prior", "e", "R"],
                           ["post", "piv"])

    def _propagate_P(self, P: ca.SX, q: ca.SX) -> ca.SX:
        """A P A' + Q from the upper triangle of P (the posterior as the node stores it)."""
        return ca.mtimes(ca.mtimes(self.A, self.symmetric(P)), self.A.T) + self.Q_of(q)

    def node_predict(self, name: str) -> ca.Function:
        """The node's prediction of its state (x, then P packed: one argument)."""
        n, m, npp = self.n, self.m, self.n * (self.n + 1) // 2
        post, v, q = _sym("post", n + npp), _sym("v", m), _sym("q", m)
        x1 = ca.mtimes(self.A, post[:n]) + ca.mtimes(self.B, v)
        P1 = self._propagate_P(self.unpack(post[n:], n), q)
        return ca.Function(name, [post, v, q], [x1, self.pack(P1)], ["post", "v", "q"], ["x1", "P1"])

    def info(self, name: str) -> ca.Function:
        """Information form about a centre c: Y = P^-1, y = Y (x - c). The master centres on its
        prior: the same fused x in exact arithmetic, without the cancellation of Y x terms
        that |x| / sigma of several hundred causes in single precision."""
        n = self.n
        x, P, c = _sym("x", n), _sym("P", n, n), _sym("c", n)
        Y, piv = spd_inverse_once(P)
        return ca.Function(name, [x, P, c], [Y, ca.mtimes(Y, x - c), piv], ["x", "P", "c"], ["Y", "y", "piv"])

    def node_predict_loop(self, name: str) -> Loop:
        """node_predict as loops: G = A P column by column, then row i of A P A' = A (row i of G)',
        both by the part `A c` (O(nnz A) code); then x1 = A x + B v and P1 = A P A' + Q packed
        (O(n^2) code). Twice the multiplications of the straight-line code (no symmetry in the
        products), none of its Theta(n^3) bytes."""
        n, m, npp = self.n, self.m, self.n * (self.n + 1) // 2
        c = _sym("col", n)
        a = ca.Function(f"{name}_a", [c], [ca.mtimes(self.A, c)], ["col"], ["Acol"])
        post, v, q, M = _sym("post", n + npp), _sym("v", m), _sym("q", m), _sym("APA", n * n)
        x1 = ca.mtimes(self.A, post[:n]) + ca.mtimes(self.B, v)
        P1 = ca.reshape(M, n, n) + self.Q_of(q)
        end = ca.Function(f"{name}_end", [post, v, q, M], [x1, self.pack(P1)], ["post", "v", "q", "APA"],
                          ["x1", "P1"])
        unpack = ["k = 0;"] + _for(f"j = 0; j < {n}; j++", _for("i = 0; i <= j; i++", [
            f"P[(j * {n}) + i] = post[{n} + k];", f"P[(i * {n}) + j] = post[{n} + k];", "k++;"]))
        body = (unpack + _for(f"j = 0; j < {n}; j++", [f"(void){name}_a(&P[j * {n}], &G[j * {n}]);"])
                + _for(f"i = 0; i < {n}; i++", _for(f"j = 0; j < {n}; j++", [f"g[j] = G[(j * {n}) + i];"])
                       + [f"(void){name}_a(g, &P[i * {n}]);"])
                + [f"(void){name}_end(post, v, q, P, x1, P1);"])
        decls = [f"casadi_real P[{n * n}]; /* P, then A P A' */", f"casadi_real G[{n * n}]; /* A P */",
                 f"casadi_real g[{n}]; /* a row of A P */", "int i;", "int j;", "int k;"]
        return Loop([a, end], decls, body)

    def _forward(self, L: ca.SX, r: ca.SX, b: ca.SX) -> list:
        """z = L^-1 b for the lower-triangular L of `info_loop` (row k at L[k n ...], 1 / L_kk in r),
        in _chol_reciprocal's order of operations; a row whose r is still 0 gives z = 0."""
        n, z = self.n, []
        for k in range(n):
            s = b[k]
            for j in range(k):
                s = s - L[k * n + j] * z[j]
            z.append(s * r[k])
        return z

    def info_loop(self, name: str) -> Loop:
        """info as loops: the Cholesky factor row by row (part `row`: a forward substitution with
        the rows above, the pivot and 1 / sqrt of it; the same operations as the straight-line
        factorisation), then each column of Y = P^-1 and y = P^-1 (x - c) by two substitutions
        (part `solve`). Each part O(n^2) code; the solves take about twice the straight-line
        code's operations."""
        n = self.n
        L, r, b, bii = _sym("L", n * n), _sym("r", n), _sym("b", n), _sym("bii")
        z = self._forward(L, r, b)
        d = bii
        for zk in z:
            d = d - zk * zk
        row = ca.Function(f"{name}_row", [L, r, b, bii], [ca.vertcat(*z), d, ca.sqrt(1 / d)],
                          ["L", "r", "b", "bii"], ["z", "d", "rd"])
        w = [None] * n
        z = self._forward(L, r, b)
        for k in reversed(range(n)):
            s = z[k]
            for j in range(k + 1, n):
                s = s - L[j * n + k] * w[j]
            w[k] = s * r[k]
        solve = ca.Function(f"{name}_solve", [L, r, b], [ca.vertcat(*w)], ["L", "r", "b"], ["sol"])
        body = (_for(f"i = 0; i < {n * n}; i++", ["L[i] = (casadi_real)0;"])
                + _for(f"i = 0; i < {n}; i++", ["r[i] = (casadi_real)0;", "e[i] = (casadi_real)0;"])
                + _for(f"i = 0; i < {n}; i++", [
                    f"(void){name}_row(L, r, &P[i * {n}], &P[(i * {n}) + i], z, &piv[i], &rd);", "r[i] = rd;"]
                    + _for("j = 0; j < i; j++", [f"L[(i * {n}) + j] = z[j];"]))
                + _for(f"j = 0; j < {n}; j++", ["e[j] = (casadi_real)1;", f"(void){name}_solve(L, r, e, z);",
                                              "e[j] = (casadi_real)0;"]
                       + _for("i = 0; i <= j; i++", [f"Y[(j * {n}) + i] = z[i];", f"Y[(i * {n}) + j] = z[i];"]))
                + _for(f"i = 0; i < {n}; i++", ["e[i] = x[i] - c[i];"])
                + [f"(void){name}_solve(L, r, e, y);"])
        decls = [f"casadi_real L[{n * n}]; /* the Cholesky factor's rows, 0 until computed */",
                 f"casadi_real r[{n}]; /* 1 / L_ii, 0 until computed */", f"casadi_real e[{n}];",
                 f"casadi_real z[{n}];", "casadi_real rd;", "int i;", "int j;"]
        return Loop([row, solve], decls, body)

    def retro_step(self, name: str) -> ca.Function:
        """One step n (slot k-n) of the backward recursion of the retrodiction (algorithms.md):
        adds slot k-n's terms to the sums and carries T(n)(A L_n)' and E(n-1) = L_n A E(n)."""
        n, m = self.n, self.m
        nn, Tp, E = _sym("n"), _sym("Tp", n, n), _sym("E", n, n)
        npp = n * (n + 1) // 2
        xm, Pp, z, used, R = _sym("xm", n), _sym("Pm", npp), _sym("z", m), _sym("used"), _sym("R", m, m)
        Pm = self.unpack(Pp, n)
        v, q = _sym("v", m), _sym("q", m)
        sw, sQ, sX, su = _sym("sw", n), _sym("sQ", n, n), _sym("sX", n, n), _sym("su", n)
        t = nn * self.opts.ts
        An = self.A_of(t)
        e = self.wrap(z - self.head_rows(xm))
        S, K, piv = self.gain(Pm, R, used)
        Si, _ = spd_inverse(S)
        T = ca.mtimes(An, self.Q_of(q)) + Tp
        Ct = self.head_cols(T)                       # C~(n) = T(n) C'
        D = self.head_rows(ca.mtimes(self.A, E))     # D(n) = C A E(n)
        CtSi = ca.mtimes(Ct, Si)
        sw1 = sw + used * ca.mtimes(CtSi, e)
        sQ1 = sQ + used * ca.mtimes(CtSi, Ct.T)
        sX1 = sX + used * ca.mtimes(ca.mtimes(D.T, Si), Ct.T)
        su1 = su + ca.mtimes(ca.mtimes(An, self.B), v)   # A^n B v(k-1-n): the known input
        L = self.I - ca.mtimes(K, self.C)
        AL = ca.mtimes(self.A, L)
        Tp1 = ca.mtimes(T, AL.T)
        E1 = ca.mtimes(ca.mtimes(L, self.A), E)
        return ca.Function(name, [nn, Tp, E, xm, Pp, z, used, R, v, q, sw, sQ, sX, su],
                           [Tp1, E1, sw1, sQ1, sX1, su1, piv],
                           ["n", "Tp", "E", "xm", "Pm", "z", "used", "R", "v", "q", "sw", "sQ", "sX", "su"],
                           ["Tp1", "E1", "sw1", "sQ1", "sX1", "su1", "piv"])

    def retro_finish(self, name: str) -> ca.Function:
        """Xia et al.'s correction (docs/mathematics.md section 4) from the sums of the recursion."""
        n, m = self.n, self.m
        npp = n * (n + 1) // 2
        N, x, Pp, PmNp, usedN = _sym("N"), _sym("x", n), _sym("P", npp), _sym("PmN", npp), _sym("usedN")
        P, PmN = self.unpack(Pp, n), self.unpack(PmNp, n)
        z, R, q = _sym("z", m), _sym("R", m, m), _sym("q", m)
        sw, sQ, sX, su = _sym("sw", n), _sym("sQ", n, n), _sym("sX", n, n), _sym("su", n)
        Phi1 = self.A_of(-N * self.opts.ts)
        AN = self.A_of(N * self.opts.ts)
        _, KN, _ = self.gain(PmN, R, usedN)
        PN = self.posterior(PmN, KN, R, usedN)        # P(k-N|k-N)
        wa = -ca.mtimes(Phi1, sw)
        # Q* = Phi1 (Q_d(N Ts) - sum) Phi1': the two nearly cancel, so subtract before Phi1
        # amplifies them (as the reference does), and keep both symmetric (the upper triangle
        # mirrored): in single precision the other order lost digits
        Dq = self.Q_of(q, N * self.opts.ts) - sQ
        Qs = self.symmetric(ca.mtimes(ca.mtimes(Phi1, self.symmetric(Dq)), Phi1.T))
        Pxw = ca.mtimes(ca.mtimes(ca.mtimes(AN, PN), sX), Phi1.T) - ca.mtimes(AN, Qs)
        xr = ca.mtimes(Phi1, x - su) + wa
        PhiPxw = ca.mtimes(Phi1, Pxw)
        inner = ca.mtimes(ca.mtimes(Phi1, P), Phi1.T) + PhiPxw + PhiPxw.T + Qs
        W = self.head_cols(self.head_rows(inner)) + R
        Mg, piv = _right_divide(self.head_cols(ca.mtimes(P, Phi1.T) + Pxw), W)
        xs = x + ca.mtimes(Mg, self.wrap(z - self.head_rows(xr)))
        Ps = P - ca.mtimes(ca.mtimes(Mg, W), Mg.T)
        Ps = (Ps + Ps.T) / 2          # symmetric again: see algorithms.md, retrodict
        _, pivP = spd_inverse(Ps)     # with a stale history P* can lose definiteness: reject then
        return ca.Function(name, [N, x, Pp, PmNp, usedN, z, R, q, sw, sQ, sX, su], [xs, self.pack(Ps), piv, pivP],
                           ["N", "x", "P", "PmN", "usedN", "z", "R", "q", "sw", "sQ", "sX", "su"],
                           ["xs", "Ps", "piv", "pivP"])

    # master kernels (fusion group: local work, symmetric results computed once, packed) -------
    def packed(self, Y: ca.SX) -> ca.SX:
        """The upper triangle of a symmetric matrix, row by row: n(n+1)/2 numbers."""
        n = Y.shape[0]
        return ca.vertcat(*[Y[i, j] for i in range(n) for j in range(i, n)])

    def unpacked(self, v: ca.SX) -> ca.SX:
        """The symmetric matrix whose packed upper triangle is v."""
        n = self.n
        out, at = ca.SX(n, n), 0
        for i in range(n):
            for j in range(i, n):
                out[i, j] = v[at]
                out[j, i] = v[at]
                at += 1
        return out

    def info_of(self, x: ca.SX, P: ca.SX, c: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        """Y = P^-1 (its upper triangle only: the lower reuses it) and y = Y (x - c), about the
        master's prior c: the same fused x in exact arithmetic, without the cancellation of Y x
        terms that |x| / sigma of several hundred causes in single precision."""
        Yi, piv = spd_inverse(P)
        Y = self.symmetric(Yi)
        return Y, ca.mtimes(Y, x - c), piv

    def master_info(self, name: str) -> ca.Function:
        """One packet's information (paper and ci rules), Y packed."""
        n = self.n
        x, P, c = _sym("x", n), _sym("P", n, n), _sym("c", n)
        Y, y, piv = self.info_of(x, P, c)
        return ca.Function(name, [x, P, c], [self.packed(Y), y, piv], ["x", "P", "c"], ["Y", "y", "piv"])

    def master_gain(self, name: str) -> ca.Function:
        """One packet's information gain (difference rule): its update's information less its
        prediction's, packed, with both factorisations' pivots."""
        n = self.n
        x, P, xp, Pp, c = _sym("x", n), _sym("P", n, n), _sym("xp", n), _sym("Pp", n, n), _sym("c", n)
        Y, y, piv = self.info_of(x, P, c)
        Yp, yp, pivp = self.info_of(xp, Pp, c)
        return ca.Function(name, [x, P, xp, Pp, c], [self.packed(Y - Yp), y - yp, ca.vertcat(piv, pivp)],
                           ["x", "P", "xp", "Pp", "c"], ["dY", "dy", "piv"])

    def advance(self, name: str) -> ca.Function:
        """A stale packet's estimate brought N steps forward at once: x1 = A(N Ts) x + effect and
        P1 = A(N Ts) P A(N Ts)' + Q_d(N Ts), `effect` the stored inputs' effect over those steps
        (`input_step`). Exactly the N one-step predictions (sum_i A^i Q A^i' = Q_d(N Ts) for the
        chains' white-noise model), in the work of one: a packet N_max steps old costs the master
        one kernel call instead of N_max."""
        n, m = self.n, self.m
        N, x, P, e, q = _sym("N"), _sym("x", n), _sym("P", n, n), _sym("effect", n), _sym("q", m)
        t = N * self.opts.ts
        A = self.A_of(t)
        P1 = self.symmetric(ca.mtimes(ca.mtimes(A, self.symmetric(P)), A.T) + self.Q_of(q, t))
        return ca.Function(name, [N, x, P, e, q], [ca.mtimes(A, x) + e, P1], ["N", "x", "P", "effect", "q"],
                           ["x1", "P1"])

    def input_step(self, name: str) -> ca.Function:
        """One stored input's step of that effect: A effect + B v (from 0 at the packet's step)."""
        e, v = _sym("effect", self.n), _sym("v", self.m)
        return ca.Function(name, [e, v], [ca.mtimes(self.A, e) + ca.mtimes(self.B, v)], ["effect", "v"],
                           ["effect1"])

    def finish_of(self, Y: ca.SX, y: ca.SX, c: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        Pi, piv = spd_inverse(Y)
        P = self.symmetric(Pi)
        return c + ca.mtimes(P, y), P, piv

    def fuse_finish(self, name: str) -> ca.Function:
        """x = c + P y, P = Y^-1 from the fused information (Y packed)."""
        n = self.n
        Y, y, c = _sym("Y", n * (n + 1) // 2), _sym("y", n), _sym("c", n)
        x, P, piv = self.finish_of(self.unpacked(Y), y, c)
        return ca.Function(name, [Y, y, c], [x, P, piv], ["Y", "y", "c"], ["x", "P", "piv"])

    def fuse_finish_difference(self, name: str) -> ca.Function:
        """The difference rule's end: Y = P_prior^-1 + sum of gains (packed), y = 0 + sum of gains
        (the prior's information about itself is 0); then x = c + P y, P = Y^-1."""
        n = self.n
        Pc, dY, dy, c = _sym("Pc", n, n), _sym("dY", n * (n + 1) // 2), _sym("dy", n), _sym("c", n)
        Yc, pivc = spd_inverse(Pc)
        x, P, piv = self.finish_of(self.symmetric(Yc) + self.unpacked(dY), dy, c)
        return ca.Function(name, [Pc, dY, dy, c], [x, P, ca.vertcat(pivc, piv)], ["Pc", "dY", "dy", "c"],
                           ["x", "P", "piv"])

    def ci_grad(self, name: str, lowrank: bool) -> ca.Function:
        """Covariance intersection, first half of a Newton step (algorithms.md, master "ci"):
        gradient of tr((sum w_i Y_i)^-1) and the Hessian H, each Y_i packed; absent nodes have
        w_i = 0 and Y_i = 0. With S = sum w_i Y_i = L L', P = S^-1 = L^-T L^-1 and
        W_i = L^-1 Y_i P: g_i = -tr(P Y_i P) = -<L^-1, W_i> and H_ij = 2 tr(P Y_i P Y_j P) =
        2 <W_i, W_j> (Frobenius), a Gram matrix. `F` carries H itself (M x M), or with `lowrank`
        its factor G (row i = sqrt(2) vec W_i, H = G G'), which the step uses without forming H:
        O(M n^4) instead of O(M^2 n^2). `hd` is H's diagonal (for the regulariser, master_ci.c.j2)."""
        n, M = self.n, self.opts.nodes
        d = n * (n + 1) // 2
        w = _sym("w", M)
        Y = _sym("Y", M * d)     # node i's packed Y_i at entries i d .. (i + 1) d - 1
        Ys = [self.unpacked(Y[i * d:(i + 1) * d]) for i in range(M)]
        Sp = w[0] * Y[0:d]
        for i in range(1, M):
            Sp = Sp + w[i] * Y[i * d:(i + 1) * d]
        L, piv = _chol(self.unpacked(Sp))
        Li = _lower_inverse(L)
        P = self.symmetric(ca.mtimes(Li.T, Li))
        W = [ca.mtimes(ca.mtimes(Li, Yi), P) for Yi in Ys]
        g = ca.vertcat(*[-_trace_of_product(Li, Wi.T) for Wi in W])
        if lowrank:
            G = ca.vertcat(*[math.sqrt(2) * ca.reshape(Wi, 1, n * n) for Wi in W])
            hd = ca.vertcat(*[ca.dot(G[i, :], G[i, :]) for i in range(M)])
            F = ca.reshape(G.T, M * n * n, 1)                       # row by row
        else:
            H = ca.SX(M, M)
            for i in range(M):
                for j in range(i, M):
                    H[i, j] = 2 * _trace_of_product(W[i], W[j].T)
                    H[j, i] = H[i, j]
            hd = ca.diag(H)
            F = ca.reshape(H, M * M, 1)
        return ca.Function(name, [w, Y], [g, F, hd, piv], ["wt", "Y"], ["g", "F", "hd", "piv"])

    def ci_dir(self, name: str, lowrank: bool) -> ca.Function:
        """Second half: the step d_F of `[H_FF + rho I, 1; 1', 0] [d; mu] = [-g_F; 0]` over the
        free set F (mask f), d_i = 0 off F, by the Schur complement: u1 = Hf^-1 (f g),
        u2 = Hf^-1 f, mu = -f'u1 / f'u2, d = -(u1 + mu u2), with Hf the regularised H on F and
        the identity off it (there the right-hand sides are 0, so d_i is exactly 0). Hf^-1 by a
        Cholesky solve of the M x M matrix, or with `lowrank` by Woodbury's identity through the
        n^2 x n^2 matrix I + G_F' G_F / rho (Hf = D + G_F G_F', D = rho on F and 1 off it; its
        eigenvalues are >= 1, so it factors in any precision): O(M n^4 + n^6), linear in M."""
        n, M = self.n, self.opts.nodes
        g, f, rho = _sym("g", M), _sym("free", M), _sym("rho")
        if lowrank:
            q = n * n
            Fs = _sym("F", M * q)
            G = ca.reshape(Fs, q, M).T                                  # row i = node i
            c = f / rho                 # D^-1 on F (the mask is 0 or 1); rows off F drop out
            cG = ca.diag(c) @ G
            C = ca.SX(q, q)             # I + G_F' D^-1 G_F, its lower triangle (all _chol reads)
            for a in range(q):
                for b in range(a + 1):
                    C[a, b] = (1 if a == b else 0) + ca.dot(cG[:, a], G[:, b])
            L, piv = _chol(C)

            def solve(bv):              # bv is 0 off F: D^-1 bv = c bv
                return c * bv - ca.mtimes(cG, _chol_solve(L, ca.mtimes(cG.T, bv)))
        else:
            Fs = _sym("F", M * M)
            H = ca.reshape(Fs, M, M)
            Hf = ca.SX(M, M)
            for i in range(M):
                for j in range(M):
                    Hf[i, j] = f[i] * f[j] * H[i, j]
                Hf[i, i] = Hf[i, i] + f[i] * rho + (1 - f[i])
            L, piv = _chol(Hf)

            def solve(bv):
                return _chol_solve(L, bv)
        u1, u2 = solve(f * g), solve(f)
        mu = -ca.dot(f, u1) / ca.dot(f, u2)
        return ca.Function(name, [g, Fs, f, rho], [-(u1 + mu * u2), piv], ["g", "F", "fmask", "rho"], ["d", "piv"])

    def ci_hd(self, name: str, lowrank: bool) -> ca.Function:
        """(H + rho I) d, for the model's gradient along a pivot: G (G' d) + rho d with `lowrank`."""
        n, M = self.n, self.opts.nodes
        d, rho = _sym("d", M), _sym("rho")
        if lowrank:
            Fs = _sym("F", M * n * n)
            G = ca.reshape(Fs, n * n, M).T
            hd = ca.mtimes(G, ca.mtimes(G.T, d))
        else:
            Fs = _sym("F", M * M)
            hd = ca.mtimes(ca.reshape(Fs, M, M), d)
        return ca.Function(name, [d, Fs, rho], [hd + rho * d], ["d", "F", "rho"], ["hd"])

    def ci_kernels(self, name) -> list[ca.Function]:
        """ci_grad, ci_dir and ci_hd in the form whose Newton step costs fewer operations for this
        model and node count (CasADi's count; the M x M form on a tie): the low-rank one once M
        outgrows n^2, roughly. `name(kernel)` gives a kernel's C name."""
        forms = [(self.ci_grad(name("ci_grad"), lowrank), self.ci_dir(name("ci_dir"), lowrank), lowrank)
                 for lowrank in (False, True)]
        grad, step, lowrank = min(forms, key=lambda f: f[0].n_instructions() + f[1].n_instructions())
        return [grad, step, self.ci_hd(name("ci_hd"), lowrank)]

    def control(self, name: str) -> ca.Function:
        """u and v = F + G u from the estimate, reference flags and gains (algorithms.md)."""
        flat, n, m = self.flat, self.n, self.m
        x, flags, gains = _sym("x", n), _sym("flags", n + m), _sym("gains", n)
        p = _sym("params", len(flat.params))
        table = dict(zip(flat.zeta, [x[i] for i in range(n)]))
        table.update(zip(flat.params, [p[i] for i in range(len(flat.params))]))
        v = []
        for j, chain in enumerate(flat.chains):
            r, off = chain.degree, chain.offset
            base = off + j                            # chain j's flags start here
            errs = [x[off + i] - flags[base + i] for i in range(r)]
            if chain.angle:
                errs[0] = self.wrap_one(errs[0])
            vj = flags[base + r]
            for i in range(r):
                vj = vj - gains[off + r - i - 1] * errs[i]
            v.append(vj)
        v = ca.vertcat(*v)
        F = ca.vertcat(*[to_casadi(flat.F[j], table, f"F-bar[{j}]") for j in range(m)])
        G = ca.SX(m, m)
        for i in range(m):
            for j in range(m):
                G[i, j] = to_casadi(flat.G[i, j], table, f"G-bar[{i},{j}]")
        if m == 1:
            u, det = (v - F) / G, G
        else:
            u, det = ca.solve(G, v - F), ca.det(G)
        # declared actuator limits: clamp u, count the clamped inputs, and broadcast the v the
        # clamped u really produces (v = F + G u), so the filters predict what the plant does
        limits = [(i, w.min, w.max) for i, w in enumerate(flat.model.inputs) if w.bounded]
        nsat = ca.SX(0)
        if limits:
            clamped = []
            for i in range(m):
                ui = u[i]
                for j, lo, hi in limits:
                    if j == i and lo is not None:
                        nsat, ui = nsat + (u[i] < lo), ca.fmax(ui, lo)
                    if j == i and hi is not None:
                        nsat, ui = nsat + (u[i] > hi), ca.fmin(ui, hi)
                clamped.append(ui)
            u = ca.vertcat(*clamped)
            v = F + ca.mtimes(G, u)
        return ca.Function(name, [x, flags, gains, p], [u, v, det, nsat],
                           ["x", "flags", "gains", "params"], ["u", "v", "det", "nsat"], {"cse": True})

    @staticmethod
    def wrap_one(e: ca.SX) -> ca.SX:
        return angles.wrap_sx(e)


# Kernels whose work array is a local of the kernel, not a parameter: then no store into it can
# alias an argument, and the compiler keeps the intermediates in registers (the node's kernels,
# called once per step on the hot path; measured: about half their instructions; and info, whose
# Cortex-M4F code this halves at n = 10).
LOCAL_WORK = ("_kern_update", "_kern_node_predict", "_kern_retro_step", "_kern_retro_finish", "_kern_info")

# node_predict and info are printed as loops (`Loop`) when their straight-line code would have
# more operations than this (CasADi's count): from a chain of 7 integrators on (548 and 601; a
# chain of 6 has 371 and 410, two_link_arm 196 and 410), where the loops are 32% smaller and
# the node step 1.8 times slower (Cortex-M4F and host figures in docs/algorithms.md).
LOOP_OPS = 500

# A replay node stores the P prior of every CHECK_EVERY-th step only (the P recursion of the
# canonical model reads neither x nor z, so the others are recomputed): 4 cuts the ring's P to a
# quarter (and packing halves it) for at most 3 extra P steps per late measurement.
CHECK_EVERY = 4


def packed_index(i: int, j: int) -> int:
    """Where entry (i, j), i <= j, of a symmetric matrix sits in the node's packed storage: the
    upper triangle column by column (LAPACK's "U" packed layout)."""
    return j * (j + 1) // 2 + i


def build(flat, opts: Options, prefix: str) -> KernelSet:
    """All kernels the chosen options need, named `<prefix>_kern_<name>`."""
    b = _Builder(flat, opts)
    name = lambda k: f"{prefix}_kern_{k}"  # noqa: E731
    node_predict, info = b.node_predict(name("node_predict")), b.info(name("info"))
    filt = [b.predict(name("predict")), node_predict, b.update(name("update")), info]
    if opts.oosm == "retrodict":
        filt += [b.retro_step(name("retro_step")), b.retro_finish(name("retro_finish"))]
    if opts.fusion == "difference":
        fusion = [b.master_gain(name("master_gain")), b.fuse_finish_difference(name("fuse_finish"))]
    else:
        fusion = [b.master_info(name("master_info")), b.fuse_finish(name("fuse_finish"))]
    if opts.fusion == "ci":
        fusion += b.ci_kernels(name)
    fusion += [b.advance(name("advance")), b.input_step(name("input_step"))]
    # the master's predict is the node's on packed copies: the same expressions (bit for bit),
    # so its Theta(n^3) straight-line code is not printed twice
    loops = {f.name(): loop(f.name()) for f, loop in ((node_predict, b.node_predict_loop), (info, b.info_loop))
             if f.n_instructions() > LOOP_OPS}
    return KernelSet({"filter": filt, "fusion": fusion, "control": [b.control(name("control"))]},
                     local_work={"fusion"}, wrappers={name("predict"): name("node_predict")}, loops=loops)


# --- C source ---------------------------------------------------------------------------------

_MATH = ("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "exp", "log",
         "sqrt", "ceil", "floor", "fabs", "fmin", "fmax", "pow", "fmod", "erf", "copysign", "hypot",
         "log10", "log1p", "expm1", "trunc", "round", "cbrt", "asinh", "acosh", "atanh")
_MATH_CALL = re.compile(r"(?<![\w.])(" + "|".join(_MATH) + r")\(")
_FLOAT_LIT = re.compile(r"(?<![\w.])(\d+\.\d*(?:[eE][+-]?\d+)?|\d+[eE][+-]?\d+)(?![\w.])")
_ENTRY = re.compile(r"^int (\w+)\(const casadi_real\*\* arg, casadi_real\*\* res, casadi_int\* iw, "
                    r"casadi_real\* w, int mem\)\{\n  return (casadi_f\d+)\(arg, res, iw, w, mem\);\n\}$", re.M)
_BODY = re.compile(r"^(/\* [^\n]*\*/\n)static int (casadi_f\d+)\(const casadi_real\*\* arg, casadi_real\*\* res, "
                   r"casadi_int\* iw, casadi_real\* w, int mem\) \{\n(.*?)^\}\n", re.M | re.S)
_HELPER = re.compile(r"^casadi_real (casadi_\w+)\(([^)\n]*)\) \{(?: ([^\n]*)\}\n|\n/\* Pre-c99 compatibility \*/\n"
                     r"#if __STDC_VERSION__ < 199901L\n[^\n]*\n#else\n([^\n]*)\n#endif\n\}\n)", re.M)
_ANY_HELPER = re.compile(r"^casadi_real casadi_\w+\(", re.M)
_CONST = re.compile(r"^static const casadi_(?:real|int) (casadi_[cs]\d+)\[\d+\] = \{[^}]*\};\n", re.M)
_TOKEN = re.compile(r"\s*(\d+\.\d*(?:[eE][+-]?\d+)?|\d+[eE][+-]?\d+|\d+|\w+|==|!=|<=|>=|&&|\|\||\S)")
_BINARY = {"+", "-", "*", "/", "=", "<", ">", "==", "!=", "<=", ">=", "&&", "||", "?", ":"}
_C_KEYWORDS = {"auto", "break", "case", "char", "const", "continue", "default", "do", "double", "else",
               "enum", "extern", "float", "for", "goto", "if", "inline", "int", "long", "register",
               "restrict", "return", "short", "signed", "sizeof", "static", "struct", "switch", "typedef",
               "union", "unsigned", "void", "volatile", "while", "free", "w"}
INDENT = "    "


@dataclass
class KernelC:
    """One kernel's typed C entry point: its named, sized inputs and outputs and its work size."""

    name: str
    signature: str      # CasADi's one-line description, e.g. "predict:(x[3],P[3x3],...)->(...)"
    sz_w: int
    inputs: list[tuple[str, int]]
    outputs: list[tuple[str, int]]
    local_work: bool = False

    def parameters(self, real: str, work: str | None = None) -> list[str]:
        """The C parameter list: inputs const, outputs writable, every array sized, then the work
        (its size is also <NAME>_SZ_W in the kernels header, for the callers; `work` names that
        macro in the prototype, so the header uses every size it defines), unless the kernel
        keeps its work in locals."""
        # a C array has at least one element: an empty input (a model without parameters) is [1]
        return ([f"const {real} {n}[{max(k, 1)}]" for n, k in self.inputs] + [f"{real} {n}[{k}]" for n, k in self.outputs]
                + ([] if self.local_work else [f"{real} w[{work or self.sz_w}]"]))


def _float_text(text: str) -> str:
    text = _MATH_CALL.sub(lambda mt: mt.group(1) + "f(", text)
    return _FLOAT_LIT.sub(lambda mt: layout.single(mt.group(1)), text)


def spaced(statement: str) -> str:
    """One C expression statement spaced as clang-format does: binary operators and `=` between
    spaces, unary signs and calls tight, `, ` after commas. CasADi prints no spaces at all."""
    tokens = _TOKEN.findall(statement)
    out, prev = "", None
    for tok in tokens:
        unary = tok in ("-", "+") and (prev is None or prev in _BINARY | {"(", "[", ",", "return"}
                                       or prev in ("!",))
        if tok == ",":
            out += ", "
        elif tok in _BINARY and not unary:
            out = out.rstrip(" ") + f" {tok} "
        elif tok in (")", "]", ";"):
            out = out.rstrip(" ") + tok
        elif tok == "return":
            out += "return "
        else:
            out += tok
        prev = tok
    return out.strip()


def _function(head: str, params: list[str], body: list[str]) -> str:
    """A C function definition laid out as the style file asks (see codegen/layout.py)."""
    return layout.pack(head + "(", params, ")") + "\n{\n" + "".join(INDENT + line + "\n" for line in body) + "}\n"


def c_source(functions: list[ca.Function], real: str, precision: str,
             helpers: str = "casadi", local_work: bool = False,
             wrappers: dict[str, str] | None = None,
             loops: dict[str, Loop] | None = None) -> tuple[str, list[KernelC]]:
    """C for a group of kernels: helpers `static`, one typed entry point per kernel
    `int name(const real in1[k1], ..., real out1[j1], ..., real w[SZ_W])`, spaced like clang-format;
    CasADi's helpers (`casadi_sq`, ...) renamed `<helpers>_sq`.

    Why typed: callers name each argument and the compiler checks its type, instead of filling
    `arg[]`/`res[]` by position; and no array of pointers is left to get wrong.
    `local_work`: the work is a local array instead of the last parameter; it cannot alias the
    arguments, so the compiler keeps it in registers (the master's kernels use this).
    `wrappers`: kernels printed as `packed_wrapper` calls of another kernel of the group.
    `loops`: kernels printed as C loops over their parts (`Loop`), the parts static."""
    wrappers, loops = wrappers or {}, loops or {}
    looped = [f for f in functions if f.name() in loops]
    parts = {g.name() for f in looped for g in loops[f.name()].parts}
    functions = functions + [g for f in looped for g in loops[f.name()].parts]
    by_name = {f.name(): f for f in functions}
    wrapped = [f for f in functions if f.name() in wrappers]
    functions = [f for f in functions if f.name() not in wrappers and f.name() not in loops]
    cg = ca.CodeGenerator("kernels", {"casadi_int": "int", "casadi_real": "double", "avoid_stack": True,
                                      "main": False, "mex": False, "with_header": False,
                                      "with_export": False, "verbose": False, "include_math": True})
    for f in functions:
        cg.add(f)
    text = cg.dump()
    entries = {fn: name for name, fn in _ENTRY.findall(text)}
    bodies = _BODY.findall(text)
    if len(bodies) != len(functions) or len(entries) != len(functions):
        raise RuntimeError("unexpected CasADi output layout (kernel bodies not found)")
    if len(_HELPER.findall(text)) != len(_ANY_HELPER.findall(text)):
        raise RuntimeError("unexpected CasADi output layout (a helper of an unknown form)")
    out, infos = [], []
    used = "".join(body for _, _, body in bodies)
    for mt in _HELPER.finditer(text):
        helper, args, one_line, c99 = mt.groups()   # a one-line body, or the C99 branch of an #if
        stmt = one_line if one_line is not None else c99
        args = re.sub(r"\bcasadi_real\b", real, args)
        out.append(_function(f"static {real} {helper}", [a.strip() for a in args.split(",")],
                             [spaced(s) + ";" for s in stmt.split(";") if s.strip()]))
        used += mt.group(0)
    for mt in _CONST.finditer(text):
        if re.search(rf"\b{mt.group(1)}\b", used):
            raise RuntimeError(f"unexpected CasADi constant table {mt.group(1)} in an SX kernel")
    for comment, fn, body in bodies:
        name = entries[fn]
        f = by_name[name]
        if re.search(r"\b(iw|mem)\b|\bcasadi_f\d+\(", body) or f.sz_iw() != 0:
            raise RuntimeError(f"kernel {name}: integer work or a nested call, unexpected for SX")
        ins = [(f.name_in(i), f.numel_in(i)) for i in range(f.n_in())]
        outs = [(f.name_out(i), f.numel_out(i)) for i in range(f.n_out())]
        names = [n for n, _ in ins + outs]
        if len(set(names)) != len(names) or set(names) & _C_KEYWORDS:
            raise RuntimeError(f"kernel {name}: argument names must be distinct C identifiers, not w")
        # `!x` and `x ? :` on a real are float-to-bool conversions (clang -Wfloat-conversion)
        body = re.sub(r"\(!(w\[\d+\])\)", r"(\1==0)", body)
        body = re.sub(r"\((w\[\d+\])\?", r"(\1!=0?", body)
        # every input and output is passed: drop CasADi's NULL checks, then name the arguments
        body = re.sub(r"arg\[(\d+)\]\? (arg\[\1\]\[\d+\]) : 0", r"\2", body)
        body = re.sub(r"if \(res\[(\d+)\]!=0\) (res\[\1\]\[\d+\]=)", r"\2", body)
        body = re.sub(r"\barg\[(\d+)\]\[", lambda mt: ins[int(mt.group(1))][0] + "[", body)
        body = re.sub(r"\bres\[(\d+)\]\[", lambda mt: outs[int(mt.group(1))][0] + "[", body)
        if re.search(r"\b(arg|res)\b", body):
            raise RuntimeError(f"kernel {name}: unexpected CasADi argument pattern")
        node_local = name.endswith(LOCAL_WORK) or name in parts   # one local work array
        info = KernelC(name, comment[3:-4], max(1, f.sz_w()), ins, outs, local_work or node_local)
        lines = [spaced(line.strip()) for line in body.splitlines() if line.strip()]
        if local_work:   # one scalar per work entry: the compiler keeps them in registers
            lines = [f"casadi_real w{i};" for i in range(info.sz_w)] + [re.sub(r"\bw\[(\d+)\]", r"w\1", line)
                                                                     for line in lines]
        elif node_local:
            lines.insert(0, f"casadi_real w[{info.sz_w}];")
        lines = [f"(void){n};" for n, k in ins if k == 0] + lines   # an empty input: never read
        lines.append("return 0;")
        out.append(f"/* {wrap_comment(info.signature)} */\n"
                   + _function(f"{'static ' if name in parts else ''}int {name}", info.parameters(real), lines))
        if name not in parts:
            infos.append(info)
    for f in looped:
        loop = loops[f.name()]
        info = KernelC(f.name(), str(f).rsplit(" ", 1)[0], 1, [(f.name_in(i), f.numel_in(i)) for i in range(f.n_in())],
                       [(f.name_out(i), f.numel_out(i)) for i in range(f.n_out())], True)
        out.append(f"/* {wrap_comment(info.signature)} */\n"
                   + _function(f"int {f.name()}", info.parameters(real), loop.decls + loop.body + ["return 0;"]))
        infos.append(info)
    for f in wrapped:
        info, text = packed_wrapper(f, by_name[wrappers[f.name()]], real)
        out.append(text)
        infos.append(info)
    code = "\n".join(out)
    for mt in _HELPER.finditer(text):   # static helpers named per file (unique across the library)
        code = re.sub(rf"\b{mt.group(1)}\b", helpers + mt.group(1)[len("casadi"):], code)
    code = re.sub(r"\bcasadi_real\b", real, code)
    code = re.sub(r"\bcasadi_int\b", "int", code)
    if precision == "float":
        code = _float_text(code)
    return code, infos


def packed_wrapper(f: ca.Function, target: ca.Function, real: str) -> tuple[KernelC, str]:
    """C for kernel f as a call of `target` on packed copies. Each of target's arguments is made of
    the next of f's, in order: one passed through when the sizes agree, else several copied into
    one buffer, an n x n one as its upper triangle (CasADi's entry (i, j), i <= j, at i + j n), as
    the node keeps a state [x; P packed]; each packed result is unpacked into both triangles.
    Same expressions, so the same results bit for bit."""
    ins = [(f.name_in(i), f.numel_in(i)) for i in range(f.n_in())]
    outs = [(f.name_out(i), f.numel_out(i)) for i in range(f.n_out())]
    t_ins = [(target.name_in(i), target.numel_in(i)) for i in range(target.n_in())]
    t_outs = [target.numel_out(i) for i in range(target.n_out())]
    if ins == t_ins or len(outs) != len(t_outs):
        raise RuntimeError(f"kernel {f.name()}: no packed counterpart in {target.name()}")

    square = {f.name_in(i) for i in range(f.n_in()) if f.size1_in(i) == f.size2_in(i) > 1}

    def packed_size(arg: str, k: int, kt: int) -> int:   # k entries of f stored in target's form
        if k == kt or arg not in square:
            return k
        n = math.isqrt(k)
        return n * (n + 1) // 2

    def loop(n: int, body: list[str]) -> list[str]:   # k runs over the packed entries (packed_index)
        return (["k = 0;", f"for (j = 0; j < {n}; j++) {{", INDENT + "for (i = 0; i <= j; i++) {"]
                + [2 * INDENT + b for b in body + ["k++;"]] + [INDENT + "}", "}"])

    decls, pack, unpack, args = [], [], [], []
    pending = list(ins)
    for t_arg, kt in t_ins:
        if pending and pending[0][1] == kt:
            args.append(pending.pop(0)[0])
            continue
        buf, filled = f"{t_arg}_packed", 0
        decls.append(f"casadi_real {buf}[{kt}];")
        args.append(buf)
        while filled < kt:
            if not pending:
                raise RuntimeError(f"kernel {f.name()}: its arguments do not fill {target.name()}'s {t_arg}")
            arg, k = pending.pop(0)
            size = packed_size(arg, k, kt - filled)
            if size == k:
                at = f"{filled} + i" if filled else "i"
                pack += [f"for (i = 0; i < {k}; i++) {{", INDENT + f"{buf}[{at}] = {arg}[i];", "}"]
            else:
                n = math.isqrt(k)
                at = f"{filled} + k" if filled else "k"
                pack += loop(n, [f"{buf}[{at}] = {arg}[(j * {n}) + i];"])
            filled += size
        if filled != kt:
            raise RuntimeError(f"kernel {f.name()}: its arguments overfill {target.name()}'s {t_arg}")
    if pending:
        raise RuntimeError(f"kernel {f.name()}: arguments left over for {target.name()}")
    for (arg, k), kt in zip(outs, t_outs):
        if k == kt:
            args.append(arg)
            continue
        n = math.isqrt(k)
        if n * n != k or n * (n + 1) // 2 != kt:
            raise RuntimeError(f"kernel {f.name()}: result {arg} is not the square of {target.name()}'s")
        decls.append(f"casadi_real {arg}_packed[{kt}];")
        args.append(f"{arg}_packed")
        unpack += loop(n, [f"{arg}[(j * {n}) + i] = {arg}_packed[k];", f"{arg}[(i * {n}) + j] = {arg}_packed[k];"])
    lines = decls + ["int i;", "int j;", "int k;"] + pack + [f"(void){target.name()}({', '.join(args)});"]
    lines += unpack + ["return 0;"]
    info = KernelC(f.name(), str(f).rsplit(" ", 1)[0], 1, ins, outs, True)
    text = f"/* {wrap_comment(info.signature)} */\n" + _function(f"int {f.name()}", info.parameters(real), lines)
    return info, re.sub(r"\bcasadi_real\b", real, text)


def wrap_comment(text: str, width: int = 94) -> str:
    """A one-line description cut into comment lines (` * ` continuations) of at most `width`."""
    lines, line = [], ""
    for piece in re.split(r"(?<=,)", text):
        if line and len(line + piece) > width:
            lines.append(line)
            line = ""
        line += piece
    lines.append(line)
    return "\n * ".join(lines)
