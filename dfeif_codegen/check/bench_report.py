"""`codegen bench`'s result (`BenchResult`): the measurements as data, the BENCHMARKS.md text
made from them (`report()`) and their JSON (`to_json()`). check/bench.py measures."""

from __future__ import annotations

import dataclasses
import json
import statistics
from dataclasses import dataclass

from dfeif_codegen import __version__
from dfeif_codegen.check import bench_peers, bench_target, target

LAGS = (1, 8, 25, 32)


@dataclass
class BenchResult:
    """What `bench` measured: per model (`sections`: build times, instruction counts per call and
    build, worst cases, struct sizes, Cortex-M4F sizes and stack, peers) and across models
    (`comparisons`: "scaling", "mc"), with the tools that measured them."""

    command: str
    repeat: int
    tools: dict          # "gcc", "arm", "valgrind": the version line of each
    sections: list[dict]
    comparisons: dict

    def report(self) -> str:
        """BENCHMARKS.md's text."""
        return _markdown(self) + _markdown_more(self.sections, self.comparisons)

    def to_json(self) -> str:
        return json.dumps(_jsonable({"command": self.command, "repeat": self.repeat, "tools": self.tools,
                                     "sections": self.sections, "comparisons": self.comparisons}))


def _jsonable(value):
    """Tuple keys ("replay", "difference") as "replay/difference", dataclasses as dicts."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return _jsonable(dataclasses.asdict(value))
    if isinstance(value, dict):
        return {"/".join(map(str, k)) if isinstance(k, tuple) else str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value


def _fmt(n: float) -> str:
    return f"{n:,.0f}"


def _markdown(r: "BenchResult") -> str:
    """The build time, instruction counts, sizes and stack of each model."""
    command, sections, repeat = r.command, r.sections, r.repeat
    gcc, arm, vg = r.tools["gcc"], r.tools["arm"], r.tools["valgrind"]
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
        out += _scheduled_table(c)
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
        out += struct_table(name, s["sizeof"]["float"], s["sizeof"]["double"])
        if "target" in s:
            out += bench_target.markdown(name, s["target"])
    return "\n".join(out)


def c_prefix(spec: str) -> str:
    """The C prefix of a benched model (its structs' names): a model file's [model] name, not the
    argument `vanish.toml` the section is named by; the file's stem if it can no longer be read."""
    from pathlib import Path

    from dfeif_codegen.errors import CodegenError
    from dfeif_codegen.symbolic import model
    try:
        return model.load(spec).name
    except (CodegenError, OSError):
        return Path(spec).stem


def struct_table(spec: str, sf: dict, sd: dict) -> list[str]:
    """sizeof the node, master and packet structs, float beside double (`spec`: the bench's model argument)."""
    p = c_prefix(spec)
    out = ["", "| struct (Cortex-M4F layout, max lag 32, 2 nodes) | float [B] | double [B] | ratio |",
           "|---|---:|---:|---:|"]
    out += [f"| `{p}_{kind}` | {sf[kind]} | {sd[kind]} | {sd[kind] / sf[kind]:.2f} |"
            for kind in ("node", "master", "packet")]
    return out + [""]


def _scheduled_table(c: dict) -> list[str]:
    """The held predictor (the default build) beside `--predictor scheduled` (replay, difference)."""
    held, sched = c[("replay", "difference")], c.get(("replay", "difference", "scheduled"))
    if not sched:
        return []
    out = ["", "| call (replay, difference) | held | scheduled | scheduled / held |", "|---|---:|---:|---:|"]
    step = lambda k: k["node_update"] + k["node_predict"]  # noqa: E731
    rows = [("node update (on time)", held["node_update"], sched["node_update"]),
            ("node predict", held["node_predict"], sched["node_predict"]),
            ("node step (update + predict)", step(held), step(sched))]
    rows += [(f"update_delayed, lag {LAGS[-1]}", held.get(key), sched.get(key))
             for key in [f"node_update_delayed_lag{LAGS[-1]}"] if key in held and key in sched]
    return out + [f"| {label} | {_fmt(a)} | {_fmt(b)} | {b / a:.2f} |" for label, a, b in rows]


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
           "forward in one step each; the difference rule's N_max - 2 steps stale over a last fused packet "
           "N_max steps old, the lost packets' channel) from distinct nodes (the CI search runs longest; with "
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




def _peers(sections: list[dict]) -> list[str]:
    """The generated filter beside the C and Python peers, one node step, with each predictor."""
    out = ["## Peers side by side (one node step: update with an on-time frame, then predict)", "",
           "Host, double. C instruction counts from callgrind; wall time median of 7 timed loops of "
           "20,000 steps (C) or of 5 loops of 2,000 steps (Python). Each C peer predicts as the generated filter it "
           "is compared with (held: the mean by one ETD2RK step with the input held, calling the model's "
           "top derivatives `F + G u` as a user's model function, the second stage's sines carried from the first's "
           "as the generated filter carries them, `P = E P E' + Q`; brunovsky: the chapter's "
           "linear chain) and is checked to give that filter's estimate (1e-9) before it is reported.", "",
           "| model | predictor | filter | instructions | x generated | ns per step | x generated |",
           "|---|---|---|---:|---:|---:|---:|"]
    labels = {"generated": "generated (this tool)", "dense": "dense-loop C (embedded-library style)",
              "straight": "hand-written straight-line C (n = 3 limit)"}
    for sec in sections:
        for pred in bench_peers.PREDICTORS:
            pe = sec["peers"][pred]
            gi, gn = pe["instructions"]["generated"], pe["ns"]["generated"]
            for key, label in labels.items():
                if key in pe["instructions"]:
                    i, t = pe["instructions"][key], pe["ns"][key]
                    out.append(f"| {sec['name']} | {pred or 'brunovsky'} | {label} | {_fmt(i)} | {i / gi:.2f} | {t:.1f} | "
                               f"{t / gn:.2f} |")
        gn = sec["peers"][bench_peers.PREDICTORS[0]]["ns"]["generated"]
        for label, t in sec["py_peers"].items():
            out.append(f"| {sec['name']} | - | {label} | - | - | {'-' if t is None else f'{t:,.0f}'} | "
                       f"{_ratio(t, gn)} |")
    out.append("")
    return out + bench_target.peers_markdown([(s["name"], pred, s["target_peers"][pred],
                                               s["peers"][pred]["instructions"])
                                              for s in sections if "target_peers" in s for pred in bench_peers.PREDICTORS])


def _peer_targets(sec: dict) -> list[str]:
    """The node step against the hand-written filter with the same predictor (targets: 1.5x on
    the M4F, 1.4x host)."""
    rows = []
    for pred in bench_peers.PREDICTORS:
        tp, hp = sec.get("target_peers", {}).get(pred, {}), sec["peers"][pred]["instructions"]
        if "straight" not in hp:
            continue
        g, s = hp["generated"], hp["straight"]
        rows.append(f"| node step / hand-written, {pred or 'brunovsky'} predictor, host instructions | {_fmt(g)} / {_fmt(s)} = "
                    f"{g / s:.2f}x | 1.4x |")
        if "straight" in tp:
            g, s = tp["generated"]["instructions"], tp["straight"]["instructions"]
            rows.append(f"| node step / hand-written, {pred or 'brunovsky'} predictor, Cortex-M4F instructions | {_fmt(g)} / "
                        f"{_fmt(s)} = {g / s:.2f}x | 1.5x |")
    return rows


def _targets(sections: list[dict]) -> list[str]:
    """Each model's figures against the targets, and its worst cases."""
    out: list[str] = []
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
    return out


def _scaling(sc: dict) -> list[str]:
    """Growth with the chain length, the node count and the window."""
    out: list[str] = []
    ch = sc["chains"]
    ns = sorted(ch)
    out += ["## Scaling (host, double instructions; Cortex-M4F float -Os sizes)", "",
            "Synthetic flat chains: one output, relative degree n (`n` integrators).", "",
            "| n | node step instructions | x previous n | filter kernels .text [B] | kernels + node .text [B] "
            "| fusion kernels .text [B] |", "|---:|---:|---:|---:|---:|---:|"]
    out += bench_peers.chain_rows(ch, lambda c: (c["kernel_text"], c["filter_text"], c["fusion_text"]))
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
    return out


def _monte_carlo(mc: dict) -> list[str]:
    """Closed-loop runs per second, and the 100-seed table as a user runs it."""
    out: list[str] = []
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
    return out


def _markdown_more(sections: list[dict], comp: dict) -> str:
    """Peers side by side, targets, worst cases, scaling and Monte Carlo throughput."""
    out = _peers(sections) + _targets(sections)
    if comp.get("scaling"):
        out += _scaling(comp["scaling"])
    if comp.get("target_scaling"):
        out += bench_target.scaling_markdown(comp["target_scaling"])
    if comp.get("mc"):
        out += _monte_carlo(comp["mc"])
    return "\n".join(out)
