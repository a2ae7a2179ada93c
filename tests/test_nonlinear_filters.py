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

import dfeif_codegen as dc
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


@pytest.fixture(scope="module")
def motor_run():
    from dfeif_codegen.experiment import scenario, simulate
    sc = scenario.load("paper")
    cfg = simulate.make_config(sc, "dc_motor_link", 2, 32, "sinusoid", sc.grid[3], "replay", "difference", 4)
    return ex.run(ex.Config(**{**cfg.__dict__, "duration": 3.0}))


def test_derivative_free_filter_through_the_same_driver(motor_run):
    """The cost column runs the derivative-free filter through the EKF's driver and call path
    (compare.CanonicalModel): on a nonlinear closed-loop recording with late frames it must be the
    derivative-free filter itself, nodes and master, to 1e-9 relative (the same linear Kalman
    filter: numpy Joseph form against one CasADi function of the same algebra)."""
    rec = motor_run.recording
    assert rec.late_step.size > 100
    out = compare.run_on_recording(rec, "df")
    for mine, theirs in ((out["node_x"], rec.node_x), (out["node_P"], rec.node_P), (out["x"], rec.x), (out["P"], rec.P)):
        np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-9 * np.abs(theirs).max())
    assert out["applied"] == int(rec.late_applied.sum())


def test_compiled_filters_give_the_interpreted_results(motor_run):
    """The compiled predict and update (physical.compiled_function: CasADi's C, -O1
    -ffp-contract=off) against CasADi's interpreter on a nonlinear recording with late frames, for
    the three filters: equal to 1e-12 relative. Both evaluate the same sequence of IEEE double
    operations (no fused multiply-add, which C forbids reordering without fast-math; sin, cos and
    sqrt from the one libm loaded in the process), so they agree to the bit on x86-64 and aarch64;
    1e-12 leaves room for a compiler keeping intermediates in extended precision (x87), a
    rounding-level difference per operation that 300 steps of a stable filter do not amplify
    beyond ~1e-14."""
    rec = motor_run.recording
    assert rec.late_step.size > 100
    for kind in ("df", "ekf", "ukf"):
        a = compare.run_on_recording(rec, kind)
        b = compare.run_on_recording(rec, kind, compiled=True)
        for key in ("node_x", "node_P", "x", "P"):
            np.testing.assert_allclose(b[key], a[key], rtol=0, atol=1e-12 * np.abs(a[key]).max(), err_msg=f"{kind} {key}")
        assert b["applied"] == a["applied"] > 100
        filt = compare.filter_of(rec.model, float(rec.ts), tuple(np.asarray(rec.q, float)), 10, kind, True)
        assert filt.operations() == compare.filter_of(rec.model, float(rec.ts), tuple(np.asarray(rec.q, float)),
                                                      10, kind).operations()


def test_simulate_filters_equal_the_compare_path(tmp_path):
    """`simulate(filters="df,ekf,ukf")` reports, per row, the mean over seeds of compare.evaluate
    on each seed's closed-loop recording: recomputed here run by run (numpy engine), equal to 1e-12
    relative (the same arithmetic, averaged in the same seed order; only the C engine's closed
    loop against numpy's differs, by rounding, ~1e-15)."""
    import json

    from dfeif_codegen.experiment import scenario, simulate
    path = tmp_path / "s.toml"
    path.write_text(TINY)
    out = tmp_path / "r.json"
    result = dc.simulate("dc_motor_link", scenario=str(path), runs=2, filters="df,ekf,ukf", json_path=str(out),
                         quiet=True, workers=1)
    assert result.ok
    doc = json.loads(out.read_text())
    assert doc == json.loads(result.to_json())
    tables = {t["method"]: t for t in doc["tables"]}
    assert set(tables) == {"replay", "df-replay", "ekf-replay", "ukf-replay"}
    assert tables["ekf-replay"]["filter"] == "ekf"
    sc = scenario.load(str(path))
    for ri, row in enumerate(sc.grid):
        res = [ex.run(simulate.make_config(sc, "dc_motor_link", 2, 32, "sinusoid", row, "replay", "difference", s))
               for s in (0, 1)]
        for kind in ("df", "ekf", "ukf"):
            mine = np.mean([compare.evaluate(r, kind)["rmse_master"] for r in res], axis=0)
            theirs = tables[f"{kind}-replay"]["rows"][ri]["rmse_master"]["mean"]
            np.testing.assert_allclose(theirs, mine, rtol=1e-12)
            nees = np.mean([compare.evaluate(r, kind)["nees_master"] for r in res], axis=0).mean()
            assert tables[f"{kind}-replay"]["rows"][ri]["nees_master"]["mean"] == pytest.approx(nees, rel=1e-12)
        # the derivative-free filter through the driver is the closed loop's own filter
        np.testing.assert_allclose(tables["df-replay"]["rows"][ri]["rmse_master"]["mean"],
                                   tables["replay"]["rows"][ri]["rmse_master"]["mean"], rtol=1e-9)
    assert set(doc["settings"]["operations"]) == {"df", "ekf", "ukf"}


def test_unknown_filter_is_bad_input(tmp_path):
    from dfeif_codegen import cli
    path = tmp_path / "s.toml"
    path.write_text(TINY)
    assert cli.main(["simulate", "--scenario", str(path), "--quiet", "--filters", "df,kf"]) == 2


TINY = """
[scenario]
name = "tiny"
duration = 1.5
runs = 2
references = ["sinusoid"]
oosm = ["replay"]
fusion = ["difference"]
baselines = []
[filter]
q = 20.0
p0_std = [0.05, 0.1, 1.0]
[control]
poles = 10.0
[[nodes]]
noise_scale = 1.0
[[nodes]]
noise_scale = 1.25
[[grid]]
d = [0, 0]
p = 0.0
[[grid]]
d = [8, 10]
p = 0.8
"""
