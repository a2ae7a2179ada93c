"""A model built from sympy (Python API, `from_sympy`) or read from a TOML file (`load`,
`loads_toml`: every problem a ModelError naming the file, line and field). Both ways end in the
same `Model` (symbolic/model_parts.py, its parts and checks); everything downstream (flatness,
kernels, the reference filters) reads only that class.
"""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path, PurePath
from typing import Mapping, Sequence

import sympy as sp

from dfeif_codegen.errors import ModelError
from dfeif_codegen.paths import parse_toml, read_text
from dfeif_codegen.symbolic.expr_parser import parse_expression
from dfeif_codegen.symbolic.model_parts import (CLASHING_WORDS, MAX_MEAN_SUBSTEPS, MODEL_NAME_LIMIT, _NAME, _twice, Measurement, Model,
                                                Output, Parameter, Variable, _finite, _where)

__all__ = ["CLASHING_WORDS", "MODEL_NAME_LIMIT", "Measurement", "Model", "Output", "Parameter", "Variable",
           "builtin_names", "from_sympy", "load", "load_toml", "loads_toml"]

# Keys a model file may use, per section (a typo must not silently switch a feature off).
SCHEMA = {
    "": {"model", "states", "inputs", "parameters", "dynamics", "outputs", "measurement", "inverse"},
    "model": {"name", "description", "ts", "mean_substeps"},
    "states": {"name", "unit", "description", "min", "max", "nominal"},
    "inputs": {"name", "unit", "description", "min", "max", "nominal"},
    "parameters": {"name", "value", "unit", "description", "source"},
    "dynamics": {"f", "g", "definitions"},
    "outputs": {"name", "expr", "angle"},
    "measurement": {"observe", "noise", "recover"},
    "inverse": set(),   # keys are state names, checked by _inverse
}
FREE_SECTIONS = {"inverse"}   # sections whose keys are the model's own names, not a fixed set


# --- TOML ------------------------------------------------------------------------------------

def _key_lines(text: str) -> dict[str, int]:
    """Map `section.key` to its line, so messages can say where (tomllib keeps no positions)."""
    lines: dict[str, int] = {}
    section = ""
    counters: dict[str, int] = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        header = re.match(r"^\[\[?\s*([^\]]+?)\s*\]\]?", line)
        if header:
            section = header.group(1).replace('"', "")
            if line.startswith("[["):
                counters[section] = counters.get(section, -1) + 1
                section = f"{section}#{counters[section]}"
            lines.setdefault(section.split("#")[0], number)
            lines.setdefault(section, number)
            continue
        key = re.match(r"^([A-Za-z0-9_\"]+)\s*=", line)
        if key:
            name = key.group(1).replace('"', "")
            lines.setdefault(f"{section}.{name}" if section else name, number)
    return lines


def _check_keys(data: Mapping, where) -> None:
    """Unknown sections and keys are errors naming the key and its line (see SCHEMA)."""
    def unknown(key: str, allowed) -> None:
        raise ModelError(f"{where(key)}: unknown key (expected one of {', '.join(sorted(allowed))})")

    for section, value in data.items():
        if section not in SCHEMA[""]:
            unknown(section, SCHEMA[""])
        entries = value if isinstance(value, list) else [value]
        for i, entry in enumerate(entries):
            if not isinstance(entry, dict) or section in FREE_SECTIONS:
                continue
            for key in entry:
                if key not in SCHEMA[section]:
                    unknown(f"{section}#{i}.{key}" if isinstance(value, list) else f"{section}.{key}", SCHEMA[section])


def _table(data: Mapping, key: str, where: str, required: bool = True) -> dict:
    value = data.get(key)
    if value is None:
        if required:
            raise ModelError(f"{where}: missing [{key}]")
        return {}
    if not isinstance(value, dict):
        raise ModelError(f"{where}: [{key}] must be a table")
    return value


def _positive(values) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0 for v in values)


def _items(data: Mapping, key: str, where, required: bool = True) -> list[dict]:
    value = data.get(key)
    if value is None:
        if required:
            raise ModelError(f"{where(key)}: missing [[{key}]] entries")
        return []
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise ModelError(f"{where(key)}: [[{key}]] must be an array of tables")
    return value


