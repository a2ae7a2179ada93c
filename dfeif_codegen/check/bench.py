"""`codegen bench`: what the generated code costs, measured side by side in one run.

Deterministic figures wherever possible: instruction counts per call from valgrind's callgrind
(host, double, -O2; the benchmark program in templates/harness/bench.c.j2 toggles collection
around each measured call), code size from arm-none-eabi-size and worst-case stack from GCC's
-fstack-usage call graph (Cortex-M4F, float, -Os), sizeof of the state structs as the target
compiler lays them out. Only `codegen build`'s wall time is a timing (median of --repeat).

It runs in three steps, each once and in order (check/bench_stages.py): compile every
program and object (host and Cortex-M4F), run every measurement, compare the peers with the
generated filter and shape the figures into a `BenchResult` (check/bench_report.py).

A built-in model name (the default) benchmarks both built-in models side by side; a model file
benchmarks that model alone.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from dfeif_codegen.check import bench_stages, harness, target
from dfeif_codegen.check.bench_report import BenchResult
from dfeif_codegen.errors import CodegenError

MODELS = ("dc_motor_link", "two_link_arm")
NETWORK_MARK = "<!-- codegen network --bench -->"


TITLE = "# Benchmarks"    # the first line of every report (bench_report) and of net/bench.py's


def check_out(out: str, model: str | None = None, flag: str = "--out", command: str = "bench") -> None:
    """`--out FILE`, before any measurement: a new file, or a report of ours (its title line;
    the network section `codegen network --bench` added is kept), never the model file."""
    from dfeif_codegen.paths import first_line, replaceable_file

    replaceable_file(out, flag, command, lambda p: first_line(p) == TITLE, {"model file": model})


def keep_network_section(text: str, previous: str) -> str:
    """The report with the section `codegen network --bench` wrote into the previous one kept."""
    if NETWORK_MARK not in previous:
        return text
    return text.rstrip() + "\n\n" + NETWORK_MARK + previous.split(NETWORK_MARK, 1)[1]


def bench(model: str | None = None, *, repeat: int = 5, command: str | None = None, progress=None,
          quick: bool = False) -> BenchResult:
    """The measurements of a model file, or (default, or a built-in name) of both built-in models
    side by side (`.report()`: BENCHMARKS.md's text). `command` is the line the report says
    regenerates it; `quick` skips the scaling sweeps and the Monte Carlo figures."""
    if isinstance(repeat, bool) or not isinstance(repeat, int) or not 1 <= repeat <= 1000:
        raise CodegenError(f"--repeat must be an integer between 1 and 1000, got {repeat!r}")
    harness.host_compiler()
    for tool in ("arm-none-eabi-gcc", "arm-none-eabi-size", "arm-none-eabi-nm", "qemu-system-arm"):
        target.require(tool)
    target.require_newlib()
    models = [model] if model not in (None, "all") and model not in MODELS else list(MODELS)
    with tempfile.TemporaryDirectory(prefix="codegen-bench-") as tmp:
        compiled = bench_stages.compile(models, repeat, quick, Path(tmp), progress)   # compile -> run -> compare
        ran = bench_stages.run(compiled, progress)
        return bench_stages.compare(ran, command or f"codegen bench --repeat {repeat}", repeat)
