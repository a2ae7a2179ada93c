"""`codegen reproduce`, the document: the tasks' results turned into the numbers docs/experiment.md
shows (`derive`: every table cell and every number the prose quotes, ratios and ranges included,
so the template only formats), stored as OUT/experiment.json, and rendered through the Jinja2
template `templates/docs/experiment.md.j2` (the prose lives there)."""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

import jinja2
import numpy as np

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.paths import parse_toml

TEMPLATE = ("docs", "experiment.md.j2")   # in the package data dfeif_codegen.templates (templates/ here)
CHAPTER = Path(__file__).with_name("chapter_tables.toml")


def chapter_tables() -> dict:
    """The chapter's Tables I-IV as printed (chapter_tables.toml)."""
    return parse_toml(CHAPTER.read_text(encoding="utf-8"), str(CHAPTER), ScenarioError)


def _cell(summary: dict, key: str, idx=None) -> list:
    m, h = np.asarray(summary[key]["mean"], float), np.asarray(summary[key]["ci95"], float)
    if idx is not None:
        m, h = m[idx], h[idx]
    return [[float(a), float(b)] for a, b in zip(np.atleast_1d(m), np.atleast_1d(h))]


def _row_label(row: dict) -> str:
    return "(" + ", ".join(str(d) for d in row["d"]) + f", {row['p']:.1f})"


def _block(t: dict, nodes: int, runs: int) -> list:
    """Per delay row, the cells of one (reference, method, rule) table (None: every run failed)."""
    out: list[dict | None] = []
    for s in t["rows"]:
        if not s.get("runs"):
            out.append(None)
            continue
        late = s["late_applied"]["mean"] + s["late_rejected"]["mean"]
        out.append({
            "runs": s["runs"], "failed": runs - s["runs"], "trace": _cell(s, "trace_nodes") + _cell(s, "trace_master"),
            "nodes": [_cell(s, "rmse_nodes", i) for i in range(nodes)], "master": _cell(s, "rmse_master"),
            "tracking": _cell(s, "rmse_tracking"),
            "est_tracking": [_cell(s, "rmse_est_tracking_nodes", i)[0] for i in range(nodes)]
            + [_cell(s, "rmse_est_tracking_master")[0]],
            "nees": [[float(m), 100.0 * float(f)] for m, f in
                     zip(s["nees_nodes"]["mean"], s["nees_nodes"]["in_band"])]
            + [[float(s["nees_master"]["mean"]), 100.0 * float(s["nees_master"]["in_band"])]],
            "band": [float(b) for b in s["nees_band"]],
            "late": [float(s["late_applied"]["mean"]), float(s["late_rejected"]["mean"]),
                     100.0 * s["late_rejected"]["mean"] / late if late else 0.0],
            "us": _cell(s, "us_per_step")[0] if "us_per_step" in s else None})
    return out


def _ratios(block: list) -> dict:
    """Master / better node per state (the fusion gain), and master x1 (estimation, tracking)
    against the first row."""
    ok = [b for b in block if b]
    if not ok:
        return {}
    gain = [[b["master"][i][0] / min(node[i][0] for node in b["nodes"]) for i in range(len(b["master"]))]
            if b else None for b in block]
    first = block[0]
    return {"gain": gain,
            "estimation": [b["master"][0][0] / first["master"][0][0] if b and first else None for b in block],
            "tracking": [b["tracking"][0][0] / first["tracking"][0][0] if b and first else None for b in block]}


def _filters(blocks: dict, kinds: list, n: int) -> dict:
    """The filter comparison: per row, each filter's master RMSE over the derivative-free one's
    (ratio of the means over the seeds) and its CPU time per step over the derivative-free one's."""
    df = blocks.get("df-replay + difference")
    out = {}
    for k in kinds:
        b = blocks.get(f"{k}-replay + difference")
        if k == "df" or not b or not df:
            continue
        out[k] = [{"rmse": [b_r["master"][i][0] / d_r["master"][i][0] for i in range(n)],
                   "cpu": b_r["us"][0] / d_r["us"][0]} if b_r and d_r else None for b_r, d_r in zip(b, df)]
    return out


