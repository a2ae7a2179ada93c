"""`codegen network`: the estimator as separate OS processes on loopback (net/launch.py starts
them), compared with the reference: at the end the reference replays the arrival pattern the relay
logged, and the nodes' and master's logged estimates and inputs must equal it (<= 1e-10 relative
in double).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dfeif_codegen import json_text
from dfeif_codegen.check import harness, verify
from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import derivation
from dfeif_codegen.net import session
from dfeif_codegen.net.launch import HOST, Options, Outcome, launch, make_config


def compare(out: Outcome) -> tuple[list, ex.Recording]:
    """The reference replayed on the logged arrivals against the programs' logs (every node from
    its first log, the master's from its log); the errors per signal as `codegen verify` prints them."""
    s, K, M = out.setup, out.steps, out.setup.nodes
    rec = session.recording(s, out.relay, out.plant["frames"], K)
    ref = ex.replay_recording(rec)
    for name, value in ref.items():
        setattr(rec, name, value)
    n = s.flat.n
    got = {"node_x": np.full((M, K, n), np.nan), "node_P": np.full((M, K, n, n), np.nan),
           "x": np.full((K, n), np.nan), "P": np.full((K, n, n), np.nan),
           "u": np.full((K, s.flat.m), np.nan), "v": np.full((K, s.flat.m), np.nan)}
    applied = {}
    for i, log in enumerate(out.nodes):   # the canonical state: the disturbance states act through it
        for k, (late, x, P) in log["first"]["steps"].items():
            if k < K:
                got["node_x"][i, k], got["node_P"][i, k] = x[:n], P[:n, :n]
                applied.update({(k, i, src): a for src, a in late})
    for k, row in out.master["first"]["steps"].items():
        if k < K:
            got["x"][k], got["P"][k] = row["x"][:n], row["P"][:n, :n]
            got["u"][k], got["v"][k] = row["u"], row["v"]
    got["late_applied"] = np.array([applied.get((int(k), int(i), int(k - lag)), -1)
                                    for k, i, lag in zip(rec.late_step, rec.late_node, rec.late_lag)]) == 1
    return verify.compare_run(got, rec, out.opts.precision), rec


def loop_verdict(out: Outcome) -> str | None:
    """What `simulate`'s divergence watch says of the loop the processes closed (None: it held):
    the comparison judges the C against the reference on that loop, not the loop itself. Without
    the master's estimate at every step (a restart) the NEES criterion is left out."""
    from dataclasses import replace
    from types import SimpleNamespace
    from typing import Any

    from dfeif_codegen.experiment.divergence import Diverged, check_divergence

    s, K, n = out.setup, out.steps, out.setup.flat.n
    logged = {**out.master["first"]["steps"], **out.master["steps"]}
    x, P = np.full((K, n), np.nan), np.full((K, n, n), np.nan)
    for k, row in logged.items():
        if k < K:
            x[k], P[k] = row["x"][:n], row["P"][:n, :n]
    cfg = s.cfg if np.all(np.isfinite(x)) else replace(s.cfg, watch_nees=False)
    watched: Any = SimpleNamespace(K=K, cfg=cfg, flat=s.flat, ref=s.ref[:K], t=np.arange(K) * s.ts)  # a Setup's fields
    try:
        check_divergence(watched, out.plant["x"], out.plant["zeta"], x, P)
    except Diverged as exc:
        return str(exc)
    return None


def figures(out: Outcome) -> dict:
    """Latency frame -> command (wall clock, no emulated delay: the relay delays in steps, not
    seconds), CPU per process, datagrams and rejections."""
    p = out.plant
    lat = (p["t_recv"] - p["t_send"])[p["got"]] * 1e6
    sends = sum(1 for e in out.relay if e["ev"] == "send")
    r = out.master["counters"].get("R", {})
    return {
        "steps": out.steps, "wall_s": out.wall, "datagrams": sends,
        "latency_median_us": float(np.median(lat)) if lat.size else float("nan"),
        "latency_p99_us": float(np.percentile(lat, 99)) if lat.size else float("nan"),
        "cpu_s": {k: round(v, 3) for k, v in out.cpu.items() if v is not None},
        "master_busy_us_per_step": out.master["counters"].get("H", {}).get("busy_us", 0) / max(out.steps, 1),
        "node_busy_us_per_step": [nd["counters"].get("H", {}).get("busy_us", 0) / max(out.steps, 1) for nd in out.nodes],
        "rejected": {k: int(v) for k, v in r.items() if v and k != "accepted"},
        "accepted": int(r.get("accepted", 0)),
        "loop": loop_verdict(out),
    }


@dataclass
class Network:
    """What `network()` measured: the run, its figures and the comparison with the reference."""

    outcome: Outcome
    figures: dict
    errors: list
    summary: str

    @property
    def ok(self) -> bool:
        return all(e.ok for e in self.errors)

    def report(self) -> str:
        return self.summary + "\n" + verify.table(self.errors)

    def to_json(self) -> str:
        """The figures and the comparison (the logs themselves stay in `outcome`)."""
        return json_text.dumps({"summary": self.summary, "ok": self.ok, "figures": self.figures,
                           "errors": verify.errors_as_dicts(self.errors)})


