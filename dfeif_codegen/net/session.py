"""One distributed run's shared facts: the closed loop's set-up drawn exactly as
`experiment.closed_loop.run` draws it (same seed -> same noise, initial state and network), and
the `Recording` rebuilt from what the processes logged, for the reference to replay."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment.network import Network
from dfeif_codegen.reference.control import FlatController
from dfeif_codegen.experiment.trajectory import flags
from dfeif_codegen.symbolic.flatness import FlatSystem


@dataclass
class Setup:
    cfg: ex.Config
    flat: FlatSystem
    ts: float
    K: int
    cams: list
    noise: list
    ref: np.ndarray
    x_phys0: np.ndarray
    x_hat0: np.ndarray
    P0: np.ndarray
    q: np.ndarray
    gains: np.ndarray
    R: np.ndarray
    net: Network
    plant_p: np.ndarray | None = None   # the plant's parameters (the scenario's model error); None: the model's

    @property
    def nodes(self) -> int:
        return len(self.cams)

    @property
    def plant_key(self) -> tuple | None:
        return None if self.plant_p is None else tuple(self.plant_p.tolist())

    def filter_start(self) -> dict[str, np.ndarray]:
        """x0, P0 and q as the programs' filters take them: with the scenario's disturbance
        states, extended as the reference's FilterBank extends them (driver_io.filter_start)."""
        from types import SimpleNamespace

        from dfeif_codegen.check import driver_io

        dist = self.cfg.disturbance
        return driver_io.filter_start(SimpleNamespace(
            m=self.flat.m, q=self.q, node_x0=[self.x_hat0], node_P0=[self.P0], master_x0=self.x_hat0,
            master_P0=self.P0, disturbance="" if dist is None else dist.to_json()))

    @property
    def filter_n(self) -> int:
        """The filters' state dimension (the canonical state, then the disturbance states)."""
        return len(self.filter_start()["master_x0"])


def setup(cfg: ex.Config) -> Setup:
    """The draws of closed_loop.run in the same order (network, noise, initial error)."""
    flat = ex._flat(cfg.model)
    ts = float(cfg.ts or flat.model.ts)
    n, m = flat.n, flat.m
    K = int(round(cfg.duration / ts))
    cams = [ex._camera(cfg.model, float(s), None if std is None else tuple(std))
            for s, std in zip(cfg.noise_scale, cfg.noise_std)]
    refs = ex.references(cfg, m)
    ref = np.array([flags(refs, flat.degrees, tk) for tk in np.arange(K) * ts])
    net_rng, noise_rng, init_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(3))
    net = Network(list(cfg.sensor), list(cfg.uplink), K, net_rng)
    noise = ex.outlying([noise_rng.standard_normal((K, len(c.channels))) for c in cams], cfg)
    P0 = ex.initial_covariance(flat, cfg.p0_std)
    x_hat0 = ex.state_of_flags(flat, ref[0])
    zeta0 = x_hat0 + (np.linalg.cholesky(P0) @ init_rng.standard_normal(n) if cfg.initial_error else 0.0)
    q = ex._per_chain(cfg.q, m)
    gains = FlatController(flat, poles=ex._per_chain(cfg.poles, m)).gains
    plant_p = cfg.plant_error.values(flat.model, cfg.seed)   # as closed_loop.prepare draws it
    return Setup(cfg, flat, ts, K, cams, noise, ref, flat.phi_inv_num(zeta0, plant_p), x_hat0, P0, q, gains,
                 np.array([c.R for c in cams]), net, plant_p)


def read_lines(path: Path) -> list[list[str]]:
    return [line.split() for line in Path(path).read_text().splitlines() if line.strip()] if Path(path).exists() else []


def parse_node_log(path: Path, n: int) -> dict:
    """Per step: late frames applied (source step, 0/1) and the estimate (x, P); plus counters."""
    steps, counters = {}, {}
    for f in read_lines(path):
        if f[0] == "S":
            bar = f.index("|")
            late = [(int(a[1:].split(":")[0]), int(a.split(":")[1])) for a in f[2:bar]]
            vals = np.array([float.fromhex(v) for v in f[bar + 1:]])
            steps[int(f[1])] = (late, vals[:n], vals[n:].reshape(n, n))
        elif f[0] in ("H", "R"):
            counters[f[0]] = {f[i]: float(f[i + 1]) for i in range(1, len(f) - 1, 2)}
        elif f[0] == "J":
            counters["joined"] = int(f[1])
    return {"steps": steps, "counters": counters}


