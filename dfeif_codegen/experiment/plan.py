"""What `codegen simulate` will run, known and checked before the first run starts.

`plan` loads the scenario and the model, checks every option, output path and reference, and
lists each distinct run once: runs that no late frame reaches are the same for every late-
measurement method, and the EKF/UKF judge the recordings of the replay + difference loops.
"""

from __future__ import annotations

import os
from pathlib import Path
from dataclasses import dataclass

from dfeif_codegen.errors import ScenarioError, SetupError
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import scenario as scenario_mod
from dfeif_codegen.experiment.trajectory import KINDS
from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.symbolic.flatness import FlatSystem

FILTERS = ("df", "ekf", "ukf", "brunovsky", "offsets", "scheduled")


def _pick(values, i):
    return values[i % len(values)]


def configurations(oosm: list[str], fusion: list[str], baselines: list[str]) -> list[tuple[str, str]]:
    """(method, fusion) pairs: every late-measurement method with every rule, baselines with the first."""
    return [(o, f) for o in oosm for f in fusion] + [(b, fusion[0]) for b in baselines]


def make_config(sc, model: str, nodes: int, max_lag: int, ref: str, row, method: str, fusion: str,
                seed: int, predictor: str | None = None) -> ex.Config:
    """One run's configuration; `predictor` None: held, brunovsky with retrodict (ex.Config)."""
    predictor = predictors.for_method(predictor, method if method in ex.OOSM else "replay")
    return ex.Config(
        model=model, ts=sc.ts, duration=sc.duration, substeps=sc.substeps, q=tuple(sc.q_for(predictor)),
        poles=tuple(sc.poles),
        p0_std=tuple(sc.p0_std), initial_error=sc.initial_error, reference=ref, amplitude=tuple(sc.amplitude),
        period=sc.period, offset=tuple(sc.offset), harmonics=sc.harmonics, phase=tuple(sc.phase),
        cycles=tuple(int(c) for c in sc.cycles), tracking_bound=tuple(sc.tracking_bound),
        noise_scale=tuple(_pick(sc.noise_scale, i) for i in range(nodes)),
        noise_std=tuple(None if _pick(sc.noise_std, i) is None else tuple(_pick(sc.noise_std, i)) for i in range(nodes)),
        sensor=row.links(nodes), uplink=tuple(sc.uplink for _ in range(nodes)), max_lag=max_lag,
        method=method, fusion=fusion, seed=seed, metrics_from=sc.metrics_from, plant_error=sc.model_error,
        predictor=predictor, q_brunovsky=tuple(sc.q_for("brunovsky")),
        q_ekf=tuple(sc.q_ekf or ()), q_scheduled=tuple(sc.q_scheduled or ()), disturbance=sc.disturbance,
        offsets=sc.offsets, gate=sc.gate, outliers=_outliers(sc, nodes),
        trajectory=sc.trajectory if ref == ex.TRAJECTORY else None)


def _outliers(sc, nodes: int) -> tuple:
    """Each node's (fraction, size) of camera outliers, () when no node has any."""
    out = tuple(_pick(sc.outliers, i) for i in range(nodes))
    return out if any(f > 0 for f, _ in out) else ()


def _canonical(cfg: ex.Config) -> ex.Config:
    """Without any late frame every method runs the same filters: run it once."""
    if any(link.p > 0 for link in cfg.sensor):
        return cfg
    return ex.Config(**{**cfg.__dict__, "method": "replay"})


@dataclass
class Plan:
    """Everything `simulate` will run, known (and checked) before the first run starts."""

    sc: scenario_mod.Scenario
    flat: FlatSystem
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
    predictor: str | None = None    # the filters' (reference/predictor.py); None: per method

    @property
    def seeds(self) -> range:
        return range(self.seed, self.seed + self.runs)

    @property
    def labels(self) -> list[tuple[str, str]]:
        """(method label, fusion) of every table: the closed loops, then each filter on their recordings."""
        extra = [(f"{k}-replay", "difference") for k in (["df", *self.filters] if self.filters else [])]
        return list(dict.fromkeys(self.configs + extra))

    @property
    def total_runs(self) -> int:
        """Runs the tables average (a distinct run shared by several rows counts for each)."""
        return sum(len(k) for k in self.wanted.values())


