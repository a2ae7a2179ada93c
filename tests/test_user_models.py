"""Models a user writes, not the built-ins: a relative degree of 4, mixed degrees over two inputs,
cameras that measure the flat outputs directly, a model without any [measurement]. Every one goes
through `codegen verify`: its generated C must reproduce the reference on its own scenario."""

from pathlib import Path

import numpy as np
import pytest

from dfeif_codegen import cli
from dfeif_codegen.symbolic import model
from dfeif_codegen.experiment.plant import Camera

# A flexible-joint link (Spong): the link angle is flat with relative degree 4. No [measurement].
FLEX_JOINT = """
[model]
name = "flex_joint"
ts = 0.01
[[states]]
name = "q1"
[[states]]
name = "w1"
[[states]]
name = "q2"
[[states]]
name = "w2"
[[inputs]]
name = "u"
[[parameters]]
name = "MgL"
value = 0.8
[[parameters]]
name = "I"
value = 0.03
[[parameters]]
name = "Jm"
value = 0.004
[[parameters]]
name = "k"
value = 31.0
[dynamics.f]
q1 = "w1"
w1 = "-MgL/I*sin(q1) - k/I*(q1 - q2)"
q2 = "w2"
w2 = "k/Jm*(q1 - q2)"
[dynamics.g.u]
w2 = "1/Jm"
[[outputs]]
name = "q1"
expr = "q1"
angle = true
"""

# Two inputs, relative degrees 2 and 3, a non-angle output; cameras see the flat outputs directly.
MIXED = """
[model]
name = "mixed"
ts = 0.01
[[states]]
name = "s"
[[states]]
name = "sd"
[[states]]
name = "a"
[[states]]
name = "ad"
[[states]]
name = "cur"
[[inputs]]
name = "F"
[[inputs]]
name = "V"
[[parameters]]
name = "J"
value = 0.05
[dynamics.f]
s = "sd"
sd = "(-5*s - 0.3*sd + 0.5*sin(a))/2"
a = "ad"
ad = "(cur - 0.1*ad + 0.2*s)/J"
cur = "(-cur - 0.3*ad)/0.02"
[dynamics.g.F]
sd = "0.5"
[dynamics.g.V]
cur = "50"
[[outputs]]
name = "pos"
expr = "s"
[[outputs]]
name = "ang"
expr = "a"
angle = true
[measurement.noise]
pos = 0.002
ang = 0.004
"""

# Seven integrators in one chain: info and the master's kernels have more than their
# kernels.LOOP_OPS operations, so they are printed as C loops (the format and MISRA tests cover
# that code; node_predict's loops, from 13 integrators on, are checked against the straight line
# in tests/test_c_compile.py, and so are the master's).
LONG_CHAIN = ("[model]\nname = \"long_chain\"\nts = 0.01\n"
              + "".join(f'[[states]]\nname = "x{i}"\n' for i in range(1, 8))
              + '[[inputs]]\nname = "u"\n[[parameters]]\nname = "b"\nvalue = 2.0\n[dynamics.f]\n'
              + "".join(f'x{i} = "x{i + 1}"\n' for i in range(1, 7)) + 'x7 = "0"\n'
              + '[dynamics.g.u]\nx7 = "b"\n[[outputs]]\nname = "y"\nexpr = "x1"\n[measurement.noise]\ny = 0.01\n')

SCENARIO = """
[scenario]
name = "user"
duration = 6.0
references = ["sinusoid"]
[filter]
q = {q}
p0_std = [0.05, 0.1, 1.0, 10.0]
[control]
poles = 8.0
[reference]
amplitude = 0.5
[[nodes]]
{noise1}
[[nodes]]
{noise2}
[[grid]]
d = [0, 0]
p = 0.0
[[grid]]
d = [4, 6]
p = 0.8
"""


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def test_cameras_that_measure_the_flat_outputs(tmp_path):
    """[measurement.noise] alone: a camera observes each flat output plus noise of that std, so the
    recovered outputs' covariance is diag(std^2) and a frame is h(x) + std * noise."""
    mdl = model.load(_write(tmp_path, "mixed.toml", MIXED))
    cam = Camera(mdl, scale=1.5)
    np.testing.assert_array_equal(cam.R, np.diag([(1.5 * 0.002) ** 2, (1.5 * 0.004) ** 2]))
    x, noise = np.array([0.3, -1.0, 0.7, 2.0, 0.1]), np.array([0.5, -2.0])
    # two products and a sum of O(1) numbers: the only difference is rounding order (<= 2 ulps)
    np.testing.assert_allclose(cam.measure(x, noise), [0.3 + 1.5 * 0.002 * 0.5, 0.7 - 1.5 * 0.004 * 2.0],
                               rtol=0, atol=1e-15)


