"""`codegen scenario --disturbance auto` (experiment/disturbance_choice.py): the rule that picks a
kind, on stand-ins for the calibrations and the pole check, so that each branch is checked
against the rule itself: the most accurate kind whose loop holds the error's corners at some
pole tried, else the most accurate."""

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


def test_candidates_take_the_gauss_markov_kinds_with_a_tau():
    assert [d.kind for d in choice.candidates(None)] == ["random_walk", "integrated_random_walk"]
    got = choice.candidates(0.3)
    assert [d.kind for d in got] == ["random_walk", "integrated_random_walk", "gauss_markov",
                                     "integrated_gauss_markov"]
    assert [d.tau for d in got] == [None, None, 0.3, 0.3]     # a walk with a tau would be refused


@pytest.mark.parametrize("errors, lost, kind", [
    # per kind, its RMSE relative to the random walk's: rw, irw, gm, igm
    ((1.0, 0.6, 0.9, 0.4), (), "integrated_gauss_markov"),                       # the most accurate
    ((1.0, 0.6, 0.9, 0.4), ("integrated_gauss_markov",), "integrated_random_walk"),  # the next that holds
    ((1.0, math.inf, 0.9, 1.2), (), "gauss_markov"),                              # a failed one ranks last
    ((1.0, 0.6, 0.9, 0.4), ("random_walk", "integrated_random_walk", "gauss_markov", "integrated_gauss_markov"),
     "integrated_gauss_markov"),                                                  # none holds: the most accurate
])
def test_with_a_tau_the_most_accurate_of_four_that_holds(monkeypatch, errors, lost, kind):
    scale = dict(zip(("random_walk", "integrated_random_walk", "gauss_markov", "integrated_gauss_markov"), errors))
    seen = []

    def densities(flat, q, loops, dist, match, tol, log):
        seen.append((dist.kind, dist.tau))
        return q, [], dist

    def hold(q, dist, log):
        return [1.0], log + ["WARNING: lost" if dist.kind in lost else "poles hold"]

    monkeypatch.setattr(choice.disturbance_calibration, "densities", densities)
    monkeypatch.setattr(choice, "master_rmse", lambda loops, q, dist: np.full(3, scale[dist.kind]))
    _, log, dist, _ = choice.choose(None, np.ones(1), [], None, 1.1, [], hold, tau=0.3)
    assert dist.kind == kind and len(seen) == 4
    assert dist.tau == (0.3 if kind in choice.TIMED else None)
    ranked = sorted(scale, key=lambda k: scale[k])
    assert log[0].startswith(f"disturbance kind: {ranked[0]} ")


@pytest.mark.parametrize("ratios, kind", [
    # per kind, its RMSE relative to the random walk's: rw, irw, gm, igm
    ((1.0, 1.0, 1.0, 1.0), "random_walk"),                    # no model error: all alike, the simplest
    ((1.0, 1.07, 1.51, 0.983), "random_walk"),                # the arm at +-20%: 1.7% is within BETTER
    ((1.0, 0.613, 1.51, 0.728), "integrated_random_walk"),    # the motor at +-20%
    ((1.0, 0.70, 0.69, 0.60), "integrated_gauss_markov"),
    ((1.0, 0.70, 0.695, 0.69), "gauss_markov"),              # three alike: one state, before two
])
def test_rank_keeps_the_simplest_of_those_within_better_of_the_best(ratios, kind):
    kinds = choice.candidates(0.3)
    order = choice.rank(kinds, list(ratios))
    assert kinds[order[0]].kind == kind and sorted(order) == [0, 1, 2, 3]
    rest = [ratios[i] for i in order[1:]]
    assert rest == sorted(rest)                               # then by accuracy
