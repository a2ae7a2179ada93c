"""Restricted parser for model expressions written as strings (e.g. in TOML model files).

Why: model files are user input, and sympify/eval/parse_expr would run arbitrary Python. This
module tokenizes and parses a small arithmetic grammar itself and builds sympy objects directly,
with hard bounds so hostile input fails fast with a one-line ModelError.

Grammar (Python precedence; ``**`` is right-associative and binds tighter than unary minus)::

    expr  := term (('+' | '-') term)*
    term  := unary (('*' | '/') unary)*
    unary := ('+' | '-') unary | power
    power := atom ['**' unary]
    atom  := NUMBER | NAME | FUNC '(' [expr (',' expr)*] ')' | '(' expr ')'

Limits (all refusals are ModelError): text <= MAX_CHARS characters, <= MAX_TOKENS tokens,
number literals <= MAX_NUMBER_CHARS characters with a decimal exponent |E| <= MAX_LITERAL_EXP,
nesting <= MAX_DEPTH (parentheses, calls, unary signs and ``**`` exponents each add one level),
rational-constant exponents |p| <= MAX_EXPONENT, and rational ** rational only when the result
lies within 10**+-MAX_LOG10 (estimated with logs, never computed). Symbolic constants (pi, e,
sin(1), ...) are not sized: sympy keeps their powers unevaluated, so they cannot blow up.
"""

from __future__ import annotations

import keyword
import math
import operator
import re
from typing import Callable, Mapping, NamedTuple, NoReturn

import sympy

from dfeif_codegen.errors import ModelError

MAX_CHARS = 10_000
MAX_TOKENS = 2_000  # real model terms use ~50 tokens; bounds sympy work (e.g. min() of many args)
MAX_DEPTH = 64
MAX_NUMBER_CHARS = 40
MAX_LITERAL_EXP = 300
MAX_EXPONENT = 64
MAX_LOG10 = 300

