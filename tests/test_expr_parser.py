"""Tests for the restricted expression parser: exact results, and hostile input refused unrun."""

import builtins
import os
import re
import time

import pytest
import sympy

from dfeif_codegen.symbolic import expr_parser
from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic.expr_parser import parse_expression

SYMS = {n: sympy.Symbol(n, real=True) for n in
        ("x", "y", "z", "a", "b", "c", "k_e", "k_d", "R", "J", "L", "x2", "theta")}
x, y, z, a, b, c = (SYMS[n] for n in "xyzabc")
MESSAGE = re.compile(r"^where: (line \d+, )?column \d+: \S.*$")


def parse(text, names=SYMS):
    return parse_expression(text, names, where="where")


def same(got, want):
    return sympy.simplify(got - want) == 0


# --- correctness against hand-built sympy expressions -------------------------------------------

def test_motor_current_equation():
    k_e, k_d, R, J, L, x2 = (SYMS[n] for n in ("k_e", "k_d", "R", "J", "L", "x2"))
    want = -(k_e ** 2 + k_d * R) / (J * L) * x2
    assert same(parse("-(k_e**2 + k_d*R)/(J*L)*x2"), want)


@pytest.mark.parametrize("text, want", [
    ("2**3**2", sympy.Integer(512)),
    ("(2**3)**2", sympy.Integer(64)),
    ("-2**2", sympy.Integer(-4)),
    ("2**-1", sympy.Rational(1, 2)),
    ("-x**2", -(x ** 2)),
    ("(-x)**2", x ** 2),
    ("x**y**z", x ** (y ** z)),
    ("a/b/c", (a / b) / c),
    ("a-b-c", (a - b) - c),
    ("a - -b", a + b),
    ("+a*-b", -a * b),
    ("1 + 2*3", sympy.Integer(7)),
    ("(1 + 2)*3", sympy.Integer(9)),
    ("a*b/c*x", a * b * x / c),
    ("x +\n  y", x + y),
])
def test_precedence_and_associativity(text, want):
    assert same(parse(text), want)


@pytest.mark.parametrize("text, want", [
    ("atan2(y, x)", sympy.atan2(y, x)),
    ("atan2(1, 1)", sympy.pi / 4),
    ("sqrt(8)", 2 * sympy.sqrt(2)),
    ("abs(-3)", sympy.Integer(3)),
    ("abs(x)", sympy.Abs(x)),
    ("min(x, y)", sympy.Min(x, y)),
    ("min(3, 1, 2)", sympy.Integer(1)),
    ("max(x, y, z)", sympy.Max(x, y, z)),
    ("hypot(3, 4)", sympy.Integer(5)),
    ("hypot(x, y)", sympy.sqrt(x ** 2 + y ** 2)),
    ("pow(x, 3)", x ** 3),
    ("sin(pi/6)", sympy.Rational(1, 2)),
    ("cos(x)**2 + sin(x)**2", sympy.Integer(1)),
    ("log(e)", sympy.Integer(1)),
    ("exp(0)", sympy.Integer(1)),
    ("sign(-2)", sympy.Integer(-1)),
    ("tanh(x)", sympy.tanh(x)),
    ("asin(1)", sympy.pi / 2),
])
def test_functions_exact(text, want):
    assert same(parse(text), want)


@pytest.mark.parametrize("text, want", [
    ("0.1", sympy.Rational(1, 10)),
    ("1.5e-3", sympy.Rational(3, 2000)),
    ("2.", sympy.Integer(2)),
    (".5", sympy.Rational(1, 2)),
    ("1E3", sympy.Integer(1000)),
    ("0.1 + 0.2", sympy.Rational(3, 10)),
])
def test_decimal_literals_are_exact(text, want):
    got = parse(text)
    assert got == want and not got.atoms(sympy.Float)


def test_constants_and_declared_names():
    assert parse("pi") is sympy.pi
    assert parse("2*e") == 2 * sympy.E
    assert parse("theta") is SYMS["theta"]  # the caller's Symbol, assumptions kept
    mine = sympy.Symbol("pi")
    assert parse_expression("pi + 1", {"pi": mine}) == mine + 1  # a declaration wins
    lam = sympy.Symbol("lambda")
    assert parse_expression("2*lambda", {"lambda": lam}) == 2 * lam


def test_depth_limit_is_exact():
    assert parse("(" * 64 + "x" + ")" * 64) == x
    assert parse("-" * 64 + "x") == x
    with pytest.raises(ModelError, match="nesting deeper than 64"):
        parse("(" * 65 + "x" + ")" * 65)


def test_depth_checked_before_recursing(monkeypatch):
    """With the length and token bounds lifted, deep nesting still fails by the counter."""
    monkeypatch.setattr(expr_parser, "MAX_CHARS", 10 ** 6)
    monkeypatch.setattr(expr_parser, "MAX_TOKENS", 10 ** 6)
    for text in ("(" * 10000 + "x" + ")" * 10000, "-" * 10000 + "x", "sin(" * 10000 + "x" +
                 ")" * 10000, "x**" * 10000 + "x"):
        with pytest.raises(ModelError, match="nesting deeper than 64"):
            parse(text)


def test_multiline_location():
    with pytest.raises(ModelError) as err:
        parse("x +\n  y.real")
    assert str(err.value) == "where: line 2, column 4: attribute access '.' is not allowed"


# --- hostile and malformed input ----------------------------------------------------------------

