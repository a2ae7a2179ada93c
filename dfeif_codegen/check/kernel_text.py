"""Where the filter kernels' code goes: .text of each kernel of the synthetic flat chains
(`bench_peers.chain_model`, n = 2..12) as `codegen bench` sizes them (Cortex-M4F, float, -Os, a
replay build with the Brunovsky predictor, whose node_predict is looped: predict, node_predict,
update, info), with the fitted growth of each and of their sum, and optionally the node step's
host instructions (callgrind, double); --predictor held: of the default build instead (the
scaling table's, whose node_predict is the held predictor's). With --fusion the same for the
fusion kernels of the default build and the master fuse's instructions (two packets).

    python -m dfeif_codegen.check.kernel_text [--fusion] [--steps] [--predictor held] [WORK]
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
from pathlib import Path

from dfeif_codegen.check import bench_measure, bench_peers, bench_programs, harness, target


def symbol_sizes(obj: Path) -> dict[str, int]:
    """Bytes of each function an object defines, static ones too (`arm-none-eabi-nm -S`, literal
    pools included)."""
    out = subprocess.run([target.require("arm-none-eabi-nm"), "-S", "--defined-only", str(obj)],
                         capture_output=True, text=True, check=True).stdout
    return {parts[3]: int(parts[1], 16) for parts in (line.split() for line in out.splitlines())
            if len(parts) == 4 and parts[2] in "tT"}


def chain_kernels(n: int, work: Path, group: str = "filter", predictor: str | None = "brunovsky") \
        -> tuple[dict[str, int], int]:
    """Per-kernel bytes (short names) of chain n's kernels of `group` (filter, fusion: the file
    <model>_kernels_<group>.c) and the object's .text; `predictor` None: the default's build
    (the scaling table's)."""
    spec = work / f"chain{n}.toml"
    spec.parent.mkdir(parents=True, exist_ok=True)
    spec.write_text(bench_peers.chain_model(n))
    label = f"chain{n}-float-{predictor or 'default'}"
    mf = harness.build_model(str(spec), work / label, "float", predictor=predictor)
    src = [s for s in mf.sources() if s.name == f"chain{n}_kernels_{group}.c"]
    obj = target.compile_objects(src, work / f"obj-{label}-{group}", [mf.path], opt="-Os")[0]
    prefix = f"chain{n}_kern_"
    sizes = {name[len(prefix):]: size for name, size in symbol_sizes(obj).items() if name.startswith(prefix)}
    per: dict[str, int] = {}
    for name, size in sorted(sizes.items()):   # a kernel's static parts (kernels.csource.Loop) count as its own
        owner = max((k for k in sizes if name.startswith(k + "_")), key=len, default=name)
        per[owner] = per.get(owner, 0) + size
    return per, target.sizes([obj])[obj.name].text


def table(work: Path, ns=bench_peers.CHAINS, steps: bool = False, group: str = "filter",
          predictor: str | None = "brunovsky") -> str:
    """The markdown table of per-kernel bytes per n, and the fitted exponents: the filter kernels
    of a replay build with `predictor` (None: the default's; `steps`: with the node step's
    instructions), or the fusion kernels of the default build (`steps`: with the master fuse's,
    two packets)."""
    predictor, section = (predictor, "node step") if group == "filter" else (None, "master fuse")
    rows, totals, kernels, step = [], [], None, []
    for n in ns:
        per, text = chain_kernels(n, work, group, predictor)
        kernels = kernels or sorted(per)
        totals.append(text)
        cells = [str(per.get(k, 0)) for k in kernels] + [str(text)]
        if steps:
            md = harness.build_model(str(work / f"chain{n}.toml"), work / f"chain{n}-double", predictor=predictor)
            c = bench_measure.callgrind(bench_measure.Measure(
                "callgrind", (bench_programs.host_template(md, "bench", work / f"cg-chain{n}", ()),), work / f"cg-chain{n}"))
            step.append(c["node_update"] + c["node_predict"] if group == "filter" else c["master_fuse"])
            cells.append(f"{step[-1]:,.0f}")
        rows.append(f"| {n} | " + " | ".join(cells) + " |")
    head = ["n"] + kernels + [f"{group} kernels .text"] + ([f"{section} instructions"] if steps else [])
    lines = ["| " + " | ".join(head) + " |", "|" + "---:|" * len(head)] + rows
    fits = [f"{k} n^{bench_peers.growth(ns, [_cell(r, i) for r in rows]):.2f}" for i, k in enumerate(kernels)]
    fits.append(f"total n^{bench_peers.growth(ns, totals):.2f}")
    if steps:
        fits.append(f"{section} n^{bench_peers.growth(ns, step):.2f}")
    return "\n".join(lines) + f"\n\nFitted growth over n = {ns[0]}..{ns[-1]}: " + ", ".join(fits) + ".\n"


def _cell(row: str, i: int) -> float:
    return float(row.strip("| ").split(" | ")[i + 1].replace(",", ""))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dfeif_codegen.check.kernel_text", description=__doc__.split("\n\n")[0])
    ap.add_argument("work", nargs="?", help="folder for the builds (default: a temporary one)")
    ap.add_argument("--steps", action="store_true",
                    help="also count the node step's (--fusion: the master fuse's) instructions (valgrind)")
    ap.add_argument("--fusion", action="store_true", help="the fusion kernels of the default build instead")
    ap.add_argument("--predictor", choices=("brunovsky", "held"), default="brunovsky",
                    help="the filter kernels' predictor (held: the default build's, the scaling table's)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        print(table(Path(args.work or tmp), steps=args.steps, group="fusion" if args.fusion else "filter",
                    predictor=None if args.predictor == "held" else "brunovsky"), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
