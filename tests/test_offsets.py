"""The comparison's `offsets` filter (reference/offsets.py): the held filter estimating relative
parameter offsets, with the covariance moved by Φ_k = [[Φ₀, S_k], [0, I]] taken at the master's
estimate."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dfeif_codegen import cli
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare, model_error as me
from dfeif_codegen.experiment.network import Link
from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.reference.offsets import OffsetModel, Offsets
from test_model_error import _write

MODEL = "dc_motor_link"
# loops closed by the chapter's filter, whose q = 20 covers a 20% parameter error (test_model_error.py)
BASE = dict(model=MODEL, duration=3.0, q=(20.0,), poles=(10.0,), noise_scale=(1.0, 1.25), metrics_from=0.5,
            seed=3, reference="sinusoid", predictor="brunovsky")
ON_TIME = (Link(0.0, 0), Link(0.0, 0))


def test_sensitivity_column_equals_a_finite_difference():
    """S_k = ∂ζ⁺/∂δ (CasADi AD of the held step) against a central difference of the step itself,
    taken as the master takes it: at its own estimate, so the point moves with δ.
    The difference's truncation is h² ζ'''/6 and its rounding ε |ζ⁺| / h: at h = 1e-5 both are
    below 1e-8 of the column's scale on any IEEE machine."""
    flat = ex._flat(MODEL)
    model = OffsetModel(flat, 0.01, (1.0,), Offsets(("R", "k_e", "m"), (0.2,)))
    x = np.array([0.4, -1.2, 3.0, 0.05, -0.1, 0.15])
    u = np.array([2.5])
    w = model.input(u, x)
    Phi = np.array(model.transition_sx(w))
    h = 1e-5
    for j in range(3):
        dx = np.zeros(6)
        dx[3 + j] = h
        fd = (np.array(model.step_sx(x + dx, model.input(u, x + dx)))
              - np.array(model.step_sx(x - dx, model.input(u, x - dx)))).ravel()[:3] / (2 * h)
        scale = max(np.abs(fd).max(), 1e-12)
        np.testing.assert_allclose(Phi[:3, 3 + j], fd, rtol=0, atol=1e-7 * scale)
        assert np.abs(fd).max() > 1e-4          # the offsets move the state: a column worth testing
    np.testing.assert_array_equal(Phi[:3, :3], predictors.held_constants(flat, 0.01).E)
    np.testing.assert_array_equal(Phi[3:], np.hstack([np.zeros((3, 3)), np.eye(3)]))


def test_a_node_steps_its_own_state_linearized_at_the_masters_offsets():
    """A node's mean moves its own ζ with the broadcast point's parameters plus the sensitivity
    times its own offsets' distance from the point's, ζ⁺ = step(ζ, δ_p) + S_k (δ - δ_p): the
    linearization its covariance already uses, so a node whose δ (observed weakly from one camera)
    strays far never evaluates the step at non-physical parameters (the master, at δ = δ_p, steps
    exactly: test above). Checked: two nodes differ by exactly S_k (δ_a - δ_b) (to rounding of the
    sums, 1e-12 of ζ's scale), even where one node's δ would flip the parameters' sign; each keeps
    its own δ (constant offsets)."""
    flat = ex._flat(MODEL)
    model = OffsetModel(flat, 0.01, (1.0,), Offsets(("R", "m"), (0.2,)))
    point = np.array([0.3, -0.8, 2.0, 0.1, -0.05])
    w = model.input(np.array([1.5]), point)
    S = np.array(model.transition_sx(w))[:3, 3:]
    zeta = np.array([0.35, -0.7, 1.0])
    da, db = np.array([0.4, 0.3]), np.array([-1.6, -1.2])      # b: R and m of the wrong sign
    a = np.array(model.step_sx(np.concatenate([zeta, da]), w)).ravel()
    b = np.array(model.step_sx(np.concatenate([zeta, db]), w)).ravel()
    np.testing.assert_allclose(a[:3] - b[:3], S @ (da - db), rtol=0,
                               atol=1e-12 * max(np.abs(a).max(), np.abs(b).max(), np.abs(S @ db).max()))
    np.testing.assert_array_equal(a[3:], da)
    assert np.abs(S).max() > 1e-4        # the offsets do move the step: the test can fail


def _centralized(rec, filt, offsets_model):
    """One filter taking every node's frame in turn (the oracle the fusion must equal)."""
    x, P = offsets_model.start(rec.master_x0, rec.master_P0)
    X = np.zeros((rec.ref.shape[0], len(x)))
    for k in range(rec.ref.shape[0]):
        for i in range(rec.nodes):
            if rec.gamma[i, k]:
                x, P = filt.update(x, P, rec.z[i, k], np.atleast_2d(rec.R[i]))
        X[k] = x
        x, P = filt.predict(x, P, offsets_model.input(rec.u[k], x))
    return X


def test_master_equals_the_centralized_filter_without_delays():
    """Every frame on time and every packet fused: the information-difference master of the
    offset filters equals one filter taking all frames, because the nodes and the master move
    their covariances by the same Φ_k (taken at the master's estimate). The two differ by
    rounding through the information matrices (condition numbers near 1e10 here: the offsets'
    prior against the position's millirad), so the bound is 1e-8 of each state's spread
    rather than ε."""
    offsets = Offsets(("R", "m"), (0.2,), 1e-6)
    res = ex.run(ex.Config(**BASE, sensor=ON_TIME, plant_error=me.ParamError(relative=(("R", 0.2), ("m", -0.1)))))
    rec = res.recording
    assert rec.gamma.all()
    out = compare.run_on_recording(rec, compare.OFFSETS, offsets=offsets)
    filt = compare.filter_of(MODEL, float(rec.ts), tuple(rec.q), 10, compare.OFFSETS, offsets=offsets)
    X = _centralized(rec, filt, filt.model)
    spread = np.sqrt(np.diagonal(out["P"], axis1=1, axis2=2))
    assert np.all(np.abs(out["x"] - X[:, :3]) <= 1e-8 * spread)     # measured: 7e-12


