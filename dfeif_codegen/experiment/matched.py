"""The matched linear plant: the filters' own canonical model driven by white noise of density q.

The same cameras (R), network draws (the seed's), node filters and master as the closed loop, but
the plant is exactly the model the filters assume, so the Kalman covariance is the true mean
squared error and `bounds.py` is the best any estimator can do. This is the experiment in which
"replay + difference reaches the bound" can be checked at all; on the real plant, whose only
"process noise" is model mismatch, the bound is a reference level, not a limit.
"""

from __future__ import annotations

import numpy as np

from dfeif_codegen.experiment import bounds
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import metrics as run_metrics
from dfeif_codegen.reference.fusion import Master
from dfeif_codegen.reference.node import NodeFilter


def run(cfg: ex.Config, steps: int | None = None) -> dict:
    """One run of the matched plant with `cfg`'s network, seed, filters and rule (inputs v = 0).
    Returns per step: true state, node and master estimates and covariances."""
    flat = ex._flat(cfg.model)
    A, Q, R, P0, ts = bounds.matched_model(cfg)
    K = steps or int(round(cfg.duration / ts))
    n, m, M = flat.n, flat.m, len(R)
    net = bounds.network_of(cfg, K)
    rng = np.random.default_rng(np.random.SeedSequence(cfg.seed).spawn(4)[3])
    oosm = cfg.method if cfg.method in ex.OOSM else "replay"
    q = ex._per_chain(cfg.q, m)
    nodes = [NodeFilter(flat, ts, q, R[i], np.zeros(n), P0, max_lag=cfg.max_lag, oosm=oosm,
                        predictor="brunovsky") for i in range(M)]
    master = Master(flat, ts, q, np.zeros(n), P0, M, rule=cfg.fusion, max_lag=cfg.max_lag, predictor="brunovsky")
    LQ, L0 = np.linalg.cholesky(Q), np.linalg.cholesky(P0)
    LR = [np.linalg.cholesky(Ri) for Ri in R]
    heads = flat.heads
    x = L0 @ rng.standard_normal(n)
    frames = np.zeros((M, K, m))
    out = {"zeta": np.zeros((K, n)), "node_x": np.zeros((M, K, n)), "node_P": np.zeros((M, K, n, n)),
           "x": np.zeros((K, n)), "P": np.zeros((K, n, n))}
    zero = np.zeros(m)
    sent: list[dict] = [{} for _ in range(M)]
    for k in range(K):
        out["zeta"][k] = x
        for i, node in enumerate(nodes):
            frames[i, k] = x[heads] + LR[i] @ rng.standard_normal(m)
            on_time = net.lag[i, k] == 0
            node.update(frames[i, k] if on_time else None, bool(on_time))
            for lag in net.late[i].get(k, []):
                if cfg.method in ex.OOSM:
                    node.update_delayed(frames[i, k - lag], lag)
            sent[i][k] = node.packet()
            out["node_x"][i, k], out["node_P"][i, k] = node.x, node.P
        master.fuse([sent[i].get(int(s)) if s >= 0 else None for i, s in enumerate(net.source[:, k])])
        out["x"][k], out["P"][k] = master.x, master.P
        for node in (*nodes, master):
            node.predict(zero)
        x = A @ x + LQ @ rng.standard_normal(n)
    return out


def metrics(cfg: ex.Config, out: dict) -> dict:
    """Per run, from `metrics_from` on: squared errors averaged over time (nodes, master), the
    master's NEES per step and its mean covariance diagonal."""
    flat = ex._flat(cfg.model)
    ts = float(cfg.ts or flat.model.ts)
    k0 = min(int(round(cfg.metrics_from / ts)), out["x"].shape[0] - 1)
    zeta = out["zeta"][k0:]
    err = ex._errors(flat, out["x"][k0:], zeta)
    node_err = ex._errors(flat, out["node_x"][:, k0:], zeta[None])
    return {"mse_master": (err ** 2).mean(axis=0), "mse_nodes": (node_err ** 2).mean(axis=1),
            "var_master": np.diagonal(out["P"][k0:], axis1=1, axis2=2).mean(axis=0),
            "nees_master": run_metrics._nees(err, out["P"][k0:])}


def centralized_covariances(cfg: ex.Config, steps: int) -> np.ndarray:
    """P(k|k) of one Kalman filter that has both cameras' frames as they arrive (the two-camera
    Riccati recursion of bounds.py over `cfg`'s arrival pattern), (K, n, n)."""
    flat = ex._flat(cfg.model)
    A, Q, R, P0, _ = bounds.matched_model(cfg)
    C = np.zeros((flat.m, flat.n))
    C[np.arange(flat.m), flat.heads] = 1.0
    H = np.array([C.T @ np.linalg.solve(Ri, C) for Ri in R])
    return bounds.posterior_covariances(A, Q, H, P0, bounds.arrivals(bounds.network_of(cfg, steps), cfg.max_lag))


def riccati_gap(cfg: ex.Config, out: dict) -> float:
    """Largest gap between the master's P and the centralized filter's, relative to the latter's
    largest entry per step. Zero (to rounding) without late frames; with late frames the difference
    rule adds each node's information *increment*, and a late frame's increment, propagated
    through process noise, depends on the information it is added to (one camera's at the node,
    both cameras' in the centralized filter), so the two differ unless Q = 0."""
    central = centralized_covariances(cfg, out["P"].shape[0])
    return float(np.max(np.abs(out["P"] - central) / np.abs(central).max(axis=(1, 2))[:, None, None]))
