"""`bench`'s three steps, each called once and in this order, as `verify`'s (check/stages.py):
compile every program and object the report measures (host and Cortex-M4F), run every
measurement on them, compare (the C peers checked against the generated filter's estimate) and
shape the figures into a `BenchResult`. Each step takes what the previous one returned: a tree of
dicts and lists whose leaves are `bench_measure.Measure` after compiling and figures after running,
so compiling never runs and running never compiles."""

from __future__ import annotations

from pathlib import Path

from dfeif_codegen.check import bench_measure, bench_peers, bench_programs, bench_target, harness, target
from dfeif_codegen.check.bench_measure import Measure
from dfeif_codegen.check.bench_report import BenchResult

# (oosm, fusion) builds measured per model; the first is the reference configuration.
BUILDS = (("replay", "difference"), ("retrodict", "difference"), ("replay", "paper"), ("replay", "ci"))


def callgrind(md: harness.ModelDir, work: Path, defines: tuple[str, ...] = ()) -> Measure:
    """Instructions per call of each section of bench.c.j2 (`defines`: -D options of the build)."""
    return Measure("callgrind", (bench_programs.host_template(md, "bench", work, defines),), work)


def worst_case(md: harness.ModelDir, work: Path, defines: tuple[str, ...] = ()) -> Measure:
    """The costliest and the median call of every public entry point over worst.c.j2's calls."""
    return Measure("worst", (bench_programs.host_template(md, "worst", work, defines),), work)


def ci_every_step(md: harness.ModelDir) -> tuple[str, ...]:
    """The define that makes the CI search run all its steps (no early stop): its worst case."""
    return (f"{md.name.upper()}_CI_TOL=-1",)


def _compile_model(name: str, repeat: int, work: Path) -> dict:
    """One model's section: instruction counts and worst cases per build, struct sizes, the
    Cortex-M4F objects' sizes and stack, peers (host and target), the target's counts."""
    counts, worst = {}, {}
    for oosm, fusion in BUILDS:
        md = harness.build_model(name, work / f"{oosm}-{fusion}", "double", oosm, fusion)
        counts[(oosm, fusion)] = callgrind(md, work / f"cg-{oosm}-{fusion}")
        worst[(oosm, fusion)] = worst_case(md, work / f"worst-{oosm}-{fusion}")
        if fusion == "ci":
            counts[(oosm, "ci-every-step")] = callgrind(md, work / f"cg-{oosm}-ci-all", ci_every_step(md))
            worst[(oosm, "ci-every-step")] = worst_case(md, work / f"worst-{oosm}-ci-all", ci_every_step(md))
    scheduled = harness.build_model(name, work / "scheduled", "double", predictor="scheduled")
    counts[("replay", "difference", "scheduled")] = callgrind(scheduled, work / "cg-scheduled")
    sizeof = {p: Measure("sizeof", (target.sizeof_probe(harness.build_model(name, work / f"sizeof-{p}", p),
                                                         work / f"sizeof-{p}-probe"),))
              for p in ("float", "double")}
    md = harness.build_model(name, work / "os-float", "float")
    objs = bench_programs.objects(md, work / "os-float-obj")
    md_retro = harness.build_model(name, work / "os-float-retro", "float", "retrodict")
    objs_retro = bench_programs.objects(md_retro, work / "os-float-retro-obj")
    peers = {}
    for pred in bench_peers.PREDICTORS:
        mp = harness.build_model(name, work / f"peers-{pred}-build", **bench_peers.with_predictor(pred))
        peers[pred] = bench_peers.peers(name, mp, work / f"peers-{pred}")
    return {"name": name, "times": Measure("build-times", (name, repeat), work / "build"), "counts": counts,
            "worst": worst, "sizeof": sizeof, "sizes": Measure("sizes", (objs,)),
            "stack": Measure("stack", (md.name, objs)), "stack_retro": Measure("stack", (md_retro.name, objs_retro)),
            "peers": peers, "py_peers": Measure("python-peers", (name,)),
            "target": bench_target.compile_model(name, work / "target"),
            "target_peers": {pred: bench_target.compile_peers(name, work / f"target-peers-{pred}", pred)
                             for pred in bench_peers.PREDICTORS}}


def compile(models: list[str], repeat: int, quick: bool, work: Path, progress=None) -> dict:
    """Step 1: every program and object measured, host and Cortex-M4F, as a tree of Measures."""
    say = progress or (lambda line: None)
    sections = []
    for name in models:
        say(f"codegen bench: compiling {name}")
        sections.append(_compile_model(name, repeat, work / Path(name).stem))   # a model file: its stem
    comparisons: dict = {}
    if not quick:
        say("codegen bench: compiling the scaling sweeps")
        comparisons["scaling"] = bench_peers.compile_scaling(work / "scaling")
        comparisons["target_scaling"] = bench_target.compile_scaling(work / "target-scaling")
        comparisons["mc"] = Measure("monte-carlo", (), work / "mc")
    return {"tools": Measure("tools"), "sections": sections, "comparisons": comparisons}


def _map(tree, fn):
    """The tree with every Measure replaced by fn(Measure), in order."""
    if isinstance(tree, Measure):
        return fn(tree)
    if isinstance(tree, dict):
        return {k: _map(v, fn) for k, v in tree.items()}
    if isinstance(tree, list):
        return [_map(v, fn) for v in tree]
    return tree


def run(compiled: dict, progress=None) -> dict:
    """Step 2: every measurement of the tree step 1 compiled, run (callgrind, QEMU, timings)."""
    say = progress or (lambda line: None)
    sections = []
    for sec in compiled["sections"]:
        say(f"codegen bench: measuring {sec['name']} (host, and the emulated Cortex-M4F)")
        sections.append(_map(sec, bench_measure.measure))
    comparisons = {}
    for key, tree in compiled["comparisons"].items():
        say(f"codegen bench: measuring {key}")
        comparisons[key] = _map(tree, bench_measure.measure)
    return {"tools": bench_measure.measure(compiled["tools"]), "sections": sections, "comparisons": comparisons}


def compare(ran: dict, command: str, repeat: int) -> BenchResult:
    """Step 3: the C peers checked against the generated filter's estimate (host and target),
    the figures shaped as the report reads them."""
    sections = []
    for sec in ran["sections"]:
        sections.append({**sec, "peers": {p: bench_peers.checked(v) for p, v in sec["peers"].items()},
                         "target": bench_target.model_rows(sec["target"]),
                         "target_peers": {p: bench_target.peer_counts(v) for p, v in sec["target_peers"].items()}})
    comp = dict(ran["comparisons"])
    if "scaling" in comp:
        comp["scaling"] = bench_peers.scaling_rows(comp["scaling"])
    if "target_scaling" in comp:
        comp["target_scaling"] = bench_target.scaling_rows(comp["target_scaling"])
    return BenchResult(command, repeat, ran["tools"], sections, comp)
