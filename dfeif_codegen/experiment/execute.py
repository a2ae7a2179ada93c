"""Run a plan (experiment/plan.py): every distinct run once, on the engine handed in, in local
processes or on a Dask cluster (experiment/sweep.py), reusing a --resume file's finished runs,
with the exact bound of every delay row computed alongside (it needs only the network draws).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.experiment import bounds
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import sweep
from dfeif_codegen.experiment.plan import Plan, make_config


def _series(res: ex.Result) -> dict:
    """The time series a figure shows, taken from a run in the worker that ran it."""
    rec = res.recording
    return {"t": res.t, "zeta": res.zeta, "ref": ex.state_of_flags(ex._flat(res.config.model), rec.ref),
            "node_x": rec.node_x, "x": rec.x, "u": rec.u, "v": rec.v, "delays": res.delays,
            "P_diag": np.diagonal(rec.P, axis1=1, axis2=2)}


class Progress:
    """A plain-text bar on stderr, only on a terminal and without --quiet."""

    def __init__(self, total: int, enabled: bool):
        self.total, self.done, self.enabled, self.start = total, 0, enabled, time.monotonic()

    def step(self) -> None:
        self.done += 1
        if self.enabled:
            width = 30
            full = int(width * self.done / self.total)
            elapsed = time.monotonic() - self.start
            eta = elapsed / self.done * (self.total - self.done)
            sys.stderr.write(f"\r[{'#' * full}{'.' * (width - full)}] {self.done}/{self.total} runs, "
                             f"{elapsed:4.0f} s elapsed, ~{eta:3.0f} s left ")
            sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")


@dataclass
class Outcome:
    results: dict            # (reference, label, fusion, row) -> [metrics] in seed order
    series: dict
    failures: list
    per_run: list
    where: str
    workers: int
    reused: int
    distinct: int
    elapsed: float
    bound: list              # per row, bounds.RowBound
    longest_side: float = 0.0    # CPU seconds of the longest row bound (one task: a cluster's floor)
    engine: str = "c"            # the engine's name, as the --results records say


def _todo(p: Plan, ids: dict, previous: dict, need_series: bool) -> tuple[list, list]:
    """(runs to do, (run id, metrics) reused from --resume): a run whose series a figure needs is rerun."""
    todo, reused = [], []
    for rid, (cfg, kind, keys) in ids.items():
        wants_series = need_series and kind == "df" and any(k in p.figure_keys for k in keys)
        if rid in previous and not wants_series:
            reused.append((rid, sweep.decode(previous[rid]["metrics"])))
        else:
            todo.append((rid, cfg, _series if wants_series else None, kind))
    return todo, reused


def _collector(p: Plan, out: Outcome, ids: dict, previous: dict, records, progress):
    """The callback that files each finished run under every table cell it serves."""

    def collect(rid, value, fresh=True):
        metrics, data = value if fresh else (value, None)
        _, _, keys = ids[rid]
        if fresh and rid not in previous:
            records.write(rid, keys, out.engine, metrics)
        for key in keys:
            out.per_run.append((*key[:4], key[4], metrics))
            if isinstance(metrics, str):
                out.failures.append((key, f"{key[0]} {key[1]} {key[2]} row {key[3] + 1} seed {key[4]}: {metrics}"))
            else:
                out.results.setdefault(key[:4], []).append((key[4], metrics))
            if data is not None and key in p.figure_keys:
                out.series[key] = data
        if fresh:
            progress.step()

    return collect


def execute(p: Plan, engine: sweep.Engine, need_series: bool, workers, scheduler, results_file, resume,
            quiet: bool) -> Outcome:
    """Run every distinct run of the plan (reusing a --resume file's), collecting per key, and the
    exact bound of every row alongside (it needs only the network draws)."""
    if resume and results_file and Path(resume) != Path(results_file):
        raise ScenarioError("--resume FILE continues FILE: give --results the same file or leave it out")
    previous = sweep.read_records(resume) if resume else {}
    digests = {spec: sweep.model_digest(spec) for spec in {cfg.model for cfg, _ in p.wanted}}
    ids = {sweep.run_id(cfg, engine.name, kind, digests[cfg.model]): (cfg, kind, keys)
           for (cfg, kind), keys in p.wanted.items()}
    todo, reused = _todo(p, ids, previous, need_series)
    workers = sweep.default_workers(workers, len(todo))
    client = sweep.connect(scheduler)
    try:
        shipped = sweep.prepare([cfg for _, cfg, _, _ in todo], engine)
    except BaseException:
        if client is not None:
            client.close()
        raise
    records = sweep.Records(resume or results_file, keep_existing=bool(resume))
    progress = Progress(len(todo), not quiet and sys.stderr.isatty())
    out = Outcome({}, {}, [], [], "", workers, len(reused), len(todo), 0.0, [], engine=engine.name)
    started = time.monotonic()
    collect = _collector(p, out, ids, previous, records, progress)
    for rid, metrics in reused:
        collect(rid, metrics, fresh=False)
    rows = [[make_config(p.sc, p.model, p.nodes, p.max_lag, p.refs[0], row, "replay", "difference", s)
             for s in p.seeds] for row in p.rows]
    try:
        out.where, side = sweep.execute(todo, engine, shipped, workers, client, collect,
                                        [(bounds.row_bound, (cfgs,)) for cfgs in rows])
        out.bound = [b for b, _ in side]
        out.longest_side = max((t for _, t in side), default=0.0)
    finally:
        records.close()
        progress.close()
    out.elapsed = time.monotonic() - started
    # the same numbers wherever and in whichever order the runs ran: average in seed order
    out.results = {k: [m for _, m in sorted(v, key=lambda sm: sm[0])] for k, v in out.results.items()}
    out.failures = [text for _, text in sorted(out.failures)]
    return out
