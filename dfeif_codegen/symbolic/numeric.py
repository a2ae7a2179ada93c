"""The one bridge from sympy to numbers: sympy -> CasADi SX (`to_casadi`), and CasADi Functions
evaluated from Python (`Numeric`).

The generated C (CasADi prints the kernels), the plant's integrator, the cameras and the flat
system's numeric functions (`FlatSystem.F_num` ...) all go through this one conversion, so
they evaluate the same expression graph: an operation the converter does not know is refused in
one place, and the reference cannot differ from the C by a different reading of the model.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import sympy as sp

from dfeif_codegen.errors import ModelError

_UNARY = {
    sp.sin: ca.sin, sp.cos: ca.cos, sp.tan: ca.tan, sp.asin: ca.asin, sp.acos: ca.acos,
    sp.atan: ca.atan, sp.sinh: ca.sinh, sp.cosh: ca.cosh, sp.tanh: ca.tanh, sp.exp: ca.exp,
    sp.log: ca.log, sp.Abs: ca.fabs, sp.sign: ca.sign,
}


class _CasADi:
    """The operations to_casadi builds with: CasADi SX (what the C is printed from)."""

    unary = _UNARY
    atan2, power, sqrt, hypot, fmin, fmax = ca.atan2, ca.power, ca.sqrt, ca.hypot, ca.fmin, ca.fmax
    relations = {sp.Eq: ca.eq, sp.Ne: ca.ne, sp.Lt: ca.lt, sp.Le: ca.le, sp.Gt: ca.gt, sp.Ge: ca.ge}
    logic_and, logic_or, logic_not, if_else = ca.logic_and, ca.logic_or, ca.logic_not, ca.if_else

    @staticmethod
    def const(value: float):
        return ca.SX(value)


class Float32:
    """The same operations on numpy float32 arrays: the expression as a float32 target computes
    it (every operation rounded to single precision), to check a form's accuracy there."""

    unary = {sp.sin: np.sin, sp.cos: np.cos, sp.tan: np.tan, sp.asin: np.arcsin, sp.acos: np.arccos,
             sp.atan: np.arctan, sp.sinh: np.sinh, sp.cosh: np.cosh, sp.tanh: np.tanh, sp.exp: np.exp,
             sp.log: np.log, sp.Abs: np.abs, sp.sign: np.sign}
    atan2, power, sqrt, hypot, fmin, fmax = np.arctan2, np.power, np.sqrt, np.hypot, np.fmin, np.fmax
    relations = {sp.Eq: np.equal, sp.Ne: np.not_equal, sp.Lt: np.less, sp.Le: np.less_equal,
                 sp.Gt: np.greater, sp.Ge: np.greater_equal}
    logic_and, logic_or, logic_not, if_else = np.logical_and, np.logical_or, np.logical_not, np.where

    @staticmethod
    def const(value: float):
        return np.float32(value)


def _int_power(base, k: int):
    """x**k by squaring: CasADi would print pow(), which is slow and double-only on newlib."""
    result, square = None, base
    while k:
        if k & 1:
            result = square if result is None else result * square
        k >>= 1
        if k:
            square = square * square
    return result


def _hypot_args(e: sp.Pow):
    """(a, b) when e is sqrt(a**2 + b**2) (or its reciprocal): printed as hypot, which neither overflows nor
    underflows in float32 where the squares would."""
    base = e.base
    if abs(e.exp) == sp.Rational(1, 2) and base.is_Add and len(base.args) == 2 \
            and all(t.is_Pow and t.exp == 2 for t in base.args):
        return base.args[0].base, base.args[1].base
    return None


def _piecewise(e: sp.Piecewise, walk, ops, where: str):
    """The first piece whose condition holds (sympy's reading; solve writes sign(x) in Phi^-1 as
    one), `walk` converting the pieces. A point no condition covers is NaN, as sympy leaves it."""
    def condition(c: sp.Basic):
        if c in (sp.true, sp.false):
            return ops.const(1.0 if c == sp.true else 0.0)
        if type(c) in ops.relations:
            return ops.relations[type(c)](walk(c.lhs), walk(c.rhs))
        if isinstance(c, sp.Not):
            return ops.logic_not(condition(c.args[0]))
        if not isinstance(c, (sp.And, sp.Or)):
            raise ModelError(f"{where}: cannot convert the condition {c}")
        both = ops.logic_and if isinstance(c, sp.And) else ops.logic_or
        parts = [condition(a) for a in c.args]
        out = parts[0]
        for p in parts[1:]:
            out = both(out, p)
        return out

    out = ops.const(math.nan)
    for value, cond in reversed(e.args):
        out = ops.if_else(condition(cond), walk(value), out)
    return out


