"""User-given trajectories (experiment/trajectory_file.py): a CSV of the flat outputs with their
derivatives reproduces the closed-form reference within the interpolation error bound; one of the
outputs only recovers the derivatives within the local fit's error bound; a scenario names the
file relative to itself, `simulate` and `verify` run on it, `codegen scenario --trajectory`
writes a calibrated one, and every bad file is one line naming the file and the row or column.

The test signals are sinusoids y = c + A sin(nu t + phi), whose derivatives are known exactly and
bounded by |y^(k)| <= A nu^k: the bounds below are the classical ones of each method with that
bound inserted, plus 1e-12 for the rounding of O(1) numbers in double.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from dfeif_codegen import api, cli
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import scenario as scenario_mod
from dfeif_codegen.experiment import nees_match, trajectory_file

TS = 0.02                     # the unicycle's sampling period; both its flat outputs have r = 2
NU = 2 * math.pi / 10         # [rad/s]
SIGNALS = {"x": (0.8, NU, math.pi / 2, 0.1), "y": (0.5, 2 * NU, 0.0, -0.2)}   # A, nu, phi, c: a figure eight


def exact(name: str, t, order: int):
    A, nu, phi, c = SIGNALS[name]
    return A * nu ** order * np.sin(nu * np.asarray(t) + phi + order * math.pi / 2) + (c if order == 0 else 0.0)


def write_csv(path, t, orders: int, noise: float = 0.0, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    cols = {"t": t}
    for name in SIGNALS:
        cols[name] = exact(name, t, 0) + noise * rng.standard_normal(len(t))
        for k in range(1, orders + 1):
            cols[f"{name}_d{k}"] = exact(name, t, k)
    lines = [",".join(cols)] + [",".join(repr(float(v)) for v in row) for row in zip(*cols.values())]
    path.write_text("\n".join(lines) + "\n")


def table(traj: trajectory_file.Trajectory, steps: int) -> np.ndarray:
    """The reference flags the closed loop uses (x, x', x'', y, y', y'') at the run's steps."""
    cfg = ex.Config(model="unicycle", reference="trajectory", trajectory=traj)
    return ex._reference_table("unicycle", "trajectory", cfg.amplitude, cfg.period, cfg.offset, cfg.harmonics, TS,
                               steps, trajectory=traj)


@pytest.mark.parametrize("orders", [2, 3])
def test_given_derivatives_reproduce_the_closed_form_within_the_interpolation_bound(tmp_path, orders):
    """Samples every h = 13 ms (no run step falls on a sample after t = 0.26 s). Order j < top:
    cubic Hermite with the next order as slope, error <= h^4/384 max|y^(j+4)|; the top given
    order (2 of 2) linearly, error <= h^2/8 max|y^(4)|."""
    h, steps = 0.013, 500
    path = tmp_path / "eight.csv"
    write_csv(path, np.arange(-3, 800) * h, orders)
    flags = table(trajectory_file.read(path), steps)
    t = np.arange(steps) * TS
    for j, name in enumerate(SIGNALS):
        A, nu = SIGNALS[name][:2]
        for k in range(3):
            hermite = k + 1 <= orders
            bound = (h ** 4 / 384 * A * nu ** (k + 4) if hermite else h ** 2 / 8 * A * nu ** (k + 2)) + 1e-12
            err = np.max(np.abs(flags[:, 3 * j + k] - exact(name, t, k)))
            assert err <= bound, (name, k, err, bound)
            assert bound < 1e-4 * A * nu ** k + 1e-12    # the bound says something
    # at a sample's time the given values come back exactly (t = 0.26 s is sample 20)
    np.testing.assert_allclose(flags[13, :3], [exact("x", 0.26, k) for k in range(3)], rtol=0, atol=1e-15)


def _fit_bound(h: float, points: int, degree: int, order: int, A: float, nu: float) -> float:
    """Largest error of the derivative `order` of a least-squares polynomial of `degree` through
    `points` consecutive samples, evaluated anywhere among them: the fit is linear, y^(j)(t) =
    sum w_i y_i, and reproduces polynomials of its degree, so its error is sum w_i R(tau_i) with
    the Taylor remainder |R(tau)| <= A nu^(d+1) |tau|^(d+1) / (d+1)!; maximised over where t lies."""
    worst = 0.0
    for s in np.linspace(0.0, (points - 1) * h, 200):
        tau = np.arange(points) * h - s
        w = np.linalg.pinv(np.vander(tau, degree + 1, increasing=True))[order] * math.factorial(order)
        worst = max(worst, np.sum(np.abs(w) * A * nu ** (degree + 1) * np.abs(tau) ** (degree + 1))
                    / math.factorial(degree + 1))
    return worst


