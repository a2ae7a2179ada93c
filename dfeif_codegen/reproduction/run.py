"""`codegen reproduce`: one command for every table and figure of docs/experiment.md.

It runs the `simulate` calls the document is made of (tasks.py: both built-in models, every
late-measurement method and fusion rule, the EKF/UKF comparison, the q sweep) on local processes
or a Dask cluster, each stored in OUT/tasks keyed by its settings (a rerun skips finished tasks),
derives the document's numbers into OUT/experiment.json and renders OUT/experiment.md through
templates/docs/experiment.md.j2 (document.py), with the figures in OUT/figures.
"""

from __future__ import annotations

import json
import re
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.paths import OutputPathError, check_figure_paths, file_head, json_keys, replaceable_file
from dfeif_codegen.reproduction import document
from dfeif_codegen.reproduction.tasks import FULL, QUICK, check_out, run_task


@dataclass
class Reproduction:
    """What `codegen reproduce` made: the document's data, its text, where they were written."""

    data: dict
    text: str
    out: str
    elapsed_s: float
    written: list[str] = field(default_factory=list)

    @property
    def failures(self) -> int:
        return sum(t["failures"] for t in self.data["tasks"].values())

    def to_json(self) -> str:
        return json.dumps(self.data)

    def report(self) -> str:
        tasks = self.data["tasks"]
        lines = [f"codegen reproduce: {len(tasks)} task(s), {self.data['runs']} runs each, "
                 f"{self.elapsed_s:.0f} s{' (--quick)' if self.data['quick'] else ''}"]
        for name, t in tasks.items():
            failed = f", {t['failures']} failed" if t["failures"] else ""
            lines.append(f"  {name}: {t['model']}, {t['distinct_runs']} runs in {t['elapsed_s']:.0f} s{failed}")
        lines += [f"wrote {path}" for path in self.written]
        return "\n".join(lines)


def _comparison_figures(data: dict, out: Path) -> None:
    """The filter comparison's bar charts (master RMSE per filter and row), one per model."""
    from dfeif_codegen.experiment import closed_loop, figures

    for name, t in data["tasks"].items():
        blocks = t["blocks"].get("sinusoid", {})
        if not t["filters"] or not blocks:
            continue
        series = {}
        for k in t["filters"]:
            rows = blocks.get(f"{k}-replay + difference") or []
            if rows and all(rows):
                series[k] = ([[c[0] for c in r["master"]] for r in rows], [[c[1] for c in r["master"]] for r in rows])
        path = out / "figures" / f"compare_{t['model']}.png"
        figures.comparison_figure(path, f"{t['model']}: master RMSE per filter (95% intervals), same recordings",
                                  closed_loop._flat(t["model"]), t["rows"], series)
        t["figures"].append(str(path.relative_to(out)))


def publish(text: str, data: dict, out: Path, doc: Path) -> list[str]:
    """docs/experiment.md, the data it was rendered from (docs/experiment.json: a test renders
    it again and compares) and the figures it shows (copied beside it, same relative paths).
    Every figure's path is checked before anything is written: the document's earlier figures
    were checked before the runs (check_doc), a new figure's name is known only now."""
    figures = figure_links(text)
    try:
        check_figure_paths(doc.parent, figures, "--doc (its figure)", "reproduce")
    except OutputPathError as exc:
        raise OutputPathError(f"{exc} (the runs are kept in {out / 'tasks'}: a rerun only renders)") from None
    doc.parent.mkdir(parents=True, exist_ok=True)
    data_file = doc.with_suffix(".json")
    data_file.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    written = [str(doc), str(data_file)]
    for rel in figures:
        target = doc.parent / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        if target.resolve() != (out / rel).resolve():    # --doc inside OUT: the figure is there already
            shutil.copyfile(out / rel, target)
        written.append(str(target))
    doc.write_text(text, encoding="utf-8")
    return written


GENERATED = "This document is generated: `codegen reproduce"   # near the top of every rendering
FIGURE_LINK = re.compile(r"^!\[[^\]]*\]\((figures/[^)]+)\)", re.M)


def figure_links(text: str) -> list[str]:
    """The figures a rendering shows, relative to it: its `![...](figures/...)` lines."""
    return FIGURE_LINK.findall(text)


def check_doc(doc: Path) -> None:
    """`--doc FILE`, the data file beside it and the figures its earlier rendering shows, before
    any run: new, or written by an earlier `codegen reproduce` (the document's generated line;
    the data's keys; a matplotlib PNG)."""
    replaceable_file(doc, "--doc", "reproduce", lambda p: GENERATED in _text(p))
    data = doc.with_suffix(".json")
    if data != doc:
        replaceable_file(data, "--doc (its data file)", "reproduce", _is_data)
    if doc.is_file():
        check_figure_paths(doc.parent, figure_links(doc.read_text(encoding="utf-8", errors="replace")),
                           "--doc (its figure)", "reproduce")


def check_results(out: Path) -> None:
    """OUT/experiment.md and OUT/experiment.json, before any run: new, or an earlier rendering's."""
    if out.is_dir():
        replaceable_file(out / "experiment.md", "--out", "reproduce", lambda p: GENERATED in _text(p))
        replaceable_file(out / "experiment.json", "--out", "reproduce", _is_data)


def _is_data(path: Path) -> bool:
    return {"runs", "quick", "tasks", "chapter", "facts"} <= json_keys(path)


def _text(path: Path) -> str:
    return file_head(path).decode("utf-8", "replace")


def reproduce(runs: int = 100, out: str = "reproduce", *, workers: int | None = None, scheduler: str | None = None,
              quick: bool = False, doc: str | None = None, quiet: bool = False) -> Reproduction:
    """Run (or reuse) every task, derive the numbers, render the document into OUT and, with
    `doc`, also to that path with its figures beside it. Bad input raises before any run."""
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 2:
        raise ScenarioError(f"--runs {runs}: at least 2 (the tables give 95% intervals over the runs)")
    folder = Path(out)
    if doc:                 # before check_out, which makes OUT
        check_doc(Path(doc))
    check_results(folder)
    check_out(folder)
    from dfeif_codegen import api

    start = time.time()
    results = {}
    for task in QUICK if quick else FULL:
        if not quiet:
            print(f"codegen reproduce: {task.name} ({task.model}, {runs} runs)", file=sys.stderr)
        results[task.name] = run_task(task, runs, folder, api.simulate, workers, scheduler)
    data = {"runs": runs, "quick": quick, "tasks": {k: document.derive(v) for k, v in results.items()},
            "chapter": document.chapter_tables()}
    data["facts"] = document.facts(data)
    _comparison_figures(data, folder)
    text = document.render(data)
    (folder / "experiment.json").write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    (folder / "experiment.md").write_text(text, encoding="utf-8")
    written = [str(folder / "experiment.json"), str(folder / "experiment.md")]
    if doc:
        written += publish(text, data, folder, Path(doc))
    return Reproduction(data, text, str(folder), time.time() - start, written)
