"""`codegen bench`: what the generated code costs, measured side by side in one run.

Deterministic figures wherever possible: instruction counts per call from valgrind's callgrind
(host, double, -O2; the benchmark program in templates/harness/bench.c.j2 toggles collection
around each measured call), code size from arm-none-eabi-size and worst-case stack from GCC's
-fstack-usage call graph (Cortex-M4F, float, -Os), sizeof of the state structs as the target
compiler lays them out. Only `codegen build`'s wall time is a timing (median of --repeat).

A built-in model name (the default) benchmarks both built-in models side by side; a model file
benchmarks that model alone.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dfeif_codegen import __version__
from dfeif_codegen.check import bench_peers, bench_target, harness, target
from dfeif_codegen.check.bench_report import BenchResult
from dfeif_codegen.codegen import render
from dfeif_codegen.errors import CodegenError, SetupError

MODELS = ("dc_motor_link", "two_link_arm")
# (oosm, fusion) builds measured per model; the first is the reference configuration.
BUILDS = (("replay", "difference"), ("retrodict", "difference"), ("replay", "paper"), ("replay", "ci"))


def build_times(model: str, repeat: int, work: Path) -> list[float]:
    """Wall time of `codegen build` as a user runs it: a fresh process each time (imports and
    the symbolic derivation included, nothing cached), into an empty folder."""
    out = []
    for i in range(repeat):
        cmd = [sys.executable, "-m", "dfeif_codegen.cli", "build", model, "--out", str(work / f"time{i}")]
        start = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        out.append(time.perf_counter() - start)
        if proc.returncode != 0:
            raise SetupError(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    return out


def _harness_program(model: harness.ModelDir, work: Path, kind: str, defines: tuple[str, ...]) -> Path:
    """templates/harness/<kind>.c.j2 rendered for the model and compiled with its sources for
    callgrind (`defines`: -D options of the build); the executable's path."""
    work.mkdir(parents=True, exist_ok=True)
    template = f"harness/{kind}.c.j2"
    src = work / f"{model.name}_{kind}.c"
    src.write_text(render.environment(model.precision).get_template(template).render(
        p=model.name, P=model.name.upper(), banner=render.banner(template, model.name, __version__)))
    return harness.compile_program([*model.sources(), src], work / kind, [model.path],
                                   [harness.BIND_NOW, *(f"-D{d}" for d in defines)])


def callgrind(model: harness.ModelDir, work: Path, defines: tuple[str, ...] = ()) -> dict[str, float]:
    """Instructions per call of each section of bench.c.j2 (`defines`: -D options of the build)."""
    return harness.callgrind(_harness_program(model, work, "bench", defines), work)[0]


def worst_case(model: harness.ModelDir, work: Path, defines: tuple[str, ...] = ()) -> dict[str, dict]:
    """Per public entry point, the instructions of its costliest call and the median call, over the
    calls of templates/harness/worst.c.j2, which drives every entry point down its longest path
    (lag N_max, packets N_max steps stale, distinct nodes, keyed frames of the largest kind)."""
    exe = _harness_program(model, work, "worst", defines)
    calls: dict[str, list[int]] = {}
    for name, _, total in harness.callgrind_dumps(exe, work)[0]:
        if name.startswith("worst/"):
            calls.setdefault(name[len("worst/"):], []).append(total)
    return {name: {"max": max(c), "median": statistics.median(c), "calls": len(c)} for name, c in calls.items()}


def ci_every_step(model: harness.ModelDir) -> tuple[str, ...]:
    """The define that makes the CI search run all its steps (no early stop): its worst case."""
    return (f"{model.name.upper()}_CI_TOL=-1",)


def target_sizes(model: harness.ModelDir, work: Path) -> tuple[dict, dict]:
    objs = target.compile_objects(model.sources(), work, [model.path], opt="-Os")
    stack = target.stack_usage(o.with_suffix(".ci") for o in objs)
    return target.sizes(objs), target.public_functions(model.name, stack)


def tool_versions() -> dict[str, str]:
    """The first line of each measuring tool's --version, as the report cites them."""
    def first(cmd: list[str]) -> str:
        return subprocess.run(cmd, capture_output=True, text=True).stdout.strip().splitlines()[0]

    return {"gcc": first([harness.host_compiler(), "--version"]),
            "arm": first([target.require("arm-none-eabi-gcc"), "--version"]),
            "valgrind": first(["valgrind", "--version"])}


