"""The one sympy -> numeric bridge (`symbolic.numeric`): the converter, CasADi Functions called
through their buffer, and the flat system, plant and cameras that use it, each against sympy's
own evaluation of the same expression (an independent evaluator, 50 significant digits)."""

from __future__ import annotations

import pickle
import re
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import sympy as sp

from dfeif_codegen.experiment.plant import Camera, Plant
from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic import flatness, model, numeric

PACKAGE = Path(__file__).resolve().parents[1] / "dfeif_codegen"

# Every expression here is a few dozen IEEE operations on O(1) values, each correctly rounded
# (libm's sin, cos, atan2, exp, log are within 1 ulp), and none of them cancels catastrophically
# at the sampled points: the error stays below 100 ulp = 2.2e-14 of the result's scale on any
# IEEE-754 machine. Relative to max(|value|, 1) so entries that are ~0 do not divide by ~0.
TOL = 1e-13


def close(got, want) -> bool:
    got, want = np.asarray(got, float), np.asarray(want, float)
    return got.shape == want.shape and bool(np.all(np.abs(got - want) <= TOL * np.maximum(np.abs(want), 1)))


def exact(expr, subs) -> np.ndarray:
    m = sp.Matrix(expr) if not isinstance(expr, sp.MatrixBase) else expr
    return np.array(m.evalf(50, subs=subs).tolist(), dtype=float)


def test_sympy_to_casadi_converter():
    x, y = sp.symbols("x y")
    exprs = [sp.sin(x) * sp.cos(y) ** 3 / (1 + x ** 2), sp.sqrt(x + 2) - 1 / sp.sqrt(y + 3),
             sp.atan2(y, x) + sp.Abs(x - y) + sp.exp(-x) * sp.log(y + 4), sp.Max(x, y, 0) + sp.Min(x, 1),
             sp.tanh(x) + sp.pi * (x + 3) ** sp.Rational(3, 2),
             x ** -3 + sp.sign(y) + sp.asin(x / 4)]
    X, Y = ca.SX.sym("x"), ca.SX.sym("y")
    for e in exprs:
        f = ca.Function("f", [X, Y], [numeric.to_casadi(e, {x: X, y: Y})])
        for point in ((0.3, -0.7), (1.2, 0.4)):
            want = float(e.evalf(50, subs={x: point[0], y: point[1]}))
            assert float(f(*point)) == pytest.approx(want, rel=1e-13), e
    with pytest.raises(Exception, match="unexpected symbol 'z'"):
        numeric.to_casadi(x + sp.Symbol("z"), {x: X})
    with pytest.raises(Exception, match="cannot convert 'gamma'"):
        numeric.to_casadi(sp.gamma(x), {x: X})


def test_numeric_matrix_layout_vector_arguments_and_pickling():
    x, y, a = sp.symbols("x y a")
    mat = sp.Matrix([[x, 2 * y, a], [3, x * y, sp.sin(a) - x]])     # not symmetric, not square
    f = numeric.Numeric.of("m", [[x, y], [a]], mat)
    got = f([0.5, -1.5], [0.25])
    assert got.shape == (2, 3) and close(got, exact(mat, {x: 0.5, y: -1.5, a: 0.25}))
    assert close(f(np.array([1.0, 2.0]), [0.0]), exact(mat, {x: 1, y: 2, a: 0}))    # buffer reused
    col = numeric.Numeric.of("c", [[x], []], [x ** 2, sp.cos(x)])                 # an empty argument
    assert close(col([0.7], []), [0.49, np.cos(0.7)]) and col([0.7], []).shape == (2,)
    again = pickle.loads(pickle.dumps(f))
    assert np.array_equal(again([0.5, -1.5], [0.25]), got)
    with pytest.raises(TypeError, match="takes 2 arguments"):
        f([0.5, -1.5])


