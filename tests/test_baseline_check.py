"""A starting scenario keeps only the baselines that keep the loop (experiment/baseline_check.py)."""

from pathlib import Path

from dfeif_codegen import cli
from dfeif_codegen.experiment import baseline_check, scenario

DATA = Path(__file__).parent / "data"


def test_a_baseline_that_loses_the_loop_is_left_out(tmp_path):
    """The kinematic car of tests/data (dynamic extension on its speed) on the circle that `codegen
    scenario --shape circle` writes for it (tests/data/bicycle_circle.toml, both baselines):
    as-current takes 4-6 step old frames as current, and the car's speed leaves its domain
    [0.2, 5] m/s on the first delayed row (seed 0, at 4.1 s), while discard keeps every loop. The
    check leaves as-current out, saying why in the header; the scenario it leaves then runs clean
    under `simulate --runs 2` (exit 0), where the one with both baselines fails (exit 1)."""
    model = str(DATA / "bicycle.toml")
    both = (DATA / "bicycle_circle.toml").read_text()
    assert scenario.loads(both).baselines == ["discard", "as-current"]
    text, log = baseline_check.kept(both, model, "bicycle_circle.toml")
    assert scenario.loads(text).baselines == ["discard"]
    assert len(log) == 1 and log[0].startswith("baseline as-current left out: under d = 4 with p = 0.8")
    assert "left its domain" in log[0] and f"#   calibration: {log[0]}\n" in text
    for body, code in ((both, 1), (text, 0)):
        path = tmp_path / "s.toml"
        path.write_text(body)
        assert cli.main(["simulate", model, "--scenario", str(path), "--runs", "2"]) == code