NETWORK_MARK = "<!-- codegen network --bench -->"


def keep_network_section(text: str, previous: str) -> str:
    """The report with the section `codegen network --bench` wrote into the previous one kept."""
    if NETWORK_MARK not in previous:
        return text
    return text.rstrip() + "\n\n" + NETWORK_MARK + previous.split(NETWORK_MARK, 1)[1]


def bench(model: str | None = None, *, repeat: int = 5, command: str | None = None, progress=None,
          quick: bool = False) -> BenchResult:
    """The measurements of a model file, or (default, or a built-in name) of both built-in models
    side by side (`.report()`: BENCHMARKS.md's text). `command` is the line the report says regenerates it; `quick` skips
    the scaling sweeps and the Monte Carlo figures."""
    if isinstance(repeat, bool) or not isinstance(repeat, int) or not 1 <= repeat <= 1000:
        raise CodegenError(f"--repeat must be an integer between 1 and 1000, got {repeat!r}")
    harness.host_compiler()
    for tool in ("arm-none-eabi-gcc", "arm-none-eabi-size", "arm-none-eabi-nm", "qemu-system-arm"):
        target.require(tool)
    target.require_newlib()
    models = [model] if model not in (None, "all") and model not in MODELS else list(MODELS)
    sections = []
    with tempfile.TemporaryDirectory(prefix="codegen-bench-") as tmp:
        work = Path(tmp)
        for name in models:
            if progress:
                progress(f"codegen bench: {name}")
            sections.append(_bench_model(name, repeat, work / name))
        if progress:
            progress("codegen bench: peers")
        for sec in sections:
            name, w = sec["name"], work / sec["name"]
            sec["peers"] = {}
            for pred in bench_peers.PREDICTORS:
                md = harness.build_model(name, w / f"peers-{pred}-build", **bench_peers.with_predictor(pred))
                sec["peers"][pred] = bench_peers.c_peers(name, md, w / f"peers-{pred}")
            sec["py_peers"] = bench_peers.python_peers(name)
            if progress:
                progress(f"codegen bench: {name} on the emulated Cortex-M4F")
            sec["target"] = bench_target.model(name, w / "target")
            sec["target_peers"] = {pred: bench_target.peers(name, w / f"target-peers-{pred}", pred)
                                   for pred in bench_peers.PREDICTORS}
        comparisons = {}
        if not quick:
            if progress:
                progress("codegen bench: scaling")
            comparisons["scaling"] = bench_peers.scaling(work / "scaling", callgrind)
            if progress:
                progress("codegen bench: scaling on the emulated Cortex-M4F")
            comparisons["target_scaling"] = bench_target.scaling(work / "target-scaling")
            if progress:
                progress("codegen bench: closed-loop Monte Carlo")
            comparisons["mc"] = bench_peers.monte_carlo(work / "mc")
    return BenchResult(command or f"codegen bench --repeat {repeat}", repeat, tool_versions(), sections,
                       comparisons)


def _bench_model(name: str, repeat: int, work: Path) -> dict:
    times = build_times(name, repeat, work / "build")
    counts, worst = {}, {}
    for oosm, fusion in BUILDS:
        md = harness.build_model(name, work / f"{oosm}-{fusion}", "double", oosm, fusion)
        counts[(oosm, fusion)] = callgrind(md, work / f"cg-{oosm}-{fusion}")
        worst[(oosm, fusion)] = worst_case(md, work / f"worst-{oosm}-{fusion}")
        if fusion == "ci":
            counts[(oosm, "ci-every-step")] = callgrind(md, work / f"cg-{oosm}-ci-all", ci_every_step(md))
            worst[(oosm, "ci-every-step")] = worst_case(md, work / f"worst-{oosm}-ci-all", ci_every_step(md))
    sizeofs = {}
    for precision in ("float", "double"):
        md = harness.build_model(name, work / f"sizeof-{precision}", precision)
        sizeofs[precision] = target.struct_sizes(md, work / f"sizeof-{precision}-probe")
    md = harness.build_model(name, work / "os-float", "float")
    sizes, stack = target_sizes(md, work / "os-float-obj")
    md_retro = harness.build_model(name, work / "os-float-retro", "float", "retrodict")
    _, stack_retro = target_sizes(md_retro, work / "os-float-retro-obj")
    return {"name": name, "times": times, "counts": counts, "worst": worst, "sizeof": sizeofs, "sizes": sizes,
            "stack": stack, "stack_retro": stack_retro}


