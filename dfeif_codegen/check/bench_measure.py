"""`codegen bench`'s measurements, run on what was compiled before (check/bench_programs.py):
a `Measure` names its runner and holds its compiled inputs; `measure` runs it and returns the raw
figures. Nothing here compiles the generated C, and nothing checks or shapes the figures (that is
the compare step, check/bench_stages.py), except what is measured as a user runs it: `codegen
build`'s wall time, the Python peers, and `codegen simulate`'s Monte Carlo throughput."""

from __future__ import annotations

import json
import resource
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dfeif_codegen.check import harness, target, target_count
from dfeif_codegen.errors import SetupError


@dataclass(frozen=True)
class Measure:
    """One measurement of the run step: `how` names its runner (RUNNERS), `args` what the compile
    step made for it (a program, objects) or its settings, `work` the folder it runs in."""

    how: str
    args: tuple = ()
    work: Path = Path(".")


def measure(m: Measure) -> Any:
    return RUNNERS[m.how](m)


def callgrind(m: Measure) -> dict[str, float]:
    """Instructions per call of each section of a host benchmark program."""
    return harness.callgrind(m.args[0], m.work)[0]


def worst(m: Measure) -> dict[str, dict]:
    """Per public entry point, the instructions of its costliest call and the median call, over the
    calls of templates/harness/worst.c.j2 (every entry point down its longest path: lag N_max,
    packets N_max steps stale, distinct nodes, keyed frames of the largest kind)."""
    calls: dict[str, list[int]] = {}
    for name, _, total in harness.callgrind_dumps(m.args[0], m.work)[0]:
        if name.startswith("worst/"):
            calls.setdefault(name[len("worst/"):], []).append(total)
    return {name: {"max": max(c), "median": statistics.median(c), "calls": len(c)} for name, c in calls.items()}


