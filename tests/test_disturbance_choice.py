"""`codegen scenario --disturbance auto` (experiment/disturbance_choice.py): the rule that picks a
kind, on stand-ins for the two calibrations and the pole check, so that each branch is checked
against the rule itself: the more accurate kind, unless its loop is lost on a corner of the
error at every pole tried and the other's holds."""

import math

import numpy as np
import pytest

from dfeif_codegen.experiment import disturbance_choice as choice


def test_ratio_is_the_geometric_mean_of_the_per_state_ratios():
    rw, irw = np.array([1.0, 2.0, 4.0]), np.array([0.5, 2.0, 1.0])
    assert choice.ratio([rw, irw]) == pytest.approx((0.5 * 1.0 * 0.25) ** (1 / 3), rel=1e-15)
    assert choice.ratio([rw, np.full(3, math.inf)]) == math.inf          # the integrated walk failed
    assert choice.ratio([np.full(3, math.inf), irw]) == 0.0             # the random walk failed


@pytest.mark.parametrize("irw_error, warns, kind, poles", [
    (0.3, (), "integrated_random_walk", [10.0]),                               # more accurate, holds
    (3.0, (), "random_walk", [10.0]),                                          # less accurate
    (0.3, ("integrated_random_walk",), "random_walk", [10.0]),                 # accurate but lost: the other
    (0.3, ("integrated_random_walk", "random_walk"), "integrated_random_walk", [1.0]),  # both lost: the first
])
def test_the_more_accurate_kind_unless_only_the_other_holds(monkeypatch, irw_error, warns, kind, poles):
    scale = {"random_walk": 1.0, "integrated_random_walk": irw_error}

    def densities(flat, q, loops, dist, match, tol, log):
        return q, [f"{dist.kind} calibrated"], choice.Disturbance(dist.kind, (scale[dist.kind],))

    def rmse(loops, q, dist):
        return np.full(3, scale[dist.kind])

    def hold(q, dist, log):
        lost = dist.kind in warns
        return ([1.0] if lost else [10.0]), log + ["WARNING: lost" if lost else "poles hold"]

    monkeypatch.setattr(choice.disturbance_calibration, "densities", densities)
    monkeypatch.setattr(choice, "master_rmse", rmse)
    q, log, dist, got_poles = choice.choose(None, np.ones(1), [], None, 1.1, ["start"], hold)
    assert dist.kind == kind and got_poles == poles and log[0] == "start"
    assert f"{kind} calibrated" in log
    assert any(line.startswith("disturbance kind: ") for line in log)