def to_casadi(expr: sp.Expr, table: dict, where: str = "expression", ops=_CasADi, trig=None):
    """Convert a sympy expression to a CasADi SX scalar by walking its tree (never by printing
    and evaluating); shared subtrees stay shared. `where` names the expression in errors. With
    `ops=Float32` and float32 arrays in `table`, the same walk computes it in single precision.
    `trig(func, arg, value)`, if given, computes sin and cos (func: sp.sin or sp.cos) of the
    sympy argument `arg`, whose converted value is `value` (sampling.TrigCarry's use)."""
    memo: dict = {}

    def walk(e: sp.Basic) -> ca.SX:
        if e in memo:
            return memo[e]
        if e.is_Symbol:
            if e not in table:
                raise ModelError(f"{where}: unexpected symbol '{e}'")
            out = table[e]
        elif e.is_Number or e.is_NumberSymbol:
            value = float(e)
            if not math.isfinite(value):
                raise ModelError(f"{where}: non-finite constant {e}")
            out = ops.const(value)
        elif e.is_Add:
            terms = [walk(a) for a in e.args]
            out = terms[0]
            for t in terms[1:]:
                out = out + t
        elif e.is_Mul:
            factors = [walk(a) for a in e.args]
            out = factors[0]
            for f in factors[1:]:
                out = out * f
        elif e.is_Pow:
            base, exp = e.args
            b = walk(base)
            if exp.is_Integer and abs(int(exp)) <= 16:
                k = int(exp)
                out = ops.const(1.0) if k == 0 else _int_power(b, abs(k))
                if k < 0:
                    out = 1 / out
            elif _hypot_args(e):
                out = ops.hypot(*(walk(a) for a in _hypot_args(e)))
                out = out if exp > 0 else 1 / out
            elif exp == sp.Rational(1, 2):
                out = ops.sqrt(b)
            elif exp == sp.Rational(-1, 2):
                out = 1 / ops.sqrt(b)
            else:
                out = ops.power(b, walk(exp))
        elif trig is not None and e.func in (sp.sin, sp.cos):
            out = trig(e.func, e.args[0], walk(e.args[0]))
        elif e.func in ops.unary:
            out = ops.unary[e.func](walk(e.args[0]))
        elif e.func == sp.atan2:
            out = ops.atan2(walk(e.args[0]), walk(e.args[1]))
        elif e.func in (sp.Min, sp.Max):
            op = ops.fmin if e.func == sp.Min else ops.fmax
            args = [walk(a) for a in e.args]
            out = args[0]
            for a in args[1:]:
                out = op(out, a)
        elif isinstance(e, sp.Piecewise):
            out = _piecewise(e, walk, ops, where)
        elif isinstance(e, sp.DiracDelta) or (isinstance(e, sp.Derivative) and isinstance(e.expr, sp.sign)):
            out = ops.const(0.0)   # sign's derivative where it has one (a linearization's L0, a Jacobian)
        else:
            raise ModelError(f"{where}: cannot convert '{e.func.__name__}' in {e}")
        memo[e] = out
        return out

    return walk(sp.sympify(expr))


def sx_function(name: str, inputs: list[list[sp.Symbol]], exprs) -> ca.Function:
    """A CasADi Function of one vector argument per symbol list, returning `exprs` (a list or a
    sympy Matrix) as one dense matrix (a column for a list)."""
    args = [ca.SX.sym(f"in{i}", len(syms)) for i, syms in enumerate(inputs)]
    table = {s: a[k] for syms, a in zip(inputs, args) for k, s in enumerate(syms)}
    rows = sp.Matrix(exprs) if not isinstance(exprs, sp.MatrixBase) else exprs
    out = ca.SX(rows.rows, rows.cols)
    for i in range(rows.rows):
        for j in range(rows.cols):
            out[i, j] = to_casadi(rows[i, j], table, f"{name}[{i},{j}]")
    return ca.Function(name, args, [ca.densify(out)], {"cse": True})


class Numeric:
    """A CasADi Function of vector arguments with one output, called from Python through its
    buffer: the arguments are copied into fixed arrays and the result read from one, instead of
    converting to and from CasADi matrices on every call (~40 us -> ~2 us, which matters for the
    plant and the controller called every step of hundreds of runs). Not reentrant: one call at
    a time per instance. Returns a 1-D array for a column output, else the (rows, cols) matrix."""

    def __init__(self, function: ca.Function):
        self.function = function
        self._in = [np.zeros(function.nnz_in(i)) for i in range(function.n_in())]
        shape = function.size_out(0)
        self._out = np.zeros(function.nnz_out(0))
        self._shape = (shape[0],) if shape[1] == 1 else shape
        self._buffer, self._trigger = function.buffer()
        for i, a in enumerate(self._in):
            self._buffer.set_arg(i, memoryview(a))
        self._buffer.set_res(0, memoryview(self._out))

    @classmethod
    def of(cls, name: str, inputs: list[list[sp.Symbol]], exprs) -> "Numeric":
        return cls(sx_function(name, inputs, exprs))

    def __call__(self, *args) -> np.ndarray:
        if len(args) != len(self._in):
            raise TypeError(f"{self.function.name()} takes {len(self._in)} arguments, got {len(args)}")
        for buf, a in zip(self._in, args):
            buf[:] = np.ravel(np.asarray(a, dtype=float))
        self._trigger()
        return self._out.reshape(self._shape, order="F").copy()   # CasADi stores column-major

    def __reduce__(self):   # the buffer points into this process: pickle the Function only
        return (Numeric, (self.function,))


