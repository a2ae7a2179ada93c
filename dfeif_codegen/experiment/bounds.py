"""The exact optimal filter's error on the matched linear model, for one row's arrival pattern.

For a plant that *is* the filters' canonical model (a chain of integrators driven by white noise
of density q) the Kalman filter's covariance is the mean squared error of the best estimator
there is, and it depends only on which frames have arrived, not on their values. So the bound of
a row is a covariance recursion over that row's network draws (the same seeds as the runs):

- per node: the Kalman filter of that node's frames received so far (what `replay` computes);
- centralized: the Kalman filter of every camera's frames received so far (what the
  information-difference master equals when the node -> master link is ideal).

At step k a frame of step j is known iff its arrival step a(j) <= k. Frames older than the
largest lag W are all settled, so P(k | k) is the settled prior of step k - W run forward through
the last W + 1 steps with the flags as known at k (the "chain" of k). Up to the oldest step
still pending at k the chain is the settled recursion itself, and chain k repeats chain k - 1 up
to the oldest frame arriving at k: one pass over the steps computes each distinct chain state
once, batched over seeds, in about a third of the time of every chain in full.
Each state is the same operations on the same matrices as in the full chain (numpy's batched
inverse and product work matrix by matrix), so the results are those of the full chains, bit
for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment.network import Network

NEVER = np.iinfo(np.int64).max
BATCH_REALS = 16_000_000  # reals of the (B, K, n, n) result of a batched recursion: 128 MB


def arrivals(net: Network, max_lag: int) -> np.ndarray:
    """(M, K) step at which each camera frame reaches its node's filter (NEVER: dropped, lost
    past the run's end, or rejected for a lag above `max_lag`)."""
    M, K = net.lag.shape
    out = np.full((M, K), NEVER, dtype=np.int64)
    j = np.arange(K)
    for i in range(M):
        lag = net.lag[i]
        ok = (lag >= 0) & (lag <= max_lag) & (j + lag < K)
        out[i, ok] = j[ok] + lag[ok]
    return out


def _spd_inv(P: np.ndarray) -> np.ndarray:
    Y = np.linalg.inv(P)
    return (Y + np.swapaxes(Y, -1, -2)) / 2


def _information(known: np.ndarray, H: np.ndarray) -> np.ndarray:
    """sum_c known[:, c] H[:, c]: camera by camera from zero, the order and signed zeros of the
    einsum the full chains used."""
    info = np.zeros((len(H), *H.shape[2:]))
    for c in range(H.shape[1]):
        info = info + known[:, c, None, None] * H[:, c]
    return info


def posterior_covariances(A, Q, H, P0, arrive) -> np.ndarray:
    """P(k | frames arrived by k) for every step k, (K, n, n); or (B, K, n, n) for a batch.

    `H[i] = C_i^T R_i^-1 C_i` is camera i's information per frame, `arrive` (cameras, K) the
    arrival step of each frame (NEVER if it never comes). Information form, so several cameras
    and a missing frame (no information) need no special case. A batch (`H` (B, cameras, n, n),
    `arrive` (B, cameras, K): seeds, node subsets) runs as one recursion over the steps, which is
    what makes a hundred seeds cost about what one does."""
    H = np.asarray(H, dtype=float)
    arrive = np.asarray(arrive, dtype=np.int64)
    single = arrive.ndim == 2
    if single:
        H, arrive = H[None], arrive[None]
    B, _, K = arrive.shape
    n = A.shape[0]
    finite = arrive < NEVER
    W = int(max(np.where(finite, arrive - np.arange(K), 0).max(initial=0), 0))
    # per chain k (padded by W + 1 steps that are never chains): its first step, the oldest step
    # pending at k (k + 1: none, P(k | k) is the settled one), and the oldest step of a frame
    # arriving at k (on time included)
    steps = np.arange(K)
    last = np.where(finite, arrive, -1).max(axis=1)
    first = np.full((B, K + W + 1), K + W + 1)
    first[:, :K] = steps + 1
    oldest = np.full((B, K + W + 1), K + W + 1)
    for lag in range(W + 1):
        k, j = steps[lag:], steps[:K - lag]
        first[:, lag:K] = np.where(last[:, :K - lag] > k, j, first[:, lag:K])
        oldest[:, lag:K] = np.where((arrive[:, :, :K - lag] == k).any(axis=1), j, oldest[:, lag:K])
    moved = np.ones_like(first, dtype=bool)
    moved[:, 1:] = first[:, 1:] != first[:, :-1]
    behind = np.arange(W + 1)                       # chain k = j + behind at step j
    out = np.empty((B, K, n, n))
    P = np.broadcast_to(np.asarray(P0, dtype=float), (B, n, n)).copy()
    post, fresh = np.empty((B, W + 1, n, n)), np.zeros((B, W + 1), dtype=bool)
    for j in range(K):
        # the states of step j that chain k - 1 does not have: chain k's last step, after a frame
        # of step j or older arrived at k, or when the chain's first step moved
        win = slice(j, j + W + 1)
        was = np.where(fresh, behind, -1)
        np.maximum.accumulate(was, axis=1, out=was)  # at j - 1: the chain whose state chain k shares
        fresh = (first[:, win] <= j) & ((behind == 0) | (oldest[:, win] <= j) | moved[:, win])
        b, t = np.nonzero(fresh)
        begin = first[b, j + t] == j
        S = np.empty((len(b), n, n))
        S[begin] = P[b[begin]]
        cont = ~begin
        S[cont] = A @ post[b[cont], was[b[cont], t[cont] + 1]] @ A.T + Q
        post[b, t] = _spd_inv(_spd_inv(S) + _information(arrive[b, :, j] <= (j + t)[:, None], H[b]))
        settled_post = _spd_inv(_spd_inv(P) + _information(finite[:, :, j], H))   # every frame that ever arrives
        out[:, j] = settled_post
        now = t == 0
        out[b[now], j] = post[b[now], 0]
        P = A @ settled_post @ A.T + Q
    return out[0] if single else out


