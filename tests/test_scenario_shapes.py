"""`codegen scenario` for any model: references from the flat outputs' declared domains (shape,
amplitude, offset, phase), a calibration that fails is exit 2 with the reason, and the scenarios
it writes for a maglev-like, a tank-like and a rotor-like model pass `verify` and close the loop
in `simulate`."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from dfeif_codegen import api, cli
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import scenario, shapes, simulate
from dfeif_codegen.experiment.trajectory import Reference

DATA = Path(__file__).parent / "data"


def test_reference_phase_and_cycles_trace_a_circle_and_a_figure_eight():
    A, T, t = 1.5, 8.0, 0.7
    w = 2 * math.pi / T
    x = Reference("sinusoid", A, T, 0.0, phase=math.pi / 2).flags(t, 2)
    y = Reference("sinusoid", A, T, 0.0).flags(t, 2)
    np.testing.assert_allclose(x, [A * math.cos(w * t), -A * w * math.sin(w * t), -A * w**2 * math.cos(w * t)],
                               rtol=1e-13)
    np.testing.assert_allclose(y, [A * math.sin(w * t), A * w * math.cos(w * t), -A * w**2 * math.sin(w * t)],
                               rtol=1e-13)
    z = Reference("sinusoid", A, T, 0.3, cycles=2).flags(t, 1)
    np.testing.assert_allclose(z, [0.3 + A * math.sin(2 * w * t), 2 * A * w * math.cos(2 * w * t)], rtol=1e-13)


def test_reference_from_domains():
    """The gap (declared [0.004, 0.02], nominal 0.01) swings by a tenth of its width around its
    nominal; the unicycle's circle has equal amplitudes a quarter period apart; given values win."""
    maglev = ex._flat(str(DATA / "maglev_like.toml"))
    s = shapes.from_domains(maglev)
    assert s.amplitude == pytest.approx((0.1 * 0.016,)) and s.offset == pytest.approx((0.01,))
    uni = ex._flat("unicycle")
    c = shapes.from_domains(uni, "circle")
    assert c.amplitude == pytest.approx((0.8, 0.8)) and c.phase == pytest.approx((math.pi / 2, 0.0))
    f = shapes.from_domains(uni, "figure8", amplitude="1.0,0.5", period=20.0)
    assert f.amplitude == (1.0, 0.5) and f.cycles == (1, 2) and f.period == 20.0


@pytest.mark.parametrize("args, needle", [
    # its rate om leaves [-10, 10] rad/s: no q closes that loop (q from 1e-4 to 4.7e7 tried)
    (["pvtol", "--shape", "figure8", "--amplitude", "1.5,0.75"], "every calibration round"),
    ([str(DATA / "tanks_like.toml"), "--period", "5", "--amplitude", "0.2"], "stays where the transform is defined"),
    (["dc_motor_link", "--shape", "circle"], "needs two flat outputs"),
])
def test_scenario_that_cannot_be_made_is_exit_2_with_the_reason(args, needle, tmp_path, capsys):
    assert cli.main(["scenario", *args, "--out", str(tmp_path / "s.toml")]) == 2
    *said, err = capsys.readouterr().err.strip().splitlines()     # a calibration's progress, then the error
    assert needle in err and err.startswith("codegen scenario: error:") and not (tmp_path / "s.toml").exists()
    assert not any(": error:" in line for line in said)


@pytest.mark.parametrize("name, shape", [
    ("maglev_like", []), ("tanks_like", []), ("rotor_like", []),
    ("unicycle", ["--shape", "circle"]), ("pvtol", ["--shape", "figure8"])])
