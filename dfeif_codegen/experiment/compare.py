"""The derivative-free filter against an EKF and a UKF, on the same recordings.

A closed-loop run of the derivative-free filters gives a recording: every frame each node got
(on time or late, in arrival order), the packets the master fused and the input `u` the plant
received. The EKF and UKF nodes (reference/ekf.py, ukf.py) run open loop on exactly that data,
with the same initial information (`Phi^-1` of the derivative-free start, `P0` mapped by the
Jacobian), the same late-frame method (replay) and the same fusion rule (information difference,
in physical coordinates). Their errors are reported in the canonical coordinates of the tables
(estimates mapped by `Phi`, covariances by its Jacobian), so every column compares like with like.

Cost, measured alike for all three: each filter (the derivative-free one too, as a Kalman filter
on its own canonical model with constant covariance matrices, `CanonicalModel`) runs on the same driver (ReplayNode, PhysicalMaster)
with its predict and its update each one CasADi function called through Numeric's buffer;
`us_per_step` is the process CPU time of that loop per step (two nodes with their replays and the
master), `operations` the arithmetic of one predict and one update (CasADi's instruction count).

A run counts as diverged when a covariance stops being positive definite or an estimate is not
finite, or by the closed loops' own criterion (closed_loop.DivergenceWatch): the master's NEES
above NEES_DIVERGED n for NEES_STEPS steps in a row, a filter that has lost the state. A filter
that is merely overconfident (a NEES of hundreds, as an EKF whose model is wrong) keeps its run:
its RMSE is a result, its NEES says how little it knows of its error.
"""

from __future__ import annotations

import dataclasses
import time
from functools import lru_cache

import casadi as ca
import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import derivation, divergence
from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.reference.ekf import EKF
from dfeif_codegen.reference.offsets import OffsetFilter, OffsetModel
from dfeif_codegen.reference.physical import CanonicalMaps, PhysicalMaster, PhysicalModel, ReplayNode
from dfeif_codegen.reference.scheduled import ScheduledFilter, ScheduledModel
from dfeif_codegen.reference.ukf import UKF
from dfeif_codegen.symbolic.disturbance import augment

FILTERS = {"ekf": EKF, "ukf": UKF}
# filters on the canonical model, fed the controller's v: "df" is the project's derivative-free
# filter, "brunovsky" the chapter's (v held over Ts, Brunovsky A_d); today they are the same
CANONICAL = ("df", "brunovsky")
# the held filter with parameter-offset states (reference/offsets.py: a candidate, not generated)
OFFSETS = "offsets"
# the held filter with its covariance transition scheduled on the master's flat outputs
# (reference/scheduled.py: a candidate, not generated)
SCHEDULED = "scheduled"
# the filters whose predict takes what the master broadcasts besides u (`model.input`)
BROADCAST = (OFFSETS, SCHEDULED)
# the filters that carry the run's disturbance states (the offset filter has its own extension)
WITH_DISTURBANCE = ("df", SCHEDULED)
KINDS = (*CANONICAL, OFFSETS, SCHEDULED, *FILTERS)


class CanonicalModel(CanonicalMaps):
    """The derivative-free filter's own model (the canonical state, the predictor's mean map and
    its constant Φ, Q, C) in the shape of a PhysicalModel, so that `DerivativeFree` on it *is* the
    derivative-free filter and runs on the same driver (ReplayNode, PhysicalMaster) and the same
    call path as the EKF and UKF: their costs per step are then measured alike. Phi (the
    flatness map) is the identity here."""

    def __init__(self, flat, ts: float, q, predictor: str = predictors.DEFAULT, disturbance=None):
        """`disturbance`: the held filter's state extended by the disturbance states
        (symbolic/disturbance.py); `phi` then reports the canonical part."""
        pred = predictors.make(predictor, flat, ts, q, disturbance=disturbance)
        self.disturbance, self.canonical_n = disturbance, flat.n
        C = np.hstack([flat.discrete(ts)[2], np.zeros((flat.m, len(pred.Phi) - flat.n))])
        self.n, self.m, self.ts = len(pred.Phi), flat.m, float(ts)
        self.inputs = flat.m
        self.angle_out = np.array([c.angle for c in flat.chains])
        self.Qd, self.transition = pred.Q, pred.Phi
        x, w = ca.SX.sym("x", self.n), ca.SX.sym("w", self.m)
        if predictor == "held":
            mean = predictors.held_mean_sx(flat, pred.H, x, w, ca.DM(flat.param_vector))
        else:
            mean = ca.DM(pred.Phi) @ x + ca.DM(pred.B) @ w
        self.step_sx = ca.Function("step", [x, w], [mean])
        self.h_sx = ca.Function("h", [x], [ca.DM(C) @ x])
        self.Qx_sx = ca.Function("Qx", [x], [ca.DM(self.Qd)])

    def start(self, x0, P0):
        """The filter's initial (x, P) from the canonical ones (disturbances at 0, their spread)."""
        return augment(x0, P0, self.disturbance, self.m)


