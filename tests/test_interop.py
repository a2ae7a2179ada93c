"""python-control interop (issue 11): a `control.flatsys.FlatSystem` from `flat.forward` and
`flat.reverse`, then `point_to_point`, for both built-ins. python-control calls them with
`params={}`. The `control` extra provides the package; CI installs it (missing there = failure)."""

import os

import numpy as np
import pytest

from dfeif_codegen.symbolic import flatness, model

if os.environ.get("CI") == "true":
    import control.flatsys as fs  # noqa: F401  (CI must have the extra: fail, do not skip)
else:
    fs = pytest.importorskip("control.flatsys")


def rest_at(flat, y):
    """State and input at rest with every flat output at y: from reverse() of the flags."""
    return flat.reverse([np.array([y] + [0.0] * c.degree) for c in flat.chains])


@pytest.mark.parametrize("name", ["dc_motor_link", "two_link_arm"])
def test_point_to_point_through_python_control(name):
    flat = flatness.derive(model.load(name))
    sys = fs.FlatSystem(flat.forward, flat.reverse, inputs=flat.m, outputs=flat.m, states=flat.n)
    (x0, u0), (xf, uf) = rest_at(flat, 0.0), rest_at(flat, 0.5)
    T = 2.0
    traj = fs.point_to_point(sys, [0, T], x0, u0, xf, uf, basis=fs.PolyFamily(2 * max(flat.degrees) + 2))
    t = np.linspace(0, T, 401)
    x, u = traj.eval(t)
    # boundary conditions met: python-control solves a linear system for the polynomial
    # coefficients (condition number ~1e6 for degree 8 on [0, 2]): 1e-8 leaves two orders of margin
    np.testing.assert_allclose(x[:, 0], x0, atol=1e-8)
    np.testing.assert_allclose(x[:, -1], xf, atol=1e-8)
    np.testing.assert_allclose(u[:, -1], uf, rtol=1e-8, atol=1e-8)
    # an independent check of the whole trajectory: it obeys the model's own dynamics
    # x' = f(x) + g(x) u, with x' from central differences (error O(dt^2 x''') ~ 1e-4 relative)
    import sympy as sp
    m = flat.model
    rhs = sp.lambdify([list(m.x), list(m.u)], (m.f + m.g * m.u).subs(m.param_values), "numpy")
    dt = t[1] - t[0]
    dx = (x[:, 2:] - x[:, :-2]) / (2 * dt)
    want = np.column_stack([np.asarray(rhs(x[:, k], u[:, k]), float).ravel() for k in range(1, len(t) - 1)])
    scale = np.max(np.abs(want), axis=1, keepdims=True) + 1e-12
    assert np.max(np.abs(dx - want) / scale) < 1e-3


def test_forward_and_reverse_take_params_by_name():
    flat = flatness.derive(model.load("dc_motor_link"))
    x = np.array([0.3, 0.1, 0.2])
    base = flat.forward(x, [1.0], params={})
    heavier = flat.forward(x, [1.0], params={"m": 0.6})
    assert np.array_equal(base[0], flat.forward(x, [1.0])[0])
    # theta'' = (k_e I - k_d omega - m g l sin theta)/J: doubling m subtracts m g l sin(theta)/J more
    assert heavier[0][2] - base[0][2] == pytest.approx(-0.3 * 9.81 * 0.25 * np.sin(0.3) / 0.02, rel=1e-12)
    with pytest.raises(ValueError, match="unknown parameter"):
        flat.forward(x, [1.0], params={"mass": 1.0})
