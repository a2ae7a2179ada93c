"""Exact zero-order-hold discretization of the block-Brunovsky form, in closed form.

A chain of r integrators driven by v has A_d = exp(A_c Ts) with entries Ts^(j-i)/(j-i)!, and
white noise of density q on v gives Q_d by the Van Loan integral, also in closed form (see
docs/mathematics.md section 2). `chain_A(r, -N*Ts)` is A_d^-N, which the retrodiction needs.
"""

from __future__ import annotations

from math import factorial

import numpy as np


def chain_A(r: int, ts: float) -> np.ndarray:
    a = np.zeros((r, r))
    for i in range(r):
        for j in range(i, r):
            a[i, j] = ts ** (j - i) / factorial(j - i)
    return a


def chain_B(r: int, ts: float) -> np.ndarray:
    return np.array([ts ** (r - i) / factorial(r - i) for i in range(r)])


def chain_Q(r: int, ts: float, q: float) -> np.ndarray:
    out = np.zeros((r, r))
    for i in range(1, r + 1):
        for j in range(1, r + 1):
            power = 2 * r - i - j + 1
            out[i - 1, j - 1] = q * ts ** power / (factorial(r - i) * factorial(r - j) * power)
    return out


def _block_diag(blocks: list[np.ndarray]) -> np.ndarray:
    size = sum(b.shape[0] for b in blocks)
    out = np.zeros((size, size))
    at = 0
    for b in blocks:
        out[at:at + b.shape[0], at:at + b.shape[0]] = b
        at += b.shape[0]
    return out


def brunovsky(degrees: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuous A_c (superdiagonal ones per chain), B_c (last row of each chain), C_c (heads)."""
    n, m = sum(degrees), len(degrees)
    a, b, c = np.zeros((n, n)), np.zeros((n, m)), np.zeros((m, n))
    at = 0
    for j, r in enumerate(degrees):
        for i in range(r - 1):
            a[at + i, at + i + 1] = 1.0
        b[at + r - 1, j] = 1.0
        c[j, at] = 1.0
        at += r
    return a, b, c


def discrete(degrees: list[int], ts: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n, m = sum(degrees), len(degrees)
    b = np.zeros((n, m))
    at = 0
    for j, r in enumerate(degrees):
        b[at:at + r, j] = chain_B(r, ts)
        at += r
    return _block_diag([chain_A(r, ts) for r in degrees]), b, brunovsky(degrees)[2]


def process_noise(degrees: list[int], ts: float, q) -> np.ndarray:
    qs = np.broadcast_to(np.asarray(q, dtype=float), (len(degrees),))
    return _block_diag([chain_Q(r, ts, qj) for r, qj in zip(degrees, qs)])