class DerivativeFree(EKF):
    """The EKF's update (C is constant, so it is the Kalman update) with the derivative-free
    prediction: the predictor's mean map and the constant transition, no Jacobian."""

    def predict_sx(self, x, P, u):
        Phi = ca.DM(self.model.transition)
        return self.model.step_sx(x, u), Phi @ P @ Phi.T + ca.DM(self.model.Qd)


@derivation.by_model
@lru_cache(maxsize=None)
def filter_of(spec: str, ts: float, q: tuple, substeps: int, kind: str, compiled: bool = False,
              predictor: str = predictors.DEFAULT, disturbance=None, offsets=None):
    """The filter `kind` (one of KINDS) of one model, built once per process (building its
    CasADi functions costs far more than a run); `compiled`: its predict and update as compiled C
    (physical.compiled_function: the same results, and CPU time per step then measures compiled
    arithmetic rather than CasADi's interpreter); `predictor`: the derivative-free filter's;
    `offsets` (reference/offsets.Offsets): what the "offsets" filter estimates."""
    flat = ex._flat(spec)
    if kind == OFFSETS:
        q = offsets.chains_q or q
        return OffsetFilter(OffsetModel(flat, ts, ex._per_chain(q, flat.m), offsets), compiled)
    if kind == SCHEDULED:
        return ScheduledFilter(ScheduledModel(flat, ts, np.array(q), disturbance), compiled)
    if kind in CANONICAL:   # "brunovsky" is the chapter's filter whatever the recording's predictor
        return DerivativeFree(CanonicalModel(flat, ts, np.array(q), predictor if kind == "df" else "brunovsky",
                                             disturbance if kind == "df" else None), compiled)
    return FILTERS[kind](PhysicalModel(flat, ts, np.array(q), substeps), compiled)


def own_kind(kind: str, predictor: str) -> str:
    """The filter `kind` names for loops closed by `predictor`: "df" is the loops' own filter,
    the scheduled one when they ran it (a filter of its own here, reference/scheduled.py)."""
    return SCHEDULED if kind == "df" and predictor == SCHEDULED else kind


