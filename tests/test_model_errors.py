"""Bad model files: one line naming the problem and where, exit code 2, no traceback."""

from importlib import resources

import pytest

from dfeif_codegen import cli
from dfeif_codegen.symbolic import model

MOTOR = (resources.files("dfeif_codegen") / "models" / "dc_motor_link.toml").read_text()

TWO_STATE = """
[model]
name = "toy"
[[states]]
name = "x1"
[[states]]
name = "x2"
[[inputs]]
name = "u1"
[[inputs]]
name = "u2"
[dynamics.f]
x1 = "0"
x2 = "0"
[dynamics.g.u1]
x1 = "1"
x2 = "1"
[dynamics.g.u2]
x1 = "1"
x2 = "1"
[[outputs]]
name = "y1"
expr = "x1"
[[outputs]]
name = "y2"
expr = "x2"
"""

CUBIC = """
[model]
name = "cubic"
[[states]]
name = "x1"
min = -2.0
max = 2.0
[[states]]
name = "x2"
min = -3.0
max = 3.0
[[states]]
name = "x3"
min = -10.0
max = 10.0
[[inputs]]
name = "u"
[[parameters]]
name = "a"
value = 0.3
[dynamics.f]
x1 = "x2"
x2 = "x3"
x3 = "-2*x3"
[dynamics.g.u]
x3 = "1"
[[outputs]]
name = "y"
expr = "x1 + a*x1**3"
"""

CASES = {
    "undeclared name": (MOTOR.replace('omega = "(k_e*I', 'omega = "(k_q*I'), ["k_q", "dynamics.f.omega"]),
    "malformed toml": (MOTOR.replace("[model]", "[model"), ["malformed TOML"]),
    "missing state name": (MOTOR.replace('name = "omega"\nunit', 'unit', 1), ["missing field 'name'"]),
    "missing f entry": (MOTOR.replace('I = "(-k_e*omega - R*I)/L"', ""), ["missing field", "I"]),
    "zero denominator": (MOTOR.replace("value = 0.02", "value = 0.0"), ["J = 0", "denominator"]),
    "hostile expression": (MOTOR.replace('theta = "omega"', "theta = \"__import__('os')\""), ["dynamics.f.theta"]),
    "g-bar identically zero": (MOTOR.replace('I = "1/L"', 'I = "0"'), ["not flat"]),
    "relative degree too low": (MOTOR.replace('expr = "theta"', 'expr = "I"'), ["not flat", "sum to 1"]),
    "singular decoupling": (TWO_STATE, ["singular", "not flat"]),
    "input in f": (MOTOR.replace('theta = "omega"', 'theta = "V"'), ["V"]),
    "wrong output count": (MOTOR.replace('[[outputs]]\nname = "theta"\nexpr = "theta"\nangle = true', ""), ["outputs"]),
    "bad parameter value": (MOTOR.replace("value = 9.81", 'value = "heavy"'), ["value", "number"]),
    "duplicate state": (MOTOR.replace('name = "omega"', 'name = "theta"', 1), ["declared twice"]),
    # Cardano's closed form for x1 rounds away in float32: its thousands of characters are cut
    "inverse exact in double only": (CUBIC, ["states[3]", "exact in double precision", "single precision",
                                             "[inverse]", " ..."]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_model_file_gives_one_line_and_exit_2(case, tmp_path, capsys):
    text, needles = CASES[case]
    path = tmp_path / "bad.toml"
    path.write_text(text)
    code = cli.main(["inspect", str(path)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err and len(err) < 400 + len(str(path))
    assert str(path) in err
    for needle in needles:
        assert needle in err


def test_error_names_the_line(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text(MOTOR.replace('omega = "(k_e*I', 'omega = "(k_q*I'))
    cli.main(["inspect", str(path)])
    line = next(i for i, t in enumerate(path.read_text().splitlines(), 1) if "k_q" in t)
    assert f"{path}:{line}:" in capsys.readouterr().err


def test_unknown_model_and_missing_file(capsys):
    assert cli.main(["inspect", "no_such_model"]) == 2
    assert cli.main(["inspect", "/nonexistent/model.toml"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and "no_such_model" in err[0] and "cannot read" in err[1]


def test_good_file_round_trips_the_builtin(tmp_path):
    path = tmp_path / "motor.toml"
    path.write_text(MOTOR)
    assert model.load(str(path)).f == model.load("dc_motor_link").f


def test_inspect_json_and_version(capsys):
    import json
    assert cli.main(["inspect", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["flat_outputs"][0]["relative_degree"] == 3
    assert info["A_d"][0][2] == pytest.approx(0.01**2 / 2, rel=1e-15)
    with pytest.raises(SystemExit) as stop:
        cli.main(["--version"])
    assert stop.value.code == 0


def test_clashing_words_cover_fresh_builds(tmp_path):
    """model.CLASHING_WORDS holds every w for which a model <a>_w declares a name a model <a>
    declares (both w_t and t follow the prefix in the generated names), from fresh builds of
    three option sets; ab_node, unistd and transport are refused in one line, long_chain is not."""
    import re

    from dfeif_codegen.codegen.build import build
    from dfeif_codegen.errors import ModelError

    suffixes = set()
    for precision, fusion, oosm in (("double", "ci", "retrodict"), ("float", "paper", "replay"),
                                    ("double", "difference", "replay")):
        out = build("two_link_arm", tmp_path / f"{precision}-{fusion}", precision=precision, fusion=fusion,
                    oosm=oosm, compile_check=False).path
        for f in out.iterdir():
            text = f.read_text()
            suffixes |= {s.lower() for s in re.findall(r"\btwo_link_arm_(\w+)", text)}
            suffixes |= {s.lower() for s in re.findall(r"\bTWO_LINK_ARM_(\w+)", text)}
    clashing = {s.split("_")[0] for s in suffixes if "_" in s and s.split("_", 1)[1] in suffixes}
    assert clashing <= model.CLASHING_WORDS, sorted(clashing - model.CLASHING_WORDS)
    text = (resources.files("dfeif_codegen") / "models" / "dc_motor_link.toml").read_text()
    named = lambda name: text.replace('name = "dc_motor_link"', f'name = "{name}"', 1)  # noqa: E731
    for name, why in (("ab_node", "'node' is a word of the generated names"), ("unistd", "standard header"),
                      ("transport", "standard header"), ("my_arm_master", "a model 'my_arm' declares my_arm_master_*")):
        with pytest.raises(ModelError, match=re.escape(why)):
            model.loads_toml(named(name), "m.toml")
    assert model.loads_toml(named("long_chain"), "m.toml").name == "long_chain"