@dataclass
class RowBound:
    """Time-averaged exact variances of one row, averaged over seeds: per node (M, n) and
    centralized (n,); `rmse_*` are their square roots."""

    var_nodes: np.ndarray
    var_central: np.ndarray

    @property
    def rmse_nodes(self) -> np.ndarray:
        return np.sqrt(self.var_nodes)

    @property
    def rmse_central(self) -> np.ndarray:
        return np.sqrt(self.var_central)


def network_of(cfg: ex.Config, steps: int) -> Network:
    """The network realization `closed_loop.run(cfg)` draws (the first of its three seed streams)."""
    net_rng = np.random.default_rng(np.random.SeedSequence(cfg.seed).spawn(3)[0])
    return Network(list(cfg.sensor), list(cfg.uplink), steps, net_rng)


def matched_model(cfg: ex.Config):
    """(A, Q, R per node, P0) of the Brunovsky filters of `cfg`: the matched linear model."""
    flat = ex._flat(cfg.model)
    ts = float(cfg.ts or flat.model.ts)
    A, _, _ = flat.discrete(ts)
    q = ex._per_chain(cfg.q, flat.m)
    Q = flat.process_noise(ts, q)
    R = np.array([ex._camera(cfg.model, float(s), None if std is None else tuple(std)).R
                  for s, std in zip(cfg.noise_scale, cfg.noise_std)])
    return A, Q, R, ex.initial_covariance(flat, cfg.p0_std), ts


def row_bound(cfgs: list[ex.Config]) -> RowBound:
    """Exact bound of one row over the seeds of `cfgs` (one Config per seed, same row)."""
    flat = ex._flat(cfgs[0].model)
    A, Q, R, P0, ts = matched_model(cfgs[0])
    K = int(round(cfgs[0].duration / ts))
    k0 = min(int(round(cfgs[0].metrics_from / ts)), K - 1)
    C = np.zeros((flat.m, flat.n))
    C[np.arange(flat.m), flat.heads] = 1.0
    H = np.array([C.T @ np.linalg.solve(Ri, C) for Ri in R])
    M = len(R)
    # one batch per chunk of seeds: each seed's M single-camera filters and its centralized one
    nodes, central = [], []
    chunk = max(1, BATCH_REALS // (K * flat.n * flat.n * (M + 1)))
    for c0 in range(0, len(cfgs), chunk):
        arrive = []
        for cfg in cfgs[c0:c0 + chunk]:
            a = arrivals(network_of(cfg, K), cfg.max_lag)
            for i in range(M):
                alone = np.full_like(a, NEVER)
                alone[i] = a[i]
                arrive.append(alone)
            arrive.append(a)
        P = posterior_covariances(A, Q, np.broadcast_to(H, (len(arrive), *H.shape)), P0, np.array(arrive))
        var = np.diagonal(P, axis1=2, axis2=3)[:, k0:].mean(axis=1).reshape(-1, M + 1, flat.n)
        nodes += list(var[:, :M])
        central += list(var[:, M])
    return RowBound(np.mean(nodes, axis=0), np.mean(central, axis=0))
