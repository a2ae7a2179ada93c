"""Sensitivity of the held-input filter to the point its covariance transition is linearized at
(docs/mathematics.md section 3): closed loops with L₀ taken at the nominal state (θ = 0) and at
θ₀ = 0.7 and -1.0 (the other states at their nominal values), the same seeds. Usage:

    python scripts/linearization_point.py [--seeds N] [--row R]
"""

from __future__ import annotations

import argparse

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import scenario, simulate
from dfeif_codegen.reference import predictor
from dfeif_codegen.symbolic import sampling
from dfeif_codegen.symbolic.flatness import nominal_state

MODEL = "dc_motor_link"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--row", type=int, default=0)
    a = ap.parse_args()
    sc = scenario.load("paper")
    flat = ex._flat(MODEL)
    original = sampling.held_sampling
    base = None
    for theta in (0.0, 0.7, -1.0):
        x = nominal_state(flat.model)
        x[0] = theta
        sampling.held_sampling = lambda f, ts, x=x, u=None: original(f, ts, x=x)   # noqa: E731
        predictor._CACHE.clear()
        runs = [ex.run(simulate.make_config(sc, MODEL, 2, 32, "sinusoid", sc.grid[a.row], "replay", "difference", s))
                for s in range(a.seeds)]
        rmse = np.mean([r.metrics["rmse_master"] for r in runs], axis=0)
        nees = np.mean([np.mean(r.metrics["nees_master"]) for r in runs])
        base = rmse if base is None else base
        print(f"theta0 = {theta:+.1f}: master RMSE " + " / ".join(f"{v:.3g}" for v in rmse)
              + f" ({' / '.join(f'{v:+.0%}' for v in rmse / base - 1)}), NEES {nees:.2f}")
    sampling.held_sampling = original


if __name__ == "__main__":
    main()
