"""`codegen simulate`: the chapter's experiment (section 7) over a delay grid, averaged over seeds.

Reports Tables I-IV in the chapter's layout (tr P per node and master; RMSE of the canonical
states per node and at the master) plus the plant's tracking error and the average NEES with its
95% chi-square band, for every reference and every (late-measurement method, fusion rule) asked
for, baselines included. Runs go to worker processes (one per core); each run is reproducible from
its seed, and the seed also fixes the noise and network draws shared by all methods (paired rows).
With `filters` ("df,ekf,ukf") the EKF and UKF of experiment/compare.py run on the recordings of
the replay + difference loops and are reported in the same tables and in Table VI.

Three steps, one module each: `plan` (experiment/plan.py) checks everything and lists each
distinct run once, `execute` (experiment/execute.py) runs them on the engine handed in
(experiment/sweep.py), and the result (experiment/report.py) holds the tables as data, with the
text and the JSON made from it. `dc.simulate` (dfeif_codegen/api.py) picks the engine by name.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import derivation, model_error, pairing, sweep
from dfeif_codegen.experiment import scenario as scenario_mod
from dfeif_codegen.experiment.execute import Outcome, execute
from dfeif_codegen.experiment.plan import FILTERS, Plan, _pick, check_figures, check_outputs, configurations, make_config, plan
from dfeif_codegen.experiment.report import SimulationResult, Table, row_label
from dfeif_codegen.experiment.stats import chi2_quantile, mean_ci, nees_band, summarize, t_quantile
from dfeif_codegen.reference import predictor as predictors

# names other modules and scripts reach through this module
__all__ = ["simulate", "SimulationResult", "Table", "Plan", "plan", "execute", "make_config", "configurations",
           "FILTERS", "t_quantile", "chi2_quantile", "mean_ci", "nees_band", "summarize"]


def _settings(p: Plan, o: Outcome) -> dict:
    sc, own = p.sc, predictors.for_method(p.predictor, "replay")
    out: dict[str, Any] = {"scenario": sc.name, "source": sc.source, "model": p.flat.model.name, "nodes": p.nodes,
           "max_lag": p.max_lag, "ts": sc.ts or p.flat.model.ts, "duration": sc.duration, "runs": p.runs,
           "seeds": [p.seed, p.seed + p.runs - 1], "q": sc.q_for(own), "poles": sc.poles, "p0_std": sc.p0_std,
           "noise_scale": [_pick(sc.noise_scale, i) for i in range(p.nodes)], "metrics_from": sc.metrics_from,
           "elapsed_s": round(o.elapsed, 3), "workers": o.workers, "engine": o.engine, "ran_on": o.where,
           "runs_resumed": o.reused, "distinct_runs": o.distinct, "longest_bound_cpu_s": round(o.longest_side, 3),
           "model_error": model_error.summary(sc.model_error, p.flat.model, p.seeds),
           "predictor": p.predictor or f"{predictors.DEFAULT} (brunovsky with retrodict)"}
    if p.filters:
        from dfeif_codegen.experiment import compare
        out["filters"] = ["df", *p.filters]
        if sc.q_ekf:
            out["q_ekf"] = sc.q_ekf
        if sc.q_scheduled and "scheduled" in p.filters:
            out["q_scheduled"] = sc.q_scheduled
        if sc.offsets is not None and "offsets" in p.filters:
            out["offsets"] = dataclasses.asdict(sc.offsets)
        out["operations"] = compare.operations(p.model, out["ts"], ex._per_chain(sc.q, p.flat.m), sc.substeps,
                                               out["filters"], predictors.for_method(p.predictor, "replay"),
                                               sc.disturbance, sc.offsets)
    return out


def _figures(p: Plan, o: Outcome) -> dict:
    """The series of the figures: the first closed loop at the first and last row, first seed."""
    figures = {}
    method, rule = p.configs[0]
    for ref in p.refs:
        first, last = (o.series.get((ref, method, rule, ri, p.seed)) for ri in (0, len(p.rows) - 1))
        if first is not None and last is not None:
            figures[ref] = {"no_delay": {**first, "row": row_label(p.rows[0])},
                            "delay": {**last, "row": row_label(p.rows[-1]).strip()},
                            "method": method, "fusion": rule}
    return figures


def result_of(p: Plan, o: Outcome) -> SimulationResult:
    """The tables (mean and 95% CI per row) and everything the report says, from the runs."""
    tables = [Table(ref, m, f, [summarize(o.results.get((ref, m, f, ri), []), p.flat.n) for ri in range(len(p.rows))])
              for ref in p.refs for m, f in p.labels]
    paired = pairing.entries(o.per_run, p.refs, p.rows, ["df", *p.filters]) if p.filters else []
    return SimulationResult(_settings(p, o), p.rows, [str(z) for z in p.flat.zeta], tables, o.bound, o.failures,
                            p.total_runs, _figures(p, o), paired=paired)


def simulate(model: str = "dc_motor_link", *, engine: sweep.Engine, scenario: str = "paper", runs: int | None = None,
             seed: int = 0, nodes: int | None = None, max_lag: int = ex.MAX_LAG, oosm=None, fusion=None, reference=None,
             filters=None, plot: str | None = None, json_path: str | None = None, quiet: bool = False,
             workers: int | None = None, scheduler: str | None = None, results: str | None = None,
             csv: str | None = None, resume: str | None = None, max_seconds: float | None = None,
             max_memory: float | None = None, param_error=None, predictor: str | None = None) -> SimulationResult:
    """The chapter's experiment on `engine` (experiment/sweep.py): returns the result and writes
    what was asked for (JSON to `json_path` unless "-", CSV, per-run records, figures into `plot`).
    Bad input raises a CodegenError before any run; failed or diverged runs are in `.failures`.
    The derivation runs under `max_seconds` CPU seconds and `max_memory` GB (None: build's).
    `param_error` replaces the scenario's [model_error] (experiment/model_error.from_option).
    `predictor`: the filters' prediction, "held" (u held), "scheduled" (held, the covariance's
    transition at the master's broadcast flat outputs) or "brunovsky" (the chapter's); None:
    the default, and brunovsky for retrodiction (the only one it can use)."""
    check_outputs(json_path, plot, csv, results, {"model file": model, "scenario file": scenario}, resume)
    scenario_mod.load(scenario)     # the file's own checks (fields, reference file) before the derivation
    derivation.derive(model, max_seconds, max_memory)
    p = plan(model, scenario, runs, seed, nodes, max_lag, oosm, fusion, reference, filters, plot, param_error,
             predictor)
    if plot:
        check_figures(plot, p)
    o = execute(p, engine, bool(plot or json_path), workers, scheduler, results, resume, quiet)
    if csv:
        sweep.write_csv(csv, o.per_run, p.flat.n, nodes=p.nodes)
    result = result_of(p, o)
    if json_path and json_path != "-":
        Path(json_path).write_text(result.to_json() + "\n", encoding="utf-8")
    if plot:
        from dfeif_codegen.experiment.figures import simulation_figures

        result.written, result.plot_dir = simulation_figures(plot, result.figures, p.flat, p.sc.metrics_from), plot
        if result.settings.get("filters"):
            from dfeif_codegen.experiment.figures import filters_figures

            result.written += filters_figures(plot, result, p.flat)
    return result
