"""A plant `x' = f(x) + g(x) u` with flat outputs, built from sympy (Python API) or a TOML file.

Both ways in end in the same `Model`; everything downstream (flatness, kernels, the reference
filters) reads only this class.
"""

from __future__ import annotations

import keyword
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Mapping, Sequence

import sympy as sp

from dfeif_codegen.errors import ModelError
from dfeif_codegen.paths import parse_toml, read_text
from dfeif_codegen.symbolic.expr_parser import parse_expression

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_RESERVED = {"pi", "e", "E", "I_", "t"}
# Names that reach C (the model name is the prefix of every file, function and macro; the others
# end up in macros and comments): no C keyword, no standard header's stem (a model `math` would
# write `math.h` and shadow the system's), nothing in CasADi's or the generated code's namespace.
C_KEYWORDS = frozenset("""auto break case char const continue default do double else enum extern float for
goto if inline int long register restrict return short signed sizeof static struct switch typedef union
unsigned void volatile while _Bool _Complex _Imaginary bool true false NULL main real""".split())
C_HEADERS = frozenset("""assert complex ctype errno fenv float inttypes iso646 limits locale math setjmp
signal stdalign stdarg stdatomic stdbool stddef stdint stdio stdlib stdnoreturn string tgmath threads
time uchar wchar wctype arm_math cmsis example_main manifest""".split())
NAME_LIMIT = 31  # C99 guarantees 31 significant characters in external identifiers
# The model name prefixes every identifier: up to this length the generated C keeps within 100
# columns laid out as clang-format would (tests/test_format.py builds models of this length).
MODEL_NAME_LIMIT = 17
# Keys a model file may use, per section (a typo must not silently switch a feature off).
SCHEMA = {
    "": {"model", "states", "inputs", "parameters", "dynamics", "outputs", "measurement"},
    "model": {"name", "description", "ts"},
    "states": {"name", "unit", "description", "min", "max", "nominal"},
    "inputs": {"name", "unit", "description", "min", "max", "nominal"},
    "parameters": {"name", "value", "unit", "description", "source"},
    "dynamics": {"f", "g", "definitions"},
    "outputs": {"name", "expr", "angle"},
    "measurement": {"observe", "noise", "recover"},
}


MAX_POWER = 1024       # |integer exponent| after sympy folds (x**64)**64: real models stay far below
MAX_CALL_NESTING = 16  # functions inside functions: every level multiplies the chain rule's terms


def growth_problem(expr: sp.Expr) -> str | None:
    """Why differentiating this expression n times would blow up before any budget could help
    (a 63-character `((theta+1)**64)**64...` is x**(2**60)), or None."""
    stack = [(sp.sympify(expr), 0, False)]
    while stack:
        node, calls, in_var_exponent = stack.pop()
        if isinstance(node, sp.Pow):
            base, exp = node.args
            if exp.is_number and exp.is_real and abs(float(exp)) > MAX_POWER and base.free_symbols:
                return f"power ({base})**{exp} beyond +-{MAX_POWER}: its derivatives cannot be formed"
            if not exp.is_number and base.free_symbols:
                if in_var_exponent:
                    return "a variable power inside a variable exponent (exponent tower): its derivatives cannot be formed"
                stack.append((base, calls, in_var_exponent))
                stack.append((exp, calls, True))
                continue
        if not node.free_symbols and isinstance(node, (sp.Function, sp.Pow)):
            value = complex(node.evalf(30)) if node.is_number else None
            if value is not None and (value.imag != 0 or value.real != value.real or abs(value.real) == float("inf")):
                return f"the constant {node} is not a finite real number"
        if isinstance(node, sp.Function):
            calls += 1
            if calls > MAX_CALL_NESTING:
                return f"functions nested more than {MAX_CALL_NESTING} deep: its derivatives cannot be formed"
        stack.extend((a, calls, in_var_exponent) for a in node.args)
    return None


def c_safe(name: str) -> bool:
    """A name that may become part of C identifiers without colliding with anything."""
    return (bool(_NAME.match(name)) and name not in C_KEYWORDS and not name.lower().startswith("casadi")
            and len(name) <= NAME_LIMIT)


