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
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dfeif_codegen import __version__
from dfeif_codegen.check import bench_peers, bench_target, harness, target
from dfeif_codegen.codegen import render
from dfeif_codegen.errors import CodegenError, SetupError

MODELS = ("dc_motor_link", "two_link_arm")
# (oosm, fusion) builds measured per model; the first is the reference configuration.
BUILDS = (("replay", "difference"), ("retrodict", "difference"), ("replay", "paper"), ("replay", "ci"))
LAGS = (1, 8, 25, 32)


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


def callgrind(model: harness.ModelDir, work: Path, defines: tuple[str, ...] = ()) -> dict[str, float]:
    """Instructions per call of each section of bench.c.j2 (`defines`: -D options of the build)."""
    work.mkdir(parents=True, exist_ok=True)
    env = render.environment(model.precision)
    src = work / f"{model.name}_bench.c"
    src.write_text(env.get_template("harness/bench.c.j2").render(
        p=model.name, P=model.name.upper(), banner=render.banner("harness/bench.c.j2", model.name, __version__)))
    exe = harness.compile_program([*model.sources(), src], work / "bench", [model.path],
                                  [harness.BIND_NOW, *(f"-D{d}" for d in defines)])
    return harness.callgrind(exe, work)[0]


def worst_case(model: harness.ModelDir, work: Path, defines: tuple[str, ...] = ()) -> dict[str, dict]:
    """Per public entry point, the instructions of its costliest call and the median call, over the
    calls of templates/harness/worst.c.j2, which drives every entry point down its longest path
    (lag N_max, packets N_max steps stale, distinct nodes, keyed frames of the largest kind)."""
    work.mkdir(parents=True, exist_ok=True)
    env = render.environment(model.precision)
    src = work / f"{model.name}_worst.c"
    src.write_text(env.get_template("harness/worst.c.j2").render(
        p=model.name, P=model.name.upper(), banner=render.banner("harness/worst.c.j2", model.name, __version__)))
    exe = harness.compile_program([*model.sources(), src], work / "worst", [model.path],
                                  [harness.BIND_NOW, *(f"-D{d}" for d in defines)])
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


def bench(model: str | None = None, *, repeat: int = 5, command: str | None = None, progress=None,
          quick: bool = False) -> str:
    """BENCHMARKS.md's text for a model file, or (default, or a built-in name) both built-in
    models side by side. `command` is the line the report says regenerates it; `quick` skips
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
            md = harness.build_model(sec["name"], work / sec["name"] / "peers-build")
            sec["peers"] = bench_peers.c_peers(sec["name"], md, work / sec["name"] / "peers")
            sec["py_peers"] = bench_peers.python_peers(sec["name"])
            if progress:
                progress(f"codegen bench: {sec['name']} on the emulated Cortex-M4F")
            sec["target"] = bench_target.model(sec["name"], work / sec["name"] / "target")
            sec["target_peers"] = bench_target.peers(sec["name"], work / sec["name"] / "target-peers")
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
    return (_markdown(command or f"codegen bench --repeat {repeat}", sections, repeat)
            + _markdown_more(sections, comparisons))


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
        sizeofs[precision] = target_sizeof(md, work / f"sizeof-{precision}-probe")
    md = harness.build_model(name, work / "os-float", "float")
    sizes, stack = target_sizes(md, work / "os-float-obj")
    md_retro = harness.build_model(name, work / "os-float-retro", "float", "retrodict")
    _, stack_retro = target_sizes(md_retro, work / "os-float-retro-obj")
    return {"name": name, "times": times, "counts": counts, "worst": worst, "sizeof": sizeofs, "sizes": sizes,
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
           "- Cortex-M4F instructions and cycles: " + bench_target.ASSUMPTIONS.format(
               flags=" ".join([*target.CPU_FLAGS, bench_target.OPT, *target.CFLAGS]), calls=bench_target.CALLS),
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
        if "target" in s:
            out += bench_target.markdown(name, s["target"])
    return "\n".join(out)


WORST_BUILDS = ((("replay", "difference"), "replay, difference"), (("retrodict", "difference"), "retrodict, difference"),
                (("replay", "paper"), "replay, paper"), (("replay", "ci-every-step"), "replay, ci (every Newton step)"))


def _worst_table(sec: dict) -> list[str]:
    """Every public entry point's costliest call per build: the real-time budget."""
    worst = sec["worst"]
    builds = [(key, label) for key, label in WORST_BUILDS if key in worst]
    base = worst[builds[0][0]]
    out = ["Worst case per entry point (the real-time budget, host -O2, double, 2 nodes, N_max = 32): the "
           "costliest of every call `templates/harness/worst.c.j2` makes, driving each entry point down its "
           "longest path: a frame back at lag N_max, the master fusing packets N_max steps stale (brought "
           "forward in one step each) from distinct nodes (the CI search runs longest; with "
           "-D<MODEL>_CI_TOL=-1 every Newton step), keyed frames of the largest kind (CRC-32 and "
           "SipHash-2-4 over the whole frame), estimates that move (the stored values' centre moves). "
           "The median call is the typical cost.", "",
           "| entry point | median call | " + " | ".join(label for _, label in builds) + " |",
           "|---|---:|" + "---:|" * len(builds)]
    for fn in sorted(base):
        cells = [_fmt(worst[key][fn]["max"]) if fn in worst[key] else "-" for key, _ in builds]
        out.append(f"| `{fn}` | {_fmt(base[fn]['median'])} | " + " | ".join(cells) + " |")
    return out + [""]


