"""The step of the C's centred storage follows the flat outputs' declared ranges.

A flat output that lives on millimetres (tests/data/maglev_like.toml: a ball's gap of 4-20 mm,
Ts = 2 ms), stored in float within 1/16 of a centre that moves by 1/8, is resolved no finer than
it would be absolutely (ulp 9e-10 m), and the filter differentiates that into its rates: the
float master then misses verify's 1e-4. With the step at 1/1024 (the largest power of two under
1/16 of the 16 mm range) it is resolved 16 times finer and passes. The step never changes the
C's results in exact arithmetic, so double builds stay at 1e-10 whatever it is.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from conftest import require_tool
from dfeif_codegen import cli
from dfeif_codegen.codegen import build, centring
from dfeif_codegen.symbolic import model

DATA = Path(__file__).resolve().parent / "data"
MAGLEV = DATA / "maglev_like.toml"

ONE_STATE = """
[model]
name = "scale"
ts = 0.01
[[states]]
name = "a"
{bounds}
[[states]]
name = "b"
[[inputs]]
name = "u"
[dynamics.f]
a = "b"
b = "-a"
[dynamics.g.u]
b = "1"
[[outputs]]
name = "y"
expr = "{expr}"
[measurement]
noise = {{ y = 0.01 }}
"""

SCENARIO = """
[scenario]
name = "maglev_mm"
description = "a millimetre-scale flat output in single precision"
duration = 4
runs = 1
substeps = 10
metrics_from = 1.0
references = ["sinusoid"]
oosm = ["replay"]
fusion = ["difference"]
baselines = []
[filter]
q = [1.4]
p0_std = [0.0001, 0.0003, 0.0008]
initial_error = true
[control]
poles = 50
[reference]
amplitude = [0.002]
period = 2
offset = [0.012]
phase = [0]
cycles = [1]
harmonics = 4
[[nodes]]
noise_scale = 1
[[nodes]]
noise_scale = 1.25
[[grid]]
d = [4, 6]
p = 0.8
"""


def _model(tmp_path, bounds: str, expr: str = "a"):
    path = tmp_path / "scale.toml"
    path.write_text(ONE_STATE.format(bounds=bounds, expr=expr))
    return model.load(str(path))


@pytest.mark.parametrize("bounds, expr, step", [
    ("", "a", 0.125),                                  # no declared range: the coarsest step
    ("min = -0.5", "a", 0.125),                        # one bound only: no range either
    ("min = -1.0\nmax = 1.0", "a", 0.125),             # 2 / 16 = 1/8 exactly
    ("min = -2.0\nmax = 2.0", "a", 0.125),             # 4 / 16 = 1/4: never above 1/8
    ("min = 0.0\nmax = 1.0", "a", 0.0625),             # 1 / 16
    ("min = 0.004\nmax = 0.02", "a", 2.0 ** -10),      # 0.016 / 16 = 1e-3: 1/1024 below it
    ("min = 0.0\nmax = 0.01", "a + b", 0.125),         # b has no range: nor has a + b
    ("min = 1.0\nmax = 1.0000000000001", "a", 2.0 ** -40),   # a range of 1e-13: the finest step
])
def test_the_step_is_a_power_of_two_under_a_sixteenth_of_the_range(tmp_path, bounds, expr, step):
    assert centring.centre_steps(_model(tmp_path, bounds, expr)) == [step]


def test_an_expression_output_takes_its_sampled_range(tmp_path):
    """y = 2a over a in [0, 0.01]: a range just under 0.02 (sampled), 0.02 / 16 = 1.25e-3, so
    1/1024; the sampled range never exceeds the true one, so the step is never coarser."""
    mdl = _model(tmp_path, "min = 0.0\nmax = 0.01", "2*a")
    (width,) = centring.output_ranges(mdl)
    assert 0.018 < width <= 0.02
    assert centring.centre_steps(mdl) == [2.0 ** -10]


def test_the_generated_c_centres_in_that_step(tmp_path):
    """maglev_like's node and master move their centre by 1/1024 (and multiply by its inverse,
    exact for a power of two); the built-in models declare no range as narrow as 2 and keep 1/8."""
    folder = build.build(str(MAGLEV), tmp_path / "maglev", precision="float").path
    assert "The steps: 1/1024." in (folder / "maglev_internal.h").read_text()
    for name in ("maglev_node.c", "maglev_master.c"):
        assert "0.0009765625f, 1024.0f)" in (folder / name).read_text(), name
    folder = build.build("two_link_arm", tmp_path / "arm").path
    assert (folder / "two_link_arm_master.c").read_text().count("0.125, 8.0)") == 2


def test_each_output_has_its_own_step(tmp_path):
    """A narrow output beside one without a range: each keeps its own step, so the other's
    centred range (2^20 steps) is not cut to the narrow one's."""
    path = tmp_path / "two.toml"
    text = ONE_STATE.format(bounds="min = 0.0\nmax = 0.001", expr="a")
    text = text.replace('[[inputs]]\nname = "u"', '[[states]]\nname = "c"\n[[states]]\nname = "e"\n'
                        '[[inputs]]\nname = "u"\n[[inputs]]\nname = "w"')
    text = text.replace('b = "-a"\n', 'b = "-a"\nc = "e"\ne = "-c"\n').replace(
        '[[outputs]]', '[dynamics.g.w]\ne = "1"\n[[outputs]]\nname = "z"\nexpr = "c"\n[[outputs]]')
    text = text.replace("noise = { y = 0.01 }", "noise = { y = 0.01, z = 0.01 }")
    path.write_text(text)
    assert centring.centre_steps(model.load(str(path))) == [0.125, 2.0 ** -14]


def _verify(tmp_path, capsys, *options) -> tuple[int, str]:
    scenario = tmp_path / "mm.toml"
    scenario.write_text(SCENARIO)
    rc = cli.main(["verify", str(MAGLEV), "--scenario", str(scenario), "--precision", "float", *options])
    return rc, capsys.readouterr().out


def _worst(out: str, signal: str) -> float:
    line = next(s for s in out.splitlines() if s.startswith(signal + " "))
    return float(line.split()[1])


def test_a_millimetre_output_verifies_in_single_precision(tmp_path, capsys, monkeypatch):
    """Host float: the master within 1e-4 of the double reference at the model's step (measured
    4–5e-5: single precision's 6e-8 on a stored value under 5e-4 m, through the rates' gains),
    and 3e-4 at the old fixed step of 1/8 on the same recording (the ulp of a 12 mm gap stored
    absolutely, 8 times the other's): the step is what passes it, not the tolerance."""
    rc, out = _verify(tmp_path, capsys)
    assert rc == 0 and out.rstrip().endswith("PASS"), out
    fine = _worst(out, "master.x")
    monkeypatch.setattr(centring, "centre_steps", lambda mdl: [centring.COARSEST] * len(mdl.outputs))
    rc, out = _verify(tmp_path, capsys)
    assert rc != 0 and _worst(out, "master.x") > 1e-4 > fine, out


def test_a_millimetre_output_verifies_on_the_cortex_m4f(tmp_path, capsys):
    require_tool("arm-none-eabi-gcc", "gcc-arm-none-eabi")
    require_tool("qemu-system-arm", "qemu-system-arm")
    rc, out = _verify(tmp_path, capsys, "--target", "cortex-m4f")
    assert rc == 0 and out.rstrip().endswith("PASS"), out
