"""Model error (experiment/model_error.py): the plant's parameters differ from the model's.

The plant is checked against an independent integration: the model's equations with the plant's
parameters, turned into numpy by sympy's lambdify (not through the CasADi bridge the plant is
built with), stepped by the same classical RK4 with the same substeps. Both evaluate the same
formulas in double in a different order, a few ulps per evaluation; over one period (10 RK4
substeps) that stays below 1e-12 relative to the state's size, on any IEEE machine. The
nominal model's step differs from the perturbed plant's by the effect of the perturbation (1e-4
and more here), so the test fails if the plant kept the model's values."""

from __future__ import annotations

import json

import numpy as np
import pytest
import sympy as sp

from dfeif_codegen import cli
from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare, model_error as me
from dfeif_codegen.experiment import scenario as scenario_mod
from dfeif_codegen.experiment.network import Link
from dfeif_codegen.experiment.plant import Plant

ERROR = me.ParamError(relative=(("R", 0.2),), absolute=(("k_d", 0.01),), draw="uniform", spread=(("*", 0.1),))
# the chapter's filter, whose q = 20 covers a 20% parameter error: the held filter at that q is
# over-confident under it (master NEES ~1e5, a divergence) and needs disturbance states
# (tests/test_disturbance.py); what is tested here is the plant's error, not a filter
BASE = dict(model="dc_motor_link", duration=2.0, q=(20.0,), poles=(10.0,), noise_scale=(1.0, 1.25),
            metrics_from=0.5, sensor=(Link(0.8, 4), Link(0.8, 6)), seed=5, reference="seesaw",
            predictor="brunovsky")


def _lambdified(model, params):
    """x' = f(x) + g(x) u with the given parameter vector, as numpy, outside the CasADi bridge."""
    values = dict(zip(model.p, params))
    rhs = (model.f + model.g * model.u).subs(values)
    return sp.lambdify([list(model.x), list(model.u)], list(rhs), "numpy")


def _rk4(f, x, u, ts, substeps):
    h = ts / substeps
    for _ in range(substeps):
        k1 = np.array(f(x, u))
        k2 = np.array(f(x + h / 2 * k1, u))
        k3 = np.array(f(x + h / 2 * k2, u))
        k4 = np.array(f(x + h * k3, u))
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def _check_trajectory(res, cfg):
    flat = ex._flat(cfg.model)
    model = flat.model
    p = cfg.plant_error.values(model, cfg.seed)
    assert p is not None and np.abs(p / flat.param_vector - 1).max() > 0.05
    true, nominal = _lambdified(model, p), _lambdified(model, flat.param_vector)
    ts = res.recording.ts
    worst_true = worst_nominal = 0.0
    for k in range(0, len(res.t) - 1, 7):
        x, u = res.x_true[k], res.recording.u[k]
        scale = np.abs(res.x_true[k + 1]) + 1e-3
        worst_true = max(worst_true, np.max(np.abs(_rk4(true, x, u, ts, cfg.substeps) - res.x_true[k + 1]) / scale))
        worst_nominal = max(worst_nominal,
                            np.max(np.abs(_rk4(nominal, x, u, ts, cfg.substeps) - res.x_true[k + 1]) / scale))
    assert worst_true < 1e-12
    assert worst_nominal > 1e-4
    # the truth's canonical state: the plant's own flat outputs and derivatives (Phi with its parameters)
    phi = sp.lambdify([list(model.x)], list(flat.phi.subs(dict(zip(model.p, p)))), "numpy")
    np.testing.assert_allclose([phi(x) for x in res.x_true[:50]], res.zeta[:50], rtol=1e-12, atol=1e-12)


def test_perturbed_plant_follows_its_own_parameters():
    cfg = ex.Config(**BASE, plant_error=ERROR)
    _check_trajectory(ex.run(cfg), cfg)


def test_perturbed_plant_in_compiled_c(host_cc):
    from dfeif_codegen.check import closed_loop_c

    cfg = ex.Config(**BASE, plant_error=ERROR)
    c = closed_loop_c.run(cfg)
    _check_trajectory(c, cfg)
    py = ex.run(cfg)   # the engines agree as without model error (tests/test_engine_c.py: 1e-9)
    for key, value in py.metrics.items():
        np.testing.assert_allclose(c.metrics[key], value, rtol=1e-9, atol=0, err_msg=key)


