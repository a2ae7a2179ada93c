"""The public Python API over the generated C (`dc.load`): the README's example run exactly as
written and compared with the numpy reference, error codes as exceptions, shapes, the cache."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np
import pytest

import dfeif_codegen as dc
from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic.sampling import held_sampling
from dfeif_codegen.reference.control import FlatController, hurwitz_gains
from dfeif_codegen.reference.fusion import Master
from dfeif_codegen.reference.node import NodeFilter
from dfeif_codegen.symbolic import flatness

README = Path(__file__).resolve().parents[1] / "README.md"

# Norm-wise relative error bound for the README example against the reference. Both sides run
# the same IEEE double operations up to reassociation (CasADi's common subexpressions, the C's
# Cholesky against numpy's solves, the C's centred storage of the flat output): each step is
# backward stable with errors of a few ulps (1.1e-16) times the dimension, and three steps of a
# filter whose covariance has condition number below 1e7 (P0 here) keep the forward error far
# below 1e-12 on any IEEE-754 machine; no BLAS kernel is involved at this size on the C side.
RTOL = 1e-12


def readme_blocks() -> list[str]:
    section = README.read_text().split("\n## From Python\n", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, re.S)


def rel(got, want) -> float:  # noqa: D103
    got, want = np.asarray(got, float), np.asarray(want, float)
    assert got.shape == want.shape
    return float(np.linalg.norm(got - want) / np.linalg.norm(want))


@pytest.fixture
def in_tmp(tmp_path, monkeypatch, host_cc):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("DFEIF_CODEGEN_CACHE", str(tmp_path / "cache"))
    return tmp_path


def test_readme_example_runs_as_written_and_matches_the_reference(in_tmp):
    blocks = readme_blocks()
    assert len(blocks) == 3 and "dc.load(module)" in blocks[1]
    ns: dict = {}
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        for block in blocks[:2]:
            exec(compile(block, str(README), "exec"), ns)
    assert printed.getvalue() == "dc_motor_link_node_predict: ERR_SEQUENCE\n"
    assert (in_tmp / "out" / "dc_motor_link" / "dc_motor_link.h").is_file()

    # the same calls on the numpy reference
    flat = flatness.derive(dc.load_model("dc_motor_link"))
    ts, x0, P0, R, q = 0.01, ns["x0"], ns["P0"], ns["R"], ns["q"]
    node = NodeFilter(flat, ts, q, R, x0, P0, max_lag=32, oosm="replay", predictor="held")
    master = Master(flat, ts, q, x0, P0, n_nodes=2, rule="difference", max_lag=32, predictor="held")
    gains = hurwitz_gains(3, 5.0)
    ctrl = FlatController(flat, gains=gains, held=held_sampling(flat, ts))   # the held build's law
    for k, z in enumerate(ns["frames"]):
        node.update(z, gamma=k != 1)
        if k == 2:
            assert node.update_delayed(ns["frames"][1], lag=1)
        master.fuse([node.packet(), None])
        u, v = ctrl(master.x, ns["flags"])
        node.predict(u)
        master.predict(u)

    assert rel(ns["gains"], gains) < RTOL
    assert rel(ns["u"], u) < RTOL and rel(ns["v"], v) < RTOL
    assert rel(ns["x_node"], node.x) < RTOL and rel(ns["P_node"], node.P) < RTOL
    x_m, P_m = ns["master"].estimate()          # after predict: the master's prediction
    assert rel(x_m, master.x_prior) < RTOL and rel(P_m, master.P_prior) < RTOL
    assert ns["node"].health() == {"updates": 2, "drops": 1, "late_applied": 1, "late_rejected": 0, "outliers": 0}


def test_readme_simulate_example_returns_the_tables_as_data(in_tmp):
    """The README's `dc.simulate` block, run as written: its tables are data, and their rows are
    the mean over the seeds of the numpy reference's runs of the same configurations (the C engine
    runs the same IEEE operations on the same draws; what differs is the order of a few sums, so
    1e-9 relative holds on any IEEE-754 machine for a closed loop of 2,000 steps that does not
    diverge), and its report and JSON say the same numbers."""
    import json

    from dfeif_codegen.experiment import closed_loop as ex
    from dfeif_codegen.experiment import scenario
    from dfeif_codegen.experiment.plan import make_config

    block = readme_blocks()[2]
    assert "dc.simulate(" in block
    ns: dict = {}
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(block, str(README), "exec"), ns)
    assert printed.getvalue() == "(6, 3) (6,) True\n"
    table, result = ns["table"], ns["result"]
    assert [t.method for t in result.tables] == ["replay", "discard", "as-current"]
    sc = scenario.load("paper")
    for ri in (0, len(sc.grid) - 1):
        runs = [ex.run(make_config(sc, "dc_motor_link", 2, 32, "sinusoid", sc.grid[ri], "replay", "difference", s))
                for s in (0, 1)]
        want = np.mean([r.metrics["rmse_master"] for r in runs], axis=0)
        np.testing.assert_allclose(ns["rmse"][ri], want, rtol=1e-9)
        assert ns["nees"][ri] == pytest.approx(np.mean([r.metrics["nees_master"] for r in runs]), rel=1e-9)
    assert f"{ns['rmse'][0][0]:.3e}" in ns["text"]
    doc = json.loads(result.to_json())
    assert doc["tables"][0]["rows"][0]["rmse_master"]["mean"] == table.rows[0]["rmse_master"]["mean"]
    assert doc["settings"]["runs"] == 2 and doc["failures"] == []


@pytest.fixture(scope="module")
def lib(tmp_path_factory, host_cc):
    tmp = tmp_path_factory.mktemp("api")
    module = dc.build("dc_motor_link", tmp / "out")
    return dc.load(module, cache=tmp / "cache")


def test_error_codes_become_named_exceptions_and_leave_the_state(lib):
    from dfeif_codegen.check import loader

    node = lib.Node([0.1, 0, 0], np.eye(3) * 1e-2, [[1e-6]], [1.0])
    node.update([0.1])
    before = node.estimate()
    with pytest.raises(loader.LagError, match=r"^dc_motor_link_node_update_delayed: ERR_LAG \(lag 3: the window "
                                              r"is 1\.\.32 steps back") as info:
        node.update_delayed([0.1], lag=3)            # older than the node's first step
    assert isinstance(info.value, dc.CError) and info.value.code == -2
    with pytest.raises(loader.SequenceError, match="dc_motor_link_node_update: ERR_SEQUENCE"):
        node.update([0.1])                           # twice in one step
    after = node.estimate()
    assert all(np.array_equal(a, b) for a, b in zip(before, after))
    assert node.health()["late_rejected"] == 1
    with pytest.raises(loader.ArgError, match="dc_motor_link_node_init: ERR_ARG"):
        lib.Node([0.1, 0, 0], np.eye(3), [[1e-6]], [-1.0])      # q < 0
    with pytest.raises(loader.NonFiniteError, match="dc_motor_link_node_predict: ERR_NONFINITE"):
        node.predict([np.nan])


def test_shapes_are_checked_before_the_call(lib):
    with pytest.raises(ValueError, match=r"dc_motor_link Node: R: expected shape \(1, 1\), got \(1,\)"):
        lib.Node([0.1, 0, 0], np.eye(3), [1e-6], [1.0])
    master = lib.Master([0, 0, 0], np.eye(3), [1.0])
    with pytest.raises(ValueError, match="expected 2 entries"):
        master.fuse([None])
    with pytest.raises(ValueError, match="control: flags: expected shape"):
        lib.control(np.zeros(3), np.zeros(3), np.ones(3))


def test_control_matches_the_reference_at_other_parameters(lib):
    """The params argument reaches the C: u at a doubled inertia, against the reference's G and F."""
    flat = flatness.derive(dc.load_model("dc_motor_link"))
    params = flat.param_vector.copy()
    params[[q.name for q in flat.model.parameters].index("J")] *= 2
    x, flags, gains = np.array([0.3, -0.2, 1.5]), np.array([0.5, 0.1, 0.0, 0.0]), lib.gains([4.0])
    u, v = lib.control(x, flags, gains, params)
    ctrl = FlatController(flat, gains=gains, held=held_sampling(flat, 0.01))   # the default build's law
    u_ref, v_ref = ctrl(x, flags, params)
    assert rel(u, u_ref) < RTOL and rel(v, v_ref) < RTOL
    assert rel(u, ctrl(x, flags)[0]) > 1e-3   # it did change u


