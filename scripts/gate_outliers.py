"""What the innovation gate (`codegen build --gate`) buys under camera outliers (docs/algorithms.md,
"Innovation gate"): recorded closed loops of the paper scenario re-filtered by the reference with
a fraction of the frames, on time and late, moved far off (a feature tracker locked onto the wrong
feature), with and without the gate. The filters predict with the recorded inputs, the plant's, so
every variant sees the same plant and frames. Prints the master's RMSE per state against the true
canonical state after the first second, and the frames the gate refused. Usage:

    python scripts/gate_outliers.py dc_motor_link --seeds 5 --fraction 0.01 --size 30
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from dfeif_codegen.check import verify
from dfeif_codegen.check.driver_io import broadcast
from dfeif_codegen.experiment import closed_loop as experiment
from dfeif_codegen.reference.node import NodeFilter


def corrupted(rec, fraction: float, size: float, rng):
    """The recording with `fraction` of its frames (on time and late) moved by `size` camera
    standard deviations, with a random sign per frame and output."""
    z, late_z = np.array(rec.z), np.array(rec.late_z)
    sd = np.sqrt(np.diagonal(rec.R, axis1=1, axis2=2))                    # (nodes, ny)
    hit = (rng.random(rec.gamma.shape) < fraction) & (np.asarray(rec.gamma) > 0)
    z += hit[..., None] * size * sd[:, None, :] * rng.choice([-1.0, 1.0], z.shape)
    late = rng.random(len(late_z)) < fraction
    late_z += late[:, None] * size * sd[np.asarray(rec.late_node)] * rng.choice([-1.0, 1.0], late_z.shape)
    return dataclasses.replace(rec, z=z, late_z=late_z), int(hit.sum() + late.sum())


def rmse(res, out) -> np.ndarray:
    keep = res.t >= res.config.metrics_from
    return np.sqrt(np.mean((out["x"][keep] - res.zeta[keep]) ** 2, axis=0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", nargs="?", default="dc_motor_link")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--row", type=int, default=2, help="the paper grid's delay row (default 2: late frames)")
    ap.add_argument("--fraction", type=float, default=0.01, help="fraction of frames made outliers")
    ap.add_argument("--size", type=float, default=30.0, help="their offset in camera standard deviations")
    ap.add_argument("--gates", default="3,4,5", help="gates to compare [standard deviations]")
    a = ap.parse_args()
    gates = [float(g) for g in a.gates.split(",")]
    labels = ["clean frames", "outliers, no gate"] + [f"outliers, gate {g:g}" for g in gates]
    errors: dict[str, list] = {k: [] for k in labels}
    refused: dict[str, int] = {k: 0 for k in labels}
    counted = {"n": 0}
    seen = NodeFilter._refused

    def counting(self, e, S):
        out = seen(self, e, S)
        counted["n"] += int(out)
        return out

    NodeFilter._refused = counting
    injected = 0
    for seed in range(a.seeds):
        res = verify.closed_loop(a.model, row=a.row, seed=seed)
        rec = res.recording
        bad, hits = corrupted(rec, a.fraction, a.size, np.random.default_rng(1000 + seed))
        injected += hits
        runs = [(labels[0], rec, 0.0), (labels[1], bad, 0.0)] + [(lab, bad, g) for lab, g in zip(labels[2:], gates)]
        for label, r, gate in runs:
            counted["n"] = 0
            out = experiment.replay_recording(dataclasses.replace(r, gate=gate), inputs=broadcast(r))
            errors[label].append(rmse(res, out))
            refused[label] += counted["n"]
    print(f"{a.model}, paper row {a.row}, {a.seeds} seeds; {injected} outliers of {a.size:g} camera sigma "
          f"({a.fraction:.1%} of the frames); master RMSE per state (mean over seeds), frames refused")
    for label in labels:
        e = np.mean(errors[label], axis=0)
        print(f"  {label:24s} " + "  ".join(f"{v:.3e}" for v in e) + f"   refused {refused[label]}")


if __name__ == "__main__":
    main()