def test_zero_error_reproduces_the_exact_model():
    """An error that moves nothing goes through the perturbed path and gives the same run, bit
    for bit in numpy (the same substituted values), to the engines' 1e-9 in C."""
    zero = me.ParamError(absolute=(("R", 0.0),))
    assert zero.active and np.array_equal(zero.values(ex._flat("dc_motor_link").model, 3),
                                          ex._flat("dc_motor_link").param_vector)
    a, b = ex.run(ex.Config(**BASE)), ex.run(ex.Config(**BASE, plant_error=zero))
    for key in a.metrics:
        np.testing.assert_array_equal(a.metrics[key], b.metrics[key], err_msg=key)
    np.testing.assert_array_equal(a.x_true, b.x_true)


def test_draws_are_per_seed_reproducible_and_within_their_bounds():
    model = ex._flat("two_link_arm").model
    spec = me.ParamError(draw="uniform", spread=(("*", 0.2),))
    draws = np.array([spec.values(model, s) for s in range(400)]) / ex._flat("two_link_arm").param_vector - 1
    np.testing.assert_array_equal(spec.values(model, 7), spec.values(model, 7))
    assert np.all(np.abs(draws) <= 0.2) and np.abs(draws).max() > 0.19
    # uniform on [-0.2, 0.2]: mean 0, std 0.2/sqrt(3); the mean of 400 within 4.5 standard errors
    assert np.all(np.abs(draws.mean(axis=0)) < 4.5 * 0.2 / np.sqrt(3) / np.sqrt(400))
    assert np.all(np.abs(draws.std(axis=0) - 0.2 / np.sqrt(3)) < 0.02)
    gauss = me.ParamError(draw="normal", spread=(("*", 0.05),))
    g = np.array([gauss.values(model, s) for s in range(400)]) / ex._flat("two_link_arm").param_vector - 1
    assert np.abs(g).max() <= 0.15 and np.all(np.abs(g.std(axis=0) - 0.05) < 0.01)
    # a parameter's draw does not depend on which others are drawn: runs stay paired
    only = me.ParamError(draw="uniform", spread=(("l1", 0.2),))
    i = [q.name for q in model.parameters].index("l1")
    assert only.values(model, 9)[i] == spec.values(model, 9)[i]


@pytest.mark.parametrize("draw, spread, second", [("uniform", (("*", 0.2),), 1 / 3),
                                                    ("normal", (("m2", 0.05), ("l1", 0.1)), None)])
def test_design_averages_any_quadratic_to_its_expectation(draw, spread, second):
    """`codegen scenario` calibrates on ParamError.design's fixed errors: the average over them
    of any quadratic in the relative change δ equals its expectation under the draw, a closed
    form: E[c + bᵀδ + δᵀAδ] = c + Σ A_ii E[δ_i²] (mean 0, independent). Exact up to the rounding
    of a few dozen additions and the quadrature of the truncated normal's variance (1e-12 and
    1e-13 relative: 1e-10 holds on any IEEE machine)."""
    grid = np.linspace(-3.0, 3.0, 6001)       # the truncated normal's variance by Simpson's rule
    simpson = np.ones(grid.size)               # (error ~h^4 ~ 1e-13: the code's closed form is
    simpson[1:-1:2], simpson[2:-1:2] = 4.0, 2.0    # checked against it, not copied)
    w = simpson * np.exp(-grid ** 2 / 2)
    truncated = float(np.sum(grid ** 2 * w) / np.sum(w))
    flat = ex._flat("two_link_arm")
    spec = me.ParamError(relative=(("m1", 0.1),), draw=draw, spread=spread)
    design = spec.design(flat.model)
    rel = np.array([e.values(flat.model, 0) for e in design]) / flat.param_vector - 1
    assert all(e.draw == "none" for e in design) and len(design) >= 8
    var = np.zeros(len(flat.params))
    for name, s in spread:
        for i, q in enumerate(flat.model.parameters):
            if name in ("*", q.name):
                var[i] = s ** 2 * (second if second is not None else truncated)
    delta = rel - np.where(np.array([q.name for q in flat.model.parameters]) == "m1", 0.1, 0.0)
    rng = np.random.default_rng(3)
    A, b, c = rng.standard_normal((len(var),) * 2), rng.standard_normal(len(var)), 1.7
    g = c + delta @ b + np.einsum("ki,ij,kj->k", delta, A, delta)
    assert g.mean() == pytest.approx(c + np.sum(np.diag(A) * var), rel=1e-10)
    assert np.all(np.abs(delta[:, var == 0]) < 1e-15)    # without a spread: at the offset (p(1 + r)/p - 1 - r rounds)


