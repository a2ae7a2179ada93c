"""The Python face of `codegen simulate` (`dc.simulate`): the one command whose default needs a
stage above its own. The experiment (experiment/) runs closed loops on an engine it is handed;
the compiled engine compiles C, so it lives in check/, and this module, above both, picks one by
the name the CLI's `--engine` takes. The other commands' functions are reached directly
(dfeif_codegen/__init__.py)."""

from __future__ import annotations

from dfeif_codegen.check import closed_loop_c
from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.experiment import simulate as experiment
from dfeif_codegen.experiment import sweep
from dfeif_codegen.experiment.closed_loop import MAX_LAG
from dfeif_codegen.experiment.report import SimulationResult

ENGINES: dict[str, sweep.Engine] = {"c": closed_loop_c.ENGINE, "reference": sweep.REFERENCE}


def engine_named(name: str) -> sweep.Engine:
    """The closed-loop engine called `name` ("c": compiled, the default; "reference": numpy)."""
    if name not in ENGINES:
        raise ScenarioError(f"--engine: {name}: choose from {', '.join(ENGINES)}")
    return ENGINES[name]


def simulate(model: str = "dc_motor_link", *, scenario: str = "paper", runs: int | None = None, seed: int = 0,
             nodes: int | None = None, max_lag: int = MAX_LAG, oosm: str | list[str] | None = None,
             fusion: str | list[str] | None = None, reference: str | list[str] | None = None,
             filters: str | list[str] | None = None, plot: str | None = None, json_path: str | None = None,
             quiet: bool = False, engine: str = "c", workers: int | None = None, scheduler: str | None = None,
             results: str | None = None, csv: str | None = None, resume: str | None = None,
             max_seconds: float | None = None, max_memory: float | None = None,
             param_error: str | float | None = None, predictor: str | None = None) -> SimulationResult:
    """`codegen simulate` as a function: the chapter's experiment, returned as a SimulationResult
    (`.tables`, `.report()`, `.to_json()`, `.failures`). Keywords are the command's options:
    `runs` seeds from `seed`, `oosm`/`fusion`/`reference` one name or a list, `filters` any of
    "df", "ekf", "ukf", "brunovsky", "offsets", "scheduled" (a list or one comma-separated
    string), `engine` "c" or "reference";
    `plot` (a folder), `json_path`, `results`, `csv` are files written on the way ("-" as
    `json_path` writes nothing: the CLI prints `.to_json()`). `max_seconds` (CPU) and `max_memory`
    (GB) bound the derivation. `param_error`: the plant's parameters against the model's,
    replacing the scenario's [model_error] (0.2: each drawn per run within +-20%; "R=0.2": R 20%
    above; 0: the exact model). `predictor` "held", "scheduled" or "brunovsky" (None: held, the default;
    brunovsky with retrodict). Bad input raises a CodegenError before any run."""
    def listed(value):
        return [value] if isinstance(value, str) else value

    return experiment.simulate(
        model, engine=engine_named(engine), scenario=scenario, runs=runs, seed=seed, nodes=nodes,
        max_lag=max_lag, oosm=listed(oosm), fusion=listed(fusion), reference=listed(reference), filters=filters,
        plot=plot, json_path=json_path, quiet=quiet, workers=workers, scheduler=scheduler, results=results,
        csv=csv, resume=resume, max_seconds=max_seconds, max_memory=max_memory, param_error=param_error,
        predictor=predictor)
