"""The filter side of a closed-loop run: the nodes, the master and the controller stepped as the
protocol says (`FilterBank`), shared by the closed loop and the replay, and everything they saw
and gave (`Recording`: the scenario format the C harness consumes)."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.reference.control import FlatController
from dfeif_codegen.reference.fusion import Master
from dfeif_codegen.reference.node import NodeFilter
from dfeif_codegen.symbolic.disturbance import augment


@dataclass
class Recording:
    """Every input the filters saw and every output they gave, as numpy arrays (`np.savez`).

    Meta: model spec, sizes, methods, ts, q (m), R (M, m, m), initial x0/P0 of the nodes
    (M, n), (M, n, n) and master, controller gains (n, chain by chain k_1..k_r), params, seed.
    Per step k: z (M, K, m) and gamma (M, K) of each node's `update` (z is 0 where gamma is 0),
    ref (K, n + m). Late events in the order applied: late_step, late_node, late_lag, late_z
    (E, m). Packets fused by the master: pkt_step (master step), pkt_node, pkt_src (source step).
    Outputs: late_applied (E), node_x (M, K, n) and node_P after the step's updates, master x, P
    after fuse, u, v. `disturbance`: the filters' disturbance states (Disturbance.to_json), ""
    without; then x0, P0 and q here are the canonical ones and the outputs the canonical part.
    """

    model: str
    n: int
    m: int
    nodes: int
    max_lag: int
    method: str           # replay | retrodict | discard | as-current
    oosm: str             # what the node filters were built with
    fusion: str
    predictor: str        # held | scheduled | brunovsky: the filters predict with u, (u, σ) or v
    ts: float
    q: np.ndarray
    R: np.ndarray
    node_x0: np.ndarray
    node_P0: np.ndarray
    master_x0: np.ndarray
    master_P0: np.ndarray
    gains: np.ndarray
    params: np.ndarray
    seed: int
    z: np.ndarray
    gamma: np.ndarray
    ref: np.ndarray
    late_step: np.ndarray
    late_node: np.ndarray
    late_lag: np.ndarray
    late_z: np.ndarray
    pkt_step: np.ndarray
    pkt_node: np.ndarray
    pkt_src: np.ndarray
    late_applied: np.ndarray
    node_x: np.ndarray
    node_P: np.ndarray
    x: np.ndarray
    P: np.ndarray
    u: np.ndarray
    v: np.ndarray
    disturbance: str = ""
    heads: tuple = ()     # the flat outputs' entries of x (the scheduled predictor's σ = x[heads])
    gate: float = 0.0     # the nodes' innovation gate [standard deviations]; 0: none (the C's --gate)

    def save(self, path) -> None:
        np.savez(path, **{f.name: np.asarray(getattr(self, f.name)) for f in fields(self)})

    def head(self, steps: int) -> "Recording":
        """The first `steps` steps: their inputs, the late frames and packets that arrive within
        them, their outputs. The filters are causal, so a run on it is the whole run's beginning
        (a target whose RAM cannot hold the whole run is checked on that)."""
        late, pkt = np.asarray(self.late_step) < steps, np.asarray(self.pkt_step) < steps
        cut = {name: np.asarray(getattr(self, name))[late] for name in
               ("late_step", "late_node", "late_lag", "late_z", "late_applied")}
        cut |= {name: np.asarray(getattr(self, name))[pkt] for name in ("pkt_step", "pkt_node", "pkt_src")}
        cut |= {name: np.asarray(getattr(self, name))[:, :steps] for name in ("z", "gamma", "node_x", "node_P")}
        cut |= {name: np.asarray(getattr(self, name))[:steps] for name in ("ref", "x", "P", "u", "v")}
        return replace(self, **cut)

    @classmethod
    def load(cls, path) -> "Recording":
        with np.load(path) as data:
            values = {f.name: data[f.name] for f in fields(cls) if f.name in data}
        values.setdefault("predictor", np.asarray("brunovsky"))   # recorded before the held predictor
        values["disturbance"] = str(values.get("disturbance", ""))
        values["heads"] = tuple(int(h) for h in values.get("heads", ()))
        for name in ("model", "method", "oosm", "fusion", "predictor"):
            values[name] = str(values[name])
        for name in ("n", "m", "nodes", "max_lag", "seed"):
            values[name] = int(values[name])
        values["ts"] = float(values["ts"])
        values["gate"] = float(values.get("gate", 0.0))
        return cls(**values)


class FilterBank:
    """Nodes, master and controller, stepped exactly as the protocol says."""

    def __init__(self, flat, ts, q, R, node_x0, node_P0, master_x0, master_P0, gains, max_lag, oosm, fusion,
                 dtype=np.float64, predictor: str = predictors.DEFAULT, disturbance=None, right_first: bool = False,
                 gate: float | None = None):
        """`disturbance`: the filters' states are extended by its states (their x0, P0 here
        are the canonical ones; the disturbances start at 0 with their initial spread); what
        `step` returns stays the canonical part, what the controller and the metrics read.
        `right_first`: every filter's covariance products associated the other way
        (predictor.Brunovsky.right_first), the second double implementation. `gate`: the
        nodes' innovation gate (NodeFilter)."""
        m, self.n, self.m = flat.m, flat.n, flat.m
        node_x0, node_P0 = zip(*[augment(x, P, disturbance, m) for x, P in zip(node_x0, node_P0)])
        master_x0, master_P0 = augment(master_x0, master_P0, disturbance, m)
        self.nodes = [NodeFilter(flat, ts, q, R[i], node_x0[i], node_P0[i], max_lag=max_lag, oosm=oosm,
                                 dtype=dtype, predictor=predictor, disturbance=disturbance, gate=gate)
                      for i in range(len(R))]
        self.master = Master(flat, ts, q, master_x0, master_P0, len(R), rule=fusion, max_lag=max_lag,
                             predictor=predictor, disturbance=disturbance, dtype=dtype)
        for f in (*self.nodes, self.master):
            f.predictor.right_first = right_first
        held = predictors.held_constants(flat, ts) if predictor != "brunovsky" else None
        self.control = FlatController(flat, gains=gains, held=held)   # the law for what the plant holds
        # the law cancels the filters' estimate of what the model misses (docs/algorithms.md)
        self.compensate = disturbance is not None
        self.max_lag = max_lag
        self.sent: list[dict[int, object]] = [{} for _ in self.nodes]

    def step(self, k, z, gamma, late, sources, ref, w=None):
        """`late`: (node, lag, z) in arrival order; `sources[i]`: source step of node i's packet
        fused now (-1: none); `w`: the input the filters predict with (None: what the master
        broadcasts from its controller's u and v). Returns (late applied flags, node x, node P,
        x, P, u, v)."""
        for node, zi, gi in zip(self.nodes, z, gamma):
            node.update(zi if gi else None, bool(gi))
        applied = [self.nodes[i].update_delayed(zl, lag) for i, lag, zl in late]
        for node, sent in zip(self.nodes, self.sent):
            sent[k] = node.packet()
            sent.pop(k - self.max_lag - 1, None)
        self.master.fuse([sent.get(s) if s >= 0 else None for sent, s in zip(self.sent, sources)])
        n = self.n
        d = self.master.x[n:n + self.m] if self.compensate else None
        u, v = self.control(self.master.x[:n], ref, disturbance=d)
        out = (applied, [nd.x[:n].copy() for nd in self.nodes], [nd.P[:n, :n].copy() for nd in self.nodes],
               self.master.x[:n].copy(), self.master.P[:n, :n].copy(), u, v)
        if w is None:
            w = self.master.predictor.input(u, v, self.master.x)   # what the master broadcasts for the prediction
        for node in self.nodes:
            node.predict(w)
        self.master.predict(w)
        return out


class _Outputs:
    """Collects what FilterBank.step returns into the recording's arrays."""

    def __init__(self, M, K, n, m):
        self.node_x, self.node_P = np.zeros((M, K, n)), np.zeros((M, K, n, n))
        self.x, self.P = np.zeros((K, n)), np.zeros((K, n, n))
        self.u, self.v = np.zeros((K, m)), np.zeros((K, m))
        self.applied: list[bool] = []

    def put(self, k, out):
        applied, nx, nP, x, P, u, v = out
        self.applied += applied
        self.node_x[:, k], self.node_P[:, k] = nx, nP
        self.x[k], self.P[k], self.u[k], self.v[k] = x, P, u, v