def test_direct_measurement_needs_one_std_per_flat_output(tmp_path, capsys):
    path = _write(tmp_path, "bad.toml", MIXED.replace("ang = 0.004\n", "angle = 0.004\n"))
    assert cli.main(["inspect", path]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "measurement.noise" in err and "pos, ang" in err


def test_builtin_scenario_that_does_not_fit_says_what_to_do(tmp_path, capsys):
    """The paper scenario has three P0 orders; a relative degree of 4 needs four."""
    path = _write(tmp_path, "flex.toml", FLEX_JOINT)
    assert cli.main(["verify", path]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "p0_std" in err and "--scenario FILE" in err
    assert "`codegen scenario MODEL --out FILE`" in err


def test_builtin_scenario_whose_reference_leaves_the_model_says_what_to_do(capsys):
    """The paper scenario's 0.5 rad sinusoid asks the hydraulic actuator of the tests for a
    pressure above its declared 9e6 Pa: the reference fails before any C runs, and the one line
    says so and names the command that writes a scenario for the model."""
    model_path = str(Path(__file__).parent / "data" / "hydraulic.toml")
    assert cli.main(["verify", model_path]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "the Python reference itself failed" in err and f"`codegen scenario {model_path} --out FILE`" in err


@pytest.mark.parametrize("which, options", [
    ("flex", ["--oosm", "retrodict"]),
    ("flex", ["--precision", "float", "--predictor", "brunovsky"]),
    # open: in float the held predictor evaluates v = F(z) + G(z) u at the node, and on this
    # stiff joint the two terms are 1e4 times v (the spring's torque against the motor's): u's
    # own rounding leaves v about 3 digits. F-bar no longer cancels the spring's deflection
    # (symbolic/conditioning.py: the nodes' jerk 2.5e-3 / 7.0e-4 from the double reference before,
    # 2.8e-4 / 5.9e-5 after, the master's 1.0e-2 -> 1.0e-3), but the float32 reference drifts as
    # far (2.8e-4 on a node, 1.4e-3 on the master): verify calls it ill-conditioned (measured)
    pytest.param("flex", ["--precision", "float"], marks=pytest.mark.xfail(
        strict=True, reason="held predictor in float on a stiff degree-4 chain: F(z) + G(z) u cancels digits")),
    ("mixed", ["--precision", "float", "--fusion", "ci"]),
    ("mixed", ["--oosm", "retrodict", "--fusion", "paper"]),
    # the scheduled transition: Φ(σ) of a user's model, both precisions
    ("flex", ["--predictor", "scheduled"]),
    ("mixed", ["--predictor", "scheduled", "--fusion", "ci"]),
    ("mixed", ["--predictor", "scheduled", "--precision", "float"]),
    # the mean in three ETD2RK steps per period ([model] mean_substeps), both precisions
    ("mixed3", []),
    ("mixed3", ["--precision", "float", "--predictor", "scheduled"]),
])
def test_user_model_verifies_on_its_own_scenario(which, options, tmp_path, capsys):
    """The generated C of a user's model, run on the user's scenario (delays (4, 6, 0.8)),
    reproduces the reference: double to 1e-10, float to 1e-4 (verify's tolerances)."""
    if which == "flex":
        path = _write(tmp_path, "flex.toml", FLEX_JOINT)
        noise = ("noise_std = [0.004]", "noise_std = [0.005]")
        q = "200.0"
    else:
        text = MIXED.replace("ts = 0.01", "ts = 0.01\nmean_substeps = 3") if which == "mixed3" else MIXED
        assert text != MIXED or which == "mixed"
        path = _write(tmp_path, "mixed.toml", text)
        noise = ("noise_scale = 1.0", "noise_scale = 1.25")
        q = "[0.5, 20.0]"     # per chain: a spring-mass position needs far less than the motor angle
    scenario = _write(tmp_path, "user.toml", SCENARIO.format(q=q, noise1=noise[0], noise2=noise[1]))
    assert cli.main(["verify", path, "--scenario", scenario, *options]) == 0
    out = capsys.readouterr().out
    assert "delays d = (4, 6), p = 0.8" in out and out.rstrip().endswith("PASS")
    assert "late measurements (0 applied)" not in out

