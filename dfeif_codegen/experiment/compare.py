"""The derivative-free filter against an EKF and a UKF, on the same recordings.

A closed-loop run of the derivative-free filters gives a recording: every frame each node got
(on time or late, in arrival order), the packets the master fused and the input `u` the plant
received. The EKF and UKF nodes (reference/ekf.py, ukf.py) run open loop on exactly that data,
with the same initial information (`Phi^-1` of the derivative-free start, `P0` mapped by the
Jacobian), the same late-frame method (replay) and the same fusion rule (information difference,
in physical coordinates). Their errors are reported in the canonical coordinates of the tables
(estimates mapped by `Phi`, covariances by its Jacobian), so every column compares like with like.

A run counts as diverged when a covariance stops being positive definite or an estimate is not
finite, or when its master NEES averages above 100 (the filter no longer knows its error).
"""

from __future__ import annotations

import time
from functools import lru_cache

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.reference.ekf import EKF
from dfeif_codegen.reference.physical import PhysicalMaster, PhysicalModel, ReplayNode
from dfeif_codegen.reference.ukf import UKF

FILTERS = {"ekf": EKF, "ukf": UKF}
DIVERGED_NEES = 100.0


@lru_cache(maxsize=None)
def physical_model(spec: str, ts: float, q: tuple, substeps: int) -> PhysicalModel:
    return PhysicalModel(ex._flat(spec), ts, np.array(q), substeps)


def run_on_recording(rec: ex.Recording, kind: str, substeps: int = 10) -> dict:
    """Nodes and master of `kind` over a recording: node and master estimates and covariances in
    canonical coordinates, (M, K, n), (M, K, n, n), (K, n), (K, n, n), and seconds of filter work."""
    pm = physical_model(rec.model, float(rec.ts), tuple(np.asarray(rec.q, float)), substeps)
    filt = FILTERS[kind](pm)
    x0, J0 = pm.phi_inv(rec.master_x0)
    P0 = J0 @ rec.master_P0 @ J0.T
    nodes = [ReplayNode(filt, rec.R[i], x0, P0, rec.max_lag) for i in range(rec.nodes)]
    master = PhysicalMaster(filt, x0, P0)
    K, n = rec.ref.shape[0], rec.n
    late_at = np.searchsorted(rec.late_step, np.arange(K + 1))
    fused = np.zeros((K, rec.nodes), dtype=bool)
    fused[rec.pkt_step, rec.pkt_node] = rec.pkt_src == rec.pkt_step      # stale packets: not handled
    phys = {"node_x": np.zeros((rec.nodes, K, n)), "node_P": np.zeros((rec.nodes, K, n, n)),
            "x": np.zeros((K, n)), "P": np.zeros((K, n, n))}
    started = time.process_time()
    for k in range(K):
        for i, node in enumerate(nodes):
            node.update(rec.z[i, k], bool(rec.gamma[i, k]))
        for i in range(rec.nodes):
            frames = [(rec.late_z[e], rec.late_lag[e]) for e in range(late_at[k], late_at[k + 1])
                      if rec.late_node[e] == i]
            if frames:
                nodes[i].update_delayed(frames)
        master.fuse([(nd.x, nd.P, nd.x_pred, nd.P_pred) if fused[k, i] else None for i, nd in enumerate(nodes)])
        for i, nd in enumerate(nodes):
            phys["node_x"][i, k], phys["node_P"][i, k] = nd.x, nd.P
        phys["x"][k], phys["P"][k] = master.x, master.P
        for nd in nodes:
            nd.predict(rec.u[k])
        master.predict(rec.u[k])
    seconds = time.process_time() - started
    out = {"seconds": seconds, "rejected": sum(nd.rejected for nd in nodes),
           "applied": sum(nd.applied for nd in nodes)}
    for xk, Pk in (("node_x", "node_P"), ("x", "P")):
        xs, Ps = phys[xk].reshape(-1, n), phys[Pk].reshape(-1, n, n)
        zs, Pz = np.zeros_like(xs), np.zeros_like(Ps)
        for j in range(xs.shape[0]):
            zs[j], J = pm.phi(xs[j])
            Pz[j] = J @ Ps[j] @ J.T
        out[xk], out[Pk] = zs.reshape(phys[xk].shape), Pz.reshape(phys[Pk].shape)
    return out


def evaluate(res: ex.Result, kind: str) -> dict:
    """The metrics of closed_loop.metrics for `kind` on `res`'s recording (plus cost per step and
    the estimated tracking error), or {"failed": reason}."""
    rec, cfg = res.recording, res.config
    try:
        with np.errstate(all="raise"):
            out = run_on_recording(rec, kind, cfg.substeps)
    except (ArithmeticError, FloatingPointError, np.linalg.LinAlgError) as exc:
        return {"failed": f"{type(exc).__name__}: {exc}"}
    flat = ex._flat(cfg.model)
    k0 = min(int(round(cfg.metrics_from / rec.ts)), len(res.t) - 1)
    zeta = res.zeta[k0:]
    err = ex._errors(flat, out["x"][k0:], zeta)
    node_err = ex._errors(flat, out["node_x"][:, k0:], zeta[None])
    xd = np.array([ex.state_of_flags(flat, r) for r in rec.ref[k0:]])
    nees = ex._nees(err, out["P"][k0:])
    m = {
        "rmse_nodes": np.sqrt(np.mean(node_err ** 2, axis=1)),
        "rmse_master": np.sqrt(np.mean(err ** 2, axis=0)),
        "nees_master": nees,
        "nees_nodes": ex._nees(node_err, out["node_P"][:, k0:]).mean(axis=-1),
        "rmse_est_track_master": np.sqrt((ex._errors(flat, out["x"][k0:], xd) ** 2).mean(0)),
        "us_per_step": 1e6 * out["seconds"] / len(res.t),
        "late_applied": out["applied"], "late_rejected": out["rejected"],
    }
    if not np.all(np.isfinite(m["rmse_master"])) or nees.mean() > DIVERGED_NEES:
        return {"failed": f"diverged (master NEES {nees.mean():.3g})", **m}
    return m


def derivative_free_cost(res: ex.Result) -> float:
    """Microseconds per step of the derivative-free nodes, master and controller on the same
    recording (replay_recording), for the cost column."""
    started = time.process_time()
    ex.replay_recording(res.recording)
    return 1e6 * (time.process_time() - started) / len(res.t)
