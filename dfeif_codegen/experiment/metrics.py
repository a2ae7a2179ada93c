"""What a closed-loop run is judged by: estimation and tracking errors (angles wrapped), NEES,
the tracking bound a run must stay within, saturated inputs, and a run's metrics from
`metrics_from` on (experiment/closed_loop.py computes them for every run)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dfeif_codegen.experiment.derivation import _flat
from dfeif_codegen.experiment.trajectory_file import KIND as TRAJECTORY
from dfeif_codegen.reference.linalg import wrap

if TYPE_CHECKING:
    from dfeif_codegen.experiment.closed_loop import Config, Result


def _per_chain(values, m) -> np.ndarray:
    return np.broadcast_to(np.asarray(values, dtype=float), (m,)).copy()


def state_of_flags(flat, ref_flags) -> np.ndarray:
    """The canonical state the reference flags describe (drop each chain's top derivative);
    `ref_flags` may hold one step per row."""
    idx = np.concatenate([np.arange(c.offset + j, c.offset + j + c.degree) for j, c in enumerate(flat.chains)])
    return np.asarray(ref_flags)[..., idx]


def tracking_errors(flat, zeta, ref) -> np.ndarray:
    """y - y_d per flat output (angles wrapped): zeta (..., n) true canonical states, ref
    (..., n + m) reference flags of the same steps."""
    e = zeta[..., flat.heads] - ref[..., [c.offset + j for j, c in enumerate(flat.chains)]]
    for j, c in enumerate(flat.chains):
        if c.angle:
            e[..., j] = wrap(e[..., j], True)
    return e


def tracking_bound(cfg: "Config", m: int) -> np.ndarray:
    """Per flat output: the scenario's tracking_bound, else twice the reference's amplitude (a
    run whose output strays by more than the reference's whole swing has stopped tracking); no
    bound for a constant reference."""
    if cfg.tracking_bound:
        return _per_chain(cfg.tracking_bound, m)
    amp = np.abs(_per_chain(cfg.amplitude, m))
    if cfg.reference == TRAJECTORY:      # a user's CSV: half each output's swing over the file
        amp = np.array(cfg.trajectory.amplitude([o.name for o in _flat(cfg.model).model.outputs]))
    return np.where(amp > 0, 2 * amp, np.inf)


def _errors(flat, est, zeta) -> np.ndarray:
    err = est - zeta
    for c in flat.chains:
        if c.angle:
            err[..., c.offset] = wrap(err[..., c.offset], True)
    return err


def _nees(err, P) -> np.ndarray:
    return np.einsum("...i,...i->...", err, np.linalg.solve(P, err[..., None])[..., 0])


def metrics(res: Result) -> dict:
    """Per run, from `metrics_from` on: estimation RMSE per canonical state (nodes, master),
    mean tr P, NEES per step (averaged later over runs), tracking RMSE of the true plant and of
    the estimates (x_hat - x_d per node and master, what the chapter's tables report)."""
    flat = _flat(res.config.model)
    rec = res.recording
    k0 = min(int(round(res.config.metrics_from / rec.ts)), len(res.t) - 1)
    zeta = res.zeta[k0:]
    node_err = _errors(flat, rec.node_x[:, k0:], zeta[None])
    err = _errors(flat, rec.x[k0:], zeta)
    desired = state_of_flags(flat, rec.ref[k0:])
    track = _errors(flat, zeta, desired)
    return {
        "rmse_nodes": np.sqrt(np.mean(node_err ** 2, axis=1)),
        "rmse_master": np.sqrt(np.mean(err ** 2, axis=0)),
        "trace_nodes": np.trace(rec.node_P[:, k0:], axis1=2, axis2=3).mean(axis=1),
        "trace_master": np.trace(rec.P[k0:], axis1=1, axis2=2).mean(),
        "nees_nodes": _nees(node_err, rec.node_P[:, k0:]),
        "nees_master": _nees(err, rec.P[k0:]),
        "rmse_tracking": np.sqrt(np.mean(track ** 2, axis=0)),
        # the chapter's literal quantity (Tables II-IV): the *estimated* tracking error x_hat - x_d
        "rmse_est_tracking_nodes": np.sqrt(np.mean(_errors(flat, rec.node_x[:, k0:], desired[None]) ** 2, axis=1)),
        "rmse_est_tracking_master": np.sqrt(np.mean(_errors(flat, rec.x[k0:], desired) ** 2, axis=0)),
        "late_applied": sum(c["late_applied"] for c in res.counters),
        "late_rejected": sum(c["late_rejected"] for c in res.counters),
        "outliers": sum(c.get("outliers", 0) for c in res.counters),   # frames the gate refused
        "saturated_steps": saturated_steps(flat, rec.u),
    }


def saturated_steps(flat, u: np.ndarray) -> int:
    """Steps (whole run) whose input the controller clamped to a declared limit: a clamped input
    equals its limit, up to single precision's rounding of the limit (1e-6 relative) in a float build."""
    inputs = flat.model.inputs
    lo = np.array([-np.inf if w.min is None else w.min for w in inputs])
    hi = np.array([np.inf if w.max is None else w.max for w in inputs])
    tol = 1e-6 * np.maximum(1.0, np.abs(np.where(np.isfinite(lo), lo, 0.0)))
    tol_hi = 1e-6 * np.maximum(1.0, np.abs(np.where(np.isfinite(hi), hi, 0.0)))
    at = (u[:, :len(inputs)] <= lo + tol) | (u[:, :len(inputs)] >= hi - tol_hi)
    return int(np.count_nonzero(at.any(axis=1)))