def run_on_recording(rec: ex.Recording, kind: str, substeps: int = 10, compiled: bool = False,
                     disturbance=None, q=None, offsets=None) -> dict:
    """Nodes and master of `kind` over a recording: node and master estimates and covariances in
    canonical coordinates, (M, K, n), (M, K, n, n), (K, n), (K, n, n), and the CPU seconds of the
    filter loop alone (process time; the maps to canonical coordinates after it are not counted).
    "df" runs the derivative-free filter itself through the same driver (CanonicalModel). `q`:
    the filter's process-noise densities when not the recording's (the chapter's filter's own).
    Every filter's nodes gate their frames as the recording's did (`rec.gate`)."""
    q = tuple(np.asarray(rec.q if q is None or len(q) == 0 else ex._per_chain(q, rec.m), float))
    kind = own_kind(kind, rec.predictor)
    filt = filter_of(rec.model, float(rec.ts), q, substeps, kind, compiled,
                     rec.predictor, disturbance, offsets)
    pm = filt.model
    brunovsky = kind == "brunovsky" or (kind == "df" and rec.predictor == "brunovsky")
    inputs = rec.v if brunovsky else rec.u
    x0, J0 = pm.phi_inv(rec.master_x0)
    P0 = J0 @ rec.master_P0 @ J0.T
    if hasattr(pm, "start"):
        x0, P0 = pm.start(x0, P0)
    nodes = [ReplayNode(filt, rec.R[i], x0, P0, rec.max_lag, rec.gate or None) for i in range(rec.nodes)]
    master = PhysicalMaster(filt, x0, P0)
    K, n = rec.ref.shape[0], pm.n
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
        w = pm.input(inputs[k], master.x) if kind in BROADCAST else inputs[k]   # with what the master broadcasts
        for nd in nodes:
            nd.predict(w)
        master.predict(w)
    seconds = time.process_time() - started
    out = {"seconds": seconds, "rejected": sum(nd.rejected for nd in nodes),
           "applied": sum(nd.applied for nd in nodes), "outliers": sum(nd.outliers for nd in nodes)}
    for xk, Pk in (("node_x", "node_P"), ("x", "P")):
        xs, Ps = phys[xk].reshape(-1, n), phys[Pk].reshape(-1, n, n)
        nc = rec.n           # the canonical state's (a filter's own may be longer: disturbances)
        zs, Pz = np.zeros((xs.shape[0], nc)), np.zeros((xs.shape[0], nc, nc))
        for j in range(xs.shape[0]):
            zs[j], J = pm.phi(xs[j])
            Pz[j] = J @ Ps[j] @ J.T
        out[xk] = zs.reshape(*phys[xk].shape[:-1], nc)
        out[Pk] = Pz.reshape(*phys[Pk].shape[:-2], nc, nc)
    return out


def evaluate(res: ex.Result, kind: str, compiled: bool = False, disturbance=None, offsets=None) -> dict:
    """closed_loop.metrics of `kind`'s estimates on `res`'s recording (the plant's tracking error
    is the run's own), plus `us_per_step`, the CPU microseconds per step of the filter loop; a
    run whose filter fails or diverges gives {"failed": reason}."""
    rec = res.recording
    try:
        with np.errstate(all="raise"):
            q = {"brunovsky": res.config.q_brunovsky, SCHEDULED: res.config.q_scheduled, "ekf": res.config.q_ekf,
                 "ukf": res.config.q_ekf}.get(kind)
            out = run_on_recording(rec, kind, res.config.substeps, compiled, disturbance, q, offsets)
    except (ArithmeticError, FloatingPointError, np.linalg.LinAlgError) as exc:
        return {"failed": f"{kind}: {type(exc).__name__}: {exc}"}
    mine = dataclasses.replace(rec, node_x=out["node_x"], node_P=out["node_P"], x=out["x"], P=out["P"])
    counters = [{"late_applied": out["applied"], "late_rejected": out["rejected"], "outliers": out["outliers"]}]
    with np.errstate(all="ignore"):       # a diverged filter's NEES is inf or nan: judged below
        m = ex.metrics(dataclasses.replace(res, recording=mine, counters=counters))
    m["us_per_step"] = 1e6 * out["seconds"] / len(res.t)
    high = ~(np.asarray(m["nees_master"]) <= divergence.NEES_DIVERGED * rec.n)
    ends = np.flatnonzero(np.diff(np.concatenate([[0], high.astype(int), [0]])))
    longest = int(np.max(ends[1::2] - ends[::2])) if ends.size else 0
    if not np.all(np.isfinite(m["rmse_master"])) or longest >= divergence.NEES_STEPS:
        return {"failed": f"{kind}: diverged (master NEES above {divergence.NEES_DIVERGED:g} n for {longest} steps "
                          f"in a row; mean {float(np.mean(m['nees_master'])):.3g})"}
    return m


def operations(spec: str, ts: float, q, substeps: int = 10, kinds=("df", *FILTERS),
               predictor: str = predictors.DEFAULT, disturbance=None, offsets=None) -> dict:
    """Elementary operations of one predict and one update of each filter (CasADi's instruction
    count of the SX functions after common-subexpression elimination): a machine-independent
    cost beside the measured CPU time."""
    q = tuple(np.asarray(q, float))
    return {kind: filter_of(spec, float(ts), q, substeps, own_kind(kind, predictor), predictor=predictor,
                            disturbance=disturbance if kind in WITH_DISTURBANCE else None,
                            offsets=offsets if kind == OFFSETS else None).operations()
            for kind in kinds}