def test_outputs_only_are_differentiated_within_the_local_fit_bound(tmp_path):
    """Outputs only, every h = 10 ms from t = 0 (so the first steps' fits are one-sided): the
    degree-4 fit over the 9 nearest samples, within _fit_bound on y, y', y''."""
    h, steps = 0.01, 500
    path = tmp_path / "eight.csv"
    write_csv(path, np.arange(0, 1001) * h, 0)
    flags = table(trajectory_file.read(path), steps)
    t = np.arange(steps) * TS
    for j, name in enumerate(SIGNALS):
        A, nu = SIGNALS[name][:2]
        for k in range(3):
            bound = _fit_bound(h, 9, 4, k, A, nu) + 1e-12 / h ** k
            err = np.max(np.abs(flags[:, 3 * j + k] - exact(name, t, k)))
            assert err <= bound, (name, k, err, bound)
            assert bound < 1e-3 * A * nu ** k                # the bound says something


def test_noisy_outputs_are_smoothed_by_the_window(tmp_path):
    """Outputs with 0.1 mm white noise and `smoothing` 0.405 s: inside the file every fit takes
    the 40 or 41 samples within 0.2025 s. Its error is the bias (as above) plus the noise through
    the weights, std sigma ||w||_2 (10% added for a 40-sample window); 5 std bound every one of the
    800 values compared (fixed seed). That stays within 20% of the signal's y''; the same data
    without the window (9 samples) differentiates the noise, beyond that bound."""
    h, sigma = 0.01, 1e-4
    path = tmp_path / "noisy.csv"
    write_csv(path, np.arange(-100, 1101) * h, 0, noise=sigma, seed=3)
    t = np.arange(50, 450) * TS
    smooth, raw = (trajectory_file.read(path, s).outputs(list(SIGNALS), [2, 2]) for s in (0.405, 0.0))
    for j, name in enumerate(SIGNALS):
        A, nu = SIGNALS[name][:2]
        got = np.array([smooth[j].flags(tk, 2) for tk in t])
        unsmoothed = np.array([raw[j].flags(tk, 2) for tk in t])
        for k in (1, 2):
            tau = np.arange(-20, 21) * h
            w = np.linalg.pinv(np.vander(tau, 5, increasing=True))[k] * math.factorial(k)
            bound = _fit_bound(h, 41, 4, k, A, nu) + 5 * sigma * 1.1 * np.linalg.norm(w)
            err = np.max(np.abs(got[:, k] - exact(name, t, k)))
            assert err <= bound < 0.2 * A * nu ** k, (name, k, err, bound)
            if k == 2:
                assert np.max(np.abs(unsmoothed[:, k] - exact(name, t, k))) > bound


def _scenario(tmp_path, csv_name: str, **reference) -> str:
    extra = "".join(f"{k} = {v!r}\n".replace("'", '"') for k, v in reference.items())
    text = f"""[scenario]
duration = 8.0
runs = 2
references = ["sinusoid", "trajectory"]
oosm = ["replay"]
fusion = ["difference"]
baselines = []
[filter]
q = 0.05
p0_std = [0.01, 0.05]
[control]
poles = 5.0
[reference]
amplitude = [0.8, 0.5]
period = 10.0
offset = [0.1, -0.2]
phase = [1.5707963267948966, 0.0]
cycles = [1, 2]
file = "data/{csv_name}"
{extra}[[nodes]]
noise_scale = 1.0
[[nodes]]
noise_scale = 1.25
[[grid]]
d = [0, 0]
p = 0.0
[[grid]]
d = [4, 6]
p = 0.8
"""
    path = tmp_path / "sc" / "eight.toml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize("orders", [2, 0])
def test_simulate_closes_the_loop_on_the_file_like_on_the_closed_form(tmp_path, capsys, orders):
    """The same figure eight as a closed-form sinusoid and as a CSV beside the scenario (path
    relative to it): the two references differ by at most the bounds above (below 1e-4 and 1e-3
    of each flag's scale, with derivatives and fitted), the loop is stable (poles at -5 rad/s), so
    the tracking and estimation RMSE agree to 1e-3 relative (measured: 4e-14 with derivatives,
    5e-7 fitted)."""
    (tmp_path / "sc" / "data").mkdir(parents=True)
    write_csv(tmp_path / "sc" / "data" / "eight.csv", np.arange(-2, 820) * 0.01, orders)
    spec = _scenario(tmp_path, "eight.csv")
    result = api.simulate("unicycle", scenario=spec, quiet=True)
    capsys.readouterr()
    assert result.ok and not result.failures
    for metric in ("rmse_master", "rmse_tracking"):
        closed = result.table("sinusoid", "replay", "difference").mean(metric)
        given = result.table("trajectory", "replay", "difference").mean(metric)
        np.testing.assert_allclose(given, closed, rtol=1e-3, err_msg=metric)