def test_cache_reuses_the_library_and_float_builds_use_float32(tmp_path, host_cc):
    module = dc.build("dc_motor_link", tmp_path / "out", precision="float")
    first = dc.load(module, cache=tmp_path / "cache")
    stamp = first.path.stat().st_mtime_ns
    again = dc.load(module.path, cache=tmp_path / "cache")
    assert again.path == first.path and again.path.stat().st_mtime_ns == stamp
    assert len(list((tmp_path / "cache").iterdir())) == 1
    x, P = first.Node([0.1, 0, 0], np.eye(3), [[1e-6]], [1.0]).estimate()
    assert x.dtype == np.float32 and P.dtype == np.float32
    other = dc.build("dc_motor_link", tmp_path / "out2", precision="double")
    assert dc.load(other, cache=tmp_path / "cache").path != first.path


def test_node_started_mid_run_refuses_frames_before_its_first_measurement(lib):
    """`Node(..., mid_run=True)` (`<model>_node_mid_run`) against the reference's
    `NodeFilter(mid_run=True)`: step 0 lost, step 1 measured, the late frame of step 0 refused
    (the node's prior alone there), that of step 2 taken at step 3; the same frames taken by a
    node started at step 0. Estimates equal to RTOL."""
    from dfeif_codegen.check import loader
    flat = flatness.derive(dc.load_model("dc_motor_link"))
    x0, P0, R, q = np.array([0.1, 0.0, 0.0]), np.diag([1e-2, 1e-1, 1.0]), np.array([[1e-6]]), np.array([1.0])
    for mid_run in (True, False):
        c = lib.Node(x0, P0, R, q, mid_run=mid_run)
        r = NodeFilter(flat, 0.01, q, R, x0, P0, mid_run=mid_run)
        for k, z in enumerate([None, [0.12], None, [0.15]]):
            c.update(z, gamma=int(z is not None))
            r.update(z, gamma=z is not None)
            if k in (1, 3):
                taken = r.update_delayed([0.11 + 0.01 * k], lag=1)
                assert taken == (k == 3 or not mid_run)
                if taken:
                    c.update_delayed([0.11 + 0.01 * k], lag=1)
                else:
                    with pytest.raises(loader.LagError):
                        c.update_delayed([0.11 + 0.01 * k], lag=1)
            x, P = c.estimate()
            assert rel(x, r.x) < RTOL and rel(P, r.P) < RTOL
            c.predict([0.2])
            r.predict([0.2])


