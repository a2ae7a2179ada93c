"""The parts of a model (`Model`: a plant `x' = f(x) + g(x) u` with flat outputs, its states,
inputs, parameters, outputs and camera measurement) and the checks every model passes however it
was written (sympy or TOML, symbolic/model.py): names that reach C, expressions whose derivatives
can be formed, domains, shapes.
"""

from __future__ import annotations

import keyword
import re
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import sympy as sp

from dfeif_codegen.errors import ModelError

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
# Names that reach C (the model name is the prefix of every file, function and macro; the others
# end up in macros and comments): no C keyword, no standard header's stem (a model `math` would
# write `math.h` and shadow the system's), nothing in CasADi's or the generated code's namespace.
C_KEYWORDS = frozenset("""auto break case char const continue default do double else enum extern float for
goto if inline int long register restrict return short signed sizeof static struct switch typedef union
unsigned void volatile while _Bool _Complex _Imaginary bool true false NULL main real""".split())
C_HEADERS = frozenset("""assert complex ctype errno fenv float inttypes iso646 limits locale math setjmp
signal stdalign stdarg stdatomic stdbool stddef stdint stdio stdlib stdnoreturn string tgmath threads
time uchar wchar wctype arm_math cmsis example_main manifest unistd fcntl pthread sched strings poll termios
dirent transport transport_udp common relay node_main master_main features newlib ieeefp endian alloca
malloc""".split())   # features ... malloc: the C library's own headers include them by these names
# Words w for which a model named <a>_w would declare a name a model <a> declares too: <a>_w_t
# where both w_t and t follow the prefix in generated names (ab_node_packet: ab's node_packet
# and ab_node's packet). tests/test_model_errors.py derives them from fresh builds.
CLASHING_WORDS = frozenset("""cov err has include internal kern kernels kind lib master nmax node
nring nu""".split())
NAME_LIMIT = 31  # C99 guarantees 31 significant characters in external identifiers
# The model name prefixes every identifier: up to this length the generated C keeps within 100
# columns laid out as clang-format would (tests/test_format.py builds models of this length).
MODEL_NAME_LIMIT = 17
MAX_MEAN_SUBSTEPS = 64   # the mean's code grows with each: past this a finer ts is the remedy

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
    return (bool(_NAME.fullmatch(name)) and name not in C_KEYWORDS and not name.lower().startswith("casadi")
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
    # ETD2RK steps per period in the held predictor's mean (symbolic/sampling.py): more where a
    # fast mode moves the remainder F + G u within a period (docs/mathematics.md section 3)
    mean_substeps: int = 1
    description: str = ""
    measurement: Measurement | None = None
    source: str = "<python>"
    _lines: Mapping[str, int] = field(default_factory=dict, repr=False)
    # [inverse]: entries of Phi^-1 the user gives (state name -> text over the canonical names and
    # parameters), kept as text: the canonical names exist only once the derivation has run
    inverse: Mapping[str, str] = field(default_factory=dict)
    # state index -> index of the input a dynamic extension made it of (symbolic/extension.py)
    made_of_input: Mapping[int, int] = field(default_factory=dict)

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

    def state_declared_at(self, i: int) -> str:
        """Where the user declared state i: its [[states]] entry or, for a state a dynamic
        extension made of an input, that input's [[inputs]] entry."""
        if i in self.made_of_input:
            return f"{self.where(f'inputs#{self.made_of_input[i]}')}, an input the extension made a state"
        return self.where(f"states#{i}")

    # --- validation ------------------------------------------------------------------------
    def _check(self) -> None:
        n, m = len(self.states), len(self.inputs)
        names: dict[str, str] = {}
        groups: tuple[tuple[str, Sequence[Variable | Parameter]], ...] = (
            ("state", self.states), ("input", self.inputs), ("parameter", self.parameters))
        for kind, items in groups:
            for i, item in enumerate(items):
                at = self.where(f"{kind}s#{i}")    # the item's own table, not the first one
                if not c_safe(item.name) or keyword.iskeyword(item.name):
                    raise ModelError(f"{at}: {item.name!r} is not a usable {kind} name "
                                     "(letters, digits, _; no C or Python keyword; at most 31 characters)")
                if item.name in names:
                    raise ModelError(f"{at}: '{item.name}' is declared twice ({_twice(names[item.name], kind)})")
                names[item.name] = kind
        for q in self.parameters:
            if not isinstance(q.value, (int, float)) or q.value != q.value or abs(q.value) == float("inf"):
                raise ModelError(f"{self.where('parameters.' + q.name)}: value must be a finite number")
        if not c_safe(self.name) or self.name.lower() in C_HEADERS or len(self.name) > MODEL_NAME_LIMIT:
            raise ModelError(f"{self.where('model.name')}: {self.name!r} cannot name a C module (a C identifier "
                             f"of at most {MODEL_NAME_LIMIT} characters, not a C keyword, a standard header or "
                             "casadi*)")
        segs = self.name.split("_")
        clash = [i for i in range(1, len(segs)) if segs[i].lower() in CLASHING_WORDS]
        if clash:
            first = "_".join(segs[:clash[0]])
            raise ModelError(f"{self.where('model.name')}: {self.name!r} cannot name a C module: "
                             f"'{segs[clash[0]]}' is a word of the generated names (a model {first!r} declares "
                             f"{first}_{segs[clash[0]].lower()}_*, and several models link into one firmware)")
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
            if not c_safe(o.name) or keyword.iskeyword(o.name):
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


def _twice(first: str, second: str) -> str:
    """Where a name was declared twice: 'as a state and as a parameter', or 'among the parameters'."""
    return f"among the {first}s" if first == second else f"as a {first} and as a {second}"


def _where(source: str, lines: Mapping[str, int], key: str) -> str:
    """`file:line: key`; entry i of an array of tables is looked up as `states#i` and shown as `states[i+1]`."""
    line = lines.get(key) or lines.get(key.rsplit(".", 1)[0]) or lines.get(key.split("#")[0].split(".")[0])
    shown = re.sub(r"#(\d+)", lambda g: f"[{int(g.group(1)) + 1}]", key)
    return f"{source}:{line}: {shown}" if line else f"{source}: {shown}"
