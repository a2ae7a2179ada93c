"""Many closed-loop runs at once: in this process, in local worker processes, or on a Dask cluster.

Why batches: a run in C takes milliseconds, so one task per run would be mostly scheduling; a task
is a batch of runs. Why the compiled code travels with the tasks: a Dask worker may share no
filesystem with the caller, so the shared libraries go as bytes (scattered once to every worker,
or handed to each local process when it starts) and each worker loads them from a private file.

Per-run records (JSON lines, one per finished run, appended and flushed as runs finish) let an
interrupted sweep continue (`--resume`): a run is identified by a hash of its engine, its whole
configuration and its model file's text, so a finished run is never recomputed and a changed
setting or model is never reused.
Results do not depend on where or in which order the runs ran: each run is a pure function of its
configuration, and the caller orders them by seed before averaging.

The engine that runs one closed loop is handed in (`Engine`): the numpy reference (`REFERENCE`,
here) or the compiled C (`check.closed_loop_c.ENGINE`, which compiles, so it lives a stage up).
"""

from __future__ import annotations

import base64
import csv
import hashlib
import json
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any, Hashable, Protocol

import numpy as np

from dfeif_codegen.errors import ScenarioError, SetupError
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import derivation
from dfeif_codegen.paths import first_line

_CODES: dict = {}          # compiled loops of this worker process (set by the pool's initializer)


class Engine(Protocol):
    """Runs one closed loop: `key` says which compiled code a run needs, `compile` builds each
    distinct key once in the caller (the result travels to every worker), `run` runs it."""

    name: str

    def key(self, cfg: ex.Config) -> Hashable: ...

    def compile(self, keys: list) -> dict: ...

    def run(self, cfg: ex.Config, code: Any) -> ex.Result: ...


class ReferenceEngine:
    """The numpy closed loop (experiment/closed_loop.py): nothing to compile."""

    name = "reference"

    def key(self, cfg: ex.Config) -> Hashable:
        return None

    def compile(self, keys: list) -> dict:
        return {}

    def run(self, cfg: ex.Config, code: Any) -> ex.Result:
        return ex.run(cfg)


REFERENCE = ReferenceEngine()


def model_digest(spec: str) -> str:
    """A digest of the model file's text (a built-in's packaged one): a run of an edited model (a
    parameter, a g entry, a noise) is another run, though its spec, the path, is the same."""
    text = derivation.MODEL_TEXT.get(spec)
    if text is None:
        from dfeif_codegen.symbolic import model as model_mod
        is_builtin = spec in model_mod.builtin_names()
        text = model_mod.builtin_text(spec) if is_builtin else Path(spec).read_text(encoding="utf-8")
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def run_id(cfg: ex.Config, engine: str, kind: str = "df", model: str = "") -> str:
    """`kind`: the filter judged on the run's recording (experiment/compare.py), "df" for the run's
    own; `model`: the model's `model_digest`."""
    key = (engine, cfg, model) if kind == "df" else (engine, cfg, kind, model)
    if cfg.plant_error.active:          # out of Config's repr, so error-free runs keep their ids
        key = (*key, cfg.plant_error)
    if cfg.disturbance is not None:     # likewise
        key = (*key, cfg.disturbance)
    if cfg.trajectory is not None:      # the same: path, content digest and smoothing of the CSV
        key = (*key, cfg.trajectory)
    if cfg.gate or cfg.outliers:         # likewise
        key = (*key, cfg.gate, cfg.outliers)
    if kind.split("-")[0] == "offsets":  # what that filter estimates
        key = (*key, cfg.offsets)
    return hashlib.sha256(repr(key).encode()).hexdigest()[:20]


# --- one batch, wherever it runs ------------------------------------------------------------------

def one(cfg: ex.Config, engine: Engine, codes: dict, series, kind: str = "df"):
    """One run -> (metrics or the error text, `series(result)` or None). With `kind` "ekf", "ukf"
    (or "df-replay", the derivative-free filter through the same driver) the metrics are those of
    that filter on the run's recording (experiment/compare.py)."""
    try:
        res = engine.run(cfg, codes.get(engine.key(cfg)))
    except (ArithmeticError, FloatingPointError, np.linalg.LinAlgError) as exc:
        return f"{type(exc).__name__}: {exc}", None
    if kind != "df":
        from dfeif_codegen.experiment import compare
        base = kind.split("-")[0]      # the derivative-free filter with the run's disturbance states
        m = compare.evaluate(res, base, disturbance=cfg.disturbance if base in compare.WITH_DISTURBANCE else None,
                             offsets=cfg.offsets if base == compare.OFFSETS else None)
        return (m["failed"] if "failed" in m else m), None
    return res.metrics, (series(res) if series else None)