def _text(entry: Mapping, field_name: str, where: str, default: str | None = None) -> str:
    value = entry.get(field_name, default)
    if value is None:
        raise ModelError(f"{where}: missing field '{field_name}'")
    if not isinstance(value, str):
        raise ModelError(f"{where}: field '{field_name}' must be a string")
    return value


def load_toml(path: str | Path, source: str | None = None) -> Model:
    """Read a model file. Every expression goes through the restricted parser (no eval)."""
    path = Path(path)
    source = source or str(path)
    return loads_toml(read_text(path, source, ModelError, "model"), source)


class _Doc:
    """A parsed model file: `where(key)` names a key's file and line; `parse` reads an expression."""

    def __init__(self, text: str, source: str):
        self.data = parse_toml(text, source, ModelError)
        self.source, self.lines = source, _key_lines(text)
        self.symbols: dict[str, sp.Expr] = {}
        self.misplaced: dict[str, str] = {}   # the inputs: named in a state function, said so, not "undeclared"

    def where(self, key: str) -> str:
        return _where(self.source, self.lines, key)

    def parse(self, key: str, expr_text, names: dict | None = None) -> sp.Expr:
        if not isinstance(expr_text, (str, int, float)) or isinstance(expr_text, bool):
            raise ModelError(f"{self.where(key)}: expression must be a string")
        return parse_expression(str(expr_text), self.symbols if names is None else names, self.where(key),
                                self.misplaced)


def _variables(doc: _Doc, key: str) -> list[Variable]:
    """[[states]] or [[inputs]]: name, unit, description and the domain (min, max, nominal)."""
    out = []
    for i, entry in enumerate(_items(doc.data, key, doc.where)):
        at = doc.where(f"{key}#{i}")
        bounds = {}
        for field_name in ("min", "max", "nominal"):
            value = entry.get(field_name)
            if value is not None and not _finite(value):
                raise ModelError(f"{doc.where(f'{key}#{i}.{field_name}')}: must be a finite number")
            bounds[field_name] = None if value is None else float(value)
        out.append(Variable(_text(entry, "name", at), _text(entry, "unit", at, ""),
                            _text(entry, "description", at, ""), **bounds))
    return out


def _parameters(doc: _Doc) -> list[Parameter]:
    parameters = []
    for i, entry in enumerate(_items(doc.data, "parameters", doc.where, required=False)):
        at = f"{doc.where('parameters')} #{i + 1}"
        value = entry.get("value")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ModelError(f"{at}: field 'value' must be a number")
        parameters.append(Parameter(_text(entry, "name", at), float(value), _text(entry, "unit", at, ""),
                                    _text(entry, "description", at, ""), _text(entry, "source", at, "")))
    return parameters


def _declare(doc: _Doc, states: list, inputs: list, parameters: list, dynamics: dict) -> None:
    """Every name declared once; the symbols of states, parameters and [dynamics.definitions]."""
    seen: dict[str, str] = {}
    for kind, items in (("states", states), ("inputs", inputs), ("parameters", parameters)):
        for i, item in enumerate(items):
            if item.name in seen:
                raise ModelError(f"{doc.where(f'{kind}#{i}')}: '{item.name}' is declared twice "
                                 f"({_twice(seen[item.name][:-1], kind[:-1])})")
            seen[item.name] = kind
    doc.symbols.update({v.name: sp.Symbol(v.name) for v in states + parameters})
    for key, expr_text in _table(dynamics, "definitions", doc.source, required=False).items():
        if not _NAME.fullmatch(key) or key in doc.symbols:
            raise ModelError(f"{doc.where('dynamics.definitions.' + key)}: '{key}' is not a new name")
        doc.symbols[key] = parse_expression(_text({key: expr_text}, key, doc.where("dynamics.definitions")),
                                            doc.symbols, doc.where(f"dynamics.definitions.{key}"))