def derive(task: dict) -> dict:
    """The numbers one task contributes to the document."""
    s, n = task["settings"], len(task["states"])
    nodes = s["nodes"]
    blocks: dict = {}
    for t in task["tables"]:
        blocks.setdefault(t["reference"], {})[f"{t['method']} + {t['fusion']}"] = _block(t, nodes, s["runs"])
    ratios = {ref: _ratios(b.get("replay + difference", [])) for ref, b in blocks.items()}
    bounds = [[float(v) for v in b["rmse_central"]] for b in task["bounds"]]
    kinds = s.get("filters", [])
    return {
        "model": s["model"], "runs": s["runs"], "seeds": s["seeds"], "n": n, "nodes": nodes, "states": task["states"],
        "q": s["q"], "ts": s["ts"], "duration": s["duration"], "elapsed_s": float(s["elapsed_s"]),
        "distinct_runs": s["distinct_runs"], "ran_on": s["ran_on"], "engine": s["engine"],
        "rows": [_row_label(r) for r in task["rows"]], "references": list(blocks), "blocks": blocks,
        "ratios": ratios, "bounds": bounds,
        "bound_ratio": [b[0] / bounds[0][0] for b in bounds] if bounds else [],
        "failures": len(task["failures"]), "figures": task.get("written", []),
        "filters": kinds, "operations": s.get("operations", {}),
        "filter_ratios": {ref: _filters(b, kinds, n) for ref, b in blocks.items()} if kinds else {},
    }


def span(values) -> list:
    """[min, max] of the finite values (the ranges the prose quotes)."""
    flat = [float(v) for v in np.ravel(np.asarray([v for v in values if v is not None], dtype=float))
            if math.isfinite(v)]
    return [min(flat), max(flat)] if flat else [math.nan, math.nan]


# --- formatting (the template's filters: the only place numbers become text) -----------------

def sci(value) -> str:
    return f"{value:.3e}"


def pm(cell) -> str:
    """mean ± 95% half-width, as the tables print them."""
    mean, half = cell
    return f"{mean:.3e}" if not math.isfinite(half) else f"{mean:.3e} ± {half:.0e}"


def fixed(value, digits: int = 2) -> str:
    return f"{value:.{digits}f}"


def pms(cells) -> str:
    """Table cells, "mean ± half-width", joined as markdown columns."""
    return " | ".join(pm(c) for c in cells)


def pct(value) -> str:
    return f"{value:.0f}%"


def template_text() -> str:
    return resources.files("dfeif_codegen.templates").joinpath(*TEMPLATE).read_text(encoding="utf-8")


def render(data: dict) -> str:
    env = jinja2.Environment(undefined=jinja2.StrictUndefined, keep_trailing_newline=True, trim_blocks=True,
                             lstrip_blocks=True)
    env.filters.update(sci=sci, pm=pm, pms=pms, pct=pct, fixed=fixed)
    env.globals.update(span=span)
    return env.from_string(template_text()).render(**data)


# --- the numbers the prose quotes -----------------------------------------------------------

def _master(block, state=0) -> list:
    return [r["master"][state][0] if r else None for r in block]


def _sim_facts(t: dict) -> dict:
    """Ranges over the delayed rows (sinusoid, replay + difference) the prose of a model's section quotes."""
    ref = "sinusoid" if "sinusoid" in t["blocks"] else t["references"][0]
    blocks, ratios = t["blocks"][ref], t["ratios"][ref]
    b = blocks["replay + difference"]
    gain = [g for g in ratios["gain"] if g]
    n = t["n"]
    out = {
        "estimation": span(ratios["estimation"][1:]), "tracking": span(ratios["tracking"][1:]),
        "gain": [span(g[i] for g in gain) for i in range(n)],
        "trace_growth": span(r["trace"][-1][0] / b[0]["trace"][-1][0] for r in b[1:] if r),
        "nees_master": span(r["nees"][-1][0] for r in b if r),
        "band": b[0]["band"], "worst_row": t["rows"][int(np.nanargmax(np.asarray(ratios["estimation"], float)))],
        "worst": max(v for v in ratios["estimation"] if v is not None),
        "last": ratios["estimation"][-1]}
    if "replay + paper" in blocks:
        p = blocks["replay + paper"]
        out["paper"] = {"first": [p[0]["master"][0][0], b[0]["master"][0][0]],
                        "last": [p[-1]["master"][0][0], b[-1]["master"][0][0]],
                        "nees": span(r["nees"][-1][0] for r in p if r)}
    for base in ("discard + difference", "as-current + difference"):
        if base in blocks:
            out[base.split(" ")[0]] = span(x / y for x, y in zip(_master(blocks[base])[1:], _master(b)[1:])
                                          if x is not None and y is not None)
    return out


