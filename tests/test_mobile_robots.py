"""The built-in unicycle and planar quadrotor end to end: derived with a dynamic extension,
inspected, verified against the reference on the host and the Cortex-M4F, and closing the loop
through delays and packet losses in `simulate`. A reference through the transform's singular
set is refused with its time."""

import json
from importlib import resources

import numpy as np
import pytest

from dfeif_codegen import cli
from dfeif_codegen import api
from dfeif_codegen.symbolic import model

ROBOTS = ["unicycle", "pvtol"]
CAMERA_STD = 0.002   # both models' [measurement.noise] per axis [m]


def test_inspect_says_what_the_extension_added_and_where_it_is_singular(capsys):
    assert cli.main(["inspect", "unicycle"]) == 0
    out = capsys.readouterr().out
    assert "step 1: one integrator on v" in out and "controller states v" in out
    assert "det = v = 0" in out and "th = atan2(y_1, x_1)" in out
    assert cli.main(["inspect", "pvtol", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    ext = info["dynamic_extension"]
    assert ext["chains"] == {"T": ["T", "T_d1"], "tau": []} and len(ext["steps"]) == 2
    assert [o["relative_degree"] for o in info["flat_outputs"]] == [4, 4]
    assert info["phi_inv"]["th"] == "atan2(-px_2, g + pz_2)"


@pytest.mark.parametrize("name", ROBOTS)
@pytest.mark.parametrize("precision", ["double", "float"])
def test_robot_verifies_on_the_host(name, precision, capsys):
    assert cli.main(["verify", name, "--scenario", name, "--precision", precision]) == 0
    out = capsys.readouterr().out
    assert "delays d = (4, 6), p = 0.8" in out and out.rstrip().endswith("PASS")


@pytest.mark.parametrize("name", ROBOTS)
def test_robot_verifies_on_the_cortex_m4f(name, cross_tools, capsys):
    assert cli.main(["verify", name, "--scenario", name, "--target", "cortex-m4f"]) == 0
    assert capsys.readouterr().out.rstrip().endswith("PASS")


@pytest.mark.parametrize("name", ROBOTS)
def test_robot_closes_the_loop_through_delays(name, tmp_path, capsys):
    """One seed per delay row, replay + difference, compiled C: no run fails, and on every row the
    master's position error stays within 1.5 times one camera's noise std (it fuses two cameras,
    2 and 2.5 mm, through the model: measured 0.5-1.0 times, up to 12-15 periods late with 20 %
    lost) and the robot tracks the reference within 5 camera stds."""
    path = tmp_path / "out.json"
    api.simulate(name, scenario=name, runs=1, oosm=["replay"], fusion=["difference"], quiet=True, json_path=str(path))
    capsys.readouterr()
    result = json.loads(path.read_text())
    assert result["failures"] == []
    flat_heads = [0, 2] if name == "unicycle" else [0, 4]
    table = next(t for t in result["tables"] if t["method"] == "replay")
    for row in table["rows"]:
        rmse = np.array(row["rmse_master"]["mean"])[flat_heads]
        tracking = np.array(row["rmse_tracking"]["mean"])[flat_heads]
        assert np.all(rmse < 1.5 * CAMERA_STD) and np.all(tracking < 5 * CAMERA_STD), (rmse, tracking)


UNICYCLE_FROM_ZERO = (resources.files("dfeif_codegen") / "models" / "unicycle.toml").read_text() \
    .replace("min = 0.05\nmax = 1.5", "min = 0.0\nmax = 1.5")
LINE = (resources.files("dfeif_codegen.experiment") / "scenarios" / "unicycle.toml").read_text() \
    .replace("phase = [1.5707963267948966, 0.0]\n", "")


def test_reference_through_the_singular_set_is_refused_with_its_time(tmp_path, capsys):
    """x = y = sin(w t): the speed sqrt(x'^2 + y'^2) is 0 at t = T/4 = 2.5 s, where det G = v = 0
    (the speed's domain is [0, 1.5] here, so only the singular set can refuse it)."""
    mdl, sc = tmp_path / "uni.toml", tmp_path / "line.toml"
    mdl.write_text(UNICYCLE_FROM_ZERO)
    sc.write_text(LINE)
    model.load(str(mdl))
    assert cli.main(["simulate", str(mdl), "--scenario", str(sc), "--runs", "1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "t = 2.500 s" in err and "decoupling matrix is singular" in err


def test_generated_control_integrates_the_controller_states(tmp_path):
    """pvtol_extension_step: the plant gets T (held), then T and T' advance exactly under the
    held T'' (closed form T + Ts T' + Ts^2/2 T'', T' + Ts T''); tau passes through. A non-finite
    input is refused and leaves xi alone."""
    import ctypes

    import dfeif_codegen as dc
    from dfeif_codegen.check.loader import NonFiniteError

    lib = dc.load(dc.build("pvtol", tmp_path))
    ts = 0.01
    xi, u, out = np.array([6.9, -0.4]), np.array([3.0, 0.02]), np.zeros(2)
    ptr = lambda a: ctypes.c_void_p(a.ctypes.data)  # noqa: E731
    lib.call("extension_step", ptr(xi), ptr(u), ptr(out))
    np.testing.assert_allclose(out, [6.9, 0.02], rtol=0, atol=0)
    # three products and two sums of O(10) numbers: a few ulps
    np.testing.assert_allclose(xi, [6.9 - 0.4 * ts + 3.0 * ts**2 / 2, -0.4 + 3.0 * ts], rtol=1e-15, atol=1e-14)
    before = xi.copy()
    with pytest.raises(NonFiniteError):
        lib.call("extension_step", ptr(xi), ptr(np.array([np.nan, 0.0])), ptr(out))
    np.testing.assert_array_equal(xi, before)


def test_plant_holds_the_controller_states_over_a_period():
    """The closed loops' plant applies the controller's T held over the period (the ZOH that
    <model>_extension_step gives the plant) and advances T, T' by the same closed form. Level
    flight (th = om = 0): vz' = T/m - g is constant over the period, so RK4 is exact and
    vz(Ts) = vz + (T/m - g) Ts; a ramped T would add T' Ts^2 / (2 m)."""
    from dfeif_codegen.experiment import closed_loop as ex
    from dfeif_codegen.experiment.plant import Plant

    flat = ex._flat("pvtol")
    ts, m, g = 0.01, 0.7, 9.81
    plant = Plant(flat.model, ts, 10, flat.extension)
    x = np.array([0.1, 1.0, 0.0, 0.2, -0.3, 0.0, 7.5, 40.0])   # x z th vx vz om T T'
    u = np.array([-200.0, 0.0])                                 # T'', tau
    after = plant.step(x, u)
    np.testing.assert_allclose(after[4], -0.3 + (7.5 / m - g) * ts, rtol=0, atol=1e-13)
    np.testing.assert_allclose(after[6:], [7.5 + 40.0 * ts - 200.0 * ts**2 / 2, 40.0 - 200.0 * ts],
                               rtol=0, atol=1e-12)


def _robot_run_config(name):
    """The robot's own scenario, its first row with late frames, 3 s (a lap's start), seed 3."""
    import dataclasses

    from dfeif_codegen.experiment import plan, scenario

    sc = scenario.load(name)
    cfg = plan.make_config(sc, name, 2, 32, sc.references[0], sc.grid[1], "replay", "difference", 3)
    return dataclasses.replace(cfg, duration=3.0, metrics_from=0.5)


@pytest.mark.parametrize("name", ROBOTS)
def test_generated_control_and_extension_step_equal_the_reference_over_a_recorded_run(name, tmp_path):
    """Along a closed loop recorded by the numpy reference, the generated C's control (u, v from
    the master's estimate and the reference flags) and <model>_extension_step (the controller's
    integrator states advanced under that u, the plant's input) give the reference's numbers to
    1e-10 relative in double: the same formulas in another order, a few ulps per step, not fed
    back (each step starts from the reference's recorded state)."""
    import ctypes

    import dfeif_codegen as dc
    from dfeif_codegen.experiment import closed_loop as ex

    cfg = _robot_run_config(name)
    res = ex.run(cfg)
    rec, flat = res.recording, ex._flat(name)
    lib = dc.load(dc.build(name, tmp_path))
    states = [s.name for s in flat.model.states]
    xi_at = [states.index(s) for s in flat.extension.states]
    assert xi_at == list(range(flat.n - len(xi_at), flat.n))            # the last NXI states
    first = {j: states.index(c[0]) for j, c in enumerate(flat.extension.chains.values()) if c}
    ptr = lambda a: ctypes.c_void_p(a.ctypes.data)  # noqa: E731
    scale = np.max(np.abs(rec.u), axis=0)
    for k in range(len(rec.u) - 1):
        u, v = lib.control(rec.x[k], rec.ref[k], rec.gains)
        assert np.all(np.abs(u - rec.u[k]) <= 1e-10 * (np.abs(rec.u[k]) + scale)), (k, u, rec.u[k])
        np.testing.assert_allclose(v, rec.v[k], rtol=1e-10, atol=1e-12)
        xi, plant_u = res.x_true[k, xi_at].copy(), np.zeros(flat.m)
        lib.call("extension_step", ptr(xi), ptr(np.ascontiguousarray(rec.u[k])), ptr(plant_u))
        np.testing.assert_allclose(xi, res.x_true[k + 1, xi_at], rtol=1e-10, atol=1e-12)
        held = [res.x_true[k, first[j]] if j in first else rec.u[k, j] for j in range(flat.m)]
        np.testing.assert_array_equal(plant_u, held)


@pytest.mark.parametrize("name", ROBOTS)
def test_compiled_closed_loop_runs_the_extension_through_the_generated_c(name, host_cc):
    """`simulate`'s compiled engine advances the controller's states with the generated
    <model>_extension_step (templates/harness/closed_loop.c.j2) and equals the numpy engine to
    1e-9 relative, the bound and reasoning of tests/test_engine_c.py (a stable loop damps the
    ulp differences of two evaluation orders); the late frames applied are the same."""
    from dfeif_codegen.check import closed_loop_c
    from dfeif_codegen.experiment import closed_loop as ex

    cfg = _robot_run_config(name)
    c, py = closed_loop_c.run(cfg), ex.run(cfg)
    assert c.counters == py.counters and c.counters[0]["late_applied"] > 0
    np.testing.assert_allclose(c.x_true, py.x_true, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(c.recording.x, py.recording.x, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(c.recording.u, py.recording.u, rtol=1e-9, atol=1e-9 * np.abs(py.recording.u).max())


@pytest.mark.parametrize("name", ROBOTS)
@pytest.mark.parametrize("precision", ["double", "float"])
def test_example_program_starts_where_the_model_is_defined(name, precision, host_cc, tmp_path):
    """The example program starts plant and filters at the nominal state's motion. It started at
    the canonical origin, where a unicycle is at rest and its extension singular: its filters
    refused that prior and the example printed `init failed`, exit 1. Its own check (the fused
    position's RMS error under 0.01, against a camera noise of 0.001) must pass."""
    import subprocess
    from dfeif_codegen.codegen import build
    module = build.build(name, tmp_path / "gen", precision=precision, compile_check=False)
    exe = tmp_path / "example"
    subprocess.run([host_cc, "-std=c99", "-O1", f"-I{module.path}", *sorted(map(str, module.path.glob("*.c"))),
                    "-lm", "-o", str(exe)], check=True, capture_output=True, timeout=300)
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stdout[-400:]
    assert "init failed" not in run.stdout and "RMS error of y1 (fused)" in run.stdout