@pytest.mark.parametrize("draw, edge", [("uniform", 1.0), ("normal", 2.0)])
def test_corners_put_every_parameter_pair_at_each_edge(draw, edge):
    """`codegen scenario`'s pole check (experiment/pole_margin.py) closes its loops on
    ParamError.corners: every perturbed parameter at offset ± edge × spread (the uniform draw's
    bounds, the normal's 95% points), each at each sign in half the rows, each pair of
    parameters at each of its four sign pairs equally often, the all-low and all-high plants
    among them; a parameter without a spread stays at its offset. Exact but for p(1 + r)/p - 1
    rounding (1e-15 relative; 1e-12 holds on any IEEE machine)."""
    flat = ex._flat("two_link_arm")
    names = [q.name for q in flat.model.parameters]
    spec = me.ParamError(relative=(("m1", 0.1),), draw=draw, spread=(("m2", 0.05), ("l1", 0.1), ("R", 0.15)))
    corners = spec.corners(flat.model)
    rel = np.array([e.values(flat.model, 0) for e in corners]) / flat.param_vector - 1
    assert all(e.draw == "none" for e in corners) and len(corners) == 16    # 8 rows (3 parameters) and their negatives
    moved = [names.index(p) for p in ("m2", "l1", "R")]
    signs = rel[:, moved] / (edge * np.array([0.05, 0.1, 0.15]))
    np.testing.assert_allclose(np.abs(signs), 1.0, rtol=1e-12)
    signs = np.sign(signs)
    for a in range(3):
        assert np.sum(signs[:, a] > 0) == 8
        for b in range(a + 1, 3):
            pairs = {(x, y): int(np.sum((signs[:, a] == x) & (signs[:, b] == y))) for x in (-1, 1) for y in (-1, 1)}
            assert set(pairs.values()) == {4}, pairs
    assert any(np.all(r == 1) for r in signs) and any(np.all(r == -1) for r in signs)
    others = [i for i in range(len(names)) if i not in moved]
    offsets = np.where(np.array(others) == names.index("m1"), 0.1, 0.0)
    np.testing.assert_allclose(rel[:, others], np.broadcast_to(offsets, (len(corners), len(others))), atol=1e-12)


def test_filters_keep_the_nominal_model():
    """The EKF/UKF predict with the model's parameters whatever the plant's."""
    flat = ex._flat("dc_motor_link")
    ekf = compare.filter_of("dc_motor_link", 0.01, (20.0,), 10, "ekf")
    x, u = np.array([0.3, -1.0, 0.5]), np.array([2.0])
    nominal = Plant(flat.model, 0.01, 10).step(x, u)
    perturbed = Plant(flat.model, 0.01, 10, params=ERROR.values(flat.model, 0)).step(x, u)
    predicted = np.array(ekf.model.step_sx(x, u)).ravel()
    np.testing.assert_allclose(predicted, nominal, rtol=1e-12, atol=1e-14)
    assert np.abs(predicted - perturbed).max() > 1e-4
    res = ex.run(ex.Config(**BASE, plant_error=ERROR))
    assert "failed" not in compare.evaluate(res, "ekf")