def check_outputs(json_path, plot_dir, csv=None, results=None, inputs=None, resume=None) -> None:
    """Output paths and matplotlib, before any run: each a new file, or this command's own earlier
    output of its kind; none of them an input (`inputs`: {what: path}) or another output."""
    from dfeif_codegen.experiment import sweep
    from dfeif_codegen.experiment.report import SimulationResult
    from dfeif_codegen.paths import replaceable_file, writable_dir

    outputs = (("--json", None if json_path == "-" else json_path, SimulationResult.is_json),
               ("--csv", csv, sweep.is_csv), ("--results", results, sweep.is_records))
    for flag, path, ours in outputs:
        if path is not None:
            given = {**(inputs or {}), **({"--resume file": resume} if flag != "--results" else {})}
            replaceable_file(path, flag, "simulate", ours, given)
    named = [(flag, path) for flag, path, _ in outputs if path is not None]
    for i, (flag, path) in enumerate(named):
        for other, there in named[:i]:
            if os.path.abspath(path) == os.path.abspath(there):
                raise ScenarioError(f"{flag} {path}: also given to {other}; give each output its own path")
    if plot_dir:
        writable_dir(plot_dir, "--plot")
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise SetupError("--plot needs matplotlib: pip install 'dfeif-codegen[plot]'") from None


def check_figures(plot_dir: str, p: Plan) -> None:
    """The figures `--plot` will write, once the plan names them and before any run: each new,
    or a figure saved earlier, never a user's file of the same name."""
    from dfeif_codegen.experiment.figures import comparison_name, figure_names
    from dfeif_codegen.paths import check_figure_paths

    for ref in p.refs:
        names = figure_names(ref, p.nodes) + ([comparison_name(ref)] if p.filters else [])
        check_figure_paths(Path(plot_dir), names, "--plot", "simulate")


def _filters_of(filters) -> list[str]:
    """The filters asked for besides the derivative-free closed loop (always run)."""
    if filters is not None and not isinstance(filters, (str, list, tuple)):
        raise ScenarioError(f"--filters {filters!r}: a name or a list of names ({', '.join(FILTERS)})")
    filters = [filters] if isinstance(filters, str) else (filters or ["df"])
    names = [f.strip() for item in filters for f in str(item).split(",") if f.strip()]
    bad = [f for f in names if f not in FILTERS]
    if bad or not names:
        raise ScenarioError(f"--filters: {', '.join(bad) or 'nothing'}: choose from {', '.join(FILTERS)}")
    return [f for f in dict.fromkeys(names) if f != "df"]


def _counts(sc, nodes, max_lag: int, runs) -> tuple[int, int]:
    """--nodes and --runs checked against the scenario (which gives their defaults)."""
    # --nodes defaults to 2 in the parser: a scenario with another node count keeps its own
    # unless --nodes asks for something other than 2 (node settings then repeat cyclically).
    nodes = len(sc.noise_scale) if nodes is None else nodes
    if nodes < 1:
        raise ScenarioError(f"--nodes: needs at least one node, got {nodes}")
    if max_lag < 1:
        raise ScenarioError(f"--max-lag: needs at least 1, got {max_lag}")
    scenario_mod.check_window(sc, max_lag, nodes)
    runs = runs if runs is not None else sc.runs
    if not 1 <= runs <= scenario_mod.MAX_RUNS:
        raise ScenarioError(f"--runs: needs 1 to {scenario_mod.MAX_RUNS}, got {runs}")
    return nodes, runs


def _list_runs(p: Plan) -> None:
    """Fill `p.wanted`: each distinct (configuration, filter) once, with every table cell it serves."""
    for ref in p.refs:
        for ri, row in enumerate(p.rows):
            for s in p.seeds:
                for method, rule in p.configs:
                    cfg = make_config(p.sc, p.model, p.nodes, p.max_lag, ref, row, method, rule, s, p.predictor)
                    p.wanted.setdefault((_canonical(cfg), "df"), []).append((ref, method, rule, ri, s))
                for label, rule in p.labels[len(p.configs):]:
                    cfg = make_config(p.sc, p.model, p.nodes, p.max_lag, ref, row, "replay", rule, s, p.predictor)
                    p.wanted.setdefault((cfg, label), []).append((ref, label, rule, ri, s))


