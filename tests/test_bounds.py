"""The exact-bound module (experiment/bounds.py) against independent expectations: the scalar
Riccati steady state in closed form (on time and with a fixed lag), the replay node filter's own
covariance on a real run (a second implementation of the same Kalman filter), and a Monte Carlo
of the matched linear plant (experiment/matched.py), whose errors the bound must predict."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dfeif_codegen.experiment import bounds, matched, scenario, simulate
from dfeif_codegen.experiment import closed_loop as ex


def scalar_steady(q, r):
    """Random walk x+ = x + w (var q), z = x + e (var r): steady prior P solves P^2 = q (P + r)."""
    prior = (q + math.sqrt(q * q + 4 * q * r)) / 2
    return prior, prior * r / (prior + r)


@pytest.mark.parametrize("lag", [0, 1, 7])
def test_scalar_riccati_closed_form(lag):
    """Every frame late by exactly `lag` steps: P(k|k) is the on-time posterior predicted `lag`
    steps, p + lag q. Converges geometrically (rate r / (P + r) ~ 0.6 here), so after 300 steps the
    recursion agrees with the closed form to rounding (1e-12 relative, a few ulps per step)."""
    q, r, K = 0.3, 0.5, 300
    arrive = (np.arange(K) + lag)[None, :].astype(np.int64)
    arrive[arrive >= K] = bounds.NEVER
    P = bounds.posterior_covariances(np.eye(1), np.array([[q]]), np.array([[[1 / r]]]), np.array([[10.0]]), arrive)
    _, post = scalar_steady(q, r)
    assert P[-1, 0, 0] == pytest.approx(post + lag * q, rel=1e-12)


def test_two_cameras_add_information():
    """Two cameras r1, r2 on time are one camera of r = r1 r2 / (r1 + r2): information adds."""
    q, r1, r2, K = 0.2, 0.4, 0.9, 300
    arrive = np.tile(np.arange(K, dtype=np.int64), (2, 1))
    H = np.array([[[1 / r1]], [[1 / r2]]])
    P = bounds.posterior_covariances(np.eye(1), np.array([[q]]), H, np.array([[5.0]]), arrive)
    assert P[-1, 0, 0] == pytest.approx(scalar_steady(q, r1 * r2 / (r1 + r2))[1], rel=1e-12)


@pytest.fixture(scope="module")
def short_run():
    sc = scenario.load("paper")
    cfg = simulate.make_config(sc, "dc_motor_link", 2, 32, "sinusoid", sc.grid[5], "replay", "difference", 3)
    # the bound is the Brunovsky filter's covariance (A, Q of the canonical model): run that filter
    cfg = ex.Config(**{**cfg.__dict__, "duration": 2.0, "predictor": "brunovsky"})
    return cfg, ex.run(cfg)


def test_nodes_equal_the_replay_filter(short_run):
    """A linear Kalman filter's covariance does not depend on the data, so the replay node filter's
    P in a real closed-loop run at (25, 30, 0.6) is the bound's per-node recursion: two
    implementations (rewind-and-replay; windowed information form), equal to
    1e-10 relative (both are backward stable on these well-conditioned 3x3 matrices)."""
    cfg, res = short_run
    A, Q, R, P0, _ = bounds.matched_model(cfg)
    K = res.recording.x.shape[0]
    net = bounds.network_of(cfg, K)
    np.testing.assert_array_equal(net.lag, res.delays)
    arrive = bounds.arrivals(net, cfg.max_lag)
    C = np.array([[1.0, 0.0, 0.0]])
    for i in range(2):
        H = (C.T @ np.linalg.solve(R[i], C))[None]
        P = bounds.posterior_covariances(A, Q, H, P0, arrive[i:i + 1])
        np.testing.assert_allclose(P, res.recording.node_P[i], rtol=1e-10, atol=1e-10 * np.abs(P).max())


def test_difference_master_is_centralized_without_delays():
    """Without late frames the information-difference master is the centralized filter (to 1e-10)."""
    sc = scenario.load("paper")
    cfg = simulate.make_config(sc, "dc_motor_link", 2, 32, "sinusoid", sc.grid[0], "replay", "difference", 1)
    cfg = ex.Config(**{**cfg.__dict__, "duration": 1.0, "predictor": "brunovsky"})
    res = ex.run(cfg)
    A, Q, R, P0, _ = bounds.matched_model(cfg)
    C = np.array([[1.0, 0.0, 0.0]])
    H = np.array([C.T @ np.linalg.solve(Ri, C) for Ri in R])
    arrive = bounds.arrivals(bounds.network_of(cfg, 100), 32)
    P = bounds.posterior_covariances(A, Q, H, P0, arrive)
    np.testing.assert_allclose(P, res.recording.P, rtol=1e-10, atol=1e-10 * np.abs(P).max())


@pytest.mark.parametrize("model", ["dc_motor_link", "two_link_arm"])
def test_monte_carlo_of_the_matched_plant(model):
    """On the matched linear plant the replay nodes' and the master's mean squared errors are the
    bounds (per node; centralized for the master, which without late frames *is* the centralized
    filter and with them is within 1% of it): 40 seeds of 400 steps at (4, 6, 0.8), for one
    chain and for the arm's two chains with their correlated 2x2 camera covariance. The per-seed
    time averages are independent across seeds, so the mean's standard error comes from their
    spread; each bound must lie within 4 standard errors (a 6e-5 chance of a false alarm per
    entry for a normal mean; the time average of 300 correlated squares is close to normal)."""
    sc = scenario.load("paper")
    cfgs = [ex.Config(**{**simulate.make_config(sc, model, 2, 32, "sinusoid", sc.grid[1], "replay",
                                                "difference", s).__dict__, "duration": 4.0})
            for s in range(40)]
    bound = bounds.row_bound(cfgs)
    runs = [matched.metrics(c, matched.run(c)) for c in cfgs]
    for key, expect in (("mse_nodes", bound.var_nodes), ("mse_master", bound.var_central)):
        mse = np.array([r[key] for r in runs])              # (S, M, n) or (S, n)
        mean, se = mse.mean(axis=0), mse.std(axis=0, ddof=1) / math.sqrt(len(cfgs))
        assert mean.shape == expect.shape and mean.shape[-1] == ex._flat(model).n
        assert np.all(np.abs(mean - expect) < 4 * se), (key, mean, expect, se)


def test_simulate_prints_and_writes_the_bounds(tmp_path, capsys):
    """`codegen simulate` puts each row's exact bound beside the measurements (Table IV-c/IV-d)
    and into the JSON, equal to bounds.row_bound over the same seeds (the same computation, so
    to the last bit)."""
    import json
    from dfeif_codegen import cli
    path = tmp_path / "short.toml"
    path.write_text("[scenario]\nduration = 2.0\nreferences = [\"sinusoid\"]\nfusion = [\"difference\"]\n"
                    "baselines = []\n[filter]\nq = 20.0\n[control]\npoles = 10.0\n"
                    "[[grid]]\nd = [0, 0]\np = 0.0\n[[grid]]\nd = [8, 10]\np = 0.8\n")
    out = tmp_path / "s.json"
    assert cli.main(["simulate", "--scenario", str(path), "--runs", "2", "--quiet", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Table IV-c" in text and "Table IV-d" in text
    doc = json.loads(out.read_text())
    sc = scenario.load(str(path))
    for ri, row in enumerate(sc.grid):
        cfgs = [simulate.make_config(sc, "dc_motor_link", 2, 32, "sinusoid", row, "replay", "difference", s)
                for s in (0, 1)]
        expect = bounds.row_bound(cfgs)
        assert doc["bounds"][ri]["rmse_central"] == expect.rmse_central.tolist()
        assert doc["bounds"][ri]["rmse_nodes"] == expect.rmse_nodes.tolist()


@pytest.mark.parametrize("model, ri, q, low, high", [
    ("dc_motor_link", 0, 20.0, 0.0, 1e-10),   # no late frame: the difference rule *is* the centralized filter
    ("dc_motor_link", 5, 20.0, 1e-3, 1.0),    # late frames: measured gap (1.0e-2 at (25, 30, 0.6))
    ("dc_motor_link", 5, 1e-12, 0.0, 1e-8),   # ... that vanishes with the process noise (O(q): 5e-10 here)
    ("two_link_arm", 0, 20.0, 0.0, 1e-10),    # two chains, correlated 2x2 R: the same without delays
    ("two_link_arm", 5, 1e-12, 0.0, 1e-8),    # ... and with them when q -> 0
])
def test_master_against_the_centralized_riccati_recursion(model, ri, q, low, high):
    """Master P of the matched plant (replay + difference) against one filter with both cameras'
    frames as they arrive. Equal to rounding without delays (1e-10: two backward-stable
    recursions of the same 3x3 information sum over 300 steps, ~1e-14 apart). With late frames
    the difference rule adds each node's information *increment*; propagated through process
    noise, a late frame's increment depends on the information it is added to (one camera's at
    the node, both cameras' centrally), so the master differs by O(q): > 1e-3 at q = 20 and
    below 1e-8 at q = 1e-12 (an algebraic term, far above rounding, so the bounds hold on any
    IEEE machine)."""
    sc = scenario.load("paper")
    cfg = simulate.make_config(sc, model, 2, 32, "sinusoid", sc.grid[ri], "replay", "difference", 1)
    cfg = ex.Config(**{**cfg.__dict__, "q": (q,), "duration": 3.0})
    gap = matched.riccati_gap(cfg, matched.run(cfg))
    assert low <= gap < high