def test_starting_scenario_verifies_and_closes_the_loop(name, shape, tmp_path, capsys):
    """Every replay row of the grid closes, the hardest delays included: the maglev's NEES-matched
    q loses its loop there (the ball drifts onto the magnet, caught by the tracking bound) and the
    calibration raises it by half a decade; the PVTOL's residual q loses every loop and the NEES
    match finds one a decade-step search below it."""
    spec = str(DATA / f"{name}.toml") if name.endswith("_like") else name
    sc = str(tmp_path / "start.toml")
    assert cli.main(["scenario", spec, *shape, "--out", sc]) == 0
    assert cli.main(["verify", spec, "--scenario", sc]) == 0
    assert capsys.readouterr().out.rstrip().endswith("PASS")
    path = tmp_path / "out.json"
    api.simulate(spec, scenario=sc, runs=1, oosm=["replay"], fusion=["difference"], quiet=True, json_path=str(path))
    capsys.readouterr()
    result = json.loads(path.read_text())
    assert not [f for f in result["failures"] if " replay " in f]   # the baselines may fail, replay not
    table = next(t for t in result["tables"] if t["method"] == "replay")
    assert all(row["runs"] == 1 for row in table["rows"])   # every delay row ran to the end


PAPER_TIGHT = (Path(__file__).parents[1] / "dfeif_codegen" / "experiment" / "scenarios" / "paper.toml").read_text() \
    .replace("harmonics = 4", "harmonics = 4\ntracking_bound = 1e-4")


@pytest.mark.parametrize("engine", ["reference", "c"])
def test_a_run_that_stops_tracking_is_a_failure(engine, tmp_path, capsys):
    """The motor tracks its 1 rad sinusoid to about 3 mrad (docs/experiment.md): a bound of 0.1 mrad
    must stop every run, in both engines, with the output named; the default bound (2 rad, twice
    the amplitude) stops none."""
    sc = tmp_path / "tight.toml"
    sc.write_text(PAPER_TIGHT)
    result = api.simulate("dc_motor_link", scenario=str(sc), runs=1, oosm=["replay"], fusion=["difference"],
                          reference=["sinusoid"], quiet=True, engine=engine)
    assert result.failures and all("stopped tracking at t = " in str(f) and "output theta" in str(f)
                                   for f in result.failures)
    result = api.simulate("dc_motor_link", scenario="paper", runs=1, oosm=["replay"], fusion=["difference"],
                          reference=["sinusoid"], quiet=True, engine=engine)
    assert not result.failures




def test_reference_slowed_until_its_input_is_within_limits(tmp_path):
    """A tank (area A = 0.1, outflow a sqrt(h), a = 0.005, inflow limited to [0, 0.01]): the level
    h = 1 + 0.19 sin(2 pi t / T) (a tenth of its [0.1, 2] domain) takes the inflow
    A h' + a sqrt(h), in closed form here on a fine grid. The default 5 s period needs up to 0.029;
    the scenario's reference is the first period of PERIODS whose inflow stays inside [0.001,
    0.009] (a tenth of the range left to the feedback), at the full swing. On it the loop tracks
    to under 1% of the swing, no input clamped (measured 0.53 mm; 106 mm at 5 s, where it was
    clamped 180 steps of 200)."""
    model = DATA / "tank_limited.toml"
    expected = None
    for T in shapes.PERIODS:
        w, t = 2 * math.pi / T, np.linspace(0.0, T, 20001)
        inflow = 0.1 * 0.19 * w * np.cos(w * t) + 0.005 * np.sqrt(1 + 0.19 * np.sin(w * t))
        if inflow.min() >= 0.001 and inflow.max() <= 0.009:
            expected = T
            break
    assert expected is not None and expected > shapes.PERIODS[0]
    out = tmp_path / "tank_start.toml"
    assert cli.main(["scenario", str(model), "--out", str(out)]) == 0
    sc = scenario.load(str(out))
    assert sc.period == expected and sc.amplitude == pytest.approx([0.19])
    cfg = simulate.make_config(sc, str(model), 2, 32, "sinusoid", sc.grid[0], "replay", "difference", 0)
    m = ex.run(cfg).metrics
    assert m["rmse_tracking"][0] < 0.01 * 0.19 and m["saturated_steps"] == 0
