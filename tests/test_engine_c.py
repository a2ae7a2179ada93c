"""The closed loop in compiled C against the numpy reference, and the sweep around it: local
processes, a Dask cluster, per-run records, resume.

Why 1e-9 (relative) holds between the engines on any IEEE-754 double machine: both evaluate the
same formulas in double, in a different order (CasADi's generated C against numpy), so each step
differs by a few ulps (~1e-16 relative); the closed loop is stable (every pole at -10 rad/s, the
filters' error dynamics contracting), so these differences are damped, not amplified, over a run:
measured at most ~2e-11 on the paper grid's metrics. No BLAS enters the C, and numpy's 3x3 / 4x4
products do not change that order of magnitude. Discrete decisions (a late frame applied or
rejected) would break this bound, which is why the counters are compared exactly.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from dfeif_codegen import cli
from dfeif_codegen.check import closed_loop_c
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import sweep
from dfeif_codegen.experiment.network import Link

RTOL = 1e-9

CASES = [
    ("dc_motor_link", "replay", "difference", (Link(0.8, 10), Link(0.8, 12, 0.1))),
    ("dc_motor_link", "retrodict", "paper", (Link(0.6, 25), Link(0.6, 30))),
    ("dc_motor_link", "as-current", "ci", (Link(0.8, 4), Link(0.8, 6))),
    ("dc_motor_link", "discard", "difference", (Link(0.8, 18), Link(0.6, 20, 0.2))),
    ("two_link_arm", "replay", "difference", (Link(0.8, 8), Link(0.8, 10))),
    ("two_link_arm", "retrodict", "ci", (Link(0.6, 12), Link(0.8, 15, 0.1))),
]


def _cfg(model, method, fusion, sensor, **kw):
    base = dict(model=model, duration=3.0, q=(20.0,), poles=(10.0,), noise_scale=(1.0, 1.25), metrics_from=0.5,
                method=method, fusion=fusion, sensor=sensor, seed=11, reference="seesaw")
    return ex.Config(**{**base, **kw})


@pytest.mark.parametrize("model, method, fusion, sensor", CASES)
def test_c_engine_equals_the_reference(host_cc, model, method, fusion, sensor):
    cfg = _cfg(model, method, fusion, sensor)
    c, py = closed_loop_c.run(cfg), ex.run(cfg)
    assert c.counters == py.counters and c.counters[0]["updates"] > 0
    if method in ex.OOSM:
        assert c.counters[0]["late_applied"] > 10
    rc, rp = c.recording, py.recording
    for name in ("gamma", "late_step", "late_node", "late_lag", "late_applied", "pkt_src"):
        np.testing.assert_array_equal(getattr(rc, name), getattr(rp, name), err_msg=name)
    np.testing.assert_allclose(c.x_true, py.x_true, rtol=RTOL, atol=1e-12)
    np.testing.assert_allclose(rc.z, rp.z, rtol=RTOL, atol=1e-12)
    np.testing.assert_allclose(rc.x, rp.x, rtol=RTOL, atol=1e-12)
    for key, value in py.metrics.items():
        np.testing.assert_allclose(c.metrics[key], value, rtol=RTOL, atol=0, err_msg=key)


@pytest.mark.parametrize("model, dist, error", [
    ("dc_motor_link", ("random_walk", None), None),
    ("two_link_arm", ("gauss_markov", 0.5), 0.2),
    ("dc_motor_link", ("integrated_random_walk", None), 0.2)])
def test_c_engine_runs_disturbance_states_as_the_reference(host_cc, model, dist, error):
    """[disturbance] through the compiled loop: the library built with the disturbance states,
    their initial spread and densities passed as the reference's FilterBank takes them, the law
    cancelling the estimate; on the arm a plant 20% off the model (the case they are for). The
    same bound as above: the loop is as stable with them."""
    from dfeif_codegen.experiment.model_error import ALL, ParamError
    from dfeif_codegen.symbolic.disturbance import Disturbance

    # no NEES watch: a density not calibrated for the arm's 20% error lets its NEES pass 1e4 n,
    # which is beside the point here (the two engines are compared, watched or not)
    kw = {"disturbance": Disturbance(dist[0], (50.0,), dist[1]), "predictor": "held", "watch_nees": False}
    if error:
        kw["plant_error"] = ParamError(draw="uniform", spread=((ALL, error),))
    cfg = _cfg(model, "replay", "difference", (Link(0.8, 8), Link(0.8, 10)), **kw)
    c, py = closed_loop_c.run(cfg), ex.run(cfg)
    assert c.counters == py.counters and c.counters[0]["late_applied"] > 10
    assert c.recording.disturbance == py.recording.disturbance != ""
    np.testing.assert_allclose(c.recording.x, py.recording.x, rtol=RTOL, atol=1e-12)
    np.testing.assert_allclose(c.recording.u, py.recording.u, rtol=RTOL, atol=1e-12)
    for key, value in py.metrics.items():
        np.testing.assert_allclose(c.metrics[key], value, rtol=RTOL, atol=0, err_msg=key)


def test_c_engine_reports_a_diverging_plant_like_the_reference(host_cc):
    # poles far beyond what Ts = 0.01 s can hold: the sampled loop is unstable in both engines
    cfg = _cfg("dc_motor_link", "replay", "difference", (Link(), Link()), poles=(400.0,), duration=4.0)
    with pytest.raises(FloatingPointError) as py:
        ex.run(cfg)
    with pytest.raises(FloatingPointError) as c:
        closed_loop_c.run(cfg)
    # the same step and cause; the NEES it reached is a number ~1e100 that the unstable loop
    # amplified from rounding (the held mean map's F evaluated by C and by CasADi's interpreter
    # round alike only to a few ulps), so it is compared to its order of magnitude
    (c_head, *c_now), (py_head, *py_now) = (str(e.value).split(" (now ") for e in (c, py))
    assert c_head == py_head and len(c_now) == len(py_now)
    for cn, pn in zip(c_now, py_now):
        assert abs(np.log10(float(cn.rstrip(")"))) - np.log10(float(pn.rstrip(")")))) < 2


def test_c_engine_names_the_earlier_cause_of_a_failed_call(host_cc):
    """The kinematic car of tests/data under as-current (tests/test_baseline_check.py): its speed
    leaves its domain at 4.12 s, and 0.5 s later the law's det G is singular. The reference's
    watch stops at the first; the C engine, whose failed call (control, ERR_SINGULAR) ends its
    loop later, now runs the same watch up to that call and names the same cause, where it used
    to report only 'error -4'."""
    from pathlib import Path

    from dfeif_codegen.experiment import scenario
    from dfeif_codegen.experiment.plan import make_config

    data = Path(__file__).parent / "data"
    sc = scenario.load(str(data / "bicycle_circle.toml"))
    row = next(r for r in sc.grid if r.p > 0)
    cfg = make_config(sc, str(data / "bicycle.toml"), 2, 32, sc.references[0], row, "as-current", "difference", 0)
    with pytest.raises(ArithmeticError) as py:
        ex.run(cfg)
    with pytest.raises(ArithmeticError) as c:
        closed_loop_c.run(cfg)
    assert type(c.value) is type(py.value) and str(c.value) == str(py.value)
    assert str(py.value).startswith("diverged at t = 4.12 s: state v = 0.104 left its domain [0.2, 5]")


TINY = """
[scenario]
duration = 1.0
runs = 3
metrics_from = 0.2
references = ["seesaw"]
fusion = ["difference"]
baselines = ["discard"]
[[grid]]
d = [0, 0]
p = 0.0
[[grid]]
d = [3, 4]
p = 0.5
[[grid]]
d = [6, 8]
p = 0.8
"""


def _simulate(tmp_path, capsys, *extra) -> dict:
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    assert cli.main(["simulate", "--scenario", str(path), "--quiet", "--json", "-", *extra]) == 0
    return json.loads(capsys.readouterr().out)


def _close(a, b, path="", scale=None):
    """a == b within RTOL relative to b, or to `scale`: a 95% CI half-width is a spread, a
    difference of nearly equal samples, so its error is relative to the samples (the mean), not to
    itself (it is exactly 0 in numpy where every seed gives the same trace, ~1e-16 in C)."""
    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            _close(a[k], b[k], f"{path}/{k}", b["mean"] if k == "ci95" else None)
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _close(x, y, f"{path}[{i}]", scale[i] if isinstance(scale, list) else scale)
    elif isinstance(a, float):
        assert abs(a - b) <= RTOL * abs(b if scale is None else scale), (path, a, b)
    else:
        assert a == b, path


def test_simulate_tables_equal_for_both_engines(host_cc, tmp_path, capsys):
    c = _simulate(tmp_path, capsys, "--workers", "1")
    py = _simulate(tmp_path, capsys, "--engine", "reference", "--workers", "1")
    assert c["settings"]["engine"] == "c" and py["settings"]["engine"] == "reference"
    _close(c["tables"], py["tables"])
    _close(c["figures"], py["figures"])


def test_one_worker_two_workers_and_a_dask_cluster_agree_exactly(host_cc, tmp_path, capsys):
    from dask.distributed import LocalCluster   # the 'cluster' extra, installed by scripts/setup-tests.sh

    one = _simulate(tmp_path, capsys, "--workers", "1")
    two = _simulate(tmp_path, capsys, "--workers", "2")
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        dask = _simulate(tmp_path, capsys, "--scheduler", cluster.scheduler_address)
    assert one["settings"]["ran_on"] == "1 process" and two["settings"]["ran_on"] == "2 processes"
    assert dask["settings"]["ran_on"].startswith("Dask cluster")
    assert one["tables"] == two["tables"] == dask["tables"]
    assert one["figures"] == two["figures"] == dask["figures"]


def test_resume_continues_without_recomputing(host_cc, tmp_path, capsys, monkeypatch):
    full_file, part_file = tmp_path / "full.jsonl", tmp_path / "part.jsonl"
    full = _simulate(tmp_path, capsys, "--workers", "1", "--results", str(full_file), "--csv", str(tmp_path / "r.csv"))
    lines = full_file.read_text().splitlines()
    # 3 rows x 2 methods x 3 seeds, the row without delays once: (1 + 2 * 2) * 3 distinct runs
    assert len(lines) == 15
    # an interrupted sweep: 6 finished runs and half of the 7th line
    part_file.write_text("\n".join(lines[:6]) + "\n" + lines[6][:40])
    calls = []
    one = sweep.one
    monkeypatch.setattr(sweep, "one", lambda cfg, *a: calls.append(cfg) or one(cfg, *a))
    again = _simulate(tmp_path, capsys, "--workers", "1", "--resume", str(part_file))
    # the runs whose time series the figures show (row 1 and the last, first seed) are rerun
    figures = sum(any(k[1:3] == ["replay", "difference"] and k[3] in (0, 2) and k[4] == 0
                      for k in json.loads(line)["runs"]) for line in lines[:6])
    assert len(calls) == 15 - 6 + figures and again["settings"]["runs_resumed"] == 6 - figures
    assert again["tables"] == full["tables"]
    assert sorted(part_file.read_text().splitlines()) == sorted(lines)
    # a resume of a finished sweep computes only the two figure runs
    calls.clear()
    assert _simulate(tmp_path, capsys, "--workers", "1", "--resume", str(part_file))["tables"] == full["tables"]
    assert sorted((c.seed, c.method, c.sensor[0].p) for c in calls) == [(0, "replay", 0.0), (0, "replay", 0.8)]


def test_resume_reruns_the_runs_of_an_edited_model(host_cc, tmp_path, capsys):
    """A run is its model's too: after the model file's k_e changes, --resume reuses none of the
    earlier runs (their ids were made of the path alone, so the old numbers were reported as the
    edited model's), and the tables are the edited model's, equal to a fresh sweep of it; resumed
    again unchanged, every run is reused (figures aside)."""
    from importlib import resources

    motor = (resources.files("dfeif_codegen") / "models" / "dc_motor_link.toml").read_text()
    model, results = tmp_path / "motor.toml", tmp_path / "r.jsonl"
    model.write_text(motor)
    before = _simulate(tmp_path, capsys, str(model), "--workers", "1", "--results", str(results))
    assert motor.count("value = 0.5\n") == 1           # k_e, the back-emf constant
    model.write_text(motor.replace("value = 0.5\n", "value = 0.55\n"))
    edited = _simulate(tmp_path, capsys, str(model), "--workers", "1", "--resume", str(results))
    assert edited["settings"]["runs_resumed"] == 0 and edited["tables"] != before["tables"]
    fresh = _simulate(tmp_path, capsys, str(model), "--workers", "1")
    assert edited["tables"] == fresh["tables"]
    again = _simulate(tmp_path, capsys, str(model), "--workers", "1", "--resume", str(results))
    assert again["settings"]["runs_resumed"] == 15 - 2 and again["tables"] == fresh["tables"]


def test_json_of_a_single_run_is_strict_json(host_cc, tmp_path, capsys):
    """One run has no 95% interval: its half-widths are written null, not NaN (which JSON does
    not have; JavaScript's JSON.parse refused the document), and the means stay numbers."""
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    assert cli.main(["simulate", "--scenario", str(path), "--quiet", "--json", "-", "--runs", "1", "--workers", "1"]) == 0

    def refuse(name):
        raise AssertionError(f"{name} in the JSON")

    doc = json.loads(capsys.readouterr().out, parse_constant=refuse)
    rmse = doc["tables"][0]["rows"][0]["rmse_master"]
    assert all(v is None for v in rmse["ci95"]) and all(v > 0 for v in rmse["mean"])


def test_one_worker_records_each_run_before_the_next(host_cc, tmp_path, capsys, monkeypatch):
    """--workers 1 --results: each run's line is in the file (flushed) before the next run starts,
    so an interrupted one-process sweep keeps every run it finished (the file has k lines when
    run k + 1 starts; 15 distinct runs as in the test above)."""
    path = tmp_path / "r.jsonl"
    seen = []
    one = sweep.one

    def counting(cfg, *a):
        seen.append(len(path.read_text().splitlines()) if path.exists() else 0)
        return one(cfg, *a)

    monkeypatch.setattr(sweep, "one", counting)
    _simulate(tmp_path, capsys, "--workers", "1", "--results", str(path))
    assert seen == list(range(15))


def test_csv_rows_average_to_the_tables(host_cc, tmp_path, capsys):
    import csv

    doc = _simulate(tmp_path, capsys, "--workers", "1", "--csv", str(tmp_path / "r.csv"))
    rows = list(csv.DictReader(open(tmp_path / "r.csv")))
    assert len(rows) == 3 * 2 * 3        # every (row, method, seed), the shared no-delay row twice
    for table in doc["tables"]:
        for ri, summary in enumerate(table["rows"]):
            mine = [float(r["rmse_master_x1"]) for r in rows
                    if r["method"] == table["method"] and int(r["row"]) == ri + 1]
            assert len(mine) == 3
            assert abs(np.mean(mine) - summary["rmse_master"]["mean"][0]) <= 1e-12 * summary["rmse_master"]["mean"][0]


@pytest.mark.parametrize("flag, value", [("--workers", "0")])
def test_bad_sweep_options_are_one_line_exit_2(tmp_path, capsys, flag, value):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    assert cli.main(["simulate", "--scenario", str(path), "--quiet", flag, value]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and flag in err


def test_resume_of_a_missing_file_is_one_line_exit_2(tmp_path, capsys):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    assert cli.main(["simulate", "--scenario", str(path), "--quiet", "--resume", str(tmp_path / "none.jsonl")]) == 2
    assert "none.jsonl" in capsys.readouterr().err


# --- the one-pass replay keeps the node unchanged when it fails ----------------------------------

CART = """
[model]
name = "cart"
ts = 0.01
[[states]]
name = "p"
[[states]]
name = "pd"
[[inputs]]
name = "F"
[dynamics.f]
p = "pd"
pd = "0"
[dynamics.g.F]
pd = "1"
[[outputs]]
name = "pos"
expr = "p"
[measurement.noise]
pos = 0.01
"""


def test_failed_replay_leaves_the_node_unchanged(host_cc, tmp_path):
    """A late frame that makes the replayed window overflow at a later step (step 9's huge frame
    then sees twice its innovation), after the replay rewrote the slots in between: the node is
    rolled back byte for byte, and later calls match a twin node that never saw the frame. A
    position output (an angle's innovation is wrapped, so bounded). Both halves of the rollback
    (the priors' x copy, the copy of the P checkpoints the replay passed: window 8, a checkpoint
    every 4th step, so steps 8 and 12 are rewritten) are needed to pass: checked by removing each."""
    import ctypes

    from dfeif_codegen.check import harness

    (tmp_path / "cart.toml").write_text(CART)
    md = harness.build_model(str(tmp_path / "cart.toml"), tmp_path / "b", "double", "replay", "difference", 2, 8)
    lib = ctypes.CDLL(str(harness.compile_shared(md.sources(), tmp_path / "libnode.so", [md.path])))
    call = lambda name, *args: getattr(lib, f"cart_{name}")(*args)  # noqa: E731
    lib.cart_node_size.restype = ctypes.c_size_t
    size = lib.cart_node_size()
    ptr = lambda a: np.ascontiguousarray(a, dtype=float).ctypes.data_as(ctypes.c_void_p)  # noqa: E731
    failed = 0
    for e in np.arange(304.0, 308.25, 0.02):
        big = 10.0 ** e
        a = ctypes.create_string_buffer(size)
        assert call("node_init", a, ptr([0.0, 0.0]), ptr(np.diag([0.05, 0.1]) ** 2), ptr([[1e-4]]), ptr([20.0])) == 0
        ok = True
        for k in range(12):   # every third step on time, the others dropped; step 9's frame is huge
            ok = ok and call("node_update", a, ptr([big if k == 9 else 0.01 * k]), int(k % 3 == 0)) == 0
            ok = ok and call("node_predict", a, ptr([0.3])) == 0
        if not (ok and call("node_update", a, ptr([0.12]), 0) == 0):
            continue          # too big for the history itself
        twin = a.raw
        # step 5's late frame, far on the other side: the replayed step 9 sees twice the innovation
        rc = call("node_update_delayed", a, ptr([-big]), 7)
        if rc != 0:
            assert rc == -3 and a.raw == twin, e       # ERR_NONFINITE, nothing changed
            failed += 1
            b = ctypes.create_string_buffer(twin, size)
            for node in (a, b):
                assert call("node_update_delayed", node, ptr([0.08]), 7) == 0
                assert call("node_predict", node, ptr([0.3])) == 0
            assert a.raw == b.raw
    assert failed >= 3


def _cart_node(tmp_path, oosm):
    import ctypes

    from dfeif_codegen.check import harness

    (tmp_path / "cart.toml").write_text(CART)
    md = harness.build_model(str(tmp_path / "cart.toml"), tmp_path / oosm, "double", oosm, "difference", 2, 8)
    lib = ctypes.CDLL(str(harness.compile_shared(md.sources(), tmp_path / f"lib{oosm}.so", [md.path])))
    lib.cart_node_size.restype = ctypes.c_size_t
    call = lambda name, *args: getattr(lib, f"cart_{name}")(*args)  # noqa: E731
    return call, lib.cart_node_size()


def _ptr(a):
    return np.ascontiguousarray(a, dtype=float).ctypes.data_as(__import__("ctypes").c_void_p)


@pytest.mark.parametrize("oosm", ["replay", "retrodict"])
def test_failed_update_puts_the_prior_back(host_cc, tmp_path, oosm):
    """The on-time update computes into the node and puts the prior back when it fails: a frame
    1.7e308 against a position prior of -1e308 has an innovation that overflows a double, so x
    becomes infinite (ERR_NONFINITE); the node is then byte for byte what it was, and the next
    calls match a twin that never saw the frame."""
    import ctypes

    call, size = _cart_node(tmp_path, oosm)
    a = ctypes.create_string_buffer(size)
    assert call("node_init", a, _ptr([-1e308, 0.0]), _ptr(np.diag([0.05, 0.1]) ** 2), _ptr([[1e-4]]),
                _ptr([20.0])) == 0
    twin = a.raw
    assert call("node_update", a, _ptr([1.7e308]), 1) == -3 and a.raw == twin    # ERR_NONFINITE
    b = ctypes.create_string_buffer(twin, size)
    for node in (a, b):
        assert call("node_update", node, _ptr([-1e308]), 1) == 0
        assert call("node_predict", node, _ptr([0.3])) == 0
    assert a.raw == b.raw


@pytest.mark.parametrize("oosm", ["replay", "retrodict"])
def test_a_non_finite_frame_or_input_fails_through_the_result_check(host_cc, tmp_path, oosm):
    """z and v are not checked on entry: a NaN or an infinity in them reaches every entry of the
    result (IEEE: NaN * 0 and inf * 0 are NaN, inf - inf too), which the results' check rejects,
    and the update puts the prior back. The node starts at position 0.3, so its centre moved by
    0.25 at init: the current step's z slot stays 0 through that move (else the put-back would
    differ in that slot)."""
    import ctypes

    call, size = _cart_node(tmp_path, oosm)
    a = ctypes.create_string_buffer(size)
    assert call("node_init", a, _ptr([0.3, 0.0]), _ptr(np.diag([0.05, 0.1]) ** 2), _ptr([[1e-4]]),
                _ptr([20.0])) == 0
    for k in range(3):
        before = a.raw
        for bad in (np.nan, np.inf, -np.inf):
            assert call("node_update", a, _ptr([bad]), 1) == -3 and a.raw == before   # ERR_NONFINITE
        assert call("node_update", a, _ptr([0.3 + 0.2 * k]), 1) == 0
        before = a.raw
        for bad in (np.nan, np.inf):
            assert call("node_predict", a, _ptr([bad])) == -3 and a.raw == before
        assert call("node_predict", a, _ptr([30.0])) == 0


def test_a_finite_state_whose_sum_overflows_is_accepted(host_cc, tmp_path):
    """The results' finiteness is one sum of x and P; a sum that overflows on finite values takes
    the per-value check, which accepts them: position and velocity 1e308 (sum 2e308 > DBL_MAX).
    A frame equal to the position leaves x as it was (zero innovation); the prediction moves the
    position by ts * velocity + ts^2 / 2 * v: computed in double in another order than here, so
    within 2 ulps (rtol 1e-15)."""
    import ctypes

    call, size = _cart_node(tmp_path, "replay")
    a = ctypes.create_string_buffer(size)
    assert call("node_init", a, _ptr([1e308, 1e308]), _ptr(np.diag([0.05, 0.1]) ** 2), _ptr([[1e-4]]),
                _ptr([20.0])) == 0
    assert call("node_update", a, _ptr([1e308]), 1) == 0
    x = np.zeros(2)
    assert call("node_estimate", a, x.ctypes.data_as(ctypes.c_void_p), None) == 0
    assert x[0] == 1e308 and x[1] == 1e308
    assert call("node_predict", a, _ptr([0.3])) == 0
    assert call("node_estimate", a, x.ctypes.data_as(ctypes.c_void_p), None) == 0
    ts = 0.01
    np.testing.assert_allclose(x, [1e308 + ts * 1e308 + ts * ts / 2 * 0.3, 1e308 + ts * 0.3], rtol=1e-15)


def test_a_worker_needs_none_of_the_callers_files(host_cc, tmp_path):
    """What a worker gets (compiled loops as bytes, model files as text) is enough: a fresh
    process runs a user model's run after the model file and every build folder are gone, and
    gets the caller's numbers exactly (the same compiled code on the same inputs)."""
    import multiprocessing
    import shutil
    from concurrent.futures import ProcessPoolExecutor

    folder = tmp_path / "models"
    folder.mkdir()
    (folder / "cart.toml").write_text(CART)
    cfg = ex.Config(model=str(folder / "cart.toml"), duration=1.0, q=(20.0,), poles=(10.0,), metrics_from=0.2,
                    sensor=(Link(0.5, 3), Link(0.5, 4)), seed=3)
    shipped = sweep.prepare([cfg], closed_loop_c.ENGINE)
    assert shipped["models"] == {str(folder / "cart.toml"): CART}
    here = sweep.batch([("r", cfg, None)], closed_loop_c.ENGINE, shipped)
    shutil.rmtree(folder)
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        there = pool.submit(sweep.batch, [("r", cfg, None)], closed_loop_c.ENGINE, shipped).result()
    (_, (mine, _)), = here
    (_, (theirs, _)), = there
    assert isinstance(theirs, dict) and mine.keys() == theirs.keys()
    for key in mine:
        np.testing.assert_array_equal(theirs[key], mine[key], err_msg=key)


def test_table_vi_names_the_predictor_df_ran_with(host_cc, tmp_path, capsys):
    """With --predictor brunovsky, "df" in Tables VI and VII is the chapter's filter, not the
    held one: Table VI's heading says which (it did not, and df / brunovsky read 1.000)."""
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    for predictor, expected in ((None, "held"), ("brunovsky", "brunovsky")):
        extra = [] if predictor is None else ["--predictor", predictor]
        assert cli.main(["simulate", "--scenario", str(path), "--quiet", "--runs", "1", "--workers", "1",
                         "--filters", "df,ekf", *extra]) == 0
        assert f"Table VI: derivative-free (df, the {expected} predictor)" in capsys.readouterr().out