def _filter_facts(t: dict) -> dict:
    ratios = t["filter_ratios"].get("sinusoid", {})
    blocks = t["blocks"]["sinusoid"]
    out = {}
    for k, rows in ratios.items():
        ok = [r for r in rows if r]
        first, last = blocks[f"{k}-replay + difference"][0], blocks[f"{k}-replay + difference"][-1]
        out[k] = {"rmse": [span(r["rmse"][i] for r in ok) for i in range(t["n"])],
                  "cpu": span(r["cpu"] for r in ok),
                  "nees": span(r["nees"][-1][0] for r in blocks[f"{k}-replay + difference"] if r),
                  "growth": last["master"][0][0] / first["master"][0][0] if first and last else math.nan}
    ops = t["operations"]
    if ops:
        base = sum(ops["df"].values())
        out["ops"] = {k: sum(v.values()) / base for k, v in ops.items() if k != "df"}
    return out


def _methods_facts(t: dict) -> dict:
    b = t["blocks"]["sinusoid"]
    rep, ret = _master(b["replay + difference"]), _master(b["retrodict + difference"])
    ci = _master(b["replay + ci"])
    return {"retrodict": [x / y if x and y else None for x, y in zip(ret, rep)],
            "ci": span(x / y for x, y in zip(ci, rep) if x and y),
            "rejected": span(r["late"][2] for r in b["retrodict + difference"][1:] if r),
            "nees_retrodict": [r["nees"][-1][0] if r else None for r in b["retrodict + difference"]]}


def facts(data: dict) -> dict:
    """Every measured number the template's prose quotes, derived here so that it is in the data."""
    tasks, out = data["tasks"], {}
    for name in ("motor", "arm"):
        if name in tasks:
            out[name] = _sim_facts(tasks[name])
    for name in ("filters_motor", "filters_arm"):
        if name in tasks:
            out[name] = _filter_facts(tasks[name])
    if "methods" in tasks:
        out["methods"] = _methods_facts(tasks["methods"])
    if "motor" in tasks:
        out["q"] = q_facts(tasks)
    if "motor" in tasks:
        ch = data["chapter"]["tables"]
        b = tasks["motor"]["blocks"]["sinusoid"]["replay + difference"]
        out["chapter"] = {"master_x1": span(v[0] for v in ch["IV"]["values"]),
                          "trace_master": span(v[2] for v in ch["I"]["values"]),
                          "tracking_x1": span(r["tracking"][0][0] for r in b if r),
                          "est_tracking_master": span(r["est_tracking"][-1][0] for r in b if r)}
    return out


def q_facts(tasks: dict) -> dict:
    """The q sweep: each q's master RMSE over the paper q's, x1 and x3, first and last row."""
    base = tasks["motor"]["blocks"]["sinusoid"]["replay + difference"]
    out = {}
    for name in ("q60", "q150"):
        if name in tasks:
            b = tasks[name]["blocks"]["sinusoid"]["replay + difference"]
            out[name] = {"x1": [b[0]["master"][0][0] / base[0]["master"][0][0],
                                b[-1]["master"][0][0] / base[-1]["master"][0][0]],
                         "x3": [b[0]["master"][-1][0] / base[0]["master"][-1][0],
                                b[-1]["master"][-1][0] / base[-1]["master"][-1][0]],
                         "delay_ratio": b[-1]["master"][0][0] / b[0]["master"][0][0]}
    return out