def test_verify_and_a_starting_scenario_on_a_file(tmp_path, capsys, monkeypatch):
    """`codegen scenario --trajectory` names the CSV relative to the scenario it writes and
    calibrates q on it (master NEES within 10% of n = 4, or below n with q at the match's floor,
    a decade under the residual's: nees_match.NEES_FLOOR); `verify` records that reference and the
    C equals it; `simulate` runs it from another folder."""
    (tmp_path / "data").mkdir()
    write_csv(tmp_path / "data" / "eight.csv", np.arange(0, 1001) * 0.01, 0)
    out = tmp_path / "sc" / "start.toml"
    out.parent.mkdir()
    monkeypatch.chdir(tmp_path)
    assert cli.main(["scenario", "unicycle", "--trajectory", "data/eight.csv", "--out", str(out)]) == 0
    text = out.read_text()
    assert 'file = "../data/eight.csv"' in text and 'references = ["trajectory"]' in text
    line = text.split(f"master NEES over {nees_match.NEES_RUNS} runs without delays: ")[1].split("\n")[0]
    nees = float(line.split()[0])
    if "q lowered at most" in line:   # the floor: the residual's q (closed loop) times NEES_FLOOR
        residual = np.array(json.loads(text.split("along the closed loop: q = ")[1].split("\n")[0]))
        written = np.array(json.loads(line.split("at q = ")[1].split(" (")[0]))
        # both printed to 3 significant digits: equal to 1% (the rounding of two such numbers)
        np.testing.assert_allclose(written, nees_match.NEES_FLOOR * residual, rtol=1e-2)
        assert nees < 4, text
    else:
        assert abs(math.log(nees / 4)) <= math.log(1.1), text
    monkeypatch.chdir(out.parent)
    assert cli.main(["verify", "unicycle", "--scenario", "start.toml"]) == 0
    assert "start, trajectory, delays" in capsys.readouterr().out
    monkeypatch.chdir("/")
    sc = scenario_mod.load(str(out))
    assert sc.references == ["trajectory"] and sc.duration == 10.0


GOOD = "t,x,y\n" + "".join(f"{k * 0.05!r},{math.cos(k * 0.05)!r},{math.sin(k * 0.05)!r}\n" for k in range(400))


def _edit(row: int, col: int, value: str) -> str:
    lines = GOOD.split("\n")
    cells = lines[row].split(",")
    cells[col] = value
    lines[row] = ",".join(cells)
    return "\n".join(lines)


def _with_column(name: str, value: str) -> str:
    head, *rows = [line for line in GOOD.split("\n") if line]
    return "\n".join([f"{head},{name}"] + [f"{row},{value}" for row in rows]) + "\n"


BAD = [
    ("missing column", GOOD.replace("t,x,y", "t,x,z"), "eight.csv: no column 'y' for flat output y"),
    ("unknown column", _with_column("w", "1"),
     "eight.csv:1: column 'w' is not t, a flat output of model unicycle (x, y)"),
    ("nan", _edit(7, 1, "nan"), "eight.csv:8: column x: nan is not a finite number"),
    ("text", _edit(9, 2, "abc"), "eight.csv:10: column y: 'abc' is not a number"),
    ("time back", _edit(7, 0, "0.25"), "eight.csv:8: t = 0.25 s is not after the previous row's 0.25 s"),
    ("too short", "t,x,y\n0,1,0\n", "eight.csv: 1 sample row(s): a trajectory needs at least 2"),
    ("short run", "\n".join(GOOD.split("\n")[:101]) + "\n", "eight.csv:101: ends at t = 4.95 s, shorter than the run"),
    ("late start", "t,x,y\n" + GOOD.split("\n", 2)[2], "eight.csv:2: starts at t = 0.05 s, after the run's start"),
    ("partial derivatives", _with_column("x_d2", "0"),
     "eight.csv: column x_d1 missing: x_d2 given; output x needs every derivative up to x_d2"),
    ("few for the fit", "t,x,y\n" + "".join(f"{k * 2.0},1,0\n" for k in range(6)),
     "eight.csv: 6 rows: fitting x up to its derivative of order 2 needs at least 9 samples"),
    ("header", "time,x,y\n0,1,0\n", "eight.csv:1: column 1 is 'time': the first column must be t"),
]


@pytest.mark.parametrize("label, text, expected", BAD, ids=[b[0] for b in BAD])
def test_a_bad_trajectory_is_one_line_naming_file_and_row_or_column(tmp_path, capsys, label, text, expected):
    (tmp_path / "sc" / "data").mkdir(parents=True)
    (tmp_path / "sc" / "data" / "eight.csv").write_text(text)
    spec = _scenario(tmp_path, "eight.csv")
    assert cli.main(["simulate", "unicycle", "--scenario", spec, "--runs", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "eight.toml:" in err and "reference.file" in err and expected in err, err


def test_scenario_reads_its_trajectory_before_the_derivation(tmp_path, monkeypatch, capsys):
    """`codegen scenario --trajectory F`: a missing file, or shape options beside one, are said
    before the model's derivation (a minute for a large user model), in one line."""
    from dfeif_codegen.experiment import derivation

    def derive(*_args, **_kwargs):
        raise AssertionError("derived before the trajectory file was read")
    monkeypatch.setattr(derivation, "derive", derive)
    missing = tmp_path / "nope.csv"
    assert cli.main(["scenario", "dc_motor_link", "--trajectory", str(missing)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope.csv" in err[0]
    assert cli.main(["scenario", "dc_motor_link", "--trajectory", str(missing), "--period", "3"]) == 2
    assert "--period do not apply" in capsys.readouterr().err
