"""The model's derivation (its FlatSystem) by spec, made once per process (`_flat`) or under the
time and memory budget before a command's runs start (`derive`), and shipped to workers with the
model files' text (experiment/sweep.py), so a worker spends no second of sympy."""

from __future__ import annotations

from dfeif_codegen.symbolic import flatness
from dfeif_codegen.symbolic import model as model_mod

# model files' text by spec, set on workers that may not see the caller's files (sweep.py)
MODEL_TEXT: dict[str, str] = {}
# derivations by spec: this process's, or the caller's shipped to a worker (sweep.py), which then
# spends no second of sympy per process
FLATS: dict = {}


def _flat(spec: str):
    if spec not in FLATS:
        text = MODEL_TEXT.get(spec)
        FLATS[spec] = flatness.derive(model_mod.loads_toml(text, spec) if text is not None else model_mod.load(spec))
    return FLATS[spec]


def derive(spec: str, max_seconds: float | None = None, max_memory: float | None = None):
    """The derivation `_flat` returns, made now under the budget (CPU seconds, GB; None: the
    process's default, see budget.configure): a command calls this before its runs start."""
    from dfeif_codegen import budget
    budget.configure(max_seconds, max_memory)
    if spec not in FLATS:
        text = MODEL_TEXT.get(spec)
        mdl = model_mod.loads_toml(text, spec) if text is not None else model_mod.load(spec)
        FLATS[spec] = budget.bounded(flatness.derive, (mdl,), None, None, f"deriving {mdl.source}")
    return FLATS[spec]