@pytest.mark.parametrize("name", ["dc_motor_link", "two_link_arm"])
def test_flat_system_plant_and_camera_evaluate_the_model(name):
    flat = flatness.derive(model.load(name))
    mdl = flat.model
    params = dict(zip(mdl.p, flat.param_vector))
    plant, camera = Plant(mdl), Camera(mdl)
    rng = np.random.default_rng(7)
    for _ in range(3):
        x, u = rng.uniform(-1, 1, mdl.n), rng.uniform(-1, 1, mdl.m)
        at_x = {**params, **dict(zip(mdl.x, x))}
        at_zeta = {**params, **dict(zip(flat.zeta, x))}
        assert close(flat.F_num(x), exact(flat.F, at_zeta).reshape(-1))
        assert close(flat.G_num(x), exact(flat.G, at_zeta))
        assert close(flat.phi_num(x), exact(flat.phi, at_x).reshape(-1))
        assert close(flat.phi_inv_num(x), exact(flat.phi_inv, at_zeta).reshape(-1))
        rhs = mdl.f + mdl.g * sp.Matrix(u)
        assert close(plant.rhs(x, u), exact(rhs, at_x).reshape(-1))
        observe = [mdl.measurement.observe[c] for c in camera.channels]
        assert close(camera.observe(x), exact(observe, at_x).reshape(-1))
    alt = flat.param_vector * 1.5                                       # parameters reach the functions
    assert close(flat.G_num(x, alt), exact(flat.G, {**dict(zip(mdl.p, alt)), **dict(zip(flat.zeta, x))}))


def test_no_other_sympy_to_numeric_path():
    """The package evaluates sympy only through symbolic/numeric.py: no lambdify anywhere."""
    offenders = [str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
                 if re.search(r"\blambdify\b", p.read_text())]
    assert offenders == []


def test_single_precision_rounds_every_operation():
    """`SinglePrecision` runs a Function's instructions in float32, each rounded as a float C
    build rounds it. Closed forms: (1 + 2^24) - 2^24 is 1 in double and 0 in float32, since
    2^24 + 1 is not a float32 and rounds to even, 2^24; 0.7 * 3 - 0.3 is float32(0.7) * 3 - float32(0.3)
    rounded step by step, not the double result. Against the double Function on a mixed expression: within 1e-6 relative (a few float32
    roundings of O(1) values, no cancellation), and float32 out."""
    a, b, c = ca.SX.sym("a"), ca.SX.sym("b"), ca.SX.sym("c")
    cancel = ca.Function("cancel", [a, b, c], [(a + b) - c])     # (a + b) - b CasADi would simplify to a
    assert numeric.Numeric(cancel)(1.0, 2.0 ** 24, 2.0 ** 24) == 1.0
    assert numeric.SinglePrecision(cancel)(1.0, 2.0 ** 24, 2.0 ** 24) == 0.0
    residue = ca.Function("residue", [a], [a * 3 - 0.3])
    f32 = np.float32
    got = numeric.SinglePrecision(residue)(0.7)[0]
    assert got == f32(f32(0.7) * f32(3)) - f32(0.3) and float(got) != 0.7 * 3 - 0.3
    x, u = ca.SX.sym("x", 3), ca.SX.sym("u")
    e = ca.vertcat(ca.sin(x[0]) * 3 + u, x[1] / x[0], u * u, ca.fabs(u), 2 * x[1], ca.fmax(x[2], u),
                   ca.if_else(x[0] < u, x[1], x[2]), ca.atan2(x[0], x[1]), ca.exp(x[2]) - ca.sqrt(x[0]), x[0] ** 3)
    mixed = ca.Function("mixed", [x, u], [e], {"cse": True})
    args = (np.array([0.3, -1.2, 2.0]), -0.7)
    got, want = numeric.SinglePrecision(mixed)(*args), numeric.Numeric(mixed)(*args)
    assert got.dtype == np.float32 and np.all(np.abs(got - want) <= 1e-6 * np.maximum(np.abs(want), 1))
    with pytest.raises(ModelError, match="no single-precision twin"):
        numeric.SinglePrecision(ca.Function("erf", [a], [ca.erf(a)]))