def _ratio(a, b) -> str:
    return "-" if a is None or b is None else f"{a / b:.2f}"


def _peer_targets(sec: dict) -> list[str]:
    """The node step against the hand-written filter (issue targets: 1.5x on the M4F, 1.4x host)."""
    tp, hp = sec.get("target_peers", {}), sec["peers"]["instructions"]
    if "straight" not in hp:
        return []
    rows = [f"| node step / hand-written, host instructions | {_fmt(hp['generated'])} / {_fmt(hp['straight'])} = "
            f"{hp['generated'] / hp['straight']:.2f}x | 1.4x |"]
    if "straight" in tp:
        g, s = tp["generated"]["instructions"], tp["straight"]["instructions"]
        rows.append(f"| node step / hand-written, Cortex-M4F instructions | {_fmt(g)} / {_fmt(s)} = {g / s:.2f}x | 1.5x |")
    return rows


def _markdown_more(sections: list[dict], comp: dict) -> str:
    """Peers side by side, targets, worst cases, scaling and Monte Carlo throughput."""
    out = ["## Peers side by side (one node step: update with an on-time frame, then predict)", "",
           "Host, double. C instruction counts from callgrind; wall time median of 7 timed loops of "
           "20,000 steps (C) or of 5 loops of 2,000 steps (Python). The C peers are checked to give the "
           "generated filter's estimate (1e-9) before they are reported.", "",
           "| model | filter | instructions | x generated | ns per step | x generated |",
           "|---|---|---:|---:|---:|---:|"]
    for sec in sections:
        pe, py = sec["peers"], sec["py_peers"]
        gi, gn = pe["instructions"]["generated"], pe["ns"]["generated"]
        labels = {"generated": "generated (this tool)", "dense": "dense-loop C (embedded-library style)",
                  "straight": "hand-written straight-line C (n = 3 limit)"}
        for key, label in labels.items():
            if key in pe["instructions"]:
                i, t = pe["instructions"][key], pe["ns"][key]
                out.append(f"| {sec['name']} | {label} | {_fmt(i)} | {i / gi:.2f} | {t:.1f} | {t / gn:.2f} |")
        for label, t in py.items():
            out.append(f"| {sec['name']} | {label} | - | - | {'-' if t is None else f'{t:,.0f}'} | "
                       f"{_ratio(t, gn)} |")
    out.append("")
    out += bench_target.peers_markdown([(s["name"], s["target_peers"], s["peers"]["instructions"])
                                        for s in sections if "target_peers" in s])
    for sec in sections:
        c = sec["counts"][("replay", "difference")]
        r = sec["counts"][("retrodict", "difference")]
        step = c["node_update"] + c["node_predict"]
        per = (c["node_update_delayed_lag32"] - c["node_update_delayed_lag8"]) / 24
        out += [f"### Targets, {sec['name']} (host, double)", "", "| figure | measured | target |",
                "|---|---:|---:|",
                f"| node predict + update | {_fmt(step)} | 350 (dc_motor_link) |",
                *_peer_targets(sec),
                f"| replay, per replayed step (lag 8 -> 32) | {_fmt(per)} = {per / step:.2f}x a plain step | 1.0x |",
                f"| update_delayed, lag 25, replay | {_fmt(c['node_update_delayed_lag25'])} | 10,000 (dc_motor_link) |",
                f"| update_delayed, lag 32, replay / retrodict | {_fmt(c['node_update_delayed_lag32'])} / "
                f"{_fmt(r['node_update_delayed_lag32'])} | |",
                f"| master fuse, difference rule, M = 2 | {_fmt(sec['counts'][('replay', 'difference')]['master_fuse'])}"
                " | 1,500 (dc_motor_link) |",
                f"| node struct, double, N_max = 32 (Cortex-M4F layout) | {sec['sizeof']['double']['node']} B | "
                "2,560 B (two_link_arm 8,192 B) |", ""]
        out += _worst_table(sec)
    sc = comp.get("scaling")
    if sc:
        ch = sc["chains"]
        ns = sorted(ch)
        out += ["## Scaling (host, double instructions; Cortex-M4F float -Os sizes)", "",
                "Synthetic flat chains: one output, relative degree n (`n` integrators).", "",
                "| n | node step instructions | x previous n | filter kernels .text [B] | kernels + node .text [B] "
                "| fusion kernels .text [B] |", "|---:|---:|---:|---:|---:|---:|"]
        for a, n in enumerate(ns):
            prev = f"{ch[n]['step'] / ch[ns[a - 1]]['step']:.2f}" if a else "-"
            out.append(f"| {n} | {_fmt(ch[n]['step'])} | {prev} | {ch[n]['kernel_text']} | {ch[n]['filter_text']} "
                       f"| {ch[n]['fusion_text']} |")
        out += ["", f"Fitted growth over n = {ns[0]}..{ns[-1]}: node step ~ n^"
                f"{bench_peers.growth(ns, [ch[n]['step'] for n in ns]):.2f}, filter kernel .text ~ n^"
                f"{bench_peers.growth(ns, [ch[n]['kernel_text'] for n in ns]):.2f}, fusion kernel .text ~ n^"
                f"{bench_peers.growth(ns, [ch[n]['fusion_text'] for n in ns]):.2f} (targets: each n at most 1.6x "
                "the previous, .text no faster than n^2).", ""]
        nd = sc["nodes"]
        Ms = sorted(nd)
        out += ["| nodes M (dc_motor_link) | master fuse, difference | CI, identical nodes | CI, distinct nodes "
                "| CI, all steps (worst case) |", "|---:|---:|---:|---:|---:|"]
        out += [f"| {M} | {_fmt(nd[M]['difference'])} | {_fmt(nd[M]['ci'])} | {_fmt(nd[M]['ci_distinct'])} "
                f"| {_fmt(nd[M]['ci_every_step'])} |" for M in Ms]
        out += ["", "Identical nodes: every node sees the same frames with the same noise, so the CI weights "
                "are 1/M from the start and the search stops after one step. Distinct nodes: node i has "
                "camera noise (1 + i)^2 R and loses every (i + 3)-th frame, so the weights differ and the "
                "search runs longer. All steps: the distinct nodes with the early stop off "
                "(-D<MODEL>_CI_TOL=-1), ci_iterations(M) Newton steps, the worst case.",
                "", f"Fitted growth over M = {Ms[0]}..{Ms[-1]}: difference ~ M^"
                f"{bench_peers.growth(Ms, [nd[M]['difference'] for M in Ms]):.2f}, CI ~ M^"
                f"{bench_peers.growth(Ms, [nd[M]['ci'] for M in Ms]):.2f} (identical), M^"
                f"{bench_peers.growth(Ms, [nd[M]['ci_distinct'] for M in Ms]):.2f} (distinct), M^"
                f"{bench_peers.growth(Ms, [nd[M]['ci_every_step'] for M in Ms]):.2f} (all steps) "
                "(CI target at M = 8: 20,000).", ""]
        wd = sc["windows"]
        Ns = sorted(wd)
        out += ["| N_max (dc_motor_link) | update_delayed at lag N_max, replay | retrodict | node struct, double [B] |",
                "|---:|---:|---:|---:|"]
        out += [f"| {N} | {_fmt(wd[N]['replay'])} | {_fmt(wd[N]['retrodict'])} | {wd[N]['node_bytes']} |" for N in Ns]
        out += ["", f"Fitted growth over N_max = {Ns[0]}..{Ns[-1]}: replay ~ N^"
                f"{bench_peers.growth(Ns, [wd[N]['replay'] for N in Ns]):.2f}, retrodict ~ N^"
                f"{bench_peers.growth(Ns, [wd[N]['retrodict'] for N in Ns]):.2f}, node struct ~ N^"
                f"{bench_peers.growth(Ns, [wd[N]['node_bytes'] for N in Ns]):.2f}.", ""]
    if comp.get("target_scaling"):
        out += bench_target.scaling_markdown(comp["target_scaling"])
    mc = comp.get("mc")
    if mc:
        out += ["## Closed-loop Monte Carlo (`codegen simulate`, scenario paper, dc_motor_link)", "",
                "Runs of 2,000 steps per second of the sweep itself (start-up and compilation excluded); "
                "the machine's other load is not controlled, so these are wall-clock figures of this run.", "",
                "| engine | where | runs | seconds | runs/s |", "|---|---|---:|---:|---:|"]
        for r in mc["rates"]:
            out.append(f"| {r['engine']} | {r['how']} | {r['runs']} | {r['seconds']:.1f} | {r['per_s']:.1f} |")
        p = mc["paper100"]
        per_run = p["cpu_s"] / p["runs"]   # CPU per run, start-up and compilation spread over the runs
        out += ["", f"100 seeds of the paper table ({p['runs']} distinct runs, 6 rows x 2 references x the 4 "
                f"methods the table compares): {p['wall_s']:.1f} s wall as a user runs it (start-up and "
                f"compilation included; {p['cpu_s']:.1f} CPU-s in all, so at best {p['cpu_s'] / p['workers']:.1f} s on "
                f"{p['workers']} otherwise idle cores), {p['loop_s']:.1f} s of runs on {p['workers']} processes "
                f"(target 60 s). "
                f"At {per_run * 1000:.1f} CPU-ms per run (the rows' exact bounds included), 64 cores would "
                f"share the work in {p['runs'] * per_run / 64:.1f} s, but the longest single task, a row's "
                f"exact bound, takes {p['longest_task_s']:.1f} CPU-s: a 64-core cluster would take about "
                f"{max(p['runs'] * per_run / 64, p['longest_task_s']):.1f} s plus the start-up.", ""]
    return "\n".join(out)