def test_ekf_and_ukf_run_at_their_own_q():
    """A scenario's q_ekf is the EKF's and UKF's q on the recordings (a held filter with
    disturbance states is consistent at a q far below theirs): each equals the same filter on a
    recording whose own q is q_ekf (the same arithmetic: 1e-12), and differs from it at the
    loop's q by far more (q 4x lower: 0.3-0.6x the RMSE on this exact-model loop, measured; under
    ERROR the EKF at q = 5 diverges, so the plant is the model's here)."""
    import dataclasses

    res = ex.run(ex.Config(**BASE, q_ekf=(5.0,)))
    as_own = dataclasses.replace(res, recording=dataclasses.replace(res.recording, q=(5.0,)),
                                 config=dataclasses.replace(res.config, q_ekf=()))
    at_loop_q = dataclasses.replace(res, config=dataclasses.replace(res.config, q_ekf=()))
    for kind in ("ekf", "ukf"):
        got = compare.evaluate(res, kind)["rmse_master"]
        np.testing.assert_allclose(got, compare.evaluate(as_own, kind)["rmse_master"], rtol=1e-12)
        assert np.abs(got / compare.evaluate(at_loop_q, kind)["rmse_master"] - 1).max() > 1e-3


def _write(tmp_path, text):
    path = tmp_path / "s.toml"
    path.write_text("[scenario]\nduration = 1.0\nruns = 2\nmetrics_from = 0.2\nreferences = [\"seesaw\"]\n"
                    "fusion = [\"difference\"]\nbaselines = []\n[[grid]]\nd = [0, 0]\n" + text)
    return str(path)