def batch(items: list, engine: Engine, shipped: dict | None = None) -> list:
    """items: (run id, cfg, series function or None[, filter kind]) -> [(run id, value)]."""
    if shipped is not None:
        _init_worker(shipped)
    return [(rid, one(cfg, engine, _CODES, series, *kind)) for rid, cfg, series, *kind in items]


def _init_worker(shipped: dict) -> None:
    derivation.MODEL_TEXT.update(shipped["models"])
    derivation.FLATS.update(shipped["flats"])
    _CODES.update(shipped["codes"])


def prepare(configs, engine: Engine) -> dict:
    """What every worker needs: the compiled loop of each distinct build (built here, once), the
    text of any model file (a worker on another machine cannot read the caller's files) and the
    models' derivations."""
    configs = list(dict.fromkeys(configs))
    models = {c.model: Path(c.model).read_text(encoding="utf-8") for c in configs if Path(c.model).is_file()}
    flats = {c.model: ex._flat(c.model) for c in configs}
    codes = engine.compile(list(dict.fromkeys(engine.key(c) for c in configs)))
    return {"codes": codes, "models": models, "flats": flats}


def _chunks(items: list, workers: int) -> list[list]:
    size = max(1, min(16, math.ceil(len(items) / (4 * max(workers, 1)))))
    return [items[i:i + size] for i in range(0, len(items), size)]


def connect(scheduler: str | None):
    """A Dask client for --scheduler (checked before anything is compiled or run), or None."""
    if not scheduler:
        return None
    try:
        from dask.distributed import Client
    except ImportError:
        raise SetupError("--scheduler needs dask.distributed: pip install 'dfeif-codegen[cluster]'") from None
    try:
        return Client(scheduler, timeout=30)
    except (OSError, TimeoutError, ValueError) as exc:   # ValueError: not an address (no port)
        raise SetupError(f"--scheduler {scheduler}: cannot connect ({exc})") from None


def _side(fn, args: tuple, shipped: dict | None = None):
    """A side task's result and its CPU seconds: the longest one bounds a sweep on any cluster."""
    if shipped is not None:
        _init_worker(shipped)
    start = time.process_time()
    return fn(*args), time.process_time() - start


def execute(items: list, engine: Engine, shipped: dict, workers: int, client, done, side=()) -> tuple[str, list]:
    """Run every item, calling `done(run id, value)` as results arrive, and each `side` task
    (function, arguments) alongside, submitted first (a long task last would run alone); returns
    where they ran and the side tasks' (result, CPU seconds). `client`: a Dask client (see
    connect), closed here, or None for local processes."""
    if not items:
        if client is not None:
            client.close()
        return "nothing to run", [_side(fn, args) for fn, args in side]
    if client is not None:
        from dask.distributed import as_completed as dask_completed

        scheduler = getattr(client.scheduler, "address", "?")
        with client:
            cores = sum(client.ncores().values()) or 1
            [shared] = client.scatter([shipped], broadcast=True, hash=False)
            extra = [client.submit(_side, fn, args, shared, pure=False) for fn, args in side]
            futures = [client.submit(batch, chunk, engine, shared, pure=False) for chunk in _chunks(items, cores)]
            for fut in dask_completed(futures):
                for rid, value in fut.result():
                    done(rid, value)
            return f"Dask cluster {scheduler} ({cores} threads)", [fut.result() for fut in extra]
    if workers == 1:       # one run at a time, each recorded (--results) before the next starts
        _init_worker(shipped)
        for item in items:
            for rid, value in batch([item], engine):
                done(rid, value)
        return "1 process", [_side(fn, args) for fn, args in side]
    with ProcessPoolExecutor(max_workers=workers, initializer=_init_worker, initargs=(shipped,)) as pool:
        extra = [pool.submit(_side, fn, args) for fn, args in side]
        futures = [pool.submit(batch, chunk, engine) for chunk in _chunks(items, workers)]
        for fut in as_completed(futures):
            for rid, value in fut.result():
                done(rid, value)
        return f"{workers} processes", [fut.result() for fut in extra]


def default_workers(requested: int | None, jobs: int) -> int:
    if requested is not None and requested < 1:
        raise ScenarioError(f"--workers: needs at least 1, got {requested}")
    return max(1, min(requested or os.cpu_count() or 1, jobs))


# --- per-run records ----------------------------------------------------------------------------

def encode(metrics) -> dict | str:
    """Metrics as JSON: short arrays as lists, long ones (NEES per step) as base64 float64; both
    round-trip exactly."""
    if isinstance(metrics, str):
        return metrics
    out = {}
    for key, value in metrics.items():
        a = np.asarray(value)
        if a.size > 64:
            out[key] = {"shape": list(a.shape), "f8": base64.b64encode(a.astype("<f8").tobytes()).decode()}
        else:
            out[key] = a.tolist()
    return out