def _unary_ops() -> dict:
    f = np.float32
    table = {"ASSIGN": lambda x: x, "NEG": np.negative, "EXP": np.exp, "LOG": np.log, "SQRT": np.sqrt,
             "SQ": lambda x: x * x, "TWICE": lambda x: x + x, "INV": lambda x: f(1) / x, "SIN": np.sin,
             "COS": np.cos, "TAN": np.tan, "ASIN": np.arcsin, "ACOS": np.arccos, "ATAN": np.arctan,
             "SINH": np.sinh, "COSH": np.cosh, "TANH": np.tanh, "ASINH": np.arcsinh, "ACOSH": np.arccosh,
             "ATANH": np.arctanh, "FABS": np.abs, "SIGN": np.sign, "FLOOR": np.floor, "CEIL": np.ceil,
             "NOT": lambda x: f(x == 0), "LOG1P": np.log1p, "EXPM1": np.expm1}
    return {getattr(ca, "OP_" + k): v for k, v in table.items() if hasattr(ca, "OP_" + k)}


def _binary_ops() -> dict:
    f = np.float32
    table = {"ADD": np.add, "SUB": np.subtract, "MUL": np.multiply, "DIV": np.divide, "POW": np.power,
             "CONSTPOW": np.power, "ATAN2": np.arctan2, "FMIN": np.fmin, "FMAX": np.fmax, "HYPOT": np.hypot,
             "COPYSIGN": np.copysign, "FMOD": np.fmod, "LT": lambda a, b: f(a < b), "LE": lambda a, b: f(a <= b),
             "EQ": lambda a, b: f(a == b), "NE": lambda a, b: f(a != b),
             "AND": lambda a, b: f(a != 0 and b != 0), "OR": lambda a, b: f(a != 0 or b != 0),
             "IF_ELSE_ZERO": lambda c, x: x if c != 0 else f(0)}
    return {getattr(ca, "OP_" + k): v for k, v in table.items() if hasattr(ca, "OP_" + k)}


class SinglePrecision:
    """A CasADi SX Function run instruction by instruction in float32, every operation rounded
    to single precision as the float build's C computes it (the C is printed from the same
    instructions). Why: a Function computes in double, so a float32 reference that called one
    would round only its result and miss what the kernel loses inside: on a stiff flexible joint,
    whose canonical top derivative cancels five digits, the float32 run's node estimates leave the
    double ones by 1.1e-2 through this class and by 4.6e-4 with the mean rounded once.
    Same calling convention as `Numeric`; slow (a Python loop), for checks only."""

    UNARY, BINARY = _unary_ops(), _binary_ops()

    def __init__(self, function: ca.Function):
        self.function = function
        self._program = [(function.instruction_id(k), function.instruction_input(k), function.instruction_output(k),
                          np.float32(function.instruction_constant(k))) for k in range(function.n_instructions())]
        known = set(self.UNARY) | set(self.BINARY) | {ca.OP_CONST, ca.OP_INPUT, ca.OP_OUTPUT}
        unknown = sorted({op for op, *_ in self._program} - known)
        if unknown:
            raise ModelError(f"{function.name()}: CasADi operation(s) {unknown} have no single-precision twin")
        size = max([max(o) for op, _, o, _ in self._program if op != ca.OP_OUTPUT and o] + [0]) + 1
        self._work = np.zeros(size, dtype=np.float32)
        shape = function.size_out(0)
        self._shape = (shape[0],) if shape[1] == 1 else shape

    def __call__(self, *args) -> np.ndarray:
        ins = [np.ravel(np.asarray(a, dtype=np.float32)) for a in args]
        out, w = np.zeros(self.function.nnz_out(0), dtype=np.float32), self._work
        unary, binary, const, load, store = self.UNARY, self.BINARY, ca.OP_CONST, ca.OP_INPUT, ca.OP_OUTPUT
        for op, i, o, c in self._program:
            if op == const:
                w[o[0]] = c
            elif op == load:
                w[o[0]] = ins[i[0]][i[1]]
            elif op == store:
                if o[0] == 0:
                    out[o[1]] = w[i[0]]
            elif op in unary:
                w[o[0]] = unary[op](w[i[0]])
            else:
                w[o[0]] = binary[op](w[i[0]], w[i[1]])
        return out.reshape(self._shape, order="F").copy()
