"""Experiment scenarios: the built-in "paper" one (scenarios/paper.toml) or a user's TOML file.

A scenario fixes everything `codegen simulate` runs except the model: run length, filter and
controller tuning, the reference, the cameras, the network and the delay grid (the rows of the
chapter's tables). Every problem is one `ScenarioError` line naming the file, line and field.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from dfeif_codegen.constants import NODES_LIMIT
from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.paths import parse_toml, read_text
from dfeif_codegen.symbolic.model import _key_lines
from dfeif_codegen.experiment.closed_loop import BASELINES, OOSM
from dfeif_codegen.experiment.network import Link
from dfeif_codegen.experiment.scenario_fields import Reader
from dfeif_codegen.experiment import model_error, trajectory_file
from dfeif_codegen.experiment.trajectory import KINDS
from dfeif_codegen.reference import offsets as offset_states, predictor as predictors
from dfeif_codegen.reference.fusion import RULES
from dfeif_codegen.symbolic import disturbance as disturbances

BUILTIN = ("paper", "unicycle", "pvtol")

_ALLOWED = {
    "scenario": {"name", "description", "duration", "ts", "runs", "substeps", "metrics_from", "references",
                 "oosm", "fusion", "baselines"},
    "filter": {"q", "q_brunovsky", "q_ekf", "q_scheduled", "p0_std", "initial_error", "gate"},
    "control": {"poles"},
    "reference": {"amplitude", "period", "offset", "harmonics", "phase", "cycles", "tracking_bound", "file",
                  "smoothing"},
    "nodes": {"noise_scale", "noise_std", "outliers", "outlier_size"},
    "uplink": {"p", "d", "p_drop"},
    "grid": {"d", "p", "p_drop"},
    "model_error": model_error.KEYS,
    "disturbance": disturbances.KEYS,
    "offsets": offset_states.KEYS,
}


@dataclass
class Row:
    """One row of the tables: per node (d_i, p, p_drop) on the camera -> node link."""

    d: list[int]
    p: float
    p_drop: float = 0.0

    def links(self, nodes: int) -> tuple[Link, ...]:
        return tuple(Link(self.p, self.d[i % len(self.d)], self.p_drop) for i in range(nodes))

    @property
    def label(self) -> tuple:
        return (*self.d, self.p)


@dataclass
class Scenario:
    name: str
    source: str
    description: str = ""
    duration: float = 20.0
    ts: float | None = None
    runs: int = 5
    substeps: int = 10
    metrics_from: float = 1.0
    references: list[str] = field(default_factory=lambda: list(KINDS))
    oosm: list[str] = field(default_factory=lambda: ["replay"])
    fusion: list[str] = field(default_factory=lambda: ["difference"])
    baselines: list[str] = field(default_factory=lambda: list(BASELINES))
    q: list[float] = field(default_factory=lambda: [20.0])
    q_brunovsky: list[float] | None = None   # the chapter's filter's q, when it differs from q
    q_ekf: list[float] | None = None   # the EKF's and UKF's q (--filters), when it differs from q
    q_scheduled: list[float] | None = None   # the scheduled filter's q (--filters), when it differs
    p0_std: list[float] = field(default_factory=lambda: [0.05, 0.1, 1.0])
    initial_error: bool = True
    poles: list[float] = field(default_factory=lambda: [10.0])
    amplitude: list[float] = field(default_factory=lambda: [1.0])
    amplitude_given: bool = False   # [reference] amplitude written in the file (not the default)
    period: float = 5.0
    offset: list[float] = field(default_factory=lambda: [0.0])
    harmonics: int = 4
    phase: list[float] = field(default_factory=lambda: [0.0])
    cycles: list[float] = field(default_factory=lambda: [1.0])
    tracking_bound: list[float] = field(default_factory=list)   # default: twice the amplitude
    noise_scale: list[float] = field(default_factory=lambda: [1.0, 1.0])
    noise_std: list[list[float] | None] = field(default_factory=lambda: [None, None])
    # per node: the fraction of its camera's frames that are outliers, and their offset in camera
    # standard deviations (a tracker on the wrong feature); the nodes' innovation gate, 0: none
    outliers: list[tuple[float, float]] = field(default_factory=lambda: [(0.0, 0.0), (0.0, 0.0)])
    gate: float = 0.0
    uplink: Link = field(default_factory=Link)
    grid: list[Row] = field(default_factory=lambda: [Row([0, 0], 0.0)])
    model_error: model_error.ParamError = model_error.NONE    # the plant's parameters against the model's
    disturbance: disturbances.Disturbance | None = None        # the filters' disturbance states, if any
    offsets: offset_states.Offsets | None = None   # what `--filters offsets` estimates (reference/offsets.py)
    trajectory: trajectory_file.Trajectory | None = None     # [reference] file: the reference "trajectory"
    _lines: dict = field(default_factory=dict, repr=False)

    def q_for(self, predictor: str) -> list[float]:
        """The process-noise densities of the filters `predictor` names: each predictor's q means
        something else (the held mean's model error, less with the scheduled transition, or all
        of F + G u's variation over a period for the chapter's chain), so a scenario may give each."""
        own = {"brunovsky": self.q_brunovsky, "scheduled": self.q_scheduled}.get(predictor)
        return own or self.q

    def where(self, key: str) -> str:
        """`file:line: key`; entry i of an array of tables is looked up as `grid#i` and shown as `grid[i+1]`."""
        head = key.split(".")[0]
        inside = [n for k, n in self._lines.items() if k.startswith(head + ".")]
        parent = key.rsplit(".", 1)[0] if key.count(".") > 1 else None    # model_error.relative.R
        line = self._lines.get(key) or (parent and self._lines.get(parent)) or self._lines.get(head) \
            or (min(inside) if inside else None)
        shown = re.sub(r"#(\d+)", lambda g: f"[{int(g.group(1)) + 1}]", key)
        return f"{self.source}:{line}: {shown}" if line else f"{self.source}: {shown}"

    def check_predictor(self, predictor: str | None, oosm: str) -> None:
        """The scenario's disturbance states need a predictor that carries them: the error names
        the [disturbance] table (the commands that take a scenario have no --disturbance)."""
        try:
            predictors.check(predictors.for_method(predictor, oosm), oosm, self.disturbance)
        except ValueError as exc:
            raise ScenarioError(f"{self.where('disturbance')}: {exc}") from None

    def check_model(self, flat) -> None:
        """What depends on the model: per-chain lengths, P0 orders, camera noise."""
        m = flat.m
        hint = (f" (the built-in scenario does not fit model {flat.model.name}: write one for it with `codegen "
                f"scenario MODEL --out FILE`, or copy dfeif_codegen/experiment/scenarios/{self.source} and edit it, "
                "and pass it with --scenario FILE)"
                if self.source in {f"{b}.toml" for b in BUILTIN} else "")

        def fail(key: str, message: str):
            raise ScenarioError(f"{self.where(key)}: {message}{hint}")

        def at(key: str) -> str:      # a spread over `params` is named on the params line
            if key.startswith("spread.") and "model_error.params" in self._lines:
                key = "params"
            return self.where(key if key == "model_error" else f"model_error.{key}")

        self.model_error.check(flat.model, at)
        if self.offsets is not None:
            try:
                self.offsets.indices(flat)
            except ValueError as exc:
                fail("offsets.params", str(exc))
        ts = self.ts or flat.model.ts
        if self.runs > MAX_RUNS:
            fail("scenario.runs", f"{self.runs} runs: at most {MAX_RUNS} (each is a closed-loop simulation)")
        if self.harmonics > MAX_HARMONICS:
            fail("reference.harmonics", f"{self.harmonics}: at most {MAX_HARMONICS} harmonics of the reference")
        if not 2 <= self.duration / ts <= MAX_STEPS:
            fail("scenario.duration", f"{self.duration:g} s at Ts = {ts:g} s is {self.duration / ts:.3g} steps; "
                                      f"at least 2 and at most {MAX_STEPS:g} per run")
        if self.substeps > MAX_SUBSTEPS:
            fail("scenario.substeps", f"{self.substeps}: at most {MAX_SUBSTEPS} plant integration steps per period")
        if self.period < 2 * ts:   # sampled below Nyquist; 1e-300 overflowed the reference's derivatives
            fail("reference.period", f"{self.period:g} s is shorter than two sampling periods ({2 * ts:g} s)")
        for key, values in (("filter.q", self.q), ("filter.q_brunovsky", self.q_brunovsky or self.q),
                            ("filter.q_ekf", self.q_ekf or self.q),
                            ("filter.q_scheduled", self.q_scheduled or self.q),
                            ("control.poles", self.poles),
                            ("reference.amplitude", self.amplitude), ("reference.offset", self.offset),
                            ("reference.phase", self.phase), ("reference.cycles", self.cycles),
                            *((("reference.tracking_bound", self.tracking_bound),) if self.tracking_bound else ()),
                            *((("offsets.chains_q", self.offsets.chains_q),)
                              if self.offsets is not None and self.offsets.chains_q else ())):
            if len(values) not in (1, m):
                needs = "1 value (its one flat output)" if m == 1 else f"1 or {m} values (one per flat output)"
                fail(key, f"needs {needs} for model {flat.model.name}, got {len(values)}")
        if self.trajectory is not None:
            K = int(round(self.duration / ts))
            trajectory_file.check(self.trajectory, [o.name for o in flat.model.outputs], flat.degrees,
                                  (K - 1) * ts, flat.model.name, self.where("reference.file"))
        if self.disturbance is not None:
            self.disturbance.check(m, fail)
        if len(self.p0_std) < max(flat.degrees):
            fail("filter.p0_std", f"needs {max(flat.degrees)} values (one per derivative order) for model "
                                  f"{flat.model.name}, got {len(self.p0_std)}")
        meas = flat.model.measurement
        channels = len(meas.observe) if meas else m
        for i, std in enumerate(self.noise_std):
            if std is None and meas is None:
                fail("nodes", f"node {i + 1}: needs noise_std, one per flat output ({flat.model.name} has no [measurement])")
            if std is not None and len(std) not in (1, channels):
                fail("nodes", f"node {i + 1}: noise_std needs 1 or {channels} values (one per camera "
                              f"channel), got {len(std)}")


MAX_STEPS = 1e6  # steps per run: the recording keeps every step's covariances in memory
MAX_SUBSTEPS = 1000  # the plant's RK4 steps per period (1e9 ran for hours, beyond a Ctrl-C in the C engine)
MAX_RUNS = 100_000  # seeds per row (a 100-seed table is the chapter's; 1e9 would never end)
MAX_HARMONICS = 1000  # of the seesaw reference (each is a term of every step's reference)


def check_window(sc: "Scenario", max_lag: int, nodes: int, rows=None) -> None:
    """A delay longer than the late-measurement window would be dropped silently: refuse it, in
    the grid's `rows` (default all; verify and network run one row, and a longer delay in a row
    they do not run is none of their business)."""
    for i, row in enumerate(sc.grid):
        if rows is not None and i not in rows:
            continue
        for d in row.d:
            if d > max_lag:
                raise ScenarioError(f"{sc.where(f'grid#{i}.d')}: delay {d} steps is longer than the window "
                                    f"--max-lag {max_lag}: every late frame would be dropped")
    if sc.uplink.d > max_lag:
        raise ScenarioError(f"{sc.where('uplink.d')}: delay {sc.uplink.d} steps is longer than the window "
                            f"--max-lag {max_lag}: every packet would reach the master too late")


# --- parsing ----------------------------------------------------------------------------------

def load(spec: str) -> Scenario:
    """A built-in scenario by name, or a path to a scenario `.toml` file."""
    if spec in BUILTIN:
        text = (resources.files("dfeif_codegen.experiment") / "scenarios" / f"{spec}.toml").read_text(encoding="utf-8")
        return loads(text, f"{spec}.toml")
    path = Path(spec)
    if path.suffix != ".toml" and not path.exists():
        raise ScenarioError(f"{spec}: not a built-in scenario ({', '.join(BUILTIN)}) nor a .toml file")
    return loads(read_text(path, spec, ScenarioError, "scenario"), spec)


def _check_keys(r: Reader, data: dict) -> None:
    """Unknown sections and fields are errors (a typo is not silently a default)."""
    for section, value in data.items():
        if section not in _ALLOWED:
            r.fail(section, f"unknown section [{section}] (expected one of {', '.join(sorted(_ALLOWED))})")
        tables = value if section in ("nodes", "grid") else [value]
        if not isinstance(value, (dict, list)) or not all(isinstance(t, dict) for t in tables):
            kind = f"[[{section}]] entries" if section in ("nodes", "grid") else f"a [{section}] table"
            r.fail(section, f"must be {kind}")
        for i, table in enumerate(tables):
            for key in table:
                if key not in _ALLOWED[section]:
                    r.fail(f"{section}#{i}.{key}" if section in ("nodes", "grid") else f"{section}.{key}",
                           f"unknown field (expected one of {', '.join(sorted(_ALLOWED[section]))})")


def _read_head(r: Reader, head: dict) -> None:
    """[scenario]: name, run length, sampling, seeds, what to compare."""
    sc = r.sc
    sc.name = head.get("name", sc.name)
    if not isinstance(sc.name, str):
        r.fail("scenario.name", "must be a string")
    sc.description = str(head.get("description", ""))
    sc.duration = r.number(head, "scenario", "duration", sc.duration, positive=True, allow_zero=False)
    if "ts" in head:   # two periods at least: check_model
        sc.ts = r.number(head, "scenario", "ts", None, positive=True, allow_zero=False)
    sc.runs = r.number(head, "scenario", "runs", sc.runs, positive=True, allow_zero=False, integer=True)
    sc.substeps = r.number(head, "scenario", "substeps", sc.substeps, positive=True, allow_zero=False, integer=True)
    sc.metrics_from = r.number(head, "scenario", "metrics_from", sc.metrics_from, positive=True)
    if sc.metrics_from >= sc.duration:
        r.fail("scenario.metrics_from", f"{sc.metrics_from} s leaves nothing of a {sc.duration} s run to measure")
    sc.references = r.names(head, "scenario", "references", sc.references, (*KINDS, trajectory_file.KIND))
    sc.oosm = r.names(head, "scenario", "oosm", sc.oosm, OOSM)
    sc.fusion = r.names(head, "scenario", "fusion", sc.fusion, RULES)
    value = head.get("baselines", sc.baselines)
    sc.baselines = [] if value == [] else r.names(head, "scenario", "baselines", value, BASELINES)


def _read_settings(r: Reader, data: dict) -> None:
    """[filter], [control], [reference]."""
    sc = r.sc
    filt = data.get("filter", {})
    sc.q = r.numbers(filt, "filter", "q", sc.q)
    if "q_brunovsky" in filt:
        sc.q_brunovsky = r.numbers(filt, "filter", "q_brunovsky", [])
    if "q_ekf" in filt:
        sc.q_ekf = r.numbers(filt, "filter", "q_ekf", [])
    if "q_scheduled" in filt:
        sc.q_scheduled = r.numbers(filt, "filter", "q_scheduled", [])
    sc.p0_std = r.stds(filt, "filter", "p0_std", sc.p0_std)
    if "gate" in filt:
        sc.gate = r.number(filt, "filter", "gate", 0.0, positive=True, allow_zero=False)
    sc.initial_error = filt.get("initial_error", sc.initial_error)
    if not isinstance(sc.initial_error, bool):
        r.fail("filter.initial_error", "must be true or false")
    sc.poles = r.numbers(data.get("control", {}), "control", "poles", sc.poles)
    ref = data.get("reference", {})
    sc.amplitude = r.numbers(ref, "reference", "amplitude", sc.amplitude, positive=False)
    sc.amplitude_given = "amplitude" in ref
    sc.offset = r.numbers(ref, "reference", "offset", sc.offset, positive=False)
    sc.period = r.number(ref, "reference", "period", sc.period, positive=True, allow_zero=False)
    sc.harmonics = r.number(ref, "reference", "harmonics", sc.harmonics, positive=True, allow_zero=False, integer=True)
    sc.phase = r.numbers(ref, "reference", "phase", sc.phase, positive=False)
    sc.cycles = r.numbers(ref, "reference", "cycles", sc.cycles)
    if "tracking_bound" in ref:
        sc.tracking_bound = r.numbers(ref, "reference", "tracking_bound", [])
    if any(c != int(c) or c < 1 for c in sc.cycles):
        r.fail("reference.cycles", f"needs whole numbers of cycles per period (>= 1), got {sc.cycles}")
    _read_trajectory(r, ref, "references" in data.get("scenario", {}))


def _read_trajectory(r: Reader, ref: dict, listed: bool) -> None:
    """[reference] file (a CSV, relative to the scenario file) and smoothing; a scenario with a
    file runs the reference "trajectory" unless [scenario] references says otherwise."""
    sc = r.sc
    if "smoothing" in ref and "file" not in ref:
        r.fail("reference.smoothing", "only applies to a [reference] file")
    if "file" in ref:
        if not isinstance(ref["file"], str) or not ref["file"]:
            r.fail("reference.file", f"must be the path of a CSV file, got {ref['file']!r}")
        smoothing = r.number(ref, "reference", "smoothing", 0.0, positive=True)
        base = Path(sc.source).parent if sc.source not in {f"{b}.toml" for b in BUILTIN} else Path(".")
        try:
            sc.trajectory = trajectory_file.read(base / ref["file"], smoothing)
        except ScenarioError as exc:
            r.fail("reference.file", str(exc))
        if not listed:
            sc.references = [trajectory_file.KIND]
    if trajectory_file.KIND in sc.references and sc.trajectory is None:
        r.fail("scenario.references", f"'{trajectory_file.KIND}' needs a [reference] file (a CSV of the flat outputs)")


def _read_network(r: Reader, data: dict) -> None:
    """[[nodes]], [uplink] and the delay rows [[grid]]."""
    sc = r.sc
    if "nodes" in data:
        if not 1 <= len(data["nodes"]) <= NODES_LIMIT:
            r.fail("nodes", f"needs 1 to {NODES_LIMIT} [[nodes]] entries (a module's limit), got {len(data['nodes'])}")
        sc.noise_scale, sc.noise_std, sc.outliers = [], [], []
        for i, node in enumerate(data["nodes"]):
            at = f"nodes#{i}"
            sc.noise_scale.append(r.std(node, at, "noise_scale", 1.0))
            sc.noise_std.append(r.stds(node, at, "noise_std", None) if "noise_std" in node else None)
            fraction = r.number(node, at, "outliers", 0.0, positive=True)
            if fraction >= 1:
                r.fail(f"{at}.outliers", f"must be a fraction of the frames in [0, 1), got {fraction!r}")
            size = r.number(node, at, "outlier_size", 30.0, positive=True, allow_zero=False)
            sc.outliers.append((fraction, size if fraction > 0 else 0.0))
    if "uplink" in data:
        sc.uplink = r.link(data["uplink"], "uplink")
    if "grid" in data:
        if not data["grid"]:
            r.fail("grid", "needs at least one [[grid]] row")
        sc.grid = []
        for i, row in enumerate(data["grid"]):
            at = f"grid#{i}"
            d = row.get("d", 0)
            ds = d if isinstance(d, list) else [d]
            if not ds or not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in ds):
                r.fail(f"{at}.d", f"must be a whole number of steps >= 0 or a list of them (one per node), got {d!r}")
            if len(ds) not in (1, len(sc.noise_scale)):
                r.fail(f"{at}.d", f"needs 1 value or one per node ({len(sc.noise_scale)}), got {len(ds)}")
            row_ = Row(list(ds), r.number(row, at, "p", 0.0, positive=True),
                       r.number(row, at, "p_drop", 0.0, positive=True))
            for lk in row_.links(len(sc.noise_scale)):
                if lk.problem():
                    r.fail(at, lk.problem())
            sc.grid.append(row_)


def loads(text: str, source: str = "<string>") -> Scenario:
    """A scenario from TOML text; every problem is a ScenarioError naming the field and its line."""
    data = parse_toml(text, source, ScenarioError)
    r = Reader(Scenario(name=Path(source).stem, source=source, _lines=_key_lines(text)))
    _check_keys(r, data)
    _read_head(r, data.get("scenario", {}))
    _read_settings(r, data)
    _read_network(r, data)
    if "model_error" in data:
        r.sc.model_error = model_error.from_table(data["model_error"], r.fail)
    if "disturbance" in data:
        r.sc.disturbance = disturbances.from_table(data["disturbance"], r.fail)
    if "offsets" in data:
        r.sc.offsets = offset_states.from_table(data["offsets"], r.fail)
    return r.sc
