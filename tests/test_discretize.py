"""Closed-form A_d, B_d, Q_d against the matrix exponential and the Van Loan integral."""

import numpy as np
import pytest
from scipy.linalg import expm

from dfeif_codegen.symbolic import discretize


def van_loan(a, b, q_density, ts):
    """Discretize by one big matrix exponential (Van Loan 1978): an independent method."""
    n, m = b.shape
    big = np.zeros((2 * n + m, 2 * n + m))
    big[:n, :n] = -a
    big[:n, n:2 * n] = b @ (q_density * np.eye(m)) @ b.T
    big[n:2 * n, n:2 * n] = a.T
    big[n:2 * n, 2 * n:] = 0
    e = expm(big * ts)
    a_d = e[n:2 * n, n:2 * n].T
    q_d = a_d @ e[:n, n:2 * n]
    zoh = np.zeros((n + m, n + m))
    zoh[:n, :n], zoh[:n, n:] = a, b
    b_d = expm(zoh * ts)[:n, n:]
    return a_d, b_d, q_d


@pytest.mark.parametrize("n", range(1, 9))
@pytest.mark.parametrize("ts", [0.001, 0.01, 0.37])
def test_chain_matches_expm_and_van_loan(n, ts):
    a_c, b_c, c_c = discretize.brunovsky([n])
    a_d, b_d, c_d = discretize.discrete([n], ts)
    q = 3.7
    q_d = discretize.process_noise([n], ts, q)
    a_ref, b_ref, q_ref = van_loan(a_c, b_c, q, ts)
    scale = lambda m: np.abs(m).max()  # noqa: E731
    # Van Loan's expm (scipy, Pade + squaring) is accurate to ~cond(expm) eps ~1e-14 for these
    # small nilpotent blocks; the closed form is t^k/k! exactly rounded: 1e-12 of the scale holds
    assert np.abs(a_d - a_ref).max() <= 1e-12 * scale(a_ref)
    assert np.abs(b_d - b_ref).max() <= 1e-12 * scale(b_ref)
    assert np.abs(q_d - q_ref).max() <= 1e-12 * scale(q_ref)
    assert np.array_equal(c_d, c_c) and c_d[0, 0] == 1


def test_block_chains_and_inverse_power():
    degrees, ts = [3, 2, 1], 0.05
    a_c, b_c, _ = discretize.brunovsky(degrees)
    a_d, b_d, _ = discretize.discrete(degrees, ts)
    q = np.array([1.0, 0.5, 2.0])
    q_d = discretize.process_noise(degrees, ts, q)
    a_ref, b_ref, _ = van_loan(a_c, b_c, 1.0, ts)
    # as above, entries O(1) at Ts = 0.01: expm's ~1e-15 absolute error is far below 1e-13
    assert np.allclose(a_d, a_ref, rtol=0, atol=1e-13) and np.allclose(b_d, b_ref, rtol=0, atol=1e-13)
    # per-chain densities: Q_d = sum_j q_j * (Van Loan with only input j)
    q_ref = sum(q[j] * van_loan(a_c, b_c[:, [j]], 1.0, ts)[2] for j in range(3))
    assert np.allclose(q_d, q_ref, rtol=0, atol=1e-14)
    # A_d(-N Ts) is the inverse of A_d(Ts)^N, which the retrodiction uses
    for N in (1, 5, 32):
        inv = discretize.chain_A(3, -N * ts)
        # N <= 32 products of unit upper-triangular 3x3 with entries <= N ts: ~N eps growth
        assert np.allclose(inv @ np.linalg.matrix_power(discretize.chain_A(3, ts), N), np.eye(3), atol=1e-12)