def c_peers(m: Measure) -> dict:
    """Instructions (callgrind) and wall ns per step of the generated filter and the C peers, and
    each one's final estimate (the compare step checks they agree)."""
    exe = m.args[0]
    counts, stdout = harness.callgrind(exe, m.work)
    proc = subprocess.run([str(exe), "time"], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SetupError(f"peers timing failed:\n{proc.stderr[-2000:]}")
    ns = {line.split()[0]: float(line.split()[1]) for line in proc.stdout.splitlines() if line.strip()}
    return {"instructions": counts, "ns": ns, "stdout": stdout}


def sizes(m: Measure) -> dict[str, target.Size]:
    return target.sizes(m.args[0])


def stack(m: Measure) -> dict[str, target.StackUse]:
    """Worst-case stack of each public function of model `args[0]` over GCC's call graph of its objects."""
    name, objs = m.args
    return target.public_functions(name, target.stack_usage(o.with_suffix(".ci") for o in objs))


def sizeof(m: Measure) -> dict[str, int]:
    return target.read_struct_sizes(m.args[0])


def qemu(m: Measure) -> dict:
    """Instructions and cycles per call of each section of a Cortex-M4F program, and its stdout."""
    counts, stdout = target_count.count(m.args[0], m.work)
    return {"counts": counts, "stdout": stdout}


def qemu_stack(m: Measure) -> dict:
    """`qemu` on worst.c.j2, and the stack of each entry point it drives (model `args[1]`), newlib's
    and libgcc's frames included."""
    elf, name = m.args
    out = qemu(m)
    roots = [f"{name}_{k[len('worst/'):]}" for k in out["counts"] if k.startswith("worst/")]
    out["stack"] = {fn[len(name) + 1:]: use for fn, use in target_count.stack_with_library(elf, roots).items()}
    return out


def build_times(m: Measure) -> list[float]:
    """Wall time of `codegen build` as a user runs it: a fresh process each time (imports and
    the symbolic derivation included, nothing cached), into an empty folder."""
    model, repeat = m.args
    out = []
    for i in range(repeat):
        cmd = [sys.executable, "-m", "dfeif_codegen.cli", "build", model, "--out", str(m.work / f"time{i}")]
        start = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        out.append(time.perf_counter() - start)
        if proc.returncode != 0:
            raise SetupError(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    return out


def tools(m: Measure) -> dict[str, str]:
    """The first line of each measuring tool's --version, as the report cites them."""
    def first(cmd: list[str]) -> str:
        return subprocess.run(cmd, capture_output=True, text=True).stdout.strip().splitlines()[0]

    return {"gcc": first([harness.host_compiler(), "--version"]),
            "arm": first([target.require("arm-none-eabi-gcc"), "--version"]),
            "valgrind": first(["valgrind", "--version"])}


def python_peers(m: Measure, steps: int = 2000, repeat: int = 5) -> dict:
    """Wall ns per step (median of `repeat`) of the numpy reference and FilterPy's KalmanFilter."""
    from dfeif_codegen.reference.node import NodeFilter
    from dfeif_codegen.symbolic import flatness, model as model_mod, sampling

    flat = flatness.derive(model_mod.load(m.args[0]))
    ts, n, mm = flat.model.ts, flat.n, flat.m
    A, B, C = flat.discrete(ts)
    Q, R = flat.process_noise(ts, np.ones(mm)), 1e-4 * np.eye(mm)
    x0, P0, v = 0.1 * np.arange(1, n + 1), 0.01 * np.eye(n), 0.5 * np.ones(mm)
    zs = [0.1 + 1e-3 * (k & 7) * np.ones(mm) for k in range(steps)]

    def timed(make, step) -> float:
        runs = []
        for _ in range(repeat):
            f = make()
            t0 = time.perf_counter()
            for z in zs:
                step(f, z)
            runs.append((time.perf_counter() - t0) / steps * 1e9)
        return statistics.median(runs)

    # the reference predicts with the held input its constants are linearized at (as the C
    # benchmarks: a constant 0.5 takes a PVTOL's thrust through its singular 0); FilterPy's chain, v
    u_held = sampling.nominal_point(flat)[1]

    def ref_step(f, z):
        f.update(z, True)
        f.predict(u_held)

    out: dict = {"numpy reference": timed(lambda: NodeFilter(flat, ts, np.ones(mm), R, x0, P0), ref_step)}
    try:
        from filterpy.kalman import KalmanFilter
    except ImportError:
        out["FilterPy KalmanFilter"] = None
        return out

    def make():
        kf = KalmanFilter(dim_x=n, dim_z=mm, dim_u=mm)
        kf.x, kf.P, kf.F, kf.B, kf.H, kf.Q, kf.R = x0.copy(), P0.copy(), A, B, C, Q, R
        return kf

    def fp_step(kf, z):
        kf.update(z)
        kf.predict(v)

    out["FilterPy KalmanFilter"] = timed(make, fp_step)
    return out


def monte_carlo(m: Measure, seeds_c: int = 2, seeds_ref: int = 1) -> dict:
    """Runs per second of `codegen simulate` (compilation and start-up excluded: the command's own
    elapsed time of the runs) for each engine and way of running, and the 100-seed paper table's
    wall time as a user runs it (start-up and compilation included)."""
    work = m.work
    work.mkdir(parents=True, exist_ok=True)
    cases = [("c", "1 process", seeds_c, ["--workers", "1"]), ("c", "2 processes", seeds_c, ["--workers", "2"]),
             ("reference", "1 process", seeds_ref, ["--workers", "1"]),
             ("reference", "2 processes", seeds_ref, ["--workers", "2"])]
    results = []
    cluster = None
    try:
        from dask.distributed import LocalCluster
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
        cases.append(("c", "LocalCluster, 2 workers", seeds_c, ["--scheduler", cluster.scheduler_address]))
    except ImportError:
        pass
    try:
        for engine, how, seeds, extra in cases:
            doc = _simulate(work, ["--engine", engine, "--runs", str(seeds), *extra])
            s = doc["settings"]
            results.append({"engine": engine, "how": how, "runs": s["distinct_runs"], "seconds": s["elapsed_s"],
                            "per_s": s["distinct_runs"] / s["elapsed_s"]})
    finally:
        if cluster is not None:
            cluster.close()
    t0, cpu0 = time.perf_counter(), _children_cpu()
    doc = _simulate(work, ["--runs", "100"])
    table = {"wall_s": time.perf_counter() - t0, "cpu_s": _children_cpu() - cpu0, "runs": doc["settings"]["distinct_runs"],
             "loop_s": doc["settings"]["elapsed_s"], "workers": doc["settings"]["workers"],
             "longest_task_s": doc["settings"]["longest_bound_cpu_s"]}
    return {"rates": results, "paper100": table}


def _children_cpu() -> float:
    """User + system CPU seconds of every finished child process (and theirs): the command's
    CPU time, which other load on the machine does not inflate the way it inflates wall time."""
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def _simulate(work: Path, extra: list[str]) -> dict:
    out = work / "mc.json"
    cmd = [sys.executable, "-m", "dfeif_codegen.cli", "simulate", "--quiet", "--json", str(out), *extra]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=work)
    if proc.returncode != 0:
        raise SetupError(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    return json.loads(out.read_text())


RUNNERS = {"callgrind": callgrind, "worst": worst, "c-peers": c_peers, "sizes": sizes, "stack": stack,
           "sizeof": sizeof, "qemu": qemu, "qemu-stack": qemu_stack, "build-times": build_times, "tools": tools,
           "python-peers": python_peers, "monte-carlo": monte_carlo}
