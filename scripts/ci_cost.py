"""The covariance-intersection fuse's cost over node counts M (dc_motor_link, replay, ci), measured
as `codegen bench` measures it (check/bench_peers.py and check/bench_target.py compile_scaling):

    python scripts/ci_cost.py WORKDIR 1 2 4 8 16 [--target] [--brunovsky]

Host, double -O2, callgrind: templates/harness/bench.c.j2's master_fuse_distinct built with
-D<MODEL>_CI_TOL=-1 (every Newton step: the "all steps" column of BENCHMARKS.md), the same with
the early stop (identical and distinct nodes), and worst.c.j2's costliest master_fuse (packets
N_max steps stale, every Newton step). --target: the Cortex-M4F (float -Os, QEMU) fresh packets
with every step, and the worst call. --brunovsky: that predictor instead of the default (the
held predictor brings a stale packet step by step, which dominates the worst call). One line
of JSON per M.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from dfeif_codegen.check import bench_measure, bench_programs, harness
from dfeif_codegen.check.bench_measure import Measure


def _host(md: harness.ModelDir, template: str, how: str, work: Path, defines: tuple[str, ...]):
    return bench_measure.measure(Measure(how, (bench_programs.host_template(md, template, work, defines),),
                                         work))


def _qemu(md: harness.ModelDir, template: str, work: Path, defines: tuple[str, ...]) -> dict:
    elf = bench_programs.elf_template(md, template, work, defines)
    return bench_measure.measure(Measure("qemu", (elf,), elf.parent))["counts"]


def _target(md: harness.ModelDir, work: Path) -> dict:
    fresh = _qemu(md, "bench", work / "bench", ("BENCH_SKIP_NODE", "BENCH_SKIP_LAGS", "CI_TOL=-1"))
    worst = _qemu(md, "worst", work / "worst", ("CI_TOL=-1",))
    return {"m4f_fresh_all_steps": fresh["master_fuse_distinct"]["instructions"],
            "m4f_worst": worst["worst/master_fuse"]["max"]}


def measure(M: int, work: Path, target: bool, predictor: str | None) -> dict:
    md = harness.build_model("dc_motor_link", work / "double", "double", "replay", "ci", M, predictor=predictor)
    every = (f"{md.name.upper()}_CI_TOL=-1",)
    out = {"host_all_steps": _host(md, "bench", "callgrind", work / "cg-all", every)["master_fuse_distinct"]}
    typical = _host(md, "bench", "callgrind", work / "cg", ())
    out.update(host_identical=typical["master_fuse"], host_distinct=typical["master_fuse_distinct"],
               host_worst=_host(md, "worst", "worst", work / "worst", every)["master_fuse"]["max"])
    if target:
        mf = harness.build_model("dc_motor_link", work / "float", "float", "replay", "ci", M, predictor=predictor)
        out.update(_target(mf, work / "target"))
    return out


def main(argv: list[str]) -> None:
    work = Path(argv[0])
    predictor = "brunovsky" if "--brunovsky" in argv else None
    for M in [int(a) for a in argv[1:] if a.isdigit()]:
        print(M, json.dumps(measure(M, work / f"M{M}", "--target" in argv, predictor)), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
