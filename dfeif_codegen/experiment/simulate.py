"""`codegen simulate`: the chapter's experiment (section 7) over a delay grid, averaged over seeds.

Prints Tables I-IV in the chapter's layout (tr P per node and master; RMSE of the canonical
states per node and at the master) plus the plant's tracking error and the average NEES with its
95% chi-square band, for every reference and every (late-measurement method, fusion rule) asked
for, baselines included. Runs go to worker processes (one per core); each run is reproducible from
its seed, and the seed also fixes the noise and network draws shared by all methods (paired rows).
With `filters` ("df,ekf,ukf") the EKF and UKF of experiment/compare.py run on the recordings of
the replay + difference loops and are reported in the same tables and in Table VI.

`simulate(...)` is the keyword API (cli.py only parses): `plan` checks everything and lists each
distinct run once, `execute` runs them (sweep.py), then the tables, JSON and figures are written.

Statistics without scipy at runtime: Student-t and chi-square quantiles from the normal quantile
(Cornish-Fisher expansion; Wilson-Hilferty), accurate to well under 1% where they are used.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from statistics import NormalDist

import numpy as np

from dfeif_codegen.experiment import scenario as scenario_mod
from dfeif_codegen.errors import ScenarioError, SetupError
from dfeif_codegen.experiment import bounds
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import sweep
from dfeif_codegen.reference import predictor as predictors


# --- statistics ---------------------------------------------------------------------------------

def t_quantile(p: float, dof: int) -> float:
    """Student-t quantile: exact for 1 and 2 degrees of freedom, Cornish-Fisher beyond."""
    if dof == 1:
        return math.tan(math.pi * (p - 0.5))
    if dof == 2:
        return (2 * p - 1) / math.sqrt(2 * p * (1 - p))
    z, v = NormalDist().inv_cdf(p), float(dof)
    g1 = (z ** 3 + z) / 4
    g2 = (5 * z ** 5 + 16 * z ** 3 + 3 * z) / 96
    g3 = (3 * z ** 7 + 19 * z ** 5 + 17 * z ** 3 - 15 * z) / 384
    g4 = (79 * z ** 9 + 776 * z ** 7 + 1482 * z ** 5 - 1920 * z ** 3 - 945 * z) / 92160
    return z + g1 / v + g2 / v ** 2 + g3 / v ** 3 + g4 / v ** 4


def chi2_quantile(p: float, dof: float) -> float:
    """Chi-square quantile by Wilson-Hilferty (cube of a normal)."""
    z, c = NormalDist().inv_cdf(p), 2.0 / (9.0 * dof)
    return dof * max(1 - c + z * math.sqrt(c), 0.0) ** 3


def mean_ci(samples) -> tuple[np.ndarray, np.ndarray]:
    """Mean over axis 0 and the half-width of its 95% confidence interval (NaN for one sample)."""
    a = np.asarray(samples, dtype=float)
    mean = a.mean(axis=0)
    if a.shape[0] < 2:
        return mean, np.full_like(mean, np.nan)
    return mean, t_quantile(0.975, a.shape[0] - 1) * a.std(axis=0, ddof=1) / math.sqrt(a.shape[0])


def nees_band(n: int, runs: int) -> tuple[float, float]:
    """95% band of the NEES averaged over `runs` independent runs at one step (Bar-Shalom)."""
    return chi2_quantile(0.025, n * runs) / runs, chi2_quantile(0.975, n * runs) / runs


# --- the job list ---------------------------------------------------------------------------------

def _pick(values, i):
    return values[i % len(values)]


def configurations(oosm: list[str], fusion: list[str], baselines: list[str]) -> list[tuple[str, str]]:
    """(method, fusion) pairs: every late-measurement method with every rule, baselines with the first."""
    return [(o, f) for o in oosm for f in fusion] + [(b, fusion[0]) for b in baselines]


def make_config(sc, model: str, nodes: int, max_lag: int, ref: str, row, method: str, fusion: str,
                seed: int, predictor: str = predictors.DEFAULT) -> ex.Config:
    return ex.Config(
        model=model, ts=sc.ts, duration=sc.duration, substeps=sc.substeps, q=tuple(sc.q), poles=tuple(sc.poles),
        p0_std=tuple(sc.p0_std), initial_error=sc.initial_error, reference=ref, amplitude=tuple(sc.amplitude),
        period=sc.period, offset=tuple(sc.offset), harmonics=sc.harmonics,
        noise_scale=tuple(_pick(sc.noise_scale, i) for i in range(nodes)),
        noise_std=tuple(None if _pick(sc.noise_std, i) is None else tuple(_pick(sc.noise_std, i)) for i in range(nodes)),
        sensor=row.links(nodes), uplink=tuple(sc.uplink for _ in range(nodes)), max_lag=max_lag,
        method=method, fusion=fusion, seed=seed, metrics_from=sc.metrics_from, predictor=predictor)


def _canonical(cfg: ex.Config) -> ex.Config:
    """Without any late frame every method runs the same filters: run it once."""
    if any(link.p > 0 for link in cfg.sensor):
        return cfg
    return ex.Config(**{**cfg.__dict__, "method": "replay"})


def _series(res: ex.Result) -> dict:
    rec = res.recording
    return {"t": res.t, "zeta": res.zeta, "ref": ex.state_of_flags(ex._flat(res.config.model), rec.ref),
            "node_x": rec.node_x, "x": rec.x, "u": rec.u, "v": rec.v, "delays": res.delays,
            "P_diag": np.diagonal(rec.P, axis1=1, axis2=2)}


class Progress:
    """A plain-text bar on stderr, only on a terminal and without --quiet."""

    def __init__(self, total: int, enabled: bool):
        self.total, self.done, self.enabled, self.start = total, 0, enabled, time.monotonic()

    def step(self) -> None:
        self.done += 1
        if self.enabled:
            width = 30
            full = int(width * self.done / self.total)
            elapsed = time.monotonic() - self.start
            eta = elapsed / self.done * (self.total - self.done)
            sys.stderr.write(f"\r[{'#' * full}{'.' * (width - full)}] {self.done}/{self.total} runs, "
                             f"{elapsed:4.0f} s elapsed, ~{eta:3.0f} s left ")
            sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")


# --- aggregation ----------------------------------------------------------------------------------

def summarize(runs: list[dict], n: int) -> dict:
    """Mean and 95% CI of each metric over the successful runs; NEES averaged over runs per step,
    then over time, with the band and the fraction of steps inside it."""
    out: dict = {"runs": len(runs)}
    if not runs:
        return out
    for key in ("trace_nodes", "trace_master", "rmse_nodes", "rmse_master", "rmse_tracking",
                "rmse_est_tracking_nodes", "rmse_est_tracking_master", "late_applied", "late_rejected", "us_per_step"):
        if key not in runs[0]:
            continue
        mean, half = mean_ci([r[key] for r in runs])
        out[key] = {"mean": mean.tolist(), "ci95": half.tolist()}
    lo, hi = nees_band(n, len(runs))
    out["nees_band"] = [lo, hi]
    for key in ("nees_nodes", "nees_master"):
        per_step = np.mean([r[key] for r in runs], axis=0)           # run-averaged NEES per step
        out[key] = {"mean": per_step.mean(axis=-1).tolist(),
                    "in_band": ((per_step >= lo) & (per_step <= hi)).mean(axis=-1).tolist()}
    return out


# --- printing -------------------------------------------------------------------------------------

def _fmt(mean, half) -> str:
    text = f"{mean:.3e}"
    return text if not np.isfinite(half) else f"{text}±{half:.1e}"


def _row_label(row, drop: bool = False) -> str:
    return " ".join(f"{d:3d}" for d in row.d) + f"  {row.p:3.1f}" + (f"  {row.p_drop:6.2f}" if drop else "")


def print_tables(out, sc, rows, groups, flat, nodes: int, bound=None) -> None:
    """`bound`: per row, the exact optimal filter on the matched linear model (bounds.RowBound)."""
    names = [str(z) for z in flat.zeta]
    n = flat.n
    drop = any(r.p_drop for r in rows)
    head = " ".join(f"d{i + 1:<2d}" for i in range(len(rows[0].d))) + "   p " + ("  p_drop" if drop else "")
    width = 21

    def table(title, cols, values):
        print(title, file=out)
        print(f"  {head}  " + "".join(f"{c:>{width}}" for c in cols), file=out)
        for row, cells in zip(rows, values):
            print(f"  {_row_label(row, drop)}  " + "".join(f"{c:>{width}}" for c in cells), file=out)
        print(file=out)

    xcols = [f"x{i + 1}" for i in range(n)]
    for (ref, method, fusion), summaries in groups.items():
        ok = [s for s in summaries if s.get("runs")]
        counts = sorted({s["runs"] for s in summaries})
        print(f"=== reference {ref} | late measurements: {method} | fusion: {fusion} | "
              f"runs per row: {'/'.join(map(str, counts))} (mean ± 95% CI) ===", file=out)
        if not ok:
            print("  every run failed\n", file=out)
            continue

        def cells(s, key, idx=None):
            if not s.get("runs"):
                return ["failed"] * (n if idx is None or isinstance(idx, int) else 1)
            m, h = np.asarray(s[key]["mean"]), np.asarray(s[key]["ci95"])
            if idx is not None:
                m, h = m[idx], h[idx]
            return [_fmt(a, b) for a, b in zip(np.atleast_1d(m), np.atleast_1d(h))]

        table("Table I: traces of the covariance matrices",
              [f"tr(P{i + 1})" for i in range(nodes)] + ["tr(P) master"],
              [(cells(s, "trace_nodes") + cells(s, "trace_master")) if s.get("runs") else ["failed"] * (nodes + 1)
               for s in summaries])
        for i in range(nodes):
            table(f"Table {'II' if i == 0 else 'III' if i == 1 else f'II.{i + 1}'}: RMSE of the estimation "
                  f"error at node {i + 1}", xcols, [cells(s, "rmse_nodes", i) for s in summaries])
        table("Table IV: RMSE of the estimation error at the master", xcols,
              [cells(s, "rmse_master") for s in summaries])
        if bound is not None and method in ex.OOSM:
            table("Table IV-c: exact optimal filter's RMSE on the matched linear model, centralized "
                  "(per node below)", xcols, [[f"{v:.3e}" for v in b.rmse_central] for b in bound])
            for i in range(nodes):
                table(f"  ... node {i + 1} alone", xcols, [[f"{v:.3e}" for v in b.rmse_nodes[i]] for b in bound])
        if bound is not None:
            table("Table IV-d: measured master RMSE / the centralized bound (< 1 is possible: the real "
                  "plant has no process noise)", xcols,
                  [[f"{a / c:.3f}" for a, c in zip(s["rmse_master"]["mean"], b.rmse_central)] if s.get("runs")
                   else ["failed"] * n for s, b in zip(summaries, bound)])
        table("Table IV-b: RMSE tracking error of the plant (x - x_d, the chapter's quantity)", xcols,
              [cells(s, "rmse_tracking") for s in summaries])
        if "rmse_est_tracking_master" in ok[0]:
            table("Table IV-e: RMSE of the estimated tracking error x_hat - x_d, x1 (the chapter's Tables II-IV "
                  "give one value per filter)", [f"node {i + 1}" for i in range(nodes)] + ["master"],
                  [(cells(s, "rmse_est_tracking_nodes", (slice(None), 0)) + cells(s, "rmse_est_tracking_master", 0))
                   if s.get("runs") else ["failed"] * (nodes + 1) for s in summaries])
        nees_rows = []
        for s in summaries:
            if not s.get("runs"):
                nees_rows.append(["failed"] * (nodes + 2))
                continue
            vals = list(zip(s["nees_nodes"]["mean"], s["nees_nodes"]["in_band"])) + \
                [(s["nees_master"]["mean"], s["nees_master"]["in_band"])]
            nees_rows.append([f"{m:.2f} ({100 * f:.0f}% in)" for m, f in vals] +
                             [f"[{s['nees_band'][0]:.2f}, {s['nees_band'][1]:.2f}]"])
        table(f"Table V: average NEES (n = {n}; in: % of steps whose run-averaged NEES is in the 95% band)",
              [f"node {i + 1}" for i in range(nodes)] + ["master", "95% band"], nees_rows)
        late = [f"{s['late_applied']['mean']:.0f}/{s['late_rejected']['mean']:.0f}" if s.get("runs") else "-"
                for s in summaries]
        print("  late frames applied/rejected per run (all nodes): " + ", ".join(late) + "\n", file=out)
    print(f"x1..x{n} = {', '.join(names)} (canonical states, chain by chain)", file=out)


def print_summary(out, rows, groups) -> None:
    """One line per (reference, method, rule): the master's x1 RMSE and NEES along the grid."""
    print("\nSummary: master RMSE of x1 (and average NEES) along the grid", file=out)
    print("  " + " " * 38 + "".join(f"{_row_label(r):>24}" for r in rows), file=out)
    for (ref, method, fusion), summaries in groups.items():
        cells = []
        for s in summaries:
            if not s.get("runs"):
                cells.append("failed")
                continue
            cells.append(f"{s['rmse_master']['mean'][0]:.3e} ({s['nees_master']['mean']:.2f})")
        print(f"  {ref + ' ' + method + ' ' + fusion:38s}" + "".join(f"{c:>24}" for c in cells), file=out)


