"""What `codegen simulate` found, as data (`SimulationResult`) and as the text the command prints.

The result holds everything the report needs (settings, delay rows, state names, one `Table` per
reference, method and fusion rule, the exact bounds, the failures), so `report()` and `to_json()`
are functions of the result alone: a notebook gets the same numbers the command prints.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field

import numpy as np

from dfeif_codegen import json_text, paths
from dfeif_codegen.experiment import closed_loop as ex


@dataclass
class Table:
    """One (reference, method, fusion rule) block: per delay row, the summary over the seeds
    (experiment/stats.py `summarize`: {"runs": 0} when every run of the row failed)."""

    reference: str
    method: str
    fusion: str
    rows: list[dict]

    @property
    def filter(self) -> str:
        """"df", "ekf" or "ukf": the filter whose estimates the table judges."""
        return self.method.split("-")[0] if self.method.endswith("-replay") else "df"

    def mean(self, metric: str) -> np.ndarray:
        """The metric's mean per delay row (first axis), NaN where every run of the row failed."""
        return self._stack(metric, "mean")

    def ci95(self, metric: str) -> np.ndarray:
        """The half-width of the mean's 95% confidence interval per row (NaN for one run)."""
        return self._stack(metric, "ci95")

    def _stack(self, metric: str, part: str) -> np.ndarray:
        ok = [np.asarray(r[metric][part], dtype=float) for r in self.rows if r.get("runs")]
        if not ok:
            raise KeyError(f"{metric}: every run of {self.reference} {self.method} {self.fusion} failed")
        return np.stack([np.asarray(r[metric][part], dtype=float) if r.get("runs") else np.full_like(ok[0], np.nan)
                         for r in self.rows])


JSON_KEYS = ("settings", "rows", "states", "tables", "bounds", "failures", "figures", "paired")   # to_dict's


@dataclass
class SimulationResult:
    """`dc.simulate`'s answer: the tables as data, `.report()` (what the command prints) and
    `.to_json()` (what `--json` writes)."""

    settings: dict
    rows: list                     # the scenario's delay rows (scenario.Row: d per node, p, p_drop)
    states: list[str]              # canonical states x1..xn
    tables: list[Table]
    bounds: list                   # per row, bounds.RowBound (exact optimal filter, matched linear model)
    failures: list[str]            # failed or diverged runs, one line each
    runs_total: int                # runs behind the tables (a shared run counts for each cell)
    figures: dict = field(default_factory=dict, repr=False)   # the time series the figures show
    written: list[str] = field(default_factory=list)          # figure files written (plot=DIR)
    plot_dir: str | None = None
    paired: list[dict] = field(default_factory=list)   # with filters: experiment/pairing.py's ratios

    @property
    def ok(self) -> bool:
        """No run failed or diverged."""
        return not self.failures

    def table(self, reference: str, method: str, fusion: str) -> Table:
        for t in self.tables:
            if (t.reference, t.method, t.fusion) == (reference, method, fusion):
                return t
        raise KeyError(f"no table for {reference} {method} {fusion}")

    def failure_line(self) -> str:
        return (f"{len(self.failures)} of {self.runs_total} run(s) failed or diverged "
                f"(first: {self.failures[0]})") if self.failures else ""

    def to_dict(self) -> dict:
        return _jsonable({
            "settings": self.settings, "rows": [{"d": r.d, "p": r.p, "p_drop": r.p_drop} for r in self.rows],
            "states": self.states,
            "tables": [{"reference": t.reference, "method": t.method, "fusion": t.fusion, "filter": t.filter,
                        "rows": t.rows} for t in self.tables],
            "bounds": [{"rmse_central": b.rmse_central, "rmse_nodes": b.rmse_nodes} for b in self.bounds],
            "failures": self.failures, "figures": self.figures, "paired": self.paired})

    def to_json(self) -> str:
        return json_text.dumps(self.to_dict())

    @staticmethod
    def is_json(path) -> bool:
        """Whether `path` holds a `to_json` an earlier run wrote (--json): its top-level keys."""
        return paths.json_keys(path) == set(JSON_KEYS)

    def report(self) -> str:
        """The tables as `codegen simulate` prints them."""
        out = io.StringIO()
        _print_report(out, self)
        if self.plot_dir is not None:
            print(f"\nwrote {len(self.written)} figures into {self.plot_dir}", file=out)
        return out.getvalue().rstrip("\n")


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


# --- the text -------------------------------------------------------------------------------------

def _fmt(mean, half) -> str:
    text = f"{mean:.3e}"
    return text if not np.isfinite(half) else f"{text}±{half:.1e}"


def row_label(row, drop: bool = False) -> str:
    return " ".join(f"{d:3d}" for d in row.d) + f"  {row.p:3.1f}" + (f"  {row.p_drop:6.2f}" if drop else "")


