"""The held-input predictor's kernels (`--predictor held`, the default; docs/mathematics.md
section 3; the reference's is reference/predictor.py): the node's and the master's prediction,
the covariance-only step a node's replay carries its checkpoints with, F-bar, G-bar at a prior
(`domain`: init refuses a prior outside the model's domain) and Q₀ of the densities
(`noise`: taken at init, each prediction adds it); above
kernels.LOOP_OPS["held_covariance"] the node's two printed as loops over small parts
(`node_predict_loop`, the master's calls the node's).

The C stores the chain heads relative to a centre (docs/algorithms.md, "Centred storage"). The
Brunovsky A maps a vector that is zero off the heads to itself, so its prediction commutes with
the centre; E = e^{(A_c + B_c L₀) Ts} does not (L₀ has entries in the heads' columns), and F, G
need the absolute state. So these kernels take the centre c (one value per head, Hc its
embedding) and add the reference's increment (sampling.held_increment_sx, evaluated at the
absolute state z = x + Hc) to the relative x: the ETD2RK step of the reference minus Hc, the
stored values keeping their resolution in single precision. The model's parameters are baked in
at their values: L₀ is taken with them at build time.

With disturbance states (`codegen build --disturbance`, symbolic/disturbance.py) the state is the
canonical one followed by the disturbances (one per chain; two, d then its rate, for the
integrated random walk), q the chains' densities followed by the disturbances' (one per chain):
the same increment and E, U of the extended A (sampling.augmented).

The scheduled predictor (`--predictor scheduled`) takes w = (u, σ) where the held one takes u:
the same mean with w[:m], and the covariance by Φ(σ) = Φ₀ + Γ₁ (L(σ) - L₀)
(sampling.scheduled_transition_sx) at the master's broadcast flat outputs σ = w[m:], absolute
(the centre does not enter); with disturbance states, Φ(σ) of the extended state. Φ(σ) is dense
where Φ₀ has structural zeros in the heads' columns, so its kernels stay straight-line (no
`node_predict_loop`).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from dfeif_codegen.codegen.kernels.csource import Loop, for_lines
from dfeif_codegen.codegen.kernels.linalg import dm, pack, sym, symmetric, unpack
from dfeif_codegen.symbolic import sampling


class Held:
    """The held predictor's constants for one flat system and period, and its SX pieces."""

    def __init__(self, flat, ts: float, disturbance=None, scheduled: bool = False):
        self.flat, self.m, self.scheduled = flat, flat.m, scheduled
        self.nw = 2 * flat.m if scheduled else flat.m       # the input the prediction takes
        self.H = sampling.held_sampling(flat, ts, disturbance=disturbance)
        self.n, self.nq = len(self.H.A), len(self.H.U)     # state and densities, disturbances included
        # the control law's constants: the canonical model's (the reference's law)
        self.law = self.H if disturbance is None else sampling.held_sampling(flat, ts)
        self.p = ca.DM(flat.param_vector)
        self.embed = np.zeros((self.n, self.m))
        self.embed[flat.heads, np.arange(self.m)] = 1.0

    def mean(self, x: ca.SX, w: ca.SX, c: ca.SX) -> ca.SX:
        """x⁺ relative to the centre c from x relative to it (module docstring), u = w[:m]."""
        z = x + ca.mtimes(dm(self.embed), c)
        return x + sampling.held_increment_sx(self.flat, self.H, x, z, w[:self.m], self.p)

    def covariance(self, P: ca.SX, Q: ca.SX, sigma: ca.SX | None = None) -> ca.SX:
        """Φ P Φᵀ + Q₀ from the upper triangles of P and Q₀ (`noise`'s, packed): Φ = Φ₀, or
        Φ(σ) when scheduled."""
        E = sampling.scheduled_transition_sx(self.flat, self.H, sigma, self.p) if self.scheduled else dm(self.H.E)
        return ca.mtimes(ca.mtimes(E, symmetric(P)), E.T) + self.noise_in(Q)

    def noise_in(self, Q: ca.SX) -> ca.SX:
        """Q₀ from its packed upper triangle, only where some U_j has a nonzero (elsewhere Q₀ is
        0 for every q): decoupled chains add no more entries than Σ q_j U_j had."""
        where = np.any([U != 0 for U in self.H.U], axis=0)
        return unpack(Q, self.n) * dm(where.astype(float))

    def noise_of(self, q: ca.SX) -> ca.SX:
        """Q₀ = Σ_j q_j U_j of the densities q, its upper triangle packed."""
        out = ca.SX(self.n, self.n)
        for j in range(self.nq):
            out = out + q[j] * dm(self.H.U[j])
        return pack(out)