def test_offsets_learn_a_fixed_parameter_error():
    """The plant's R is 20% above the model's: the filter estimating R's offset ends near +0.2
    (within 3 of its own standard deviations, which is below 0.05), and its acceleration error is
    far below that of the chapter's filter which closed the loop, while the same filter with R
    pinned to the model's (a prior of 1e-9) diverges on this recording."""
    res = ex.run(ex.Config(**{**BASE, "duration": 6.0}, sensor=ON_TIME,
                           plant_error=me.ParamError(relative=(("R", 0.2),))))
    rec = res.recording
    offsets = Offsets(("R",), (0.3,))
    filt = compare.filter_of(MODEL, float(rec.ts), (1.0,), 10, compare.OFFSETS, offsets=offsets)
    x, P = filt.model.start(rec.master_x0, rec.master_P0)
    for k in range(rec.ref.shape[0]):
        for i in range(rec.nodes):
            x, P = filt.update(x, P, rec.z[i, k], np.atleast_2d(rec.R[i]))
        x, P = filt.predict(x, P, filt.model.input(rec.u[k], x))
    sigma = np.sqrt(P[3, 3])
    assert sigma < 0.05 and abs(x[3] - 0.2) < 3 * sigma, (x[3], sigma)
    with_offsets = compare.evaluate(res, compare.OFFSETS, offsets=Offsets(("R",), (0.3,), 0.0, (1.0,)))
    without = compare.evaluate(res, compare.OFFSETS, offsets=Offsets(("R",), (1e-9,), 0.0, (1.0,)))
    chapter = compare.evaluate(res, "df")            # the loop's own filter: Brunovsky, q = 20
    assert "diverged" in without["failed"]           # the held filter at q = 1 cannot ignore the error
    assert with_offsets["rmse_master"][2] < 0.1 * chapter["rmse_master"][2]   # measured: 0.0096 against 2.79


BAD = {
    "unknown key": ("[offsets]\nparams = [\"R\"]\nstdd = 0.1\n", ["s.toml:12", "offsets.stdd", "unknown"]),
    "unknown parameter": ("[offsets]\nparams = [\"R\", \"Rx\"]\n", ["s.toml:11", "offsets.params", "Rx", "k_e"]),
    "no params": ("[offsets]\nstd = 0.1\n", ["offsets.params", "non-empty"]),
    "repeated": ("[offsets]\nparams = [\"R\", \"R\"]\n", ["offsets.params", "distinct"]),
    "bad std": ("[offsets]\nparams = [\"R\", \"m\"]\nstd = [0.1, 0.2, 0.3]\n", ["s.toml:12", "offsets.std"]),
    "negative q": ("[offsets]\nparams = [\"R\"]\nq = -1\n", ["s.toml:12", "offsets.q", ">= 0"]),
    "chains_q": ("[offsets]\nparams = [\"R\"]\nchains_q = [1, 2]\n", ["offsets.chains_q", "needs 1 value", "got 2"]),
    "no table": ("", ["--filters offsets", "no [offsets] table"]),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_offsets_exit_2_before_any_run(case, tmp_path, capsys):
    text, words = BAD[case]
    code = cli.main(["simulate", MODEL, "--scenario", _write(tmp_path, text), "--engine", "reference", "--quiet",
                     "--filters", "df,offsets"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    for word in words:
        assert word in err[0], (word, err[0])


def test_simulate_records_the_offsets_it_ran(tmp_path):
    """End to end through the CLI: the JSON names the [offsets] spec the filter ran with (read
    back from the scenario file) and pairs the filter with the held one on the same seed."""
    out = tmp_path / "o.json"
    table = "[offsets]\nparams = [\"R\", \"m\"]\nstd = [0.2, 0.1]\nq = 1e-6\nchains_q = 2.0\n"
    code = cli.main(["simulate", MODEL, "--scenario", _write(tmp_path, table), "--engine", "reference", "--quiet",
                     "--runs", "1", "--filters", "df,offsets", "--json", str(out)])
    doc = json.loads(out.read_text())
    assert code == 0
    assert doc["settings"]["offsets"] == {"params": ["R", "m"], "std": [0.2, 0.1], "q": 1e-6, "chains_q": [2.0]}
    (pair,) = [p for p in doc["paired"] if p["filter"] == "offsets"]
    assert pair["pairs"] == 1 and all(np.isfinite(pair["mean"]))


def test_calibration_refuses_offsets_the_filter_cannot_run():
    """`codegen scenario --offsets`: when the offset filter fails on the calibration's loops at every
    scale of its chains' q (the match reports every scale lost), the calibration stops with one
    line naming --offsets and the parameters, rather than the closed-loop message the held
    filter's q gets (no loop was lost: the loops are already recorded)."""
    from dfeif_codegen.errors import ScenarioError
    from dfeif_codegen.experiment import offsets_calibration
    from dfeif_codegen.experiment.nees_match import NO_LOOP

    def lost_everywhere(q, log, nees):
        return q, log + [f"master NEES: {NO_LOOP} lost a closed loop; q kept from the residual"]

    with pytest.raises(ScenarioError) as err:
        offsets_calibration.chains_q([1.0], [], Offsets(("R", "m"), (0.1,)), lost_everywhere, [])
    assert str(err.value).startswith("--offsets R,m: the offset filter failed") and "\n" not in str(err.value)