# --- figures ----------------------------------------------------------------------------------------

def _jsonable(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return value


def plot_figures(directory: str, figures: dict, flat) -> list[str]:
    """PNG figures like the chapter's Figs 9-13 (experiment/figures.py): states against the
    reference, the estimation error with its +-3 sigma band, the delays."""
    from dfeif_codegen.experiment import figures as figs

    figs.pyplot()
    folder = Path(directory)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    name = flat.model.name

    def save(path):
        written.append(str(path))
        return path

    for ref, fig in figures.items():
        a, b = fig["no_delay"], fig["delay"]
        how = f"{fig['method']} + {fig['fusion']}"
        b = {**b, "row": figs.row_text(b["row"])}
        t = np.asarray(a["t"])
        figs.states_figure(save(folder / f"fig09_{ref}_master_no_delay.png"),
                           f"Fig. 9: {name}, master estimate without delays ({ref} reference, {how})", flat,
                           t, np.asarray(a["x"]), np.asarray(a["zeta"]), np.asarray(a["ref"]), np.asarray(a["u"]),
                           who="master estimate")
        ts = float(t[1] - t[0]) if len(t) > 1 else 1.0
        figs.delay_figure(save(folder / f"fig10_{ref}_delays.png"),
                          f"Fig. 10: {name}, camera -> node delays at {b['row']}: late with probability p by 1..d_i steps",
                          np.asarray(b["t"]), b["delays"], ts)
        node_x = np.asarray(b["node_x"])
        for i in range(node_x.shape[0]):
            figs.states_figure(save(folder / f"fig{11 + i}_{ref}_node{i + 1}_delay.png"),
                               f"Fig. {11 + i}: {name}, node {i + 1} under delays {b['row']} ({ref})", flat,
                               b["t"], node_x[i], np.asarray(b["zeta"]), np.asarray(b["ref"]), np.asarray(b["u"]),
                               who=f"node {i + 1} estimate")
        last = 11 + node_x.shape[0]
        figs.states_figure(save(folder / f"fig{last}_{ref}_master_delay.png"),
                           f"Fig. {last}: {name}, master under delays {b['row']} ({ref}, {how})", flat,
                           b["t"], np.asarray(b["x"]), np.asarray(b["zeta"]), np.asarray(b["ref"]), np.asarray(b["u"]),
                           who="master estimate")
        for key, label in (("no_delay", "without delays"), ("delay", f"under delays {b['row']}")):
            d = fig[key]
            if "P_diag" in d:
                figs.error_figure(save(folder / f"fig{last + 1}_{ref}_master_error_{key}.png"),
                                  f"{name}: master estimation error {label} ({ref}, {how})", flat,
                                  np.asarray(d["t"]), np.asarray(d["x"]), np.asarray(d["zeta"]), np.asarray(d["P_diag"]))
    return written


# --- the command --------------------------------------------------------------------------------------

FILTERS = ("df", "ekf", "ukf")


@dataclass
class Plan:
    """Everything `simulate` will run, known (and checked) before the first run starts."""

    sc: object
    flat: object
    model: str
    nodes: int
    max_lag: int
    runs: int
    seed: int
    refs: list
    configs: list            # (method, fusion) of the derivative-free closed loops
    filters: list            # "ekf", "ukf": judged on the recordings of replay + difference
    rows: list
    wanted: dict             # (cfg, kind) -> [(reference, method label, fusion, row, seed)]
    figure_keys: set
    predictor: str | None = None    # the filters' (reference/predictor.py); None: for_method

    @property
    def seeds(self) -> range:
        return range(self.seed, self.seed + self.runs)

    @property
    def labels(self) -> list[tuple[str, str]]:
        """(method label, fusion) of every table: the closed loops, then each filter on their recordings."""
        extra = [(f"{k}-replay", "difference") for k in (["df", *self.filters] if self.filters else [])]
        return list(dict.fromkeys(self.configs + extra))


def _check_outputs(json_path, plot_dir) -> None:
    from dfeif_codegen.paths import writable_dir, writable_file

    if json_path and json_path != "-":
        writable_file(json_path, "--json")
    if plot_dir:
        writable_dir(plot_dir, "--plot")
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise SetupError("--plot needs matplotlib: pip install 'dfeif-codegen[plot]'") from None


def _filters_of(filters) -> list[str]:
    """The filters asked for besides the derivative-free closed loop (always run)."""
    filters = [filters] if isinstance(filters, str) else (filters or ["df"])
    names = [f.strip() for item in filters for f in str(item).split(",") if f.strip()]
    bad = [f for f in names if f not in FILTERS]
    if bad or not names:
        raise ScenarioError(f"--filters: {', '.join(bad) or 'nothing'}: choose from {', '.join(FILTERS)}")
    return [f for f in dict.fromkeys(names) if f != "df"]


def plan(model: str, scenario: str, runs, seed: int, nodes, max_lag: int, oosm, fusion, reference,
         filters, plot_dir, predictor: str | None = None) -> Plan:
    """Load and check everything, then list each distinct run once."""
    kinds = _filters_of(filters)
    sc = scenario_mod.load(scenario)
    flat = ex._flat(model)   # the derivation every run of this process (and its workers) uses
    if plot_dir:                          # a missing matplotlib is said before the runs, not after
        from dfeif_codegen.experiment import figures as figs
        figs.pyplot()
    sc.check_model(flat)
    # --nodes defaults to 2 in the parser: a scenario with another node count keeps its own
    # unless --nodes asks for something other than 2 (node settings then repeat cyclically).
    nodes = len(sc.noise_scale) if nodes is None else nodes
    if nodes < 1:
        raise ScenarioError(f"--nodes: needs at least one node, got {nodes}")
    if max_lag < 1:
        raise ScenarioError(f"--max-lag: needs at least 1, got {max_lag}")
    scenario_mod.check_window(sc, max_lag, nodes)
    runs = runs if runs is not None else sc.runs
    if runs < 1:
        raise ScenarioError(f"--runs: needs at least 1, got {runs}")
    refs = list(reference or sc.references)
    configs = list(dict.fromkeys(configurations(list(oosm or sc.oosm), list(fusion or sc.fusion), sc.baselines)))
    for method, _ in configs:
        try:
            oosm_of = method if method in ex.OOSM else "replay"
            predictors.check(predictors.for_method(predictor, oosm_of), oosm_of)
        except ValueError as exc:
            raise ScenarioError(str(exc) if oosm else f"{sc.where('oosm')}: {exc}") from None
    rows = [scenario_mod.Row([_pick(r.d, i) for i in range(nodes)], r.p, r.p_drop) for r in sc.grid]
    p = Plan(sc, flat, model, nodes, max_lag, runs, seed, refs, configs, kinds, rows, {}, set(), predictor)
    for ref in refs:
        for ri, row in enumerate(rows):
            for s in p.seeds:
                for method, rule in configs:
                    cfg = make_config(sc, model, nodes, max_lag, ref, row, method, rule, s,
                                      predictors.for_method(predictor, method if method in ex.OOSM else "replay"))
                    p.wanted.setdefault((_canonical(cfg), "df"), []).append((ref, method, rule, ri, s))
                for label, rule in p.labels[len(configs):]:
                    cfg = make_config(sc, model, nodes, max_lag, ref, row, "replay", rule, s,
                                      predictors.for_method(predictor, "replay"))
                    p.wanted.setdefault((cfg, label), []).append((ref, label, rule, ri, s))
    for cfg in {c.reference: c for c, _ in p.wanted}.values():
        try:  # a reference outside the model's domain is bad input, known before any run
            ex.check_reference_of(cfg)
        except ex.UndefinedReference as exc:
            raise ScenarioError(f"{sc.where('reference')}: {cfg.reference}: {exc}") from None
    p.figure_keys = {(ref, configs[0][0], configs[0][1], ri, seed) for ref in refs for ri in (0, len(rows) - 1)}
    return p


@dataclass
class Outcome:
    results: dict            # (reference, label, fusion, row) -> [metrics] in seed order
    series: dict
    failures: list
    per_run: list
    where: str
    workers: int
    reused: int
    distinct: int
    elapsed: float
    bound: list              # per row, bounds.RowBound
    longest_side: float = 0.0    # CPU seconds of the longest row bound (one task: a cluster's floor)


def execute(p: Plan, engine: str, need_series: bool, workers, scheduler, results_file, resume,
            quiet: bool) -> Outcome:
    """Run every distinct run of the plan (reusing a --resume file's), collecting per key, and the
    exact bound of every row alongside (it needs only the network draws)."""
    if resume and results_file and Path(resume) != Path(results_file):
        raise ScenarioError("--resume FILE continues FILE: give --results the same file or leave it out")
    previous = sweep.read_records(resume) if resume else {}
    ids = {sweep.run_id(cfg, engine, kind): (cfg, kind, keys) for (cfg, kind), keys in p.wanted.items()}
    todo, reused = [], []
    for rid, (cfg, kind, keys) in ids.items():
        wants_series = need_series and kind == "df" and any(k in p.figure_keys for k in keys)
        if rid in previous and not wants_series:
            reused.append((rid, sweep.decode(previous[rid]["metrics"])))
        else:
            todo.append((rid, cfg, _series if wants_series else None, kind))
    workers = sweep.default_workers(workers, len(todo))
    client = sweep.connect(scheduler)
    try:
        shipped = sweep.prepare([cfg for _, cfg, _, _ in todo], engine)
    except BaseException:
        if client is not None:
            client.close()
        raise
    records = sweep.Records(resume or results_file, keep_existing=bool(resume))
    progress = Progress(len(todo), not quiet and sys.stderr.isatty())
    out = Outcome({}, {}, [], [], "", workers, len(reused), len(todo), 0.0, [])
    started = time.monotonic()

    def collect(rid, value, fresh=True):
        metrics, data = value if fresh else (value, None)
        _, _, keys = ids[rid]
        if fresh and rid not in previous:
            records.write(rid, keys, engine, metrics)
        for key in keys:
            out.per_run.append((*key[:4], key[4], metrics))
            if isinstance(metrics, str):
                out.failures.append((key, f"{key[0]} {key[1]} {key[2]} row {key[3] + 1} seed {key[4]}: {metrics}"))
            else:
                out.results.setdefault(key[:4], []).append((key[4], metrics))
            if data is not None and key in p.figure_keys:
                out.series[key] = data
        if fresh:
            progress.step()

    for rid, metrics in reused:
        collect(rid, metrics, fresh=False)
    rows = [[make_config(p.sc, p.model, p.nodes, p.max_lag, p.refs[0], row, "replay", "difference", s)
             for s in p.seeds] for row in p.rows]
    try:
        out.where, side = sweep.execute(todo, engine, shipped, workers, client, collect,
                                        [(bounds.row_bound, (cfgs,)) for cfgs in rows])
        out.bound = [b for b, _ in side]
        out.longest_side = max((t for _, t in side), default=0.0)
    finally:
        records.close()
        progress.close()
    out.elapsed = time.monotonic() - started
    # the same numbers wherever and in whichever order the runs ran: average in seed order
    out.results = {k: [m for _, m in sorted(v, key=lambda sm: sm[0])] for k, v in out.results.items()}
    out.failures = [text for _, text in sorted(out.failures)]
    return out


def _settings(p: Plan, o: Outcome, engine: str) -> dict:
    sc = p.sc
    out = {"scenario": sc.name, "source": sc.source, "model": p.flat.model.name, "nodes": p.nodes,
           "max_lag": p.max_lag, "ts": sc.ts or p.flat.model.ts, "duration": sc.duration, "runs": p.runs,
           "seeds": [p.seed, p.seed + p.runs - 1], "q": sc.q, "poles": sc.poles, "p0_std": sc.p0_std,
           "noise_scale": [_pick(sc.noise_scale, i) for i in range(p.nodes)], "metrics_from": sc.metrics_from,
           "elapsed_s": round(o.elapsed, 3), "workers": o.workers, "engine": engine, "ran_on": o.where,
           "runs_resumed": o.reused, "distinct_runs": o.distinct, "longest_bound_cpu_s": round(o.longest_side, 3),
           "predictor": p.predictor or f"{predictors.DEFAULT} (brunovsky with retrodict)"}
    if p.filters:
        from dfeif_codegen.experiment import compare
        out["filters"] = ["df", *p.filters]
        out["operations"] = compare.operations(p.model, out["ts"], ex._per_chain(sc.q, p.flat.m), sc.substeps,
                                               predictors.for_method(p.predictor, "replay"))
    return out


def _figures(p: Plan, o: Outcome) -> dict:
    figures = {}
    method, rule = p.configs[0]
    for ref in p.refs:
        pair = [o.series.get((ref, method, rule, ri, p.seed)) for ri in (0, len(p.rows) - 1)]
        if all(x is not None for x in pair):
            figures[ref] = {"no_delay": {**pair[0], "row": _row_label(p.rows[0])},
                            "delay": {**pair[1], "row": _row_label(p.rows[-1]).strip()},
                            "method": method, "fusion": rule}
    return figures


def print_filters(out, p: Plan, groups: dict, operations: dict) -> None:
    """Table VI: the derivative-free filter, the EKF and the UKF on the same recordings."""
    labels = [(f"{k}-replay", "difference") for k in ("df", *p.filters)]
    print("Table VI: derivative-free (df) against EKF and UKF on the same recordings (replay + difference; "
          "master x1 RMSE, time-averaged NEES, failed or diverged runs, CPU us per step of the filter loop, "
          "mean ± 95% CI)", file=out)
    for ref in p.refs:
        for ri, row in enumerate(p.rows):
            for label, rule in labels:
                s = groups[(ref, label, rule)][ri]
                failed = p.runs - s.get("runs", 0)
                if not s.get("runs"):
                    print(f"  {ref} {_row_label(row)}  {label:11s} every run failed", file=out)
                    continue
                rm, us = s["rmse_master"], s["us_per_step"]
                print(f"  {ref} {_row_label(row)}  {label:11s} x1 {_fmt(rm['mean'][0], rm['ci95'][0]):>20}  "
                      f"NEES {s['nees_master']['mean']:6.2f}  failed {failed:3d}/{p.runs}  "
                      f"{_fmt(us['mean'], us['ci95']):>20} us/step", file=out)
    ops = ", ".join(f"{k} {v['predict']}/{v['update']}" for k, v in operations.items())
    print(f"  operations per predict/update (CasADi SX instructions): {ops}\n", file=out)


def simulate(model: str = "dc_motor_link", *, scenario: str = "paper", runs: int | None = None, seed: int = 0,
             nodes: int | None = None, max_lag: int = 32, oosm=None, fusion=None, reference=None,
             filters=None, plot: str | None = None, json_path: str | None = None, quiet: bool = False,
             engine: str = "c", workers: int | None = None, scheduler: str | None = None,
             results: str | None = None, csv: str | None = None, resume: str | None = None, out=None,
             predictor: str | None = None) -> int:
    """The chapter's experiment: tables on `out` (stdout), optionally JSON, CSV, per-run records and
    figures. `filters`: any of "df", "ekf", "ukf" (or one comma-separated string); the EKF and UKF
    run on the recordings of the replay + difference closed loops. Returns 0, or 1 when a run
    failed or diverged. Bad input raises a CodegenError before any run. `predictor`: the
    derivative-free filters' prediction, "held" (u held) or "brunovsky" (the chapter's); None:
    held, and brunovsky for retrodiction (the only one it can use)."""
    out = out or sys.stdout
    _check_outputs(json_path, plot)
    p = plan(model, scenario, runs, seed, nodes, max_lag, oosm, fusion, reference, filters, plot, predictor)
    o = execute(p, engine, bool(plot or json_path), workers, scheduler, results, resume, quiet)
    bound = o.bound
    if csv:
        sweep.write_csv(csv, o.per_run, p.flat.n, nodes=p.nodes)
    groups = {(ref, m, f): [summarize(o.results.get((ref, m, f, ri), []), p.flat.n) for ri in range(len(p.rows))]
              for ref in p.refs for m, f in p.labels}
    settings = _settings(p, o, engine)
    to_stdout = json_path == "-"
    if not to_stdout:
        _print_report(out, p, o, settings, groups, bound, engine)
    figures = _figures(p, o)
    if json_path:
        doc = {"settings": settings, "rows": [{"d": r.d, "p": r.p, "p_drop": r.p_drop} for r in p.rows],
               "states": [str(z) for z in p.flat.zeta],
               "tables": [{"reference": ref, "method": m, "fusion": f,
                           "filter": m.split("-")[0] if m.endswith("-replay") else "df", "rows": s}
                          for (ref, m, f), s in groups.items()],
               "bounds": [{"rmse_central": b.rmse_central, "rmse_nodes": b.rmse_nodes} for b in bound],
               "failures": o.failures, "figures": figures}
        text = json.dumps(_jsonable(doc))
        if to_stdout:
            sys.stdout.write(text + "\n")
        else:
            Path(json_path).write_text(text + "\n", encoding="utf-8")
    if plot:
        written = plot_figures(plot, figures, p.flat)
        if not to_stdout:
            print(f"\nwrote {len(written)} figures into {plot}", file=out)
    if o.failures:  # a run that failed or diverged is a result to act on, not a footnote
        print(f"codegen simulate: {len(o.failures)} of {sum(len(k) for k in p.wanted.values())} run(s) failed "
              f"or diverged (first: {o.failures[0]})", file=sys.stderr)
        return 1
    return 0


def _print_report(out, p: Plan, o: Outcome, settings: dict, groups: dict, bound, engine: str) -> None:
    sc = p.sc
    print(f"codegen simulate: scenario {sc.name} on {p.flat.model.name}: {p.nodes} nodes, Ts = {settings['ts']:g} s, "
          f"{sc.duration:g} s runs, N_max = {p.max_lag}, q = {sc.q}, poles {sc.poles}, "
          f"seeds {p.seed}..{p.seed + p.runs - 1}, {o.distinct} runs in {o.elapsed:.0f} s on {o.where} "
          f"({engine} engine{f', {o.reused} resumed' if o.reused else ''})\n", file=out)
    print_tables(out, sc, p.rows, groups, p.flat, p.nodes, bound)
    if p.filters:
        print(file=out)
        print_filters(out, p, groups, settings["operations"])
    print_summary(out, p.rows, groups)
    if o.failures:
        print(f"\n{len(o.failures)} run(s) failed (left out of the averages):", file=out)
        for line in o.failures[:10]:
            print(f"  {line}", file=out)