def parse_master_log(path: Path, n: int, m: int, nodes: int) -> dict:
    steps, counters, events = {}, {}, []
    for f in read_lines(path):
        if f[0] == "M":
            bar = f.index("|")
            vals = np.array([float.fromhex(v) for v in f[bar + 1:]])
            steps[int(f[1])] = {"rc": int(f[2]), "src": [int(s) for s in f[3:3 + nodes]], "x": vals[:n],
                                "P": vals[n:n + n * n].reshape(n, n), "u": vals[n + n * n:n + n * n + m],
                                "v": vals[n + n * n + m:]}
        elif f[0] in ("H", "R"):
            counters[f[0]] = {f[i]: float(f[i + 1]) for i in range(1, len(f) - 1, 2)}
        elif f[0] == "N":
            events.append((int(f[1]), f[2], int(f[3])))
        elif f[0] == "J":
            counters["joined"] = int(f[1])
    return {"steps": steps, "counters": counters, "events": events}


def recording(s: Setup, relay_log: list[dict], frames: np.ndarray, K: int) -> ex.Recording:
    """The Recording of what actually reached each filter, from the relay's log of deliveries:
    camera frames delivered to a node before its tick of step k (on time if taken at k, late
    otherwise, in delivery order) and the uncorrupted packets delivered to the master before its
    tick of step k (the freshest one newer than the last fused, per node: the master's rule)."""
    flat, M = s.flat, s.nodes
    n, m = flat.n, flat.m
    z, gamma = np.zeros((M, K, m)), np.zeros((M, K), dtype=np.int8)
    late_rows = []
    sources = np.full((K, M), -1, dtype=int)
    last = np.full(M, -1)
    for e in relay_log:
        if e["ev"] != "arrive" or e.get("corrupt") or e["at"] >= K:
            continue
        k, i, src = e["at"], e["node"], e["step"]
        if e["kind"] == "camera":
            if src == k:
                z[i, k], gamma[i, k] = frames[i, k], 1
            else:
                late_rows.append((k, i, k - src, frames[i, src]))
        elif e["kind"] == "packet" and src <= k and k - src <= s.cfg.max_lag and src > sources[k, i]:
            sources[k, i] = src
    for k in range(K):        # the freshest per step, and only if newer than the last one fused
        for i in range(M):
            if sources[k, i] >= 0 and sources[k, i] > last[i]:
                last[i] = sources[k, i]
            else:
                sources[k, i] = -1
    pk, pn = np.nonzero(sources >= 0)
    node_x0, node_P0 = np.tile(s.x_hat0, (M, 1)), np.tile(s.P0, (M, 1, 1))
    empty = np.zeros(0)
    return ex.Recording(
        model=s.cfg.model, n=n, m=m, nodes=M, max_lag=s.cfg.max_lag, method=s.cfg.method, oosm=s.cfg.method,
        fusion=s.cfg.fusion, predictor=s.cfg.predictor, ts=s.ts, q=s.q, R=s.R, node_x0=node_x0, node_P0=node_P0,
        master_x0=s.x_hat0,
        master_P0=s.P0, gains=s.gains, params=flat.param_vector, seed=s.cfg.seed, z=z, gamma=gamma, ref=s.ref[:K],
        late_step=np.array([r[0] for r in late_rows], dtype=int), late_node=np.array([r[1] for r in late_rows], dtype=int),
        late_lag=np.array([r[2] for r in late_rows], dtype=int),
        late_z=np.array([r[3] for r in late_rows]).reshape(-1, m),
        pkt_step=pk, pkt_node=pn, pkt_src=sources[pk, pn],
        late_applied=empty, node_x=empty, node_P=empty, x=empty, P=empty, u=empty, v=empty, heads=tuple(flat.heads),
        disturbance="" if s.cfg.disturbance is None else s.cfg.disturbance.to_json(), gate=s.cfg.gate)


def write_json(path: Path, data) -> None:
    Path(path).write_text(json.dumps(data))
