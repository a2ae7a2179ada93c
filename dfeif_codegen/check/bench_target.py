"""`codegen bench` on the Cortex-M4F: the same benchmark programs as on the host (bench.c.j2,
worst.c.j2, peers.c.j2), cross-compiled (float, -Os, check/bench_programs.py) and run under QEMU
mps2-an386, each executed instruction counted and costed (check/target_count.py); stack per entry
point with the newlib and libgcc code it calls, read from the linked program. What each figure
compiles, how its measurements are shaped, and its tables in the report.
"""

from __future__ import annotations

from pathlib import Path

from dfeif_codegen.check import bench_peers, bench_programs, harness
from dfeif_codegen.check.bench_measure import Measure
from dfeif_codegen.check.bench_programs import CALLS, OPT

# (oosm, fusion, defines, label) of the worst-case runs; the first is the reference configuration
WORST = (("replay", "difference", (), "replay, difference"), ("retrodict", "difference", (), "retrodict, difference"),
         ("replay", "ci", ("CI_TOL=-1",), "replay, ci (every Newton step)"))


def _qemu(md: harness.ModelDir, template: str, work: Path, defines=(), how: str = "qemu") -> Measure:
    elf = bench_programs.elf_template(md, template, work, defines)
    return Measure(how, (elf, md.name) if how == "qemu-stack" else (elf,), elf.parent)


def compile_model(name: str, work: Path) -> dict:
    """Typical counts per call (bench.c.j2), the worst call per entry point for each WORST build
    (worst.c.j2) and, for the difference builds, the stack per entry point with library calls."""
    md = harness.build_model(name, work / "replay-difference", "float")
    out: dict = {"typical": _qemu(md, "bench", work / "bench"), "worst": {}}
    for oosm, fusion, defines, label in WORST:
        md = harness.build_model(name, work / f"{oosm}-{fusion}", "float", oosm, fusion)
        out["worst"][label] = _qemu(md, "worst", work / f"worst-{oosm}-{fusion}", defines,
                                    "qemu-stack" if fusion == "difference" else "qemu")
    return out


def model_rows(ran: dict) -> dict:
    """compile_model's measurements as the report reads them: typical, worst per label, stack per oosm."""
    worst, stack = {}, {}
    for oosm, _, _, label in WORST:
        got = ran["worst"][label]
        worst[label] = {k[len("worst/"):]: v for k, v in got["counts"].items() if k.startswith("worst/")}
        if "stack" in got:
            stack[oosm] = got["stack"]
    return {"typical": ran["typical"]["counts"], "worst": worst, "stack": stack}


def compile_peers(spec: str, work: Path, predictor: str | None = None) -> Measure:
    """The peers of one node step (peers.c.j2) for the target, float."""
    md = harness.build_model(spec, work / "float", "float", **bench_peers.with_predictor(predictor))
    elf = bench_programs.elf(md, bench_peers.render_peers(spec, md, work / "src"), work / "peers")
    return Measure("qemu", (elf,), elf.parent)


def peer_counts(ran: dict) -> dict:
    """The target peers' counts, after checking each peer ends where the generated filter does
    (float: 1e-3 relative, 200 steps of a filter whose covariance settles, far above single
    precision's 6e-8 but far below a wrong filter's error)."""
    bench_peers.check_finals(ran["stdout"], 1e-3, 1e-5, " on the target")
    return ran["counts"]


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


def compile_scaling(work: Path, chains=None, nodes=None) -> dict:
    """On the target: the node step (update + predict) and the kernels' .text over the synthetic
    chains, and the CI fuse with every Newton step over nodes M, typical (fresh packets) and
    worst (worst.c.j2: packets N_max steps stale too)."""
    out: dict = {"chains": {}, "nodes": {}}
    for n in chains or bench_peers.CHAINS:
        md = harness.build_model(bench_peers.chain_spec(n, work), work / f"chain{n}", "float")
        step = _qemu(md, "bench", work / f"chain{n}-bench", ("BENCH_SKIP_LAGS", "BENCH_SKIP_FUSE"))
        out["chains"][n] = {"counts": step, "sizes": Measure("sizes", (sorted((step.work / "lib").glob("*.o")),))}
    for M in nodes or bench_peers.NODES:
        md = harness.build_model("dc_motor_link", work / f"nodes{M}", "float", "replay", "ci", M)
        out["nodes"][M] = {"fresh": _qemu(md, "bench", work / f"nodes{M}-bench",
                                          ("BENCH_SKIP_NODE", "BENCH_SKIP_LAGS", "CI_TOL=-1")),
                           "worst": _qemu(md, "worst", work / f"nodes{M}-worst", ("CI_TOL=-1",))}
    return out


def scaling_rows(ran: dict) -> dict:
    """compile_scaling's measurements as the report reads them."""
    out: dict = {"chains": {}, "nodes": {}}
    for n, r in ran["chains"].items():
        counts, text = r["counts"]["counts"], {k: z.text for k, z in r["sizes"].items()}
        out["chains"][n] = {"step": counts["node_update"]["instructions"] + counts["node_predict"]["instructions"],
                            "cycles": tuple(counts["node_update"]["cycles"][i] + counts["node_predict"]["cycles"][i]
                                            for i in (0, 1)),
                            "filter_text": text[f"chain{n}_kernels_filter.o"],
                            "fusion_text": text[f"chain{n}_kernels_fusion.o"]}
    for M, r in ran["nodes"].items():
        worst = r["worst"]["counts"]["worst/master_fuse"]
        out["nodes"][M] = {"fresh": r["fresh"]["counts"]["master_fuse_distinct"]["instructions"],
                           "worst": worst["max"], "worst_cycles": worst["max_cycles"]}
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
