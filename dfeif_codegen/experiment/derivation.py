"""The model's derivation (its FlatSystem) by spec, made once per process (`_flat`) or under the
time and memory budget before a command's runs start (`derive`), and shipped to workers with the
model files' text (experiment/sweep.py), so a worker spends no second of sympy."""

from __future__ import annotations

from pathlib import Path, PurePath

from dfeif_codegen.symbolic import flatness
from dfeif_codegen.symbolic import model as model_mod

# model files' text by spec, set on workers that may not see the caller's files (sweep.py)
MODEL_TEXT: dict[str, str] = {}
# derivations by spec: this process's, or the caller's shipped to a worker (sweep.py), which then
# spends no second of sympy per process
FLATS: dict = {}
# the model file's text each spec's caches were made from, and the caches keyed by spec
# (`by_model`): an API user who edits a model file between two calls gets the edited model
SOURCES: dict[str, bytes] = {}
_CACHES: list = []


def by_model(cached):
    """Register an lru_cache'd function whose arguments include a model's spec: `refresh` clears
    it when that model's file changes."""
    _CACHES.append(cached)
    return cached


def refresh(spec: str) -> None:
    """Forget what this process derived and built from an earlier text of the spec's file."""
    path = Path(spec)
    if not path.is_file():
        return
    text = path.read_bytes()    # bytes: a file that is no model text is the loader's to name
    if SOURCES.get(spec, text) != text:
        FLATS.pop(spec, None)
        MODEL_TEXT.pop(spec, None)
        for cached in _CACHES:
            cached.cache_clear()
    SOURCES[spec] = text


def _flat(spec: str):
    if spec not in FLATS:
        text = MODEL_TEXT.get(spec)
        FLATS[spec] = flatness.derive(model_mod.loads_toml(text, spec) if text is not None else model_mod.load(spec))
    return FLATS[spec]


def derive(spec: str, max_seconds: float | None = None, max_memory: float | None = None):
    """The derivation `_flat` returns, made now under the budget (CPU seconds, GB; None: the
    process's default, see budget.configure): a command calls this before its runs start."""
    from dfeif_codegen import budget
    from dfeif_codegen.errors import ModelError
    if not isinstance(spec, (str, PurePath)):   # a Model object: the runs load the model by name or path
        raise ModelError(f"{type(spec).__name__}: give the model as a built-in name or a .toml path (the runs "
                         "load it by that name, in worker processes too)")
    budget.configure(max_seconds, max_memory)
    refresh(spec)
    if spec not in FLATS:
        text = MODEL_TEXT.get(spec)
        mdl = model_mod.loads_toml(text, spec) if text is not None else model_mod.load(spec)
        FLATS[spec] = budget.bounded(flatness.derive, (mdl,), None, None, f"deriving {mdl.source}")
    return FLATS[spec]
