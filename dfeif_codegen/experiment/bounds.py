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
the last W + 1 steps with the flags as known at k. That is vectorized over k: W + 1 batched
updates of (K, n, n) arrays, milliseconds per row and seed instead of a replayed filter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment.network import Network

NEVER = np.iinfo(np.int64).max


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


def posterior_covariances(A, Q, H, P0, arrive) -> np.ndarray:
    """P(k | frames arrived by k) for every step k, (K, n, n).

    `H[i] = C_i^T R_i^-1 C_i` is camera i's information per frame, `arrive` (cameras, K) the
    arrival step of each frame (NEVER if it never comes). Information form, so several cameras
    and a missing frame (no information) need no special case."""
    H = np.asarray(H, dtype=float)
    arrive = np.asarray(arrive, dtype=np.int64)
    cams, K = arrive.shape
    n = A.shape[0]
    finite = arrive < NEVER
    W = int(max((arrive[finite] - np.nonzero(finite)[1]).max(initial=0), 0))
    # settled chain: every frame that ever arrives
    prior = np.empty((K, n, n))
    P = np.asarray(P0, dtype=float)
    for k in range(K):
        prior[k] = P
        post = _spd_inv(_spd_inv(P) + np.tensordot(finite[:, k].astype(float), H, axes=1))
        P = A @ post @ A.T + Q
    steps = np.arange(K)
    start = np.maximum(steps - W, 0)
    P = prior[start].copy()
    out = np.empty_like(P)
    for t in range(W + 1):
        j = start + t                                   # the step each k is at, (K,)
        live = j <= steps
        jj = np.minimum(j, K - 1)
        known = (arrive[:, jj] <= steps[None, :]) & live[None, :]          # (cams, K)
        Y = _spd_inv(P) + np.einsum("ck,cab->kab", known.astype(float), H)
        post = _spd_inv(Y)
        done = j == steps
        out[done] = post[done]
        P = np.where(live[:, None, None], A @ post @ A.T + Q, P)
    return out


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
    """(A, Q, R per node, P0) of the filters of `cfg`: the matched linear model."""
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
    nodes, central = [], []
    for cfg in cfgs:
        arrive = arrivals(network_of(cfg, K), cfg.max_lag)
        per = [posterior_covariances(A, Q, H[i:i + 1], P0, arrive[i:i + 1]) for i in range(len(R))]
        nodes.append([np.diagonal(P, axis1=1, axis2=2)[k0:].mean(axis=0) for P in per])
        allc = posterior_covariances(A, Q, H, P0, arrive)
        central.append(np.diagonal(allc, axis1=1, axis2=2)[k0:].mean(axis=0))
    return RowBound(np.mean(nodes, axis=0), np.mean(central, axis=0))