def test_build_check_and_inspect_are_api_functions():
    """`codegen build --check` and `codegen inspect` as functions: the committed output is what
    the build writes (the golden test's claim, by the other route), and inspect's A_d at another
    Ts is the closed form Ts^(j-i)/(j-i)!."""
    from dfeif_codegen.symbolic import inspect_model

    root = Path(__file__).resolve().parents[1] / "generated"
    assert dc.check_build("dc_motor_link", root) == []
    for fn in (dc.check_build, dc.build):      # a CodegenError like every other bad option, not a TypeError
        with pytest.raises(dc.BuildError, match="--out must be a folder path .*got None"):
            fn("dc_motor_link", out=None)
        with pytest.raises(dc.BuildError, match="--out must be a folder path .*got 3"):
            fn("dc_motor_link", 3)
    info = inspect_model.inspect("dc_motor_link", ts=0.02)
    assert info["A_d"] == [[1.0, 0.02, 0.02 ** 2 / 2], [0.0, 1.0, 0.02], [0.0, 0.0, 1.0]]
    with pytest.raises(ModelError, match="sampling period must be a number of seconds"):
        inspect_model.inspect("dc_motor_link", ts=-1.0)


@pytest.mark.parametrize("oosm, predictor, kind", [("retrodict", "brunovsky", None), ("replay", "held", None),
                                                   ("replay", "held", "gauss_markov")])