def _dynamics(doc: _Doc, dynamics: dict, state_names: list[str], input_names: list[str]) -> tuple:
    """f (one expression per state) and g (a column per input, entries not given 0)."""
    f_table = _table(dynamics, "f", doc.source)
    for key in f_table:
        if key not in state_names:
            raise ModelError(f"{doc.where('dynamics.f.' + key)}: '{key}' is not a declared state")
    missing = [s for s in state_names if s not in f_table]
    if missing:
        raise ModelError(f"{doc.where('dynamics.f')}: missing field for state(s) {', '.join(missing)}")
    f = sp.Matrix([doc.parse(f"dynamics.f.{s}", f_table[s]) for s in state_names])
    if "g" not in dynamics:
        raise ModelError(f"{doc.where('dynamics')}: missing [dynamics.g.<input>] tables (how each input enters f)")
    g_table = _table(dynamics, "g", doc.source)
    for key in g_table:
        if key not in input_names:
            raise ModelError(f"{doc.where('dynamics.g.' + key)}: '{key}' is not a declared input")
    g = sp.zeros(len(state_names), len(input_names))
    for j, u in enumerate(input_names):
        column = g_table.get(u, {})
        if not isinstance(column, dict):
            raise ModelError(f"{doc.where('dynamics.g.' + u)}: must be a table of state = expression")
        for s, expr_text in column.items():
            if s not in state_names:
                raise ModelError(f"{doc.where(f'dynamics.g.{u}.{s}')}: '{s}' is not a declared state")
            g[state_names.index(s), j] = doc.parse(f"dynamics.g.{u}.{s}", expr_text)
    return f, g


def _outputs(doc: _Doc) -> list[Output]:
    outputs = []
    for i, entry in enumerate(_items(doc.data, "outputs", doc.where)):
        at = f"{doc.where('outputs')} #{i + 1}"
        out_name = _text(entry, "name", at)
        angle = entry.get("angle", False)
        if not isinstance(angle, bool):
            raise ModelError(f"{at}: field 'angle' must be true or false")
        outputs.append(Output(out_name, doc.parse("outputs", _text(entry, "expr", at, out_name)), angle))
    return outputs


def _measurement(doc: _Doc, outputs: list[Output], parameters: list[Parameter]) -> Measurement | None:
    """[measurement]: what a camera observes, its noise, how a node recovers the flat outputs."""
    where = doc.where
    meas = _table(doc.data, "measurement", doc.source, required=False)
    if not meas:
        return None
    if "observe" not in meas and "recover" not in meas:
        # Only [measurement.noise]: the cameras measure the flat outputs themselves.
        observe = {o.name: o.expr for o in outputs}
        recover = {o.name: sp.Symbol(o.name) for o in outputs}
        noise = _table(meas, "noise", where("measurement"))
        if sorted(noise) != sorted(observe) or not _positive(noise.values()):
            raise ModelError(f"{where('measurement.noise')}: without [measurement.observe], needs one positive "
                             f"std dev per flat output ({', '.join(observe)})")
        return Measurement(observe, {k: float(v) for k, v in noise.items()}, recover)
    observe = {k: doc.parse(f"measurement.observe.{k}", v) for k, v in _table(meas, "observe", where("measurement")).items()}
    seen = {k: sp.Symbol(k) for k in observe}
    recover_table = _table(meas, "recover", where("measurement"))
    if sorted(recover_table) != sorted(o.name for o in outputs):
        raise ModelError(f"{where('measurement.recover')}: needs exactly one entry per flat output")
    recover = {k: doc.parse(f"measurement.recover.{k}", v, {**seen, **{p.name: sp.Symbol(p.name) for p in parameters}})
               for k, v in recover_table.items()}
    noise = _table(meas, "noise", where("measurement"))
    if sorted(noise) != sorted(observe) or not _positive(noise.values()):
        raise ModelError(f"{where('measurement.noise')}: needs one positive std dev per observed channel")
    return Measurement(observe, {k: float(v) for k, v in noise.items()}, recover)