BAD = {
    "unknown key": ("[model_error]\nrelatve = { R = 0.1 }\n", None, ["s.toml:11", "model_error.relatve", "unknown"]),
    "unknown parameter": ("[model_error]\nrelative = { Rs = 0.1 }\n", None, ["s.toml:11", "'Rs'", "k_e"]),
    "unknown in params": ("[model_error]\nspread = 0.1\nparams = [\"J\", \"JJ\"]\n", None, ["s.toml:12", "'JJ'"]),
    "sub-table line": ("[model_error.absolute]\nR = 0.1\nRx = 0.2\n", None, ["s.toml:12", "'Rx'"]),
    "bad draw": ("[model_error]\ndraw = \"gauss\"\nspread = 0.1\n", None, ["s.toml:11", "model_error.draw"]),
    "draw without spread": ("[model_error]\ndraw = \"normal\"\n", None, ["model_error.spread", "needs a spread"]),
    "sign flip": ("[model_error]\nrelative = { R = -0.9 }\nspread = 0.2\n", None, ["s.toml:11", "R", "sign"]),
    "not a number": ("[model_error]\nrelative = { R = \"x\" }\n", None, ["model_error.relative", "number"]),
    "option": ("", "J=", ["--param-error", "'J='"]),
    "option name": ("", "Jx=0.1", ["--param-error", "'Jx'"]),
    "option negative": ("", "-0.1", ["--param-error", "spread >= 0"]),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_model_error_exits_2(case, tmp_path, capsys):
    text, option, words = BAD[case]
    argv = ["simulate", "dc_motor_link", "--scenario", _write(tmp_path, text), "--engine", "reference", "--quiet"]
    code = cli.main(argv + (["--param-error", option] if option is not None else []))
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    for word in words:
        assert word in err[0], (word, err[0])


def test_simulate_prints_the_model_error_block(tmp_path, capsys):
    path = _write(tmp_path, "[model_error]\nrelative = { R = 0.2 }\n")
    js = tmp_path / "o.json"
    code = cli.main(["simulate", "dc_motor_link", "--scenario", path, "--engine", "reference", "--quiet",
                     "--json", str(js), "--param-error", "0.1", "--seed", "4"])
    out = capsys.readouterr().out
    assert code == 0
    flat = ex._flat("dc_motor_link")
    spec = me.from_option("0.1")                 # the option replaces the scenario's offsets
    values = np.array([spec.values(flat.model, s) for s in (4, 5)])
    assert "every parameter uniform +-10%" in out and "R +20%" not in out
    for i, q in enumerate(flat.model.parameters):
        line = next(x for x in out.splitlines() if x.split()[:1] == [q.name])
        assert f"{values[:, i].min():.5g} / {values[:, i].mean():.5g} / {values[:, i].max():.5g}" in line
    settings = json.loads(js.read_text())["settings"]["model_error"]
    np.testing.assert_array_equal(settings["per_seed"]["4"], values[0])
    sc = scenario_mod.load(path)
    assert sc.model_error == me.ParamError(relative=(("R", 0.2),))
    with pytest.raises(ScenarioError):
        me.from_option("R=abc")


def test_paired_ratios_under_model_error(tmp_path):
    """simulate --filters with model error: Table VII's ratios are df / EKF per seed, averaged with
    a Student-t interval, recomputed here from compare.evaluate on each seed's recording (numpy
    engine, the same arithmetic in the same order: 1e-12)."""
    import dfeif_codegen as dc
    from dfeif_codegen.experiment import simulate

    path = _write(tmp_path, "[[grid]]\nd = [3, 5]\np = 0.8\n")
    out = tmp_path / "r.json"
    result = dc.simulate("dc_motor_link", scenario=path, runs=3, filters="df,ekf,brunovsky", engine="reference",
                         json_path=str(out), quiet=True, workers=1, param_error="0.2",
                         predictor="brunovsky")
    assert result.ok
    doc = json.loads(out.read_text())
    sc = scenario_mod.load(path)
    sc.model_error = me.from_option("0.2")
    for ri, row in enumerate(sc.grid):
        runs = [ex.run(simulate.make_config(sc, "dc_motor_link", 2, 32, "seesaw", row, "replay", "difference", s,
                                               "brunovsky"))
                for s in range(3)]
        ratio = [compare.evaluate(r, "df")["rmse_master"] / compare.evaluate(r, "ekf")["rmse_master"] for r in runs]
        mean, half = simulate.mean_ci(ratio)
        got = next(e for e in doc["paired"] if e["row"] == ri and e["filter"] == "ekf" and e["numerator"] == "df")
        np.testing.assert_allclose(got["mean"], mean, rtol=1e-12)
        np.testing.assert_allclose(got["ci95"], half, rtol=1e-12)
        assert got["pairs"] == 3
        same = next(e for e in doc["paired"] if e["row"] == ri and e["filter"] == "brunovsky")
        np.testing.assert_allclose(same["mean"], 1.0, rtol=1e-12)   # today the df filter is the chapter's
        # each candidate is also paired with the EKF: the chapter's filter / EKF, per seed
        theirs = [compare.evaluate(r, "brunovsky")["rmse_master"] / compare.evaluate(r, "ekf")["rmse_master"]
                  for r in runs]
        cand = next(e for e in doc["paired"] if e["row"] == ri and e["numerator"] == "brunovsky")
        assert cand["filter"] == "ekf" and cand["pairs"] == 3
        np.testing.assert_allclose(cand["mean"], simulate.mean_ci(theirs)[0], rtol=1e-12)
    text = result.report()
    assert "Table VII" in text and "every parameter uniform +-20%" in text and "seesaw" in text


def test_absolute_offsets_are_checked_like_relative_ones():
    """L = 0.005 H: an offset of -0.004 leaves 0.001 (accepted, and the plant's L is exactly
    that); -0.005 makes it 0 and -0.01 flips it (refused, naming the field); with a +-50% draw
    -0.004 can reach 0.0025 - 0.004 < 0 (refused)."""
    flat = ex._flat("dc_motor_link")
    names = [q.name for q in flat.model.parameters]
    ok = me.ParamError(absolute=(("L", -0.004),))
    ok.check(flat.model, lambda key: key)
    assert ok.values(flat.model, 0)[names.index("L")] == pytest.approx(0.001, rel=1e-12)
    for spec in (me.ParamError(absolute=(("L", -0.005),)), me.ParamError(absolute=(("L", -0.01),)),
                 me.ParamError(absolute=(("L", -0.004),), draw="uniform", spread=(("*", 0.5),))):
        with pytest.raises(ScenarioError, match=r"^absolute\.L: .*zero or sign flip"):
            spec.check(flat.model, lambda key: key)


def test_a_parameter_given_twice_in_the_option_is_refused():
    with pytest.raises(ScenarioError, match="--param-error: R=0.1,R=0.2: R is given twice"):
        me.from_option("R=0.1,R=0.2")
    assert me.from_option("R=0.1,J=0.2").relative == (("J", 0.2), ("R", 0.1))