def plan(model: str, scenario: str, runs, seed: int, nodes, max_lag: int, oosm, fusion, reference,
         filters, plot_dir, param_error=None, predictor: str | None = None) -> Plan:
    """Load and check everything, then list each distinct run once. `param_error`
    (experiment/model_error.from_option's text) replaces the scenario's [model_error]."""
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2 ** 32:
        raise ScenarioError(f"--seed {seed!r}: a whole number from 0 to 2^32 - 1")
    for flag, value in (("--runs", runs), ("--nodes", nodes), ("--max-lag", max_lag)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int)):
            raise ScenarioError(f"{flag} {value!r}: a whole number")
    for ref in reference or []:
        if ref not in (*KINDS, ex.TRAJECTORY):
            raise ScenarioError(f"--reference {ref!r}: choose from {', '.join((*KINDS, ex.TRAJECTORY))}")
    kinds = _filters_of(filters)
    sc = scenario_mod.load(scenario)
    flat = ex._flat(model)   # the derivation every run of this process (and its workers) uses
    if param_error is not None:
        from dfeif_codegen.experiment import model_error
        sc.model_error = model_error.from_option(param_error)
        sc.model_error.check(flat.model, lambda key: "--param-error")
    if plot_dir:                          # a missing matplotlib is said before the runs, not after
        from dfeif_codegen.experiment import figures as figs
        figs.pyplot()
    sc.check_model(flat)
    if "offsets" in kinds and sc.offsets is None:
        raise ScenarioError(f"--filters offsets: {sc.source} has no [offsets] table (the parameters whose "
                            f"offsets the filter estimates, e.g. params = [\"R\", \"m\"], std = 0.2)")
    nodes, runs = _counts(sc, nodes, max_lag, runs)
    if seed + runs > 2 ** 32:   # the seeds are seed .. seed + runs - 1, each a 32-bit seed
        raise ScenarioError(f"--seed {seed} --runs {runs}: the last seed, {seed + runs - 1}, is above 2^32 - 1")
    refs = list(reference or sc.references)
    if ex.TRAJECTORY in refs and sc.trajectory is None:
        raise ScenarioError(f"--reference {ex.TRAJECTORY}: {sc.source} has no [reference] file (a CSV of the flat outputs)")
    for ref in refs:   # a shape the file does not size would run at the default amplitude, 1
        if ref in KINDS and ref not in sc.references and sc.trajectory is not None and not sc.amplitude_given:
            raise ScenarioError(f"--reference {ref}: {sc.source} gives its reference as a file only; a {ref} "
                                "needs [reference] amplitude (and period) for the model's outputs")
    configs = list(dict.fromkeys(configurations(list(oosm or sc.oosm), list(fusion or sc.fusion), sc.baselines)))
    for method, _ in configs:
        oosm_of = method if method in ex.OOSM else "replay"
        try:
            predictors.check(predictors.for_method(predictor, oosm_of), oosm_of)
        except ValueError as exc:
            raise ScenarioError(str(exc) if oosm else f"{sc.where('oosm')}: {exc}") from None
        sc.check_predictor(predictor, oosm_of)
    rows = [scenario_mod.Row([_pick(r.d, i) for i in range(nodes)], r.p, r.p_drop) for r in sc.grid]
    p = Plan(sc, flat, model, nodes, max_lag, runs, seed, refs, configs, kinds, rows, {}, set(), predictor)
    _list_runs(p)
    for cfg in {c.reference: c for c, _ in p.wanted}.values():
        try:  # a reference outside the model's domain is bad input, known before any run
            ex.check_reference_of(cfg)
        except ex.UndefinedReference as exc:
            raise ScenarioError(f"{sc.where('reference')}: {cfg.reference}: {exc}") from None
    p.figure_keys = {(ref, configs[0][0], configs[0][1], ri, seed) for ref in refs for ri in (0, len(rows) - 1)}
    return p
