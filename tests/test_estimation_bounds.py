"""What any estimator can reach on the *matched linear model* of the paper scenario (the
canonical chain driven by white noise of density q; its Kalman filters are the Brunovsky
predictor's, built with predictor="brunovsky"): the reference levels two of the experiment's
acceptance figures are compared with (docs/experiment.md, "The acceptance figures, restated").
The real plant has no process noise, so on it these are reference levels, not limits: the
measured fusion gain on x3 and the master x1 RMSE both beat them (experiment/bounds.py computes
them per row beside the measurements).

For a plant that is exactly the filters' linear canonical model, the Kalman filter's covariance
is the mean squared error of the best estimator there is, and it depends only on which
measurements arrived, not on their values. So the bounds come out of covariance recursions,
deterministic and without Monte Carlo noise:

- fusion: the information-difference master is the centralized Kalman filter, whose steady state
  is the discrete algebraic Riccati equation of the stacked cameras (scipy, an independent
  solver); its RMSE ratio to the better node bounds what any fusion rule can do;
- delays: the `replay` node filter is the Kalman filter of every frame received so far (checked
  against a batch filter in test_reference_filters.py); its covariance with the paper's delays,
  against the same without delays, bounds what any late-measurement method can do.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg

from dfeif_codegen.experiment import scenario, simulate
from dfeif_codegen.check import verify
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.reference.fusion import Master
from dfeif_codegen.experiment.network import Network
from dfeif_codegen.reference.node import NodeFilter


def paper_settings(model: str):
    """ts, q, R per node and P0 of the paper scenario for `model` (from a 0.1 s run)."""
    rec = verify.closed_loop(model, duration=0.1, row=0)
    return rec.recording.ts, rec.recording.q, rec.recording.R, rec.recording.node_P0[0]


def dare_posterior(A, C, Q, R):
    prior = linalg.solve_discrete_are(A.T, C.T, Q, R)
    K = prior @ C.T @ np.linalg.inv(C @ prior @ C.T + R)
    return (np.eye(A.shape[0]) - K @ C) @ prior


@pytest.mark.parametrize("model", ["dc_motor_link", "two_link_arm"])
def test_fusion_gain_bound(model):
    """Node and difference-rule master run without delays settle on the Riccati solutions of one
    camera and of both; the master / better-node RMSE ratio of the highest derivative then stays
    far above 0.85 on the matched model: fusing two cameras cannot shrink an error that process
    noise dominates."""
    ts, q, R, P0 = paper_settings(model)
    flat = ex._flat(model)
    A, _, C = flat.discrete(ts)
    Q = flat.process_noise(ts, q)
    nodes = [NodeFilter(flat, ts, q, R[i], np.zeros(flat.n), P0, predictor="brunovsky") for i in range(2)]
    master = Master(flat, ts, q, np.zeros(flat.n), P0, 2, rule="difference", predictor="brunovsky")
    for _ in range(600):
        for node in nodes:
            node.update(np.zeros(flat.m), True)
        master.fuse([node.packet() for node in nodes])
        for node in (*nodes, master):
            node.predict(np.zeros(flat.m))
    for node in nodes:
        node.update(np.zeros(flat.m), True)
    master.fuse([node.packet() for node in nodes])
    single = dare_posterior(A, C, Q, R[0])
    both = dare_posterior(A, np.vstack([C, C]), Q, linalg.block_diag(R[0], R[1]))
    # the filters converge geometrically to the DARE fixed point after the warm-up; scipy's DARE
    # solver is backward stable (~cond eps ~1e-12): 1e-8 bounds the remaining transient plus that
    np.testing.assert_allclose(nodes[0].P, single, rtol=1e-8, atol=1e-14)
    np.testing.assert_allclose(master.P, both, rtol=1e-8, atol=1e-14)
    ratio = np.sqrt(np.diag(both) / np.diag(single))
    print(f"\n{model}: best possible master / node-1 RMSE per state {np.round(ratio, 3)}")
    for chain in flat.chains:
        head, top = chain.offset, chain.offset + chain.degree - 1
        assert ratio[head] < 0.85 < ratio[top]


def test_delay_loss_bound():
    """The paper's worst delay row, (25, 30, 0.6), against no delays: the best possible master
    x1 RMSE (the exact filter's covariance, on two seeded draws of the paper's network) is more than
    10% higher, because the frames of the last steps have mostly not arrived yet."""
    ts, q, R, P0 = paper_settings("dc_motor_link")
    flat = ex._flat("dc_motor_link")
    sc = scenario.load("paper")
    steps, start = int(round(sc.duration / ts)), int(round(sc.metrics_from / ts))

    def mean_master_p11(row, seed) -> float:
        cfg = simulate.make_config(sc, "dc_motor_link", 2, 32, "sinusoid", row, "replay", "difference", seed)
        net = Network(list(cfg.sensor), list(cfg.uplink), steps, np.random.default_rng(seed))
        nodes = [NodeFilter(flat, ts, q, R[i], np.zeros(flat.n), P0, predictor="brunovsky") for i in range(2)]
        master = Master(flat, ts, q, np.zeros(flat.n), P0, 2, rule="difference", predictor="brunovsky")
        p11 = []
        for k in range(steps):
            for i, node in enumerate(nodes):
                node.update(np.zeros(flat.m), net.lag[i, k] == 0)
                for lag in net.late[i].get(k, []):
                    node.update_delayed(np.zeros(flat.m), lag)
            master.fuse([node.packet() for node in nodes])
            p11.append(master.P[0, 0])
            for node in (*nodes, master):
                node.predict(np.zeros(flat.m))
        return float(np.mean(p11[start:]))

    ratios = [np.sqrt(mean_master_p11(sc.grid[5], s) / mean_master_p11(sc.grid[0], s)) for s in range(2)]
    print(f"\nbest possible master x1 RMSE, (25,30,0.6) / (0,0,0): {np.round(ratios, 3)}")
    assert tuple(sc.grid[5].d) == (25, 30) and sc.grid[5].p == 0.6 and sc.grid[0].p == 0
    assert min(ratios) > 1.1