class _Printer:
    """Tables I-V of one (reference, method, rule) block in the chapter's layout."""

    WIDTH = 21

    def __init__(self, out, rows, n: int, nodes: int):
        self.out, self.rows, self.n, self.nodes = out, rows, n, nodes
        self.drop = any(r.p_drop for r in rows)
        self.head = " ".join(f"d{i + 1:<2d}" for i in range(len(rows[0].d))) + "   p " + \
            ("  p_drop" if self.drop else "")

    def table(self, title, cols, values) -> None:
        w = self.WIDTH
        print(title, file=self.out)
        print(f"  {self.head}  " + "".join(f"{c:>{w}}" for c in cols), file=self.out)
        for row, cells in zip(self.rows, values):
            print(f"  {row_label(row, self.drop)}  " + "".join(f"{c:>{w}}" for c in cells), file=self.out)
        print(file=self.out)

    def cells(self, s, key, idx=None) -> list[str]:
        if not s.get("runs"):
            return ["failed"] * (self.n if idx is None or isinstance(idx, int) else 1)
        m, h = np.asarray(s[key]["mean"]), np.asarray(s[key]["ci95"])
        if idx is not None:
            m, h = m[idx], h[idx]
        return [_fmt(a, b) for a, b in zip(np.atleast_1d(m), np.atleast_1d(h))]

    def estimates(self, summaries, method: str, bound) -> None:
        """Tables I-IV and the bound's IV-c, IV-d."""
        n, nodes, xcols = self.n, self.nodes, [f"x{i + 1}" for i in range(self.n)]
        self.table("Table I: traces of the covariance matrices",
                   [f"tr(P{i + 1})" for i in range(nodes)] + ["tr(P) master"],
                   [(self.cells(s, "trace_nodes") + self.cells(s, "trace_master")) if s.get("runs")
                    else ["failed"] * (nodes + 1) for s in summaries])
        for i in range(nodes):
            self.table(f"Table {'II' if i == 0 else 'III' if i == 1 else f'II.{i + 1}'}: RMSE of the estimation "
                       f"error at node {i + 1}", xcols, [self.cells(s, "rmse_nodes", i) for s in summaries])
        self.table("Table IV: RMSE of the estimation error at the master", xcols,
                   [self.cells(s, "rmse_master") for s in summaries])
        if bound is not None and method in ex.OOSM:
            self.table("Table IV-c: exact optimal filter's RMSE on the matched linear model (the Brunovsky "
                       "chain with q), centralized (per node below)", xcols, [[f"{v:.3e}" for v in b.rmse_central] for b in bound])
            for i in range(nodes):
                self.table(f"  ... node {i + 1} alone", xcols, [[f"{v:.3e}" for v in b.rmse_nodes[i]] for b in bound])
        if bound is not None:
            self.table("Table IV-d: measured master RMSE / the centralized bound (< 1 is possible: the real "
                       "plant has no process noise)", xcols,
                       [[f"{a / c:.3f}" for a, c in zip(s["rmse_master"]["mean"], b.rmse_central)] if s.get("runs")
                        else ["failed"] * n for s, b in zip(summaries, bound)])

    def tracking(self, summaries, ok) -> None:
        """Table IV-b (the plant), IV-e (the estimated tracking error), V (NEES), late frames."""
        nodes, xcols = self.nodes, [f"x{i + 1}" for i in range(self.n)]
        self.table("Table IV-b: RMSE tracking error of the plant (x - x_d, the chapter's quantity)", xcols,
                   [self.cells(s, "rmse_tracking") for s in summaries])
        if "rmse_est_tracking_master" in ok[0]:
            self.table("Table IV-e: RMSE of the estimated tracking error x_hat - x_d, x1 (the chapter's Tables "
                       "II-IV give one value per filter)", [f"node {i + 1}" for i in range(nodes)] + ["master"],
                       [(self.cells(s, "rmse_est_tracking_nodes", (slice(None), 0)) +
                         self.cells(s, "rmse_est_tracking_master", 0))
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
        self.table(f"Table V: average NEES (n = {self.n}; in: % of steps whose run-averaged NEES is in the 95% "
                   f"band)", [f"node {i + 1}" for i in range(nodes)] + ["master", "95% band"], nees_rows)
        late = [f"{s['late_applied']['mean']:.0f}/{s['late_rejected']['mean']:.0f}" if s.get("runs") else "-"
                for s in summaries]
        print("  late frames applied/rejected per run (all nodes): " + ", ".join(late), file=self.out)
        if any(s.get("outliers", {}).get("mean") for s in summaries):
            refused = [f"{s['outliers']['mean']:.1f}" if "outliers" in s else "-" for s in summaries]
            print("  frames the innovation gate refused, per run (all nodes): " + ", ".join(refused), file=self.out)
        sat = [f"{s['saturated_steps']['mean']:.1f}" if "saturated_steps" in s else "-" for s in summaries]
        print("  steps with an input clamped to its declared limits, per run: " + ", ".join(sat) + "\n",
              file=self.out)


def print_tables(out, rows, tables: list[Table], states: list[str], nodes: int, bound=None) -> None:
    """`bound`: per row, the exact optimal filter on the matched linear model (bounds.RowBound)."""
    n = len(states)
    printer = _Printer(out, rows, n, nodes)
    for t in tables:
        summaries = t.rows
        ok = [s for s in summaries if s.get("runs")]
        counts = sorted({s["runs"] for s in summaries})
        print(f"=== reference {t.reference} | late measurements: {t.method} | fusion: {t.fusion} | "
              f"runs per row: {'/'.join(map(str, counts))} (mean ± 95% CI) ===", file=out)
        if not ok:
            print("  every run failed\n", file=out)
            continue
        printer.estimates(summaries, t.method, bound)
        printer.tracking(summaries, ok)
    print(f"x1..x{n} = {', '.join(states)} (canonical states, chain by chain)", file=out)


def print_summary(out, rows, tables: list[Table]) -> None:
    """One line per (reference, method, rule): the master's x1 RMSE and NEES along the grid."""
    print("\nSummary: master RMSE of x1 (and average NEES) along the grid", file=out)
    print("  " + " " * 38 + "".join(f"{row_label(r):>24}" for r in rows), file=out)
    for t in tables:
        cells = []
        for s in t.rows:
            if not s.get("runs"):
                cells.append("failed")
                continue
            cells.append(f"{s['rmse_master']['mean'][0]:.3e} ({s['nees_master']['mean']:.2f})")
        print(f"  {t.reference + ' ' + t.method + ' ' + t.fusion:38s}" + "".join(f"{c:>24}" for c in cells), file=out)


def print_filters(out, r: SimulationResult) -> None:
    """Table VI: the derivative-free filter, the EKF and the UKF on the same recordings."""
    runs = r.settings["runs"]
    labels = [(f"{k}-replay", "difference") for k in r.settings["filters"]]
    predictor = str(r.settings.get("predictor", "held")).split(" ")[0]   # df is the closed loop's filter
    print(f"Table VI: derivative-free (df, the {predictor} predictor) against EKF and UKF on the same "
          "recordings (replay + difference; "
          "master x1 RMSE, time-averaged NEES, failed or diverged runs, CPU us per step of the filter loop, "
          "mean ± 95% CI)", file=out)
    for ref in dict.fromkeys(t.reference for t in r.tables):
        for ri, row in enumerate(r.rows):
            for label, rule in labels:
                s = r.table(ref, label, rule).rows[ri]
                failed = runs - s.get("runs", 0)
                if not s.get("runs"):
                    print(f"  {ref} {row_label(row)}  {label:16s} every run failed", file=out)
                    continue
                rm, us = s["rmse_master"], s["us_per_step"]
                print(f"  {ref} {row_label(row)}  {label:16s} x1 {_fmt(rm['mean'][0], rm['ci95'][0]):>20}  "
                      f"NEES {s['nees_master']['mean']:6.2f}  failed {failed:3d}/{runs}  "
                      f"{_fmt(us['mean'], us['ci95']):>20} us/step", file=out)
    ops = ", ".join(f"{k} {v['predict']}/{v['update']}" for k, v in r.settings["operations"].items())
    print(f"  operations per predict/update (CasADi SX instructions): {ops}\n", file=out)


def _print_report(out, r: SimulationResult) -> None:
    s = r.settings
    first, last = s["seeds"]
    reused = s["runs_resumed"]
    print(f"codegen simulate: scenario {s['scenario']} on {s['model']}: {s['nodes']} nodes, Ts = {s['ts']:g} s, "
          f"{s['duration']:g} s runs, N_max = {s['max_lag']}, q = {s['q']}, poles {s['poles']}, "
          f"seeds {first}..{last}, {s['distinct_runs']} runs in {s['elapsed_s']:.0f} s on {s['ran_on']} "
          f"({s['engine']} engine{f', {reused} resumed' if reused else ''})\n", file=out)
    if "per_seed" in s.get("model_error", {}):
        from dfeif_codegen.experiment import model_error
        model_error.report(out, s["model_error"])
    print_tables(out, r.rows, r.tables, r.states, s["nodes"], r.bounds)
    if "filters" in s:
        from dfeif_codegen.experiment import pairing
        print(file=out)
        print_filters(out, r)
        pairing.print_ratios(out, r.paired, r.rows, s["operations"], row_label, len(r.states))
    print_summary(out, r.rows, r.tables)
    if r.failures:
        print(f"\n{len(r.failures)} run(s) failed (left out of the averages):", file=out)
        for line in r.failures[:10]:
            print(f"  {line}", file=out)
        if len(r.failures) > 10:
            print(f"  ... and {len(r.failures) - 10} more (every one in --json's \"failures\")", file=out)
