"""Which of a starting scenario's baselines keep the loop: `discard` and `as-current` are the
chapter's comparisons, which late frames are meant to hurt, but on some models they lose the
closed loop itself (a kinematic car whose speed leaves its domain under as-current's stale
corrections, a reactor whose node drifts past its transform's domain when discard drops 80% of
its frames), and `simulate` then exits 1 on a scenario `codegen scenario` wrote. Each baseline
runs on every delayed row with simulate's first seeds; one that loses a loop is left out of the
scenario, the reason in its header.
"""

from __future__ import annotations

import re

from dfeif_codegen.experiment import scenario as scenario_mod
from dfeif_codegen.experiment.closed_loop import MAX_LAG
from dfeif_codegen.experiment.nees_match import first_loss, links_text
from dfeif_codegen.experiment.plan import make_config

SEEDS = (0, 1)      # simulate's first runs: `simulate --runs 2` on the scenario then runs clean


def kept(text: str, spec: str, source: str, progress=None) -> tuple[str, list[str]]:
    """The scenario `text` with only the baselines that keep every loop, and a log line per one
    left out (why, and where); `progress(line)` hears each baseline as its loops start."""
    sc = scenario_mod.loads(text, source)
    nodes = len(sc.noise_scale)
    delayed = [row for row in sc.grid if row.p > 0]
    keep, log = [], []
    for method in sc.baselines:
        if progress:
            progress(f"baseline {method}: its loops on the {len(delayed)} delayed rows, seeds {SEEDS[0]}-{SEEDS[-1]}")
        configs = [make_config(sc, spec, nodes, MAX_LAG, sc.references[0], row, method, sc.fusion[0], seed)
                   for row in delayed for seed in SEEDS]
        loss = first_loss(configs)
        if loss is None:
            keep.append(method)
            continue
        row = delayed[loss[0] // len(SEEDS)]
        log.append(f"baseline {method} left out: under {links_text(row.links(nodes))} it lost the loop "
                   f"({loss[1].split(' (')[0]}, seed {SEEDS[loss[0] % len(SEEDS)]})")
    if len(keep) == len(sc.baselines):
        return text, log
    listed = ", ".join(f'"{b}"' for b in keep)
    text = re.sub(r"^baselines = \[.*\]$", f"baselines = [{listed}]", text, count=1, flags=re.M)
    header = "".join(f"#   calibration: {line}\n" for line in log)
    at = text.index("\n\n") + 1          # after the header's comment lines
    return text[:at] + header + text[at:], log