def test_a_user_model_with_other_options_matches_the_reference(tmp_path, host_cc, oosm, predictor, kind):
    """Any flat model: a user's two-input model (relative degrees 2 and 3), three nodes, covariance
    intersection and retrodiction (Brunovsky predictor, predicting with v) or replay (held
    predictor, with u; also with Gauss-Markov disturbance states, whose densities follow the
    chains' in q and whose estimate the control law cancels), driven through the API for six
    steps with a drop, late frames and a missing packet, against the reference (RTOL: the same
    argument as for the README; the CI weights come from at most 8 Newton steps on a 3 x 3
    system that is well conditioned here)."""
    from dfeif_codegen.symbolic.disturbance import Disturbance, augment

    from test_user_models import MIXED

    path = tmp_path / "mixed.toml"
    path.write_text(MIXED)
    mdl = dc.load_model(str(path))
    dist = None if kind is None else Disturbance(kind, (3.0, 7.0), 0.5)
    lib = dc.load(dc.build(mdl, tmp_path / "out", nodes=3, oosm=oosm, fusion="ci", max_lag=4, predictor=predictor,
                           disturbance=kind, tau=dist and dist.tau), cache=tmp_path / "cache")
    flat = flatness.derive(mdl)
    n, m, ts = flat.n, flat.m, mdl.ts
    nx = n + (m if dist else 0)
    assert (lib.nx, lib.nz, lib.ny, lib.nq, lib.nodes) == (nx, n, m, nx - n + m, 3)
    rng = np.random.default_rng(3)
    x0, P0, q = np.zeros(n), np.diag(rng.uniform(0.5, 2.0, n)), np.array([2.0, 5.0])
    x0, P0 = augment(x0, P0, dist, m)
    q_c = q if dist is None else np.concatenate([q, dist.densities(m)])
    Rs = [np.diag(rng.uniform(1e-4, 4e-4, m)) for _ in range(3)]
    c_nodes = [lib.Node(x0, P0, R, q_c) for R in Rs]
    r_nodes = [NodeFilter(flat, ts, q, R, x0, P0, max_lag=4, oosm=oosm, predictor=predictor, disturbance=dist)
               for R in Rs]
    c_master = lib.Master(x0, P0, q_c)
    r_master = Master(flat, ts, q, x0, P0, n_nodes=3, rule="ci", max_lag=4, predictor=predictor, disturbance=dist)
    gains = lib.gains([3.0, 4.0])
    ctrl = FlatController(flat, gains=gains, held=held_sampling(flat, ts) if predictor == "held" else None)
    frames = rng.normal(0.0, 0.05, (6, 3, m))
    for k in range(6):
        for i, (c, r) in enumerate(zip(c_nodes, r_nodes)):
            on_time = not (i == 1 and k in (2, 3))            # node 1's frames of steps 2, 3 come late
            c.update(frames[k, i] if on_time else None, gamma=int(on_time))
            r.update(frames[k, i], gamma=on_time)
            if i == 1 and k in (3, 4):
                c.update_delayed(frames[k - 1, i], lag=1)
                assert r.update_delayed(frames[k - 1, i], lag=1)
        present = [k != 4, True, True]                         # node 0's packet of step 4 is lost
        c_master.fuse([c.packet() if p else None for c, p in zip(c_nodes, present)])
        r_master.fuse([r.packet() if p else None for r, p in zip(r_nodes, present)])
        flags = np.concatenate([[0.1 * k, 0.1, 0.0], [0.05, 0.0, 0.0, 0.0]])
        u, v = lib.control(c_master.estimate()[0], flags, gains)
        u_ref, v_ref = ctrl(r_master.x[:n], flags, disturbance=r_master.x[n:] if dist else None)
        assert rel(c_master.estimate()[0], r_master.x) < RTOL and rel(c_master.estimate()[1], r_master.P) < RTOL
        assert rel(u, u_ref) < RTOL and rel(v, v_ref) < RTOL
        w = v_ref if predictor == "brunovsky" else u_ref
        for c, r in zip(c_nodes, r_nodes):
            c.predict(w)
            r.predict(w)
        c_master.predict(w)
        r_master.predict(w)
    for c, r in zip(c_nodes, r_nodes):
        x, P = c.estimate()
        assert rel(x, r.x) < RTOL and rel(P, r.P) < RTOL


