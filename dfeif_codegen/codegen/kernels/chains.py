"""The flat model's chain structure as CasADi constants and expressions, shared by every kernel.

Why one place: the node, fusion and control kernels all read the same Brunovsky A_d, B_d and
C = e_head, the closed forms of A_d(t) and Q_d(t) for a runtime period, the angle wrap and the
Kalman gain; each kernel module takes a `Chains` and builds its functions from it.
"""

from __future__ import annotations

from math import factorial

import casadi as ca

from dfeif_codegen import angles
from dfeif_codegen.symbolic import discretize
from dfeif_codegen.codegen.kernels.linalg import dm, powers, right_divide
from dfeif_codegen.codegen.options import Options


def wrap_angle(e: ca.SX) -> ca.SX:
    """An angle's difference into (-pi, pi], exactly for any finite e (dfeif_codegen/angles.py)."""
    return angles.wrap_sx(e)


class Chains:
    """The model's integrator chains for the build's options: sizes, heads, angles, A, B, C."""

    def __init__(self, flat, opts: Options):
        self.flat, self.opts = flat, opts
        # the filters' state: the canonical one, then the disturbance states if built with them
        self.nz, self.m = flat.n, flat.m
        dist = opts.disturbance_states()
        self.n = flat.n + (0 if dist is None else dist.order * flat.m)
        self.degrees = flat.degrees
        self.heads = flat.heads
        self.angles = [c.angle for c in flat.chains]
        A, B, C = flat.discrete(opts.ts)
        self.A, self.B, self.C = dm(A), dm(B), dm(C)
        self.Qunit = [discretize.chain_Q(r, opts.ts, 1.0) for r in self.degrees]
        self.I = ca.DM.eye(self.n)

    def A_of(self, t: ca.SX) -> ca.SX:
        """A_d(t) = exp(A_c t) for symbolic t: A^n = A_of(n Ts), A^-N = A_of(-N Ts)."""
        out = ca.SX(self.n, self.n)
        pw = powers(t, max(self.degrees))
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
        pw = powers(t, 2 * max(self.degrees)) if t is not None else None
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
        return ca.vertcat(*[wrap_angle(e[j]) if self.angles[j] else e[j] for j in range(self.m)])

    def gain(self, Pm: ca.SX, R: ca.SX, scale: ca.SX):
        """Innovation covariance, gain K = scale P C' S^-1 and the pivots of S."""
        S = self.head_cols(self.head_rows(Pm)) + R
        K, piv = right_divide(self.head_cols(Pm), S)
        return S, scale * K, piv

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

