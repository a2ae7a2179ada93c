"""`codegen bench` on the Cortex-M4F: the same benchmark programs as on the host (bench.c.j2,
worst.c.j2, peers.c.j2), cross-compiled (float, -Os) and run under QEMU mps2-an386, each executed
instruction counted and costed (check/target_count.py); stack per entry point with the newlib
and libgcc code it calls, read from the linked program.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dfeif_codegen import __version__
from dfeif_codegen.check import bench_peers, harness, target_count
from dfeif_codegen.codegen import render
from dfeif_codegen.errors import SetupError

CALLS = 20    # calls averaged per section (the host's 200 would take ten times the emulation)
OPT = "-Os"
# (oosm, fusion, defines, label) of the worst-case runs; the first is the reference configuration
WORST = (("replay", "difference", (), "replay, difference"), ("retrodict", "difference", (), "retrodict, difference"),
         ("replay", "ci", ("CI_TOL=-1",), "replay, ci (every Newton step)"))


def _render(md: harness.ModelDir, template: str, work: Path) -> Path:
    work.mkdir(parents=True, exist_ok=True)
    src = work / f"{md.name}_{template}.c"
    src.write_text(render.environment(md.precision).get_template(f"harness/{template}.c.j2").render(
        p=md.name, P=md.name.upper(), banner=render.banner(f"harness/{template}.c.j2", md.name, __version__)))
    return src


def _run(md: harness.ModelDir, src: Path, work: Path, defines=()) -> tuple[dict, str, Path]:
    elf = target_count.program(md.sources(), src, [md.path], work,
                               [f"CALLS={CALLS}", *(f"{md.name.upper()}_{d}" if d.startswith("CI_") else d
                                                    for d in defines)], OPT)
    counts, stdout = target_count.count(elf, work)
    return counts, stdout, elf


def model(name: str, work: Path) -> dict:
    """Typical counts per call (bench.c.j2), the worst call per entry point for each WORST build
    (worst.c.j2) and the stack per entry point with library calls (replay and retrodict)."""
    md = harness.build_model(name, work / "replay-difference", "float")
    typical, _, _ = _run(md, _render(md, "bench", work / "bench-src"), work / "bench")
    worst, stack = {}, {}
    for oosm, fusion, defines, label in WORST:
        md = harness.build_model(name, work / f"{oosm}-{fusion}", "float", oosm, fusion)
        counts, _, elf = _run(md, _render(md, "worst", work / f"worst-src-{oosm}-{fusion}"),
                              work / f"worst-{oosm}-{fusion}", defines)
        worst[label] = {k[len("worst/"):]: v for k, v in counts.items() if k.startswith("worst/")}
        if fusion == "difference":
            roots = [f"{name}_{fn}" for fn in worst[label]]
            stack[oosm] = {fn[len(name) + 1:]: use for fn, use in
                           target_count.stack_with_library(elf, roots).items()}
    return {"typical": typical, "worst": worst, "stack": stack}


def peers(spec: str, work: Path, predictor: str | None = None) -> dict:
    """The peers of one node step (peers.c.j2) on the target, float: instructions and cycles per
    step, after checking each peer ends where the generated filter does (float: 1e-3 relative,
    200 steps of a filter whose covariance settles, far above single precision's 6e-8 but far
    below a wrong filter's error)."""
    md = harness.build_model(spec, work / "float", "float", **bench_peers.with_predictor(predictor))
    src = bench_peers.render_peers(spec, md, work / "src")
    counts, stdout, _ = _run(md, src, work / "peers")
    finals = bench_peers.finals(stdout)
    ref = np.array(finals["generated"])
    for peer, x in finals.items():
        if not np.allclose(x, ref, rtol=1e-3, atol=1e-5):
            raise SetupError(f"bench peer '{peer}' on the target disagrees with the generated filter: {x} vs {ref}")
    return counts


def _fmt(n: float) -> str:
    return f"{n:,.0f}"


def _cyc(c) -> str:
    return f"{c[0]:,.0f}-{c[1]:,.0f}"


ASSUMPTIONS = (
    "Instructions executed on QEMU's mps2-an386 (Cortex-M4F), one instruction per translation block "
    "and every executed block logged (`-singlestep -d exec,nochain`): an exact, deterministic count of the "
    "instructions inside each call, callees and newlib included (the harness's argument set-up not); "
    "library built with `{flags}`, averaged over {calls} calls per section. Cycles are an estimate: each "
    "executed instruction costed from the Cortex-M4 Technical Reference Manual (table 3-1, and table 7-1 "
    "for the FPU: VADD/VSUB/VMUL/VCMP/VCVT/VMOV 1, VMLA/VFMA family 3, VDIV/VSQRT 14, VLDR/VSTR 2, "
    "VLDM/VSTM/VPUSH/VPOP 1+N), zero wait states (code and data in single-cycle memory, no flash "
    "accelerator misses, no bus contention), LDR/STR 2 (1 when pipelined behind another load or store, "
    "low figure only), LDM/STM/PUSH/POP 1+N, MLA 2, SDIV/UDIV 2-12, a taken branch 1+P with the "
    "pipeline refill P = 1 (low) to 3 (high), IT 0 (folded) to 1.")


def markdown(name: str, t: dict) -> list[str]:
    """The per-entry-point table on the target: typical (median) call, worst call per build, the
    worst call's cycle estimate, and stack with library calls."""
    labels = [label for *_, label in WORST if label in t["worst"]]
    base = t["worst"][labels[0]]
    st, sr = t["stack"].get("replay", {}), t["stack"].get("retrodict", {})
    out = [f"### Cortex-M4F, executed instructions per call (float, {OPT}, QEMU mps2-an386)", "",
           "| entry point | median call | " + " | ".join(f"worst, {lb}" for lb in labels)
           + f" | cycles of the worst, {labels[0]} | stack with library calls, replay / retrodict [B] |",
           "|---|---:|" + "---:|" * len(labels) + "---:|---:|"]
    for fn in sorted(base):
        cells = [_fmt(t["worst"][lb][fn]["max"]) if fn in t["worst"][lb] else "-" for lb in labels]
        s = st.get(fn)
        r = sr.get(fn)
        stack = "-" if s is None else f"{s[0]} / {r[0] if r else '-'}"
        out.append(f"| `{fn}` | {_fmt(base[fn]['median'])} | " + " | ".join(cells)
                   + f" | {_cyc(base[fn]['max_cycles'])} | {stack} |")
    ty = t["typical"]
    out += ["", f"Typical calls ({CALLS} each, averaged): node update {_fmt(ty['node_update']['instructions'])} "
            f"({_cyc(ty['node_update']['cycles'])} cycles), node predict {_fmt(ty['node_predict']['instructions'])} "
            f"({_cyc(ty['node_predict']['cycles'])}), control {_fmt(ty['control']['instructions'])} "
            f"({_cyc(ty['control']['cycles'])}), master fuse {_fmt(ty['master_fuse']['instructions'])} "
            f"({_cyc(ty['master_fuse']['cycles'])}). The stack path includes newlib's code (e.g. `sinf`'s "
            "large-argument reduction), its frames read from the linked program's prologues.", ""]
    return out


def peers_markdown(rows: list[tuple[str, str, dict, dict | None]]) -> list[str]:
    """Peers on the target beside the host's: (model, predictor, target counts, host counts)."""
    labels = {"generated": "generated (this tool)", "dense": "dense-loop C (embedded-library style)",
              "straight": "hand-written straight-line C (n = 3 limit)"}
    out = [f"### Peers on the Cortex-M4F (float, {OPT}, one node step: update then predict)", "",
           "| model | predictor | filter | M4F instructions | x generated | M4F cycles (estimate) | host instructions "
           "| x generated |", "|---|---|---|---:|---:|---:|---:|---:|"]
    for model_name, pred, tc, host in rows:
        g = tc["generated"]["instructions"]
        hg = host["generated"] if host else None
        for key, label in labels.items():
            if key not in tc:
                continue
            i = tc[key]["instructions"]
            h = host.get(key) if host else None
            hcell = "-" if h is None else f"{_fmt(h)} | {h / hg:.2f}"
            out.append(f"| {model_name} | {pred or 'brunovsky'} | {label} | {_fmt(i)} | {i / g:.2f} | "
                       f"{_cyc(tc[key]['cycles'])} | {hcell} |")
    return out + [""]


def _chain_spec(n: int, work: Path) -> str:
    spec = work / f"chain{n}.toml"
    spec.parent.mkdir(parents=True, exist_ok=True)
    spec.write_text(bench_peers.chain_model(n))
    return str(spec)


def scaling(work: Path, chains=None, nodes=None) -> dict:
    """On the target: the node step (update + predict) and the kernels' .text over the synthetic
    chains, and the CI fuse with every Newton step over nodes M, typical (fresh packets) and
    worst (worst.c.j2: packets N_max steps stale too)."""
    from dfeif_codegen.check import target

    out: dict = {"chains": {}, "nodes": {}}
    for n in chains or bench_peers.CHAINS:
        md = harness.build_model(_chain_spec(n, work), work / f"chain{n}", "float")
        counts, _, _ = _run(md, _render(md, "bench", work / f"chain{n}-src"), work / f"chain{n}-bench",
                            ("BENCH_SKIP_LAGS", "BENCH_SKIP_FUSE"))
        text = {k: z.text for k, z in target.sizes(sorted((work / f"chain{n}-bench" / "lib").glob("*.o"))).items()}
        out["chains"][n] = {"step": counts["node_update"]["instructions"] + counts["node_predict"]["instructions"],
                            "cycles": tuple(counts["node_update"]["cycles"][i] + counts["node_predict"]["cycles"][i]
                                            for i in (0, 1)),
                            "filter_text": text[f"chain{n}_kernels_filter.o"],
                            "fusion_text": text[f"chain{n}_kernels_fusion.o"]}
    for M in nodes or bench_peers.NODES:
        md = harness.build_model("dc_motor_link", work / f"nodes{M}", "float", "replay", "ci", M)
        fresh, _, _ = _run(md, _render(md, "bench", work / f"nodes{M}-src"), work / f"nodes{M}-bench",
                           ("BENCH_SKIP_NODE", "BENCH_SKIP_LAGS", "CI_TOL=-1"))
        worst, _, _ = _run(md, _render(md, "worst", work / f"nodes{M}-wsrc"), work / f"nodes{M}-worst",
                           ("CI_TOL=-1",))
        out["nodes"][M] = {"fresh": fresh["master_fuse_distinct"]["instructions"],
                           "worst": worst["worst/master_fuse"]["max"],
                           "worst_cycles": worst["worst/master_fuse"]["max_cycles"]}
    return out


def scaling_markdown(sc: dict) -> list[str]:
    ch, nd = sc["chains"], sc["nodes"]
    ns, Ms = sorted(ch), sorted(nd)
    out = [f"### Scaling on the Cortex-M4F (float, {OPT})", "",
           "| n | node step instructions | x previous n | cycles (estimate) | filter kernels .text [B] "
           "| fusion kernels .text [B] |", "|---:|---:|---:|---:|---:|---:|"]
    out += bench_peers.chain_rows(ch, lambda c: (_cyc(c["cycles"]), c["filter_text"], c["fusion_text"]))
    g = bench_peers.growth
    out += ["", f"Fitted growth over n = {ns[0]}..{ns[-1]}: node step ~ n^{g(ns, [ch[n]['step'] for n in ns]):.2f}, "
            f"filter kernels .text ~ n^{g(ns, [ch[n]['filter_text'] for n in ns]):.2f}, fusion kernels .text ~ "
            f"n^{g(ns, [ch[n]['fusion_text'] for n in ns]):.2f} (targets: each n at most 1.6x the previous, "
            ".text no faster than n^2).", "",
            "| nodes M (dc_motor_link, ci) | fuse, every Newton step, fresh packets | worst: stale packets too "
            "| cycles of the worst (estimate) |", "|---:|---:|---:|---:|"]
    out += [f"| {M} | {_fmt(nd[M]['fresh'])} | {_fmt(nd[M]['worst'])} | {_cyc(nd[M]['worst_cycles'])} |" for M in Ms]
    return out + ["", "Every Newton step: built with -D<MODEL>_CI_TOL=-1 (the early stop off); stale: "
                  "`templates/harness/worst.c.j2`'s packets N_max steps old, each brought forward before the "
                  "fuse (target at M = 8: 20,000 instructions).", ""]
