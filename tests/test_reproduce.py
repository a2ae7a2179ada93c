"""`codegen reproduce`: one command runs the documented experiment (here its --quick subset at 2
seeds), resumes from what it stored, and renders docs/experiment.md in which every number is the
run's (or a fixed fact written in the template); the committed document is that rendering."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

from dfeif_codegen.reproduction import document

ROOT = Path(__file__).resolve().parents[1]
# A number standing alone: not part of a name (x1, P0, fig13), a version or a path.
NUMBER = re.compile(r"(?<![\w.\-/])-?\d+(?:\.\d+)?(?:e[+-]\d+)?(?![\w/])")


def numbers_in(value) -> list[float]:
    """Every number in the JSON data: values, and numbers inside its strings (row labels)."""
    if isinstance(value, dict):
        return [x for v in value.values() for x in numbers_in(v)]
    if isinstance(value, list):
        return [x for v in value for x in numbers_in(v)]
    if isinstance(value, bool) or value is None:
        return []
    if isinstance(value, (int, float)):
        return [float(value)] if math.isfinite(value) else []
    return [float(t) for t in NUMBER.findall(str(value))]


def half_unit(token: str) -> float:
    """Half a unit of the token's last printed digit: how far the value it was rounded from can be."""
    mantissa, _, exponent = token.partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 0.5 * 10.0 ** (int(exponent or 0) - decimals)


def unmatched(text: str, data: dict, literal: set[str]) -> list[str]:
    """Numeric tokens of `text` that are neither a literal of the template nor a value of the
    data rounded as printed."""
    values = sorted(numbers_in(data))
    import bisect

    bad = []
    for line in text.splitlines():
        for token in NUMBER.findall(line):
            if token in literal:
                continue
            v, tol = float(token), half_unit(token) * (1 + 1e-9) + 1e-300
            i = bisect.bisect_left(values, v - tol)
            if not (i < len(values) and values[i] <= v + tol):
                bad.append(f"{token} in: {line[:120]}")
    return bad


def literals() -> set[str]:
    return set(NUMBER.findall(document.template_text()))


def run_cli(*args, timeout=600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "dfeif_codegen", "reproduce", *args], capture_output=True, text=True,
                          timeout=timeout, cwd=ROOT)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    doc = out / "docs" / "experiment.md"
    doc.parent.mkdir()   # --doc names a file of an existing folder, as every output file
    proc = run_cli("--runs", "2", "--quick", "--out", str(out), "--doc", str(doc), "--quiet", "--workers", "2")
    assert proc.returncode == 0, proc.stderr
    return out, doc, proc


def test_every_number_of_the_document_comes_from_the_run(quick):
    out, doc, _ = quick
    data = json.loads((out / "experiment.json").read_text())
    text = doc.read_text()
    assert text == (out / "experiment.md").read_text()
    assert unmatched(text, data, literals()) == []
    # and the check can fail: a number the run did not produce is found
    assert unmatched("| (0, 0, 0.0) | 7.777e+07 ± 1e-04 |", data, literals()) == \
        ["7.777e+07 in: | (0, 0, 0.0) | 7.777e+07 ± 1e-04 |"]


def test_tables_are_the_simulate_results(quick):
    """Independent of document.derive: Table IV's cells are simulate's JSON (the stored task)."""
    out, doc, _ = quick
    task = json.loads(next((out / "tasks").glob("motor-*.json")).read_text())
    table = next(t for t in task["tables"] if (t["reference"], t["method"], t["fusion"]) ==
                 ("sinusoid", "replay", "difference"))
    text = doc.read_text()
    section = text[text.index("**Table IV: RMSE of the estimation error at the master**"):]
    lines = [ln for ln in section.splitlines() if re.match(r"\| \(\d", ln)][:len(task["rows"])]
    for row, summary, line in zip(task["rows"], table["rows"], lines):
        mean, half = summary["rmse_master"]["mean"], summary["rmse_master"]["ci95"]
        label = "(" + ", ".join(map(str, row["d"])) + f", {row['p']:.1f})"
        assert line == f"| {label} | " + " | ".join(f"{m:.3e} ± {h:.0e}" for m, h in zip(mean, half)) + " |"


def test_the_chapter_tables_as_printed(quick):
    _, doc, _ = quick
    text = doc.read_text()
    chapter = document.chapter_tables()
    for name in ("I", "II", "III", "IV"):
        for values in chapter["tables"][name]["values"]:
            assert " | ".join(f"{v:.3e}" for v in values) in text
    assert sum(bool(r["lost"]) for r in chapter["rows"]) == 3
    assert text.count(" † |") == 2 * 3   # both comparison tables mark the three rows


def test_figures_written_and_published(quick):
    out, doc, _ = quick
    shown = re.findall(r"\]\((figures/[^)]+\.png)\)", doc.read_text())
    assert any("compare_dc_motor_link" in p for p in shown) and any("master_delay" in p for p in shown)
    for rel in shown:
        assert (doc.parent / rel).stat().st_size > 10_000


def test_rerun_reuses_every_task(quick):
    out, doc, _ = quick
    stamps = {p: p.stat().st_mtime_ns for p in (out / "tasks").glob("*.json")}
    before = doc.read_text()
    proc = run_cli("--runs", "2", "--quick", "--out", str(out), "--quiet", timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert {p: p.stat().st_mtime_ns for p in (out / "tasks").glob("*.json")} == stamps
    assert (out / "experiment.md").read_text() == before


def test_committed_document_is_the_rendering_of_its_data():
    """docs/experiment.md is what `codegen reproduce --doc docs/experiment.md` rendered from
    docs/experiment.json with the template in the repository."""
    data = json.loads((ROOT / "docs" / "experiment.json").read_text())
    text = (ROOT / "docs" / "experiment.md").read_text()
    assert document.render(data) == text
    assert unmatched(text, data, literals()) == []
    for rel in re.findall(r"\]\((figures/[^)]+\.png)\)", text):
        assert (ROOT / "docs" / rel).exists(), rel


@pytest.mark.parametrize("args, says", [
    (["--runs", "1"], "--runs 1: at least 2"),
    (["--out", "README.md"], "--out README.md: exists and is not a folder"),
])
def test_bad_input_is_one_line_before_any_run(args, says):
    proc = run_cli(*args, "--quick", timeout=60)
    assert proc.returncode == 2
    assert says in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_every_task_of_the_full_command_is_a_valid_simulate_call(tmp_path):
    """The full list (not run here) passes simulate's own checks: model, scenario variant,
    methods, rules, references and filters, as the test's --quick subset does by running."""
    from dfeif_codegen.experiment.plan import plan
    from dfeif_codegen.reproduction import tasks

    names = [t.name for t in tasks.FULL]
    assert len(set(names)) == len(names) and {t.name for t in tasks.QUICK} <= set(names)
    for task in tasks.FULL:
        scenario = "paper"
        if task.q is not None or task.rows is not None:
            scenario = str(tmp_path / f"{task.name}.toml")
            Path(scenario).write_text(tasks.scenario_text(task.q, task.rows, task.options.get("predictor")))
        o = task.options

        def listed(v):
            return [v] if isinstance(v, str) else v

        p = plan(task.model, scenario, 2, 0, None, 32, listed(o.get("oosm")), listed(o.get("fusion")),
                 listed(o.get("reference")), o.get("filters"), None)
        assert p.runs == 2 and (task.q is None or p.sc.q_for(task.options.get("predictor", "held"))[0] == task.q)