def test_load_names_a_folder_that_is_not_a_module(tmp_path):
    from dfeif_codegen.errors import SetupError

    with pytest.raises(SetupError, match="is not a folder written by `codegen build`"):
        dc.load(tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_shape_numbers_from_python_take_lists_as_the_command_line_takes_text():
    """`scenario(amplitude=[1, 0.5])` from Python means what `--amplitude 1,0.5` does; a list
    of the wrong length is refused naming the option, as the text is."""
    from dfeif_codegen.experiment import shapes
    flat = flatness.derive(dc.load_model("two_link_arm"))
    by_list = shapes.from_domains(flat, amplitude=[1, 0.5], offset=(0.1, -0.2), phase=0.3)
    by_text = shapes.from_domains(flat, amplitude="1,0.5", offset="0.1,-0.2", phase="0.3")
    assert by_list == by_text and by_list.amplitude == (1.0, 0.5) and by_list.phase == (0.3, 0.3)
    with pytest.raises(dc.CodegenError, match="--amplitude"):
        shapes.from_domains(flat, amplitude=[1, 2, 3])


@pytest.mark.parametrize("call, words", [
    (lambda m: dc.simulate(m, runs=1), ["Model", "built-in name or a .toml path"]),
    (lambda m: dc.verify(m), ["Model", "built-in name or a .toml path"]),
    (lambda m: dc.scenario(m), ["Model", "built-in name or a .toml path"]),
    (lambda m: dc.simulate(reference="circle"), ["--reference 'circle'", "sinusoid"]),
    (lambda m: dc.simulate(runs="1"), ["--runs '1'", "whole number"]),
    (lambda m: dc.simulate(runs=1.5), ["--runs 1.5", "whole number"]),
    (lambda m: dc.simulate(filters=5), ["--filters 5", "ekf"]),
    (lambda m: dc.load_model(5), ["int", "built-in name"]),
    # a period given as text reads like a valid number: the line says it is a string
    (lambda m: dc.inspect(m, ts="0.01"), ["--ts '0.01'", "not a str"]),
    (lambda m: dc.build(m, "unused", ts="0.01"), ["--ts", "'0.01' (a str)"]),
])
def test_api_arguments_of_the_wrong_kind_raise_the_documented_errors(call, words):
    """The functions the commands share take what their options take; given a Model object (from
    load_model or from_sympy), a string count or an unknown name, they raise a CodegenError
    naming it, as the CLI's parser would, not a TypeError from deep inside (unhashable 'Model')."""
    with pytest.raises(dc.CodegenError) as err:
        call(dc.load_model("dc_motor_link"))
    for word in words:
        assert word in str(err.value)
