"""Closed loops that go wrong say so (issue 11): a run whose state leaves the declared domain has
diverged, `simulate` names the run, the time and the cause, exits 1 and lists it in the JSON;
`verify` builds the C at the scenario's sampling period."""

import json
import re
from importlib import resources

import numpy as np
import pytest

from dfeif_codegen import cli
from dfeif_codegen.check import harness
from dfeif_codegen.errors import CodegenError
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import divergence

MOTOR = (resources.files("dfeif_codegen") / "models" / "dc_motor_link.toml").read_text()
# the motor with its speed declared to stay within +-0.5 rad/s
NARROW = MOTOR.replace('unit = "rad/s"', 'unit = "rad/s"\nmin = -0.5\nmax = 0.5', 1)
# a reference that stays inside (omega_d <= 0.35 * 2 pi / 5 = 0.44 rad/s) but a true initial speed
# drawn with std 2 rad/s: the plant starts outside the domain in all but ~20% of seeds
SCENARIO = """
[scenario]
duration = 1.0
runs = 2
metrics_from = 0.2
references = ["sinusoid"]
fusion = ["difference"]
baselines = []
[reference]
amplitude = 0.35
[filter]
p0_std = [0.01, 2.0, 1.0]
"""


@pytest.fixture
def narrow(tmp_path):
    path = tmp_path / "narrow.toml"
    path.write_text(NARROW)
    return path


def test_leaving_the_domain_is_divergence_with_time_and_cause(narrow):
    cfg = ex.Config(model=str(narrow), duration=2.0, amplitude=(0.35,), p0_std=(0.01, 2.0, 1.0), metrics_from=0.5)
    with pytest.raises(divergence.Diverged, match=r"diverged at t = 0\.00 s: state omega = (\S+) left its domain \[-0\.5, 0\.5\]") as err:
        ex.run(cfg)
    # the value named is the state's, outside the domain (p0_std 2 rad/s on omega's chain)
    assert abs(float(re.search(r"omega = (\S+) left", str(err.value)).group(1))) > 0.5
    # the same run on the undeclared model is fine: the domain, not the numbers, made it fail
    wide = ex.run(ex.Config(duration=0.5, amplitude=(0.35,), p0_std=(0.01, 2.0, 1.0), metrics_from=0.1))
    assert wide.metrics["rmse_master"][0] < 0.1


def test_simulate_exits_1_and_lists_the_failed_runs(narrow, tmp_path, capsys):
    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO)
    out = tmp_path / "r.json"
    assert cli.main(["simulate", str(narrow), "--scenario", str(scenario), "--quiet", "--json", str(out)]) == 1
    err = capsys.readouterr().err
    assert "run(s) failed or diverged" in err and "left its domain" in err
    failures = json.loads(out.read_text())["failures"]
    assert failures, "the JSON must list the failed runs"
    for line in failures:
        assert line.startswith("sinusoid replay difference row 1 seed ") and "diverged at t = " in line
        assert "state omega" in line and "left its domain [-0.5, 0.5]" in line


def test_verify_builds_at_the_scenarios_sampling_period(tmp_path, monkeypatch, capsys):
    scenario = tmp_path / "fast.toml"
    scenario.write_text("[scenario]\nts = 0.005\nduration = 1.0\nmetrics_from = 0.2\n")
    seen = {}

    def stop(*args, **kw):
        seen.update(kw)
        raise CodegenError("stopped after the build options were seen")
    monkeypatch.setattr(harness, "build_model", stop)
    assert cli.main(["verify", "--scenario", str(scenario)]) == 2
    assert seen["ts"] == 0.005      # the model's own ts is 0.01: the recording is at the scenario's


def test_nees_watch_needs_fifty_high_steps_in_a_row():
    from dfeif_codegen.symbolic import model

    watch = ex.DivergenceWatch(model.load("dc_motor_link"))
    P, x = np.eye(3), np.zeros(3)
    high = np.array([200.0, 0.0, 0.0])       # NEES 4e4 > 1e4 n = 3e4
    low = np.array([1.0, 0.0, 0.0])          # NEES 1: a consistent filter's typical value
    for k in range(divergence.NEES_STEPS - 1):
        watch.step(k * 0.01, x, high, P)
    watch.step(0.49, x, low, P)              # one ordinary step resets the count
    for k in range(divergence.NEES_STEPS - 1):
        watch.step(0.5 + k * 0.01, x, high, P)
    with pytest.raises(divergence.Diverged, match=r"t = 0\.99 s: master NEES above 10000 n = 30000 for 50 steps \(now 4e\+04\)"):
        watch.step(0.99, x, high, P)
    with pytest.raises(divergence.Diverged, match="not finite"):
        ex.DivergenceWatch(model.load("dc_motor_link")).step(0.0, np.array([np.nan, 0, 0]), low, P)
