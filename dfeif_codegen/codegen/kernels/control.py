"""The flatness-based control kernel: u and v from the estimate, the reference and the gains.

The model's F-bar and G-bar (sympy, from `symbolic.flatness`) are converted here by
`symbolic.numeric.to_casadi`, the one sympy -> CasADi bridge, and CasADi's common-subexpression
elimination shares their terms. With the held-input predictor (`held`: its build-time constants)
u is the input to hold over the period (symbolic/sampling.py `held_input_sx`), the reference's law.
With disturbance states the estimate x carries them after the canonical state, and u cancels the
estimated disturbance d as the reference's law does (u - G⁻¹ d before the clamp).
"""

from __future__ import annotations

import casadi as ca

from dfeif_codegen.symbolic import sampling
from dfeif_codegen.symbolic.numeric import to_casadi
from dfeif_codegen.codegen.kernels.chains import Chains, wrap_angle
from dfeif_codegen.codegen.kernels.linalg import sym


def _clamp(flat, u: ca.SX) -> tuple[ca.SX, ca.SX]:
    """u clamped to the declared actuator limits, and the count of inputs clamped."""
    nsat = ca.SX(0)
    for i, w in enumerate(flat.model.inputs):
        if w.min is not None:
            nsat = nsat + (u[i] < w.min)
        if w.max is not None:
            nsat = nsat + (u[i] > w.max)
    return sampling.within_limits(flat, u), nsat


def control(s: Chains, name: str, held: sampling.HeldSampling | None = None) -> ca.Function:
    """u and v = F + G u from the estimate, reference flags and gains (algorithms.md)."""
    flat, n, m = s.flat, s.nz, s.m
    xd, flags, gains = sym("x", s.n), sym("flags", n + m), sym("gains", n)
    x = xd[:n]
    p = sym("params", len(flat.params))
    table = dict(zip(flat.zeta, [x[i] for i in range(n)]))
    table.update(zip(flat.params, [p[i] for i in range(len(flat.params))]))
    v = []
    for j, chain in enumerate(flat.chains):
        r, off = chain.degree, chain.offset
        base = off + j                            # chain j's flags start here
        errs = [x[off + i] - flags[base + i] for i in range(r)]
        if chain.angle:
            errs[0] = wrap_angle(errs[0])
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
    det = G if m == 1 else ca.det(G)
    if held is not None:
        u = sampling.held_input_sx(flat, held, x, v, p)[0]
    else:
        u = (v - F) / G if m == 1 else ca.solve(G, v - F)
    if s.n > n:                                   # the estimated disturbance cancelled
        d = xd[n:n + m]                           # (an integrated random walk's rates follow)
        u = u - (d / G if m == 1 else ca.solve(G, d))
    # declared actuator limits: clamp u, count the clamped inputs, and broadcast the v the
    # clamped u really produces (v = F + G u), so the filters predict what the plant does
    nsat = ca.SX(0)
    if any(w.bounded for w in flat.model.inputs):
        u, nsat = _clamp(flat, u)
        v = F + ca.mtimes(G, u)
    return ca.Function(name, [xd, flags, gains, p], [u, v, det, nsat],
                       ["x", "flags", "gains", "params"], ["u", "v", "det", "nsat"], {"cse": True})
