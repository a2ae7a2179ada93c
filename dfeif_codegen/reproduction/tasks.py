"""`codegen reproduce`, the runs: every `simulate` call behind docs/experiment.md as a task, each
stored in OUT/tasks as JSON under a name keyed by its settings, so a rerun skips what is done (and
an interrupted task continues from its per-run records, simulate's --resume)."""

from __future__ import annotations

import hashlib
import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.experiment import scenario as scenario_mod
from dfeif_codegen.paths import OutputPathError, writable_dir

PAPER = Path(scenario_mod.__file__).parent / "scenarios" / "paper.toml"


@dataclass(frozen=True)
class Task:
    """One `codegen simulate` call: `name` is the document's handle for it; `options` are
    dc.simulate's keywords; `q` and `rows` make a variant of the paper scenario (None: as is)."""

    name: str
    model: str
    options: dict = field(default_factory=dict)
    q: float | None = None
    rows: tuple[int, ...] | None = None
    plot: bool = False

    def settings(self, runs: int) -> dict:
        return {"name": self.name, "model": self.model, "runs": runs, "options": self.options, "q": self.q,
                "rows": list(self.rows) if self.rows else None, "plot": self.plot}

    def key(self, runs: int) -> str:
        """The file name of the task's result: its settings, hashed (a changed setting is a new task)."""
        text = json.dumps(self.settings(runs), sort_keys=True)
        return f"{self.name}-{hashlib.sha256(text.encode()).hexdigest()[:12]}"


# The document's tables are the chapter's filter's (`--predictor brunovsky`): the experiment as the
# chapter ran it, before the held predictor (its section of the document says what it changes).
_CHAPTER = {"predictor": "brunovsky"}
_FILTERS = {"reference": "sinusoid", "oosm": "replay", "fusion": "difference", "filters": "df,ekf,ukf", **_CHAPTER}
_ONE = {"reference": "sinusoid", "oosm": "replay", "fusion": "difference", **_CHAPTER}

# Every table and figure of docs/experiment.md (the document's sections name these tasks).
FULL = [
    Task("motor", "dc_motor_link", _CHAPTER, plot=True),
    Task("arm", "two_link_arm", _CHAPTER),
    Task("methods", "dc_motor_link", {"reference": "sinusoid", "oosm": ["replay", "retrodict"],
                                      "fusion": ["difference", "ci"], **_CHAPTER}),
    Task("filters_motor", "dc_motor_link", _FILTERS),
    Task("filters_arm", "two_link_arm", _FILTERS),
    Task("q60", "dc_motor_link", _ONE, q=60.0),
    Task("q150", "dc_motor_link", _ONE, q=150.0),
]

# A subset for a quick check (the test, CI): the motor's tables and figures, the filter comparison
# on the first and last delay rows.
QUICK = [FULL[0], Task("filters_motor", "dc_motor_link", _FILTERS, rows=(0, 5))]


def scenario_text(q: float | None, rows: tuple[int, ...] | None, predictor: str | None = None) -> str:
    """The paper scenario with another q (of `predictor`'s filters: the scenario gives the
    chapter's its own) and/or only some of its delay rows (indices in order)."""
    text = PAPER.read_text(encoding="utf-8")
    if q is not None:
        text, count = re.subn(r"(?m)^q = [0-9.eE+-]+", f"q = {q!r}", text)
        if count != 1:
            raise ScenarioError(f"{PAPER}: expected one 'q = ...' line")
        if predictor == "brunovsky":      # the chapter's filter takes its own q where one is given
            text = re.sub(r"(?m)^q_brunovsky = [0-9.eE+-]+", f"q_brunovsky = {q!r}", text)
    if rows is not None:
        head, *blocks = text.split("[[grid]]")
        if any(not 0 <= r < len(blocks) for r in rows):
            raise ScenarioError(f"reproduce: rows {list(rows)}: the paper scenario has {len(blocks)} rows")
        text = head + "".join("[[grid]]" + blocks[r].rstrip("\n") + "\n" for r in rows)
    scenario_mod.loads(text, "reproduce variant")   # a bad variant is said before any run
    return text


def check_out(out: Path) -> None:
    """OUT is a folder (made if missing) that can be written, checked before any run."""
    writable_dir(out, "--out")
    try:
        (out / "tasks").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputPathError(f"--out {out}: cannot create it: {exc.strerror}") from None


def run_task(task: Task, runs: int, out: Path, simulate, workers=None, scheduler=None, quiet=True) -> dict:
    """The task's result as simulate's JSON dict: read from OUT/tasks/KEY.json when a previous
    run finished it, else run (continuing OUT/tasks/KEY.jsonl's finished runs) and stored."""
    key = task.key(runs)
    done = out / "tasks" / f"{key}.json"
    if done.exists():
        return json.loads(done.read_text(encoding="utf-8"))
    scenario = "paper"
    if task.q is not None or task.rows is not None:
        path = out / "scenarios" / f"{key}.toml"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(scenario_text(task.q, task.rows, task.options.get("predictor")), encoding="utf-8")
        scenario = str(path)
    records = out / "tasks" / f"{key}.jsonl"
    result = simulate(task.model, scenario=scenario, runs=runs, quiet=quiet, workers=workers, scheduler=scheduler,
                      plot=str(out / "figures" / task.name) if task.plot else None, json_path="-",
                      results=str(records), resume=str(records) if records.exists() else None, **task.options)
    data = result.to_dict()
    data["task"] = task.settings(runs)
    data["figures"] = {}          # the series are drawn already; the document needs the numbers
    data["written"] = [os.path.relpath(p, out) for p in result.written]
    tmp = done.with_suffix(".tmp")
    tmp.write_text(json.dumps(data) + "\n", encoding="utf-8")
    tmp.replace(done)             # a task is done only once its whole result is stored
    return data