HOSTILE = [
    ("__import__('os').system('x')", "string"),
    ("__import__(os)", "'__import__' is not an allowed function"),
    ("x.__class__", "attribute"),
    ("x.real", "attribute"),
    ("lambda: 0", ":"),
    ("lambda", "keyword 'lambda'"),
    ("(lambda: 0)()", ":"),
    ("9**9**9**9", "exponent"),
    ("10**1000", "exponent"),
    ("x**100000", "exponent"),
    ("(10**30)**20", "1e300"),
    ("1e999999999", "exponent"),
    ("(" * 10000 + "x" + ")" * 10000, "longer than 10000"),
    ("-" * 10000 + "x", "longer than 10000"),
    ("x+" * 10000 + "x", "longer than 10000"),
    ("+x" * 1500, "tokens"),
    ("(" * 65 + "x" + ")" * 65, "nesting"),
    ("-" * 65 + "x", "nesting"),
    ("sin(" * 65 + "x" + ")" * 65, "nesting"),
    ("eval('1')", "string"),
    ("eval(x)", "'eval' is not an allowed function"),
    ("open('f')", "string"),
    ("exec", "undeclared name 'exec'"),
    ("exec(x)", "not an allowed function"),
    ("globals()", "'globals' is not an allowed function"),
    ("x[0]", "subscript"),
    ("'s'", "string"),
    ('"s"', "string"),
    ("x if y else z", "keyword 'if'"),
    ("x = 1", "'='"),
    ("x == y", "'='"),
    ("x; y", "';'"),
    ("x @ y", "'@'"),
    ("x % y", "'%'"),
    ("x // y", "'//'"),
    ("x ^ 2", "use **"),
    ("x < y", "comparison"),
    ("x >= y", "comparison"),
    ("x != y", "comparison"),
    ("undeclared_name", "undeclared name 'undeclared_name'"),
    ("x + undeclared_name", "column 5: undeclared name 'undeclared_name'"),
    ("sin()", "sin() takes 1 argument(s), got 0"),
    ("atan2(x)", "atan2() takes 2 argument(s), got 1"),
    ("sin(x, y)", "got 2"),
    ("min(x)", "at least 2"),
    ("sin", "must be called"),
    ("x(1)", "not an allowed function"),
    ("(x)(y)", "'('"),
    ("1/0", "column 2: division by zero"),
    ("x/(y - y)", "division by zero"),
    ("0**-1", "division by zero"),
    ("sqrt(-1)", "complex"),
    ("log(0)", "infinite"),
    ("()", "empty parentheses"),
    ("", "column 1: empty expression"),
    ("   ", "empty expression"),
    ("x y", "column 3: unexpected 'y'"),
    ("x +", "end of expression"),
    ("1..2", "malformed number"),
    ("2x", "malformed number"),
    ("1e", "malformed number"),
    ("x, y", "','"),
    ("(x", "unbalanced '('"),
    ("x)", "unbalanced ')'"),
    ("((x)", "unbalanced '('"),
    ("sin(x,)", "operand missing"),
    ("\u03b8 + 1", "non-ASCII"),
    ("x\u00e9", "column 2: non-ASCII"),
    ("x\u2028+y", "non-ASCII"),
    ("1" * 50, "longer than 40"),
    ("x & y | ~z", "'&'"),
    ("{x}", "'{'"),
    ("`x`", "'`'"),
    ("x # comment", "'#'"),
    ("f(**x)", "not an allowed function"),
]


@pytest.mark.parametrize("text, fragment", HOSTILE, ids=lambda v: repr(v)[:40])
def test_hostile_input_refused(text, fragment):
    with pytest.raises(ModelError) as err:
        parse(text)
    message = str(err.value)
    assert "\n" not in message and MESSAGE.match(message), message
    assert fragment in message, message


def test_non_string_input_refused():
    with pytest.raises(ModelError, match="column 1: expected a string"):
        parse(42)


def _spy(calls, label, real):
    def spy(*args, **kwargs):
        calls.append((label, args[:1]))
        return real(*args, **kwargs)
    return spy


def test_nothing_runs_and_time_is_bounded(monkeypatch, tmp_path):
    target = tmp_path / "pwned"
    side_effects = [
        f"open('{target}', 'w').write('x')",
        f"__import__('pathlib').Path('{target}').touch()",
        f"__import__('os').mkdir(\"{target}\")",
        f"exec(\"open('{target}','w')\")",
    ]
    calls, imports = [], []
    real_import = builtins.__import__

    def import_spy(name, *args, **kwargs):
        # sympy does function-level imports of its own modules; only record the ones an
        # injected payload would want.
        if name.split(".")[0] in {"os", "subprocess", "pathlib", "shutil", "sys", "socket"}:
            imports.append(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", import_spy)
    for label in ("eval", "exec", "open", "compile"):
        monkeypatch.setattr(builtins, label, _spy(calls, label, getattr(builtins, label)))
    monkeypatch.setattr(os, "system", _spy(calls, "os.system", os.system))

    # A safety bound, not a benchmark: generous, yet a real blow-up (evaluating 9**9**9**9,
    # recursing 10 000 levels, quadratic rescans) would blow far past it.
    start = time.perf_counter()
    for text in [t for t, _ in HOSTILE] + side_effects:
        with pytest.raises(ModelError):
            parse(text)
    elapsed = time.perf_counter() - start
    monkeypatch.undo()

    assert calls == [] and imports == []
    assert not target.exists()
    assert elapsed < 5.0, elapsed
