"""Where a node step's instructions go: the generated code against the C library it calls (libm's
sin, cos, sqrt, ...), measured as `codegen bench` measures the step (host, double -O2, callgrind
over templates/harness/bench.c.j2's node_update and node_predict sections):

    python scripts/step_cost.py WORKDIR [MODEL]

For each predictor (held, brunovsky) one line of JSON: instructions per call of node_update and
node_predict, and of those the instructions executed inside each shared object other than the
program (callgrind's self cost per object, callees of callees included). Why: issue 22 asks the
node's predict + update for at most 2x the chapter filter's 321 instructions; the held
predictor's mean evaluates the model's nonlinearity twice (ETD2RK's two stages), and on the
host each evaluation of a trigonometric model is one libm sincos call. This separates that cost
(fixed by the model and the integrator) from the code the generator prints.
"""

from __future__ import annotations

import json
import re
import sys
from collections import defaultdict
from pathlib import Path

from dfeif_codegen.check import bench_programs, harness

SECTIONS = ("node_update", "node_predict")


def self_cost_by_object(text: str) -> dict[str, int]:
    """Self instructions per shared object of one callgrind dump (name compression resolved; the
    line after `calls=` is the call's inclusive cost, counted in the callee's own lines)."""
    names: dict[str, str] = {}
    cost: dict[str, int] = defaultdict(int)
    obj, skip = "?", False
    for line in text.splitlines():
        m = re.match(r"^(c?ob)=\((\d+)\)(?: (.*))?$", line)
        if m:
            if m.group(3):
                names[m.group(2)] = m.group(3)
            if m.group(1) == "ob":
                obj = names[m.group(2)]
            continue
        if line.startswith("calls="):
            skip = True
            continue
        if line[:1].isdigit() or line[:1] in "+-*":
            if skip:
                skip = False
                continue
            parts = line.split()
            if len(parts) >= 2:
                cost[obj] += int(parts[1])
    return dict(cost)


def measure(model: str, predictor: str, work: Path) -> dict:
    md = harness.build_model(model, work / "double", "double", "replay", "difference", 2, predictor=predictor)
    exe = bench_programs.host_template(md, "bench", work / "cg")
    dumps, _ = harness.callgrind_dumps(exe, work / "cg")
    calls = {name: n for name, n, _ in dumps}
    out: dict = {"model": model, "predictor": predictor}
    for dump in sorted((work / "cg").glob("callgrind.out*")):
        text = dump.read_text(errors="replace")
        desc = re.search(r"^desc: Trigger: Client Request: (\S+):(\d+)$", text, re.M)
        if not desc or desc.group(1) not in SECTIONS:
            continue
        n = calls[desc.group(1)]
        by_obj = self_cost_by_object(text)
        total = sum(by_obj.values())
        shared = {Path(k).name: round(v / n, 1) for k, v in by_obj.items() if Path(k).name != exe.name and v}
        out[desc.group(1)] = {"instructions": round(total / n, 1), "of which": shared}
    return out


def main(argv: list[str]) -> None:
    work = Path(argv[0])
    model = argv[1] if len(argv) > 1 else "dc_motor_link"
    for predictor in ("held", "brunovsky"):
        print(json.dumps(measure(model, predictor, work / predictor)), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
