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

import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dfeif_codegen import __version__
from dfeif_codegen.check import harness, target
from dfeif_codegen.codegen import render
from dfeif_codegen.errors import CodegenError, SetupError

MODELS = ("dc_motor_link", "two_link_arm")
# (oosm, fusion) builds measured per model; the first is the reference configuration.
BUILDS = (("replay", "difference"), ("retrodict", "difference"), ("replay", "paper"), ("replay", "ci"))
LAGS = (1, 8, 32)


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


def callgrind(model: harness.ModelDir, work: Path) -> dict[str, float]:
    """Instructions per call of each section of bench.c.j2."""
    valgrind = shutil.which("valgrind")
    if valgrind is None:
        raise SetupError("valgrind not found: install the Debian package valgrind (apt-get install valgrind)")
    work.mkdir(parents=True, exist_ok=True)
    env = render.environment(model.precision)
    src = work / f"{model.name}_bench.c"
    src.write_text(env.get_template("harness/bench.c.j2").render(
        p=model.name, P=model.name.upper(), banner=render.banner("harness/bench.c.j2", model.name, __version__)))
    exe = harness.compile_program([*model.sources(), src], work / "bench", [model.path])
    for old in work.glob("callgrind.out*"):
        old.unlink()
    proc = subprocess.run([valgrind, "--tool=callgrind", "--collect-atstart=no", "--callgrind-out-file=callgrind.out",
                           str(exe)], cwd=work, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SetupError(f"callgrind run failed:\n{proc.stderr[-3000:]}")
    result = {}
    for dump in sorted(work.glob("callgrind.out*")):
        text = dump.read_text(errors="replace")
        desc = re.search(r"^desc: Trigger: Client Request: (\S+):(\d+)$", text, re.M)
        total = re.search(r"^(?:summary|totals): (\d+)", text, re.M)
        if desc and total:
            result[desc.group(1)] = int(total.group(1)) / int(desc.group(2))
    return result


def target_sizes(model: harness.ModelDir, work: Path) -> tuple[dict, dict]:
    objs = target.compile_objects(model.sources(), work, [model.path], opt="-Os")
    stack = target.stack_usage(o.with_suffix(".ci") for o in objs)
    return target.sizes(objs), target.public_functions(model.name, stack)


def target_sizeof(model: harness.ModelDir, work: Path) -> dict[str, int]:
    """sizeof the state structs as arm-none-eabi-gcc lays them out (read from its assembly)."""
    work.mkdir(parents=True, exist_ok=True)
    src = work / "sizeof.c"
    kinds = ("node", "master", "packet")
    src.write_text(f'#include "{model.name}.h"\nconst unsigned sizes[] = {{'
                   + ", ".join(f"sizeof({model.name}_{k})" for k in kinds) + "};\n")
    gcc = target.require("arm-none-eabi-gcc")
    proc = subprocess.run([gcc, *target.CPU_FLAGS, "-O2", f"-I{model.path}", "-S", "-o", "-", str(src)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise SetupError(f"sizeof probe failed:\n{proc.stderr[-2000:]}")
    words = [int(w) for w in re.findall(r"\.word\s+(\d+)", proc.stdout)]
    return dict(zip(kinds, words))


NETWORK_MARK = "<!-- codegen network --bench -->"


def keep_network_section(text: str, previous: str) -> str:
    """The report with the section `codegen network --bench` wrote into the previous one kept."""
    if NETWORK_MARK not in previous:
        return text
    return text.rstrip() + "\n\n" + NETWORK_MARK + previous.split(NETWORK_MARK, 1)[1]


def bench(model: str | None = None, *, repeat: int = 5, command: str | None = None, progress=None) -> str:
    """BENCHMARKS.md's text for a model file, or (default, or a built-in name) both built-in
    models side by side. `command` is the line the report says regenerates it."""
    if isinstance(repeat, bool) or not isinstance(repeat, int) or not 1 <= repeat <= 1000:
        raise CodegenError(f"--repeat must be an integer between 1 and 1000, got {repeat!r}")
    harness.host_compiler()
    for tool in ("arm-none-eabi-gcc", "arm-none-eabi-size"):
        target.require(tool)
    models = [model] if model not in (None, "all") and model not in MODELS else list(MODELS)
    sections = []
    with tempfile.TemporaryDirectory(prefix="codegen-bench-") as tmp:
        work = Path(tmp)
        for name in models:
            if progress:
                progress(f"codegen bench: {name}")
            sections.append(_bench_model(name, repeat, work / name))
    return _markdown(command or f"codegen bench --repeat {repeat}", sections, repeat)


def _bench_model(name: str, repeat: int, work: Path) -> dict:
    times = build_times(name, repeat, work / "build")
    counts = {}
    for oosm, fusion in BUILDS:
        md = harness.build_model(name, work / f"{oosm}-{fusion}", "double", oosm, fusion)
        counts[(oosm, fusion)] = callgrind(md, work / f"cg-{oosm}-{fusion}")
    sizeofs = {}
    for precision in ("float", "double"):
        md = harness.build_model(name, work / f"sizeof-{precision}", precision)
        sizeofs[precision] = target_sizeof(md, work / f"sizeof-{precision}-probe")
    md = harness.build_model(name, work / "os-float", "float")
    sizes, stack = target_sizes(md, work / "os-float-obj")
    md_retro = harness.build_model(name, work / "os-float-retro", "float", "retrodict")
    _, stack_retro = target_sizes(md_retro, work / "os-float-retro-obj")
    return {"name": name, "times": times, "counts": counts, "sizeof": sizeofs, "sizes": sizes,
            "stack": stack, "stack_retro": stack_retro}


def _fmt(n: float) -> str:
    return f"{n:,.0f}"


def _markdown(command: str, sections: list[dict], repeat: int) -> str:
    gcc = subprocess.run([harness.host_compiler(), "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    arm = subprocess.run([target.require("arm-none-eabi-gcc"), "--version"], capture_output=True,
                         text=True).stdout.splitlines()[0]
    vg = subprocess.run(["valgrind", "--version"], capture_output=True, text=True).stdout.strip()
    out = ["# Benchmarks", "",
           f"Written by `{command}` (dfeif-codegen {__version__}); regenerate with the same command.",
           "", f"- host: `{gcc}`, `-O2`, double; instruction counts from `{vg} --tool=callgrind` "
           "(deterministic: each count is the instructions executed inside the call, callees included, "
           "averaged over the calls of one section of `templates/harness/bench.c.j2`)",
           f"- target: `{arm}`, `{' '.join(target.CPU_FLAGS)} -Os`, float; sizes of the library's own "
           "objects (no newlib), stack from `-fstack-usage` over GCC's call graph (`-fcallgraph-info=su`), "
           "newlib leaf functions (`ceilf`, `sinf`, `memset`, ...) not included",
           f"- build time: wall clock of `codegen build` in a fresh process (imports included), "
           f"median of {repeat}", ""]
    for s in sections:
        name, c = s["name"], s["counts"]
        base = c[("replay", "difference")]
        out += [f"## {name}", "", f"`codegen build {name}`: median {statistics.median(s['times']):.2f} s "
                f"(min {min(s['times']):.2f} s, max {max(s['times']):.2f} s, {len(s['times'])} runs)", "",
                "### Instructions per call (host, double)", "",
                "| call | instructions | ratio to node update |", "|---|---:|---:|"]
        upd = base.get("node_update", float("nan"))
        for key, label in (("node_update", "node update (on time)"), ("node_predict", "node predict"),
                           ("control", "control (u and v)")):
            out.append(f"| {label} | {_fmt(base[key])} | {base[key] / upd:.2f} |")
        for fusion in ("paper", "difference", "ci"):
            cnt = c[("replay", fusion)]["master_fuse"]
            out.append(f"| master fuse, {fusion} rule, 2 packets | {_fmt(cnt)} | {cnt / upd:.2f} |")
        out += ["", "| late measurement | replay | retrodict | retrodict / replay |", "|---|---:|---:|---:|"]
        for lag in LAGS:
            key = f"node_update_delayed_lag{lag}"
            rp, rt = c[("replay", "difference")].get(key), c[("retrodict", "difference")].get(key)
            if rp and rt:
                out.append(f"| update_delayed, lag {lag} | {_fmt(rp)} | {_fmt(rt)} | {rt / rp:.2f} |")
        out += ["", "### Cortex-M4F (float, -Os)", "", "| object | .text | .data | .bss |", "|---|---:|---:|---:|"]
        total = [0, 0, 0]
        for obj, z in s["sizes"].items():
            out.append(f"| `{obj}` | {z.text} | {z.data} | {z.bss} |")
            total = [total[0] + z.text, total[1] + z.data, total[2] + z.bss]
        out += [f"| total | {total[0]} | {total[1]} | {total[2]} |", "",
                "| entry point | worst-case stack, replay [B] | retrodict [B] |", "|---|---:|---:|"]
        for fn, use in s["stack"].items():
            if use.bytes > 16:
                retro = s["stack_retro"].get(fn)
                out.append(f"| `{fn}` | {use.bytes} | {retro.bytes if retro else '-'} |")
        sf, sd = s["sizeof"]["float"], s["sizeof"]["double"]
        out += ["", "| struct (Cortex-M4F layout, max lag 32, 2 nodes) | float [B] | double [B] | ratio |",
                "|---|---:|---:|---:|"]
        for kind in ("node", "master", "packet"):
            out.append(f"| `{name}_{kind}` | {sf[kind]} | {sd[kind]} | {sd[kind] / sf[kind]:.2f} |")
        out.append("")
    return "\n".join(out)