def decode(doc):
    if isinstance(doc, str):
        return doc
    out = {}
    for key, value in doc.items():
        if isinstance(value, dict):
            out[key] = np.frombuffer(base64.b64decode(value["f8"]), dtype="<f8").reshape(value["shape"]).copy()
        elif isinstance(value, list):
            out[key] = np.asarray(value)
        else:
            out[key] = value
    return out


def read_records(path) -> dict[str, dict]:
    """run id -> record from a --results file (a torn last line from an interrupted run is ignored)."""
    records = {}
    p = Path(path)
    if not p.is_file():
        raise ScenarioError(f"--resume {path}: no such file")
    try:
        text = p.read_text(encoding="utf-8")
        lines = text.splitlines()
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"--resume {path}: not a --results file (not UTF-8 text, byte {exc.start})") from None
    except OSError as exc:
        raise ScenarioError(f"--resume {path}: cannot read it ({exc.strerror})") from None
    torn = not text.endswith("\n")    # an interrupted run's last record, cut short
    for number, line in enumerate(lines, 1):
        try:
            rec = json.loads(line)
        except ValueError:
            rec = None
        if isinstance(rec, dict) and RECORD_KEYS <= set(rec):
            records[rec["id"]] = rec
        elif not (rec is None and torn and number == len(lines) and line.startswith(RECORD_START)):
            # not a cut record: another file, which --resume would append to or cut
            raise ScenarioError(f"--resume {path}: line {number} is not a run record")
    return records


class Records:
    """Appends one JSON line per finished run (flushed, so an interruption loses at most one)."""

    def __init__(self, path, keep_existing: bool):
        self.path = Path(path) if path else None
        self.file = None
        if self.path:
            if keep_existing and self.path.is_file():
                text = self.path.read_text(encoding="utf-8")
                if text and not text.endswith("\n"):   # drop a torn last line
                    self.path.write_text(text[:text.rfind("\n") + 1], encoding="utf-8")
            self.file = open(self.path, "a" if keep_existing else "w", encoding="utf-8")

    def write(self, rid: str, keys: list, engine: str, value) -> None:
        if self.file:
            self.file.write(json.dumps({"id": rid, "engine": engine, "runs": [list(k) for k in keys],
                                        "metrics": encode(value)}) + "\n")
            self.file.flush()

    def close(self) -> None:
        if self.file:
            self.file.close()


CSV_HEAD = ("reference", "method", "fusion", "row", "seed", "error")   # --csv's first columns
RECORD_START = '{"id": '   # how a --results line begins (Records.write)
RECORD_KEYS = {"id", "engine", "runs", "metrics"}


def is_csv(path: Path) -> bool:
    """Whether `path` is a --csv file an earlier run wrote (its header line)."""
    return first_line(path).startswith(",".join(CSV_HEAD) + ",")


def is_records(path: Path) -> bool:
    """Whether `path` is a --results file an earlier run wrote: empty (no run finished) or
    starting with a run record (the whole first line, or a torn one from an interruption)."""
    line = first_line(path, limit=2 ** 24)
    if path.stat().st_size == 0:
        return True
    try:
        rec = json.loads(line)
    except ValueError:
        return line.startswith(RECORD_START) and path.stat().st_size == len(line.encode())
    return isinstance(rec, dict) and RECORD_KEYS <= set(rec)


def write_csv(path, rows: list[tuple], n: int, nodes: int) -> None:
    """rows: (reference, method, fusion, row number, seed, metrics or error text)."""
    head = list(CSV_HEAD)
    head += [f"rmse_master_x{j + 1}" for j in range(n)] + [f"rmse_tracking_x{j + 1}" for j in range(n)]
    head += [f"rmse_node{i + 1}_x{j + 1}" for i in range(nodes) for j in range(n)]
    head += ["trace_master"] + [f"trace_node{i + 1}" for i in range(nodes)]
    head += ["nees_master"] + [f"nees_node{i + 1}" for i in range(nodes)] + ["late_applied", "late_rejected"]
    with open(path, "w", newline="", encoding="utf-8") as f:
        out = csv.writer(f)
        out.writerow(head)
        for ref, method, fusion, ri, seed, m in sorted(rows, key=lambda r: r[:5]):
            if isinstance(m, str):
                out.writerow([ref, method, fusion, ri + 1, seed, m] + [""] * (len(head) - 6))
                continue
            vals = list(m["rmse_master"]) + list(m["rmse_tracking"]) + list(np.ravel(m["rmse_nodes"]))
            vals += [float(m["trace_master"])] + list(m["trace_nodes"])
            vals += [float(np.mean(m["nees_master"]))] + list(np.mean(m["nees_nodes"], axis=-1))
            vals += [int(m["late_applied"]), int(m["late_rejected"])]
            out.writerow([ref, method, fusion, ri + 1, seed, ""] + [repr(float(v)) for v in vals[:-2]] + vals[-2:])