_DIGITS = frozenset("0123456789")
_NUMBER = re.compile(r"(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_CONSTANTS = {"pi": sympy.pi, "e": sympy.E}
_BAD_VALUES = (sympy.zoo, sympy.nan, sympy.oo, -sympy.oo, sympy.I)
_COMPARE = "comparison operators are not allowed"
_REFUSED = {
    "^": "'^' is not allowed; use ** for powers", "//": "floor division '//' is not allowed",
    ";": "';' is not allowed (one expression only)", "<": _COMPARE, ">": _COMPARE, "!": _COMPARE,
    "=": "'=' is not allowed (no assignments or comparisons)",
    "'": "string literals are not allowed", '"': "string literals are not allowed",
    "[": "subscripts '[...]' are not allowed", "]": "subscripts '[...]' are not allowed",
    ".": "attribute access '.' is not allowed",
    ":": "':' is not allowed (no lambdas, slices or annotations)",
}
# name -> (min args, max args or None, sympy builder; None = handled in call())
_FUNCS: dict[str, tuple[int, int | None, Callable | None]] = {
    **{f: (1, 1, getattr(sympy, f)) for f in
       ("sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp", "log", "sqrt",
        "sign")},
    "abs": (1, 1, sympy.Abs), "atan2": (2, 2, sympy.atan2),
    "min": (2, None, sympy.Min), "max": (2, None, sympy.Max),
    "pow": (2, 2, None), "hypot": (2, 2, None),
}


class _Tok(NamedTuple):
    kind: str  # "num", "name", "op" or "end"
    text: str
    pos: int  # 0-based offset into the text


def _tokenize(t: str, fail: Callable[[int, str], NoReturn]) -> list[_Tok]:
    """Every token of `t`, the end marker last; `fail(pos, problem)` raises."""
    toks: list[_Tok] = []
    i, n = 0, len(t)
    while i < n:
        ch = t[i]
        if ch in " \t\r\n":
            i += 1
            continue
        if len(toks) >= MAX_TOKENS:
            fail(i, f"expression has more than {MAX_TOKENS} tokens")
        if ch in _DIGITS or (ch == "." and t[i + 1:i + 2] in _DIGITS):
            end = _NUMBER.match(t, i).end()
            if end < n and (t[end].isalnum() or t[end] in "._"):
                fail(i, f"malformed number {t[i:end + 1]!r}")
            if end - i > MAX_NUMBER_CHARS:
                fail(i, f"number longer than {MAX_NUMBER_CHARS} characters")
            exp_part = t[i:end].lower().partition("e")[2]
            if exp_part and abs(int(exp_part)) > MAX_LITERAL_EXP:
                fail(i, f"number exponent beyond +-{MAX_LITERAL_EXP}")
            toks.append(_Tok("num", t[i:end], i))
            i = end
        elif ch.isascii() and (ch.isalpha() or ch == "_"):
            end = _NAME.match(t, i).end()
            toks.append(_Tok("name", t[i:end], i))
            i = end
        elif t.startswith("**", i):
            toks.append(_Tok("op", "**", i))
            i += 2
        elif t.startswith("//", i):
            fail(i, _REFUSED["//"])
        elif ch in "+-*/(),":
            toks.append(_Tok("op", ch, i))
            i += 1
        elif not ch.isascii():
            fail(i, f"non-ASCII character {ch!r} (names must be ASCII)")
        else:
            fail(i, _REFUSED.get(ch, f"character {ch!r} is not allowed"))
    toks.append(_Tok("end", "", n))
    return toks


class _Parser:
    """One parse: tokenize everything first, then recursive descent with a depth counter."""

    def __init__(self, text: str, names: Mapping[str, sympy.Expr], where: str, misplaced: Mapping[str, str]):
        self.text, self.names, self.where, self.misplaced = text, names, where, misplaced
        self.toks: list[_Tok] = []
        self.i = 0
        self.depth = 0

    def fail(self, pos: int, problem: str) -> NoReturn:
        col = pos - self.text.rfind("\n", 0, pos)
        loc = f"column {col}"
        if "\n" in self.text:
            loc = f"line {self.text.count(chr(10), 0, pos) + 1}, {loc}"
        raise ModelError(f"{self.where}: {loc}: {problem}")

    def peek(self) -> _Tok:
        return self.toks[self.i]

    def take(self) -> _Tok:
        self.i += 1
        return self.toks[self.i - 1]

    def enter(self, tok: _Tok) -> None:
        """Count a nesting level BEFORE recursing, so deep input fails without RecursionError."""
        if self.depth >= MAX_DEPTH:
            self.fail(tok.pos, f"nesting deeper than {MAX_DEPTH} levels")
        self.depth += 1

    def unexpected(self, tok: _Tok, operand: bool = False) -> NoReturn:
        if tok.kind == "end":
            self.fail(tok.pos, "unexpected end of expression (operand missing)")
        if tok.text == ")":
            self.fail(tok.pos, "operand missing before ')'" if operand else "unbalanced ')'")
        if tok.text == ",":
            self.fail(tok.pos, "',' is only allowed between function arguments")
        if tok.text == "(":
            self.fail(tok.pos, "unexpected '(' (only the allowed functions can be called)")
        if tok.kind == "name" and keyword.iskeyword(tok.text) and tok.text not in self.names:
            self.fail(tok.pos, f"keyword {tok.text!r} is not allowed")
        self.fail(tok.pos, f"unexpected {tok.text!r}")

    def build(self, tok: _Tok, fn: Callable, *args, check: bool = False) -> sympy.Expr:
        """Call sympy; turn its exceptions and undefined/complex results into ModelError."""
        try:
            out = fn(*args)
        except Exception as exc:  # sympy raises many types; none may leak to the user
            self.fail(tok.pos, f"cannot build {tok.text!r}: {type(exc).__name__}")
        if check and out.has(*_BAD_VALUES):
            self.fail(tok.pos, f"{tok.text!r} gives an undefined, infinite or complex value")
        return out

    def parse(self) -> sympy.Expr:
        if len(self.text) > MAX_CHARS:
            self.fail(MAX_CHARS, f"expression longer than {MAX_CHARS} characters")
        self.toks = _tokenize(self.text, self.fail)
        if self.peek().kind == "end":
            self.fail(0, "empty expression")
        out = self.expr()
        if self.peek().kind != "end":
            self.unexpected(self.peek())
        return out

    def expr(self) -> sympy.Expr:
        first, terms = self.peek(), [self.term()]
        while self.peek().text in ("+", "-"):
            tok = self.take()
            term = self.term()
            terms.append(term if tok.text == "+" else self.build(tok, operator.neg, term))
        return terms[0] if len(terms) == 1 else self.build(first, sympy.Add, *terms)

    def term(self) -> sympy.Expr:
        first, factors = self.peek(), [self.unary()]
        while self.peek().text in ("*", "/"):
            tok = self.take()
            factor = self.unary()
            if tok.text == "/":
                if factor.is_Number and factor == 0:
                    self.fail(tok.pos, "division by zero")
                factor = self.build(tok, sympy.Pow, factor, -1)
            factors.append(factor)
        return factors[0] if len(factors) == 1 else self.build(first, sympy.Mul, *factors)

    def unary(self) -> sympy.Expr:
        tok = self.peek()
        if tok.text not in ("+", "-"):
            return self.power()
        self.take()
        self.enter(tok)
        operand = self.unary()
        self.depth -= 1
        return operand if tok.text == "+" else self.build(tok, operator.neg, operand)

    def power(self) -> sympy.Expr:
        base = self.atom()
        tok = self.peek()
        if tok.text != "**":
            return base
        self.take()
        self.enter(tok)
        exponent = self.unary()
        self.depth -= 1
        return self.pow(base, exponent, tok)

    def pow(self, base: sympy.Expr, exponent: sympy.Expr, tok: _Tok) -> sympy.Expr:
        """Size-check rational exponents with logs before sympy is allowed to evaluate."""
        if exponent.is_Rational:
            if abs(exponent) > MAX_EXPONENT:
                self.fail(tok.pos, f"constant exponent {exponent} beyond +-{MAX_EXPONENT}")
            if base.is_Number and base == 0 and exponent < 0:
                self.fail(tok.pos, "division by zero (0 to a negative power)")
            if base.is_Rational and base != 0:
                log10 = float(exponent) * (math.log10(abs(base.p)) - math.log10(base.q))
                if abs(log10) > MAX_LOG10:
                    self.fail(tok.pos, f"constant power is about 10**{log10:.0f}, beyond 1e{MAX_LOG10}")
        return self.build(tok, sympy.Pow, base, exponent, check=True)

    def atom(self) -> sympy.Expr:
        tok = self.take()
        if tok.kind == "num":
            return self.build(tok, sympy.Rational, tok.text)  # exact: "0.1" -> 1/10
        if tok.kind == "name":
            if self.peek().text == "(":
                return self.call(tok)
            if tok.text in self.names:
                return self.names[tok.text]
            if tok.text in _CONSTANTS:
                return _CONSTANTS[tok.text]
            if tok.text in _FUNCS:
                self.fail(tok.pos, f"function {tok.text!r} must be called with arguments")
            if keyword.iskeyword(tok.text):
                self.unexpected(tok)
            self.fail(tok.pos, self.misplaced.get(tok.text, f"undeclared name {tok.text!r}"))
        if tok.text != "(":
            self.unexpected(tok, operand=True)
        self.enter(tok)
        if self.peek().text == ")":
            self.fail(self.peek().pos, "empty parentheses")
        inner = self.expr()
        if self.peek().text != ")":
            self.fail(self.peek().pos, "unbalanced '(': expected ')'")
        self.take()
        self.depth -= 1
        return inner

    def call(self, name: _Tok) -> sympy.Expr:
        if name.text not in _FUNCS:
            self.fail(name.pos, f"{name.text!r} is not an allowed function "
                                f"(allowed: {', '.join(sorted(_FUNCS))})")
        lo, hi, fn = _FUNCS[name.text]
        self.enter(name)
        self.take()  # '('
        args = []
        if self.peek().text != ")":
            args.append(self.expr())
            while self.peek().text == ",":
                self.take()
                args.append(self.expr())
        if self.peek().text != ")":
            self.fail(self.peek().pos, f"expected ',' or ')' in the call of {name.text}()")
        self.take()
        self.depth -= 1
        if len(args) < lo or (hi is not None and len(args) > hi):
            want = str(lo) if lo == hi else f"at least {lo}"
            self.fail(name.pos, f"{name.text}() takes {want} argument(s), got {len(args)}")
        if name.text == "pow":
            return self.pow(args[0], args[1], name)
        if name.text == "hypot":
            two = sympy.Integer(2)
            squares = self.build(name, sympy.Add, self.pow(args[0], two, name),
                                 self.pow(args[1], two, name))
            return self.build(name, sympy.sqrt, squares, check=True)
        return self.build(name, fn, *args, check=True)


def parse_expression(text: str, names: Mapping[str, sympy.Expr],
                     where: str = "expression", misplaced: Mapping[str, str] | None = None) -> sympy.Expr:
    """Parse `text` into a sympy expression over `names` (plus pi and e), never evaluating it.
    `misplaced`: names declared elsewhere but not usable here, each with what to say instead of
    "undeclared name" (a model's inputs in a state function).

    Raises ModelError with one line ``"{where}: [line L, ]column C: problem"`` for bad input.
    """
    where = " ".join(str(where).split()) or "expression"
    if not isinstance(text, str):
        raise ModelError(f"{where}: column 1: expected a string, got {type(text).__name__}")
    try:
        return _Parser(text, names, where, misplaced or {}).parse()
    except RecursionError:  # not expected (depth is bounded); kept so nothing else can leak
        raise ModelError(f"{where}: column 1: expression too deeply nested") from None