def noise(h: Held, name: str) -> ca.Function:
    """Q₀ packed from the densities: constant between inits, so the node and the master take it
    once at init and each prediction adds it (n(n+1)/2 additions) instead of forming Σ q_j U_j
    (two operations per nonzero of every U_j: dc_motor_link's node_predict 347 -> 317
    operations with a random walk per chain, two_link_arm's 2,818 -> 2,585 with an integrated
    Gauss-Markov)."""
    q = sym("q", h.nq)   # dense: CasADi writes a sparse result's nonzeros only, one after another
    return ca.Function(name, [q], [ca.densify(h.noise_of(q))], ["q"], ["Q"])


def node_predict(h: Held, name: str) -> ca.Function:
    """The node's prediction of its state (x, then P packed: one argument) with the applied u
    (and σ, scheduled: the argument u is then w = (u, σ)) and Q₀ packed (`noise`)."""
    n, m, npp = h.n, h.m, h.n * (h.n + 1) // 2
    post, u, Q, c = sym("post", n + npp), sym("u", h.nw), sym("Q", npp), sym("centre", m)
    P1 = h.covariance(unpack(post[n:], n), Q, u[m:])
    return ca.Function(name, [post, u, Q, c], [h.mean(post[:n], u, c), pack(P1)], ["post", "u", "Q", "centre"],
                       ["x1", "P1"])


def domain(h: Held, name: str) -> ca.Function:
    """F-bar and G-bar at an absolute state x (a prior at init, whose centre is 0; disturbance
    states are not read): the first stage of every prediction out of x evaluates F + G u there,
    so where either is not finite no input predicts out of x. A trial prediction with some fixed
    u would not do: its second stage depends on u (at sqrt_motor's nominal equilibrium u = 0 lets
    the current decay below the model's domain and gives NaN, u = R I predicts)."""
    x, u = sym("x", h.n), sym("u", h.m)
    v = sampling.remainder_sx(h.flat, x[:h.flat.n], u, h.p)
    F = ca.substitute(v, u, ca.SX.zeros(h.m))
    G = ca.jacobian(v, u)
    return ca.Function(name, [x], [ca.densify(F), ca.densify(G)], ["x"], ["F", "G"])