def _inverse(doc: _Doc, states: list[Variable], inputs: list[Variable]) -> dict[str, str]:
    """[inverse]: a user's closed forms of Phi^-1 entries, where sympy's solver does not finish (a
    3-D quadrotor's attitude and thrust from its accelerations). A key names a state, an input (a
    dynamic extension may make it a state) or an input's derivative (T_d1); the text is parsed and
    checked once the canonical names are known (symbolic/given_inverse.py)."""
    table = _table(doc.data, "inverse", doc.source, required=False)
    stems = {u.name for u in inputs}
    for key, text in table.items():
        key_at = doc.where(f"inverse.{key}")
        if key not in {s.name for s in states} and re.sub(r"_d\d+$", "", key) not in stems:
            raise ModelError(f"{key_at}: '{key}' is not a state of the model (nor an input or an input's "
                             "derivative a dynamic extension makes a state)")
        if not isinstance(text, str):
            raise ModelError(f"{key_at}: must be a string (an expression of the canonical names and parameters)")
    return dict(table)


def loads_toml(text: str, source: str = "<string>") -> Model:
    """A model from TOML text: every problem a ModelError naming the file, line and field."""
    doc = _Doc(text, source)
    _check_keys(doc.data, doc.where)
    head = _table(doc.data, "model", source)
    name = _text(head, "name", doc.where("model"))
    if not _NAME.fullmatch(name):
        raise ModelError(f"{doc.where('model.name')}: {name!r} must be a C identifier (letters, digits, _)")
    ts = head.get("ts", 0.01)
    if not _finite(ts) or not 1e-9 <= ts <= 1e3:
        raise ModelError(f"{doc.where('model.ts')}: must be a sampling period in seconds in [1e-9, 1e3], got {ts!r}")
    steps = head.get("mean_substeps", 1)
    if type(steps) is not int or not 1 <= steps <= MAX_MEAN_SUBSTEPS:
        raise ModelError(f"{doc.where('model.mean_substeps')}: must be a whole number of ETD2RK steps per period "
                         f"in [1, {MAX_MEAN_SUBSTEPS}], got {steps!r}")
    states, inputs = _variables(doc, "states"), _variables(doc, "inputs")
    parameters = _parameters(doc)
    dynamics = _table(doc.data, "dynamics", source)
    doc.misplaced = {u.name: f"the input {u.name!r} appears here, but an input enters only through "
                             f"[dynamics.g.{u.name}] (f, the outputs and the observations are functions of the state)"
                     for u in inputs}
    _declare(doc, states, inputs, parameters, dynamics)
    f, g = _dynamics(doc, dynamics, [s.name for s in states], [u.name for u in inputs])
    outputs = _outputs(doc)
    return Model(name=name, states=states, inputs=inputs, parameters=parameters, f=f, g=g, outputs=outputs,
                 ts=float(ts), mean_substeps=steps, description=str(head.get("description", "")),
                 measurement=_measurement(doc, outputs, parameters), source=source, _lines=doc.lines,
                 inverse=_inverse(doc, states, inputs))


# --- built-ins -------------------------------------------------------------------------------

def builtin_names() -> list[str]:
    folder = resources.files("dfeif_codegen") / "models"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def builtin_text(name: str) -> str:
    """A built-in model's TOML text, as packaged."""
    return (resources.files("dfeif_codegen") / "models" / f"{name}.toml").read_text(encoding="utf-8")


def load(spec: str) -> Model:
    """A built-in model by name, or a path to a `.toml` model file."""
    if not isinstance(spec, (str, PurePath)):
        raise ModelError(f"{type(spec).__name__}: a model is a built-in name or the path of a .toml file")
    if spec in builtin_names():
        return loads_toml(builtin_text(spec), f"{spec}.toml")
    path = Path(spec)
    if path.suffix == ".toml" or path.exists():
        return load_toml(path)
    raise ModelError(f"{spec}: not a built-in model ({', '.join(builtin_names())}) nor a .toml file")


def from_sympy(name: str, states: Sequence[Variable | str], inputs: Sequence[Variable | str],
               parameters: Sequence[Parameter], f, g, outputs: Sequence[Output], **kwargs) -> Model:
    """Python API: expressions use `sympy.Symbol(name)` for states and parameters."""
    as_var = [s if isinstance(s, Variable) else Variable(str(s)) for s in states]
    as_in = [s if isinstance(s, Variable) else Variable(str(s)) for s in inputs]
    return Model(name=name, states=as_var, inputs=as_in, parameters=list(parameters), f=sp.Matrix(f),
                 g=sp.Matrix(g), outputs=list(outputs), **kwargs)