def _finite(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and value == value \
        and abs(value) != float("inf")


@dataclass(frozen=True)
class Variable:
    """A state or an input: name, unit, one-line description. `min`/`max` are the physical
    domain of a state (the branch of Phi^-1 is chosen on it, a run leaving it has diverged) or an
    input's actuator limits (the controller saturates there); `nominal` is a representative state."""

    name: str
    unit: str = ""
    description: str = ""
    min: float | None = None
    max: float | None = None
    nominal: float | None = None

    @property
    def bounded(self) -> bool:
        return self.min is not None or self.max is not None


@dataclass(frozen=True)
class Parameter:
    """A physical constant with its default value; `source` says where the value comes from."""

    name: str
    value: float
    unit: str = ""
    description: str = ""
    source: str = ""


@dataclass(frozen=True)
class Output:
    """A flat output `y = h(x)`; `angle` outputs have innovations wrapped to (-pi, pi]."""

    name: str
    expr: sp.Expr
    angle: bool = False


@dataclass(frozen=True)
class Measurement:
    """What a camera sees (`observe`, functions of the states, with noise std per channel) and
    how a node recovers the flat outputs from it (`recover`, functions of the observed names)."""

    observe: dict[str, sp.Expr]
    noise: dict[str, float]
    recover: dict[str, sp.Expr]


@dataclass
class Model:
    name: str
    states: list[Variable]
    inputs: list[Variable]
    parameters: list[Parameter]
    f: sp.Matrix
    g: sp.Matrix
    outputs: list[Output]
    ts: float = 0.01
    description: str = ""
    measurement: Measurement | None = None
    source: str = "<python>"
    _lines: Mapping[str, int] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self.f = sp.Matrix(self.f)
        self.g = sp.Matrix(self.g)
        if self.g.shape == (len(self.states), 0) or not self.inputs:
            raise ModelError(f"{self.source}: the model needs at least one input")
        self._check()

    # --- symbols ---------------------------------------------------------------------------
    @property
    def x(self) -> sp.Matrix:
        return sp.Matrix([sp.Symbol(s.name) for s in self.states])

    @property
    def u(self) -> sp.Matrix:
        return sp.Matrix([sp.Symbol(s.name) for s in self.inputs])

    @property
    def p(self) -> list[sp.Symbol]:
        return [sp.Symbol(q.name) for q in self.parameters]

    @property
    def h(self) -> sp.Matrix:
        return sp.Matrix([o.expr for o in self.outputs])

    @property
    def param_values(self) -> dict[sp.Symbol, float]:
        return {sp.Symbol(q.name): float(q.value) for q in self.parameters}

    @property
    def n(self) -> int:
        return len(self.states)

    @property
    def m(self) -> int:
        return len(self.inputs)

    def where(self, key: str) -> str:
        """`file:line: key` for messages, with the line when the TOML loader recorded it."""
        return _where(self.source, self._lines, key)

    # --- validation ------------------------------------------------------------------------
    def _check(self) -> None:
        n, m = len(self.states), len(self.inputs)
        names: dict[str, str] = {}
        for kind, items in (("state", self.states), ("input", self.inputs), ("parameter", self.parameters)):
            for item in items:
                if not c_safe(item.name) or keyword.iskeyword(item.name) or item.name in _RESERVED:
                    raise ModelError(f"{self.where(kind + 's')}: {item.name!r} is not a usable {kind} name "
                                     "(letters, digits, _; no C or Python keyword; at most 31 characters)")
                if item.name in names:
                    raise ModelError(
                        f"{self.where(kind + 's')}: '{item.name}' is declared twice ({names[item.name]} and {kind})")
                names[item.name] = kind
        for q in self.parameters:
            if not isinstance(q.value, (int, float)) or q.value != q.value or abs(q.value) == float("inf"):
                raise ModelError(f"{self.where('parameters.' + q.name)}: value must be a finite number")
        if not c_safe(self.name) or self.name.lower() in C_HEADERS or len(self.name) > MODEL_NAME_LIMIT:
            raise ModelError(f"{self.where('model.name')}: {self.name!r} cannot name a C module (a C identifier "
                             f"of at most {MODEL_NAME_LIMIT} characters, not a C keyword, a standard header or "
                             "casadi*)")
        if self.name.endswith("_") or "__" in self.name:
            raise ModelError(f"{self.where('model.name')}: {self.name!r} cannot name a C module: it must not end "
                             "with '_' or contain '__' (CasADi refuses its kernels' names, <name>_kern_*)")
        for kind, items in (("states", self.states), ("inputs", self.inputs)):
            for i, item in enumerate(items):
                at = self.where(f"{kind}#{i}")
                for key in ("min", "max", "nominal"):
                    value = getattr(item, key)
                    if value is not None and not _finite(value):
                        raise ModelError(f"{at}: {item.name}: {key} must be a finite number")
                lo = -float("inf") if item.min is None else item.min
                hi = float("inf") if item.max is None else item.max
                if lo >= hi:
                    raise ModelError(f"{at}: {item.name}: min {lo:g} must be below max {hi:g}")
                if item.nominal is not None and not lo <= item.nominal <= hi:
                    raise ModelError(f"{at}: {item.name}: nominal {item.nominal:g} is outside [{lo:g}, {hi:g}]")
        for o in self.outputs:
            if not c_safe(o.name) or o.name in _RESERVED or keyword.iskeyword(o.name):
                raise ModelError(f"{self.where('outputs')}: {o.name!r} is not a usable flat output name "
                                 "(letters, digits, _; no C or Python keyword; at most 31 characters)")
        if self.f.shape != (n, 1):
            raise ModelError(f"{self.where('dynamics.f')}: f needs one entry per state ({n}), got {self.f.shape[0]}")
        if self.g.shape != (n, m):
            raise ModelError(f"{self.where('dynamics.g')}: g must be {n}x{m} (states x inputs), got {self.g.shape}")
        if len(self.outputs) != m:
            raise ModelError(
                f"{self.where('outputs')}: a flat system needs as many flat outputs as inputs ({m}), got {len(self.outputs)}")
        if not (_finite(self.ts) and 1e-9 <= self.ts <= 1e3):
            raise ModelError(f"{self.where('model.ts')}: the sampling period must be a number of seconds in "
                             f"[1e-9, 1e3], got {self.ts!r}")
        allowed = {sp.Symbol(s) for s, kind in names.items() if kind != "input"}
        for key, expr in [(f"dynamics.f.{s.name}", e) for s, e in zip(self.states, self.f)] + \
                         [(f"dynamics.g.{u.name}.{s.name}", self.g[i, j]) for j, u in enumerate(self.inputs)
                          for i, s in enumerate(self.states)] + \
                         [(f"outputs.{o.name}", o.expr) for o in self.outputs]:
            problem = growth_problem(expr)
            if problem:
                raise ModelError(f"{self.where(key)}: {problem}")
            extra = sp.sympify(expr).free_symbols - allowed
            if extra:
                bad = ", ".join(sorted(str(s) for s in extra))
                raise ModelError(f"{self.where(key)}: undeclared name(s) or input in a state function: {bad}")
        outs = [o.name for o in self.outputs]
        if len(set(outs)) != len(outs):
            raise ModelError(f"{self.where('outputs')}: flat output names must be unique")


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


def _where(source: str, lines: Mapping[str, int], key: str) -> str:
    """`file:line: key`; entry i of an array of tables is looked up as `states#i` and shown as `states[i+1]`."""
    line = lines.get(key) or lines.get(key.rsplit(".", 1)[0]) or lines.get(key.split("#")[0].split(".")[0])
    shown = re.sub(r"#(\d+)", lambda g: f"[{int(g.group(1)) + 1}]", key)
    return f"{source}:{line}: {shown}" if line else f"{source}: {shown}"


def _check_keys(data: Mapping, where) -> None:
    """Unknown sections and keys are errors naming the key and its line (see SCHEMA)."""
    def unknown(key: str, allowed) -> None:
        raise ModelError(f"{where(key)}: unknown key (expected one of {', '.join(sorted(allowed))})")

    for section, value in data.items():
        if section not in SCHEMA[""]:
            unknown(section, SCHEMA[""])
        entries = value if isinstance(value, list) else [value]
        for i, entry in enumerate(entries):
            if not isinstance(entry, dict):
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

    def where(self, key: str) -> str:
        return _where(self.source, self.lines, key)

    def parse(self, key: str, expr_text, names: dict | None = None) -> sp.Expr:
        if not isinstance(expr_text, (str, int, float)) or isinstance(expr_text, bool):
            raise ModelError(f"{self.where(key)}: expression must be a string")
        return parse_expression(str(expr_text), self.symbols if names is None else names, self.where(key))


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
        for item in items:
            if item.name in seen:
                raise ModelError(f"{doc.where(kind)}: '{item.name}' is declared twice ({seen[item.name]} and {kind})")
            seen[item.name] = kind
    doc.symbols.update({v.name: sp.Symbol(v.name) for v in states + parameters})
    for key, expr_text in _table(dynamics, "definitions", doc.source, required=False).items():
        if not _NAME.match(key) or key in doc.symbols:
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


def loads_toml(text: str, source: str = "<string>") -> Model:
    """A model from TOML text: every problem a ModelError naming the file, line and field."""
    doc = _Doc(text, source)
    _check_keys(doc.data, doc.where)
    head = _table(doc.data, "model", source)
    name = _text(head, "name", doc.where("model"))
    if not _NAME.match(name):
        raise ModelError(f"{doc.where('model.name')}: '{name}' must be a C identifier (letters, digits, _)")
    ts = head.get("ts", 0.01)
    if not _finite(ts) or not 1e-9 <= ts <= 1e3:
        raise ModelError(f"{doc.where('model.ts')}: must be a sampling period in seconds in [1e-9, 1e3], got {ts!r}")
    states, inputs = _variables(doc, "states"), _variables(doc, "inputs")
    parameters = _parameters(doc)
    dynamics = _table(doc.data, "dynamics", source)
    _declare(doc, states, inputs, parameters, dynamics)
    f, g = _dynamics(doc, dynamics, [s.name for s in states], [u.name for u in inputs])
    outputs = _outputs(doc)
    return Model(name=name, states=states, inputs=inputs, parameters=parameters, f=f, g=g, outputs=outputs,
                 ts=float(ts), description=str(head.get("description", "")),
                 measurement=_measurement(doc, outputs, parameters), source=source, _lines=doc.lines)


# --- built-ins -------------------------------------------------------------------------------

def builtin_names() -> list[str]:
    folder = resources.files("dfeif_codegen") / "models"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def load(spec: str) -> Model:
    """A built-in model by name, or a path to a `.toml` model file."""
    if spec in builtin_names():
        resource = resources.files("dfeif_codegen") / "models" / f"{spec}.toml"
        return loads_toml(resource.read_text(encoding="utf-8"), f"{spec}.toml")
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