def node_predict_P(h: Held, name: str) -> ca.Function:
    """The covariance alone (a replay's checkpoints: P reads neither x nor u). Not for the
    scheduled predictor, whose P reads σ: its node stores every step's P prior instead
    (Options.check_every)."""
    P, Q = sym("P", h.n * (h.n + 1) // 2), sym("Q", h.n * (h.n + 1) // 2)
    return ca.Function(name, [P, Q], [pack(h.covariance(unpack(P, h.n), Q))], ["P", "Q"], ["P1"])


def predict(h: Held, name: str) -> ca.Function:
    """The master's prediction (x, P full; Q₀ packed): printed as node_predict on packed copies."""
    x, P, u, c = sym("x", h.n), sym("P", h.n, h.n), sym("u", h.nw), sym("centre", h.m)
    Q = sym("Q", h.n * (h.n + 1) // 2)
    P1 = symmetric(h.covariance(symmetric(P), Q, u[h.m:]))
    return ca.Function(name, [x, P, u, Q, c], [h.mean(x, u, c), P1], ["x", "P", "u", "Q", "centre"], ["x1", "P1"])


# The covariance loops' bands: G = E P and E Gᵀ are computed a band of columns (rows) at a time
# by one part, which computes only the rows of E the band needs, E's structural zeros folded
# away; more bands waste fewer products (E upper triangular, a chain: about 1/(2 BANDS) of the
# straight line's) for more parts (each O(nnz E) code). Measured on chains, n = 6..12 (host,
# node_predict alone): 4 bands take 1.15-1.26x the straight line's instructions, 6 bands
# 1.08-1.17x for a tenth more filter code (Cortex-M4F, n = 12).
BANDS = 4


def _bands(E: np.ndarray) -> list[tuple[int, int, int, int]]:
    """(s, e, t, c) per band of rows and columns [s, e): pass 1 computes rows 0..t-1 of E P's
    columns s..e-1, pass 2 reads columns c..n-1 of E P's rows s..e-1 (where E[s:, :] has
    nonzeros), into rows s..n-1 of E (E P)ᵀ. Each (i, k) pass 2 reads, pass 1 computed: t is the
    end of every band whose c is within [0, e)."""
    n = E.shape[0]
    bounds = sorted({round(b * n / BANDS) for b in range(BANDS + 1)})
    spans = list(zip(bounds, bounds[1:]))
    cols = [min((k for k in range(n) if np.any(E[s:, k] != 0)), default=n) for s, _ in spans]
    return [(s, e, max([e] + [e2 for (_, e2), c in zip(spans, cols) if c < e]), c)
            for (s, e), c in zip(spans, cols)]


def _parts(h: Held, name: str) -> list[ca.Function]:
    """The looped form's parts (`node_predict_loop`), each O(n^2) code: `mean` (x1), `unpack`
    (P, both triangles), `top<t>` (rows 0..t-1 of E times a column), `bot<s>` (rows s..n-1 of
    it, from a row of E P read with stride n in E P's columns; E's structural zeros folded away
    in both) and `q` (P1 packed from E P Eᵀ by rows plus Q₀, packed)."""
    n, m, E = h.n, h.m, h.H.E
    x, u, c, col, Q = sym("x", n), sym("u", m), sym("centre", m), sym("col", n), sym("Q", n * (n + 1) // 2)
    P, M, row = sym("P", n * (n + 1) // 2), sym("EPE", n * n), sym("EProw", (n - 1) * n + 1)
    out = ca.reshape(M, n, n).T + h.noise_in(Q)   # row i of E P Eᵀ at M[i n ...]: entry (i, j) as the straight line's
    bands = _bands(E)
    strided = ca.vertcat(*[row[k * n] for k in range(n)])   # row i of E P, read in its columns
    parts = {f"{name}_top{t}": ca.Function(f"{name}_top{t}", [col], [ca.mtimes(dm(E[:t, :]), col)], ["col"], ["Ecol"])
             for _, _, t, _ in bands}
    parts.update({f"{name}_bot{s}": ca.Function(f"{name}_bot{s}", [row], [ca.mtimes(dm(E[s:, :]), strided)],
                                                ["EProw"], ["Erow"]) for s, _, _, _ in bands})
    return [ca.Function(f"{name}_mean", [x, u, c], [h.mean(x, u, c)], ["x", "u", "centre"], ["x1"]),
            ca.Function(f"{name}_unpack", [P], [ca.reshape(unpack(P, n), n * n, 1)], ["P"], ["S"]),
            *parts.values(), ca.Function(f"{name}_q", [M, Q], [pack(out)], ["EPE", "Q"], ["P1"])]


def _covariance_lines(E: np.ndarray, parts: str, packed: str, out: str) -> list[str]:
    """C of P1 = E P Eᵀ + Q₀ (`packed`: P's upper triangle, packed_index order; into `out`,
    packed) by the parts of `parts` (`_parts`): P unpacked into S, G = E P column by column
    into G, then row i of E P Eᵀ = E (row i of G)ᵀ into S, band by band (`_bands`), each entry
    the straight line's sum in its order. bot<s> reads G from &G[i] with stride n: the entries
    (n - 1) n + 1 it is declared with are within G for i < n."""
    n = E.shape[0]
    lines = [f"(void){parts}_unpack({packed}, S);"]
    for s, e, t, _ in _bands(E):
        lines += for_lines(f"i = {s}; i < {e}; i++", [f"(void){parts}_top{t}(&S[i * {n}], &G[i * {n}]);"])
    for s, e, _, _ in _bands(E):
        at = f"(i * {n}) + {s}" if s else f"i * {n}"   # no `+ 0` (MISRA 2.2)
        lines += for_lines(f"i = {s}; i < {e}; i++", [f"(void){parts}_bot{s}(&G[i], &S[{at}]);"])
    return lines + [f"(void){parts}_q(S, Q, {out});"]


def _decls(n: int) -> list[str]:
    return [f"casadi_real S[{n * n}]; /* P, then E P E' by rows (the entries q reads) */",
            f"casadi_real G[{n * n}]; /* E P by columns (the entries bot<s> reads) */", "int i;"]


def node_predict_loop(h: Held, name: str) -> Loop:
    """node_predict as the mean's straight-line part and the covariance's loops over parts
    (`_parts`, `_bands`): O(n^2) code instead of Theta(n^3), with about 1/BANDS more products
    than the straight line's (a chain's E, upper triangular: 11% more at n = 8, 15% at 12),
    and O(n^2) copies (P unpacked, E P and E P Eᵀ through memory) and 2 n + 3 calls."""
    body = [f"(void){name}_mean(post, u, centre, x1);"] + _covariance_lines(h.H.E, name, f"&post[{h.n}]", "P1")
    return Loop(_parts(h, name), _decls(h.n), body)


def node_predict_P_loop(h: Held, parts: str) -> Loop:
    """node_predict_P as the covariance loops of `node_predict_loop`, calling its parts (the
    kernel `parts`, looped in the same file)."""
    return Loop([], _decls(h.n), _covariance_lines(h.H.E, parts, "P", "P1"))


def covariance_ops(h: Held) -> int:
    """CasADi's operation count of the straight-line covariance (the loops' threshold's measure:
    the mean's code is the same either way)."""
    return node_predict_P(h, "covariance").n_instructions()
