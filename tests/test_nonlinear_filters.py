"""The EKF and UKF on the physical model (reference/ekf.py, ukf.py, physical.py) and their run on
a recording (experiment/compare.py).

On a model that is already a chain of integrators the physical model *is* the canonical one:
Phi is the identity, RK4 integrates a cubic exactly (u held: the solution is a polynomial of
degree 3, and RK4 is exact up to degree 4), the unscented transform is exact for linear maps, and
Q_x = Q_d. Both filters must then reproduce the derivative-free filter of the same recording,
node by node (replay of late frames) and at the master (information difference), to rounding.
"""

from __future__ import annotations

import numpy as np
import pytest

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare
from dfeif_codegen.experiment.network import Link

JERK_CHAIN = """
[model]
name = "jerk_chain"
ts = 0.01
[[states]]
name = "p"
[[states]]
name = "v"
[[states]]
name = "a"
[[inputs]]
name = "j"
[dynamics.f]
p = "v"
v = "a"
a = "0"
[dynamics.g.j]
a = "1"
[[outputs]]
name = "p"
expr = "p"
"""


@pytest.fixture(scope="module")
def chain_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("m") / "jerk_chain.toml"
    path.write_text(JERK_CHAIN)
    cfg = ex.Config(model=str(path), duration=3.0, q=(20.0,), poles=(10.0,), p0_std=(0.05, 0.1, 1.0),
                    noise_std=((0.004,), (0.005,)), sensor=(Link(0.6, 12), Link(0.6, 15)), seed=5)
    return ex.run(cfg)


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_equal_to_the_kalman_filter_on_a_linear_model(chain_run, kind):
    """Node and master estimates and covariances equal the derivative-free filter's to 1e-9
    relative: the same linear filter by two routes (RK4 + AD or sigma points against the exact
    discretization), each backward stable, over 300 steps with replayed late frames."""
    rec = chain_run.recording
    assert rec.late_step.size > 50
    out = compare.run_on_recording(rec, kind)
    scale = np.abs(rec.node_x).max()
    np.testing.assert_allclose(out["node_x"], rec.node_x, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(out["node_P"], rec.node_P, rtol=0, atol=1e-9 * np.abs(rec.node_P).max())
    np.testing.assert_allclose(out["x"], rec.x, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(out["P"], rec.P, rtol=0, atol=1e-9 * np.abs(rec.P).max())
    assert out["applied"] == int(rec.late_applied.sum())


def test_ekf_and_ukf_agree_on_the_motor():
    """On the motor with millimetre cameras the linearization error is tiny against the noise, so
    the two nonlinear filters (Jacobians against sigma points) give the same master RMSE to 1%,
    and both track the true state: an independent check of each implementation."""
    from dfeif_codegen.experiment import scenario, simulate
    sc = scenario.load("paper")
    cfg = simulate.make_config(sc, "dc_motor_link", 2, 32, "sinusoid", sc.grid[1], "replay", "difference", 2)
    res = ex.run(ex.Config(**{**cfg.__dict__, "duration": 3.0}))
    ekf, ukf = compare.evaluate(res, "ekf"), compare.evaluate(res, "ukf")
    assert "failed" not in ekf and "failed" not in ukf
    np.testing.assert_allclose(ekf["rmse_master"], ukf["rmse_master"], rtol=1e-2)
    # both well below the camera's angle noise (4 mrad): they use every frame
    assert ekf["rmse_master"][0] < 4e-3 and ekf["late_applied"] > 100