DEFAULT_ROW = 2         # the paper grid's (8, 10, 0.8)
MAX_DURATION = 600.0   # simulated seconds of one network run (60,000 steps at 10 ms)


def network(model: str = "dc_motor_link", *, scenario: str = "paper", row: int | None = None, seed: int = 0,
            precision: str = "double", oosm: str = "replay", fusion: str = "difference", nodes: int | None = None,
            max_lag: int = 32, duration: float | None = 5.0, key: str | None = None, flip_rate: float = 0.0,
            keep: str | Path | None = None, max_seconds: float | None = None,
            max_memory: float | None = None, predictor: str | None = None) -> Network:
    """One run of the estimator as separate processes, compared with the reference replaying the
    logged arrivals. Bad options raise (one line) before anything is built; `keep` (an empty or
    new folder) keeps the programs and logs. `row`: the scenario's delay row, from 0 (None: 2,
    the paper grid's (8, 10, 0.8), or a shorter grid's last)."""
    import tempfile

    harness.host_compiler()
    if key is not None and (len(key) != 32 or any(c not in "0123456789abcdefABCDEF" for c in key)):
        raise ScenarioError(f"--key {key!r}: needs 32 hex digits (a 16-byte SipHash key)")
    if not 0 <= flip_rate < 1:
        raise ScenarioError(f"--flip-rate {flip_rate}: not in [0, 1)")
    if duration is not None and (isinstance(duration, bool) or not isinstance(duration, (int, float))
                                 or not 0 < duration <= MAX_DURATION):
        raise ScenarioError(f"--duration {duration!r}: seconds, more than 0 and at most {MAX_DURATION:g} "
                            "(every step is a datagram exchange between the processes)")
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2 ** 32:
        raise ScenarioError(f"--seed {seed!r}: a whole number from 0 to 2^32 - 1")
    if keep:
        from dfeif_codegen.paths import writable_dir
        writable_dir(keep, "--keep")
    if nodes is None or row is None:   # the scenario's [[nodes]], as simulate's; its row 2 or last
        from dfeif_codegen.experiment import scenario as scenarios
        sc = scenarios.load(scenario)
        nodes = len(sc.noise_scale) if nodes is None else nodes
        row = min(DEFAULT_ROW, len(sc.grid) - 1) if row is None else row
    o = Options(model=model, scenario=scenario, row=row, seed=seed, precision=precision, oosm=oosm,
                fusion=fusion, nodes=nodes, max_lag=max_lag, duration=duration, key=key, flip_rate=flip_rate,
                predictor=predictor)
    if keep and Path(keep).exists() and any(Path(keep).iterdir()):
        raise ScenarioError(f"--keep {keep}: not empty (the run writes its programs and logs there)")
    derivation.derive(o.model, max_seconds, max_memory)   # under the budget; make_config reuses it
    make_config(o)   # bad scenario or row: one line, before any build
    with tempfile.TemporaryDirectory(prefix="codegen-network-") as tmp:
        work = Path(keep) if keep else Path(tmp)
        out = launch(o, work, kept=bool(keep))
        errors, rec = compare(out)
        f = figures(out)
    return Network(out, f, errors, summary(o, out, f, rec))


def pairs(values: dict, fmt: str) -> str:
    """A dict as readable text ("master 0.120 s, node0 0.080 s"), not its Python repr."""
    return ", ".join(f"{k} {fmt.format(v)}" for k, v in values.items())


def summary(o: Options, out: Outcome, f: dict, rec) -> str:
    """The run's summary as printed by `codegen network`."""
    dist = out.setup.cfg.disturbance
    extra = ("" if dist is None else f", disturbance {dist.kind}") + \
        ("" if out.setup.plant_p is None else ", plant parameters as [model_error] draws them")
    return "\n".join([
        f"codegen network: {o.model}, {o.precision}, {o.nodes} nodes as separate processes on {HOST}, "
        f"scenario {o.scenario} ({out.setup.cfg.reference}) row {o.row} seed {o.seed}{extra}, {out.steps} steps in "
        f"{f['wall_s']:.1f} s",
        f"wire: packet {out.layout.size(out.layout.packet_reals)} B, command "
        f"{out.layout.size(out.layout.command_reals)} B{' + SipHash-2-4 tag' if o.key else ''}; "
        f"{f['datagrams']} datagrams; master accepted {f['accepted']}, rejected {pairs(f['rejected'], '{}') or 'none'}",
        f"logged arrivals: {int(rec.gamma.sum())} on-time frames, {len(rec.late_step)} late, "
        f"{len(rec.pkt_step)} packets fused",
        "the loop: " + (f"{f['loop']} (simulate counts such a run failed; below, the C against the reference on it)"
                        if f.get("loop") else "held (the divergence watch of simulate: tracking, domain, master NEES)"),
        f"frame -> command latency: median {f['latency_median_us']:.0f} us, p99 {f['latency_p99_us']:.0f} us "
        f"(master busy {f['master_busy_us_per_step']:.1f} us/step); CPU: {pairs(f['cpu_s'], '{:.3f} s') or 'not measured'}"])
