"""The derived flatness transform against hand derivations (issue: models and flatness)."""

from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic import flatness, model


@pytest.fixture(scope="module")
def motor():
    return flatness.derive(model.load("dc_motor_link"))


@pytest.fixture(scope="module")
def arm():
    return flatness.derive(model.load("two_link_arm"))


def test_dc_motor_canonical_form_is_eq_116(motor):
    J, L, R, ke, kd, m, g, l = sp.symbols("J L R k_e k_d m g l")
    z1, z2, z3 = motor.zeta
    # Eq. (116) of the chapter, with the square on k_e that the OCR of Eq. (115) lost
    f_bar = (-((ke**2 + kd * R) / (J * L)) * z2 - ((R * J + kd * L) / (J * L)) * z3
             - (R * m * g * l / (J * L)) * sp.sin(z1) - (m * g * l / J) * sp.cos(z1) * z2)
    g_bar = ke / (J * L)
    assert motor.degrees == [3]
    assert sp.simplify(motor.F[0] - f_bar) == 0
    assert sp.simplify(motor.G[0, 0] - g_bar) == 0


@pytest.mark.parametrize("name", ["dc_motor_link", "two_link_arm"])
def test_phi_inverse_round_trip(name, motor, arm):
    flat = motor if name == "dc_motor_link" else arm
    x = flat.model.x
    composed = flat.phi_inv.subs(dict(zip(flat.zeta, flat.phi)), simultaneous=True)
    assert sp.simplify(composed - x) == sp.zeros(flat.n, 1)
    rng = np.random.default_rng(7)
    for _ in range(100):
        xs = rng.uniform(-3, 3, flat.n)
        assert np.allclose(flat.phi_inv_num(flat.phi_num(xs)), xs, rtol=1e-12, atol=1e-12)


def test_arm_decoupling_matrix_is_M_inverse_K_over_L(arm):
    m1, m2, l1, l2, Jm1, Jm2, ke, L, q2 = sp.symbols("m1 m2 l1 l2 Jm1 Jm2 k_e L q2")
    # hand derivation: y'' = M(q)^-1 (k_e I - ...), L I' = ... + V  =>  d y'''/dV = M^-1 k_e / L
    M = sp.Matrix([[Jm1 + m1 * l1**2 + m2 * (l1**2 + l2**2 + 2 * l1 * l2 * sp.cos(q2)), m2 * (l2**2 + l1 * l2 * sp.cos(q2))],
                   [m2 * (l2**2 + l1 * l2 * sp.cos(q2)), Jm2 + m2 * l2**2]])
    expected = M.inv() * ke / L
    assert sp.simplify(arm.decoupling_x - expected) == sp.zeros(2, 2)
    rng = np.random.default_rng(3)
    for _ in range(20):
        zeta = rng.uniform(-3, 3, arm.n)
        G = arm.G_num(zeta)
        assert abs(np.linalg.det(G)) > 1e-6
        values = {**arm.model.param_values, q2: zeta[3]}
        assert np.allclose(G, np.array(expected.subs(values), dtype=float), rtol=1e-12)


@pytest.mark.parametrize("name", ["dc_motor_link", "two_link_arm"])
def test_flatsys_forward_reverse(name, motor, arm):
    flat = motor if name == "dc_motor_link" else arm
    rng = np.random.default_rng(11)
    for _ in range(20):
        x, u = rng.uniform(-2, 2, flat.n), rng.uniform(-5, 5, flat.m)
        flags = flat.forward(x, u)
        assert [len(f) for f in flags] == [c.degree + 1 for c in flat.chains]
        x2, u2 = flat.reverse(flags)
        # reverse(forward(x)) composes closed forms (no iteration); u adds one solve with G
        # (cond < 1e3 on this box): 1e-10/1e-9 absolute on O(1) values is ~1e5 eps of margin
        assert np.allclose(x2, x, atol=1e-10) and np.allclose(u2, u, atol=1e-9)
    # the top flag is the physical derivative: d^r y/dt^r from f + g u by finite differences
    mdl, x, u = flat.model, rng.uniform(-1, 1, flat.n), rng.uniform(-1, 1, flat.m)
    rhs = sp.lambdify([list(mdl.x), list(mdl.u), mdl.p], mdl.f + mdl.g * mdl.u)
    xdot = np.array(rhs(x, u, list(flat.param_vector)), dtype=float).ravel()
    h = 1e-6
    zdot = (flat.phi_num(x + h * xdot) - flat.phi_num(x - h * xdot)) / (2 * h)
    for j, c in enumerate(flat.chains):
        # central differences at h = 1e-6: truncation O(h^2 f''') ~1e-12, rounding O(eps/h) ~1e-10
        assert np.isclose(zdot[c.offset + c.degree - 1], flat.forward(x, u)[j][-1], rtol=1e-6, atol=1e-6)


def test_multi_input_linear_model_via_python_api():
    x1, x2, x3, a = sp.symbols("x1 x2 x3 a")
    mdl = model.from_sympy("lin", ["x1", "x2", "x3"], ["u1", "u2"], [model.Parameter("a", 2.0)],
                           f=[x2, -a * x1, 0], g=[[0, 0], [1, 0], [0, 1]],
                           outputs=[model.Output("y1", x1), model.Output("y2", x3)])
    flat = flatness.derive(mdl)
    assert flat.degrees == [2, 1]
    assert sp.simplify(flat.F[0] + a * flat.zeta[0]) == 0 and flat.F[1] == 0
    assert flat.G == sp.eye(2)


def test_a_stop_names_the_largest_expression_of_f_g_and_outputs():
    """When the derivation stops on its budget, the message names the model's largest expression,
    the likely culprit: a 3-D quadrotor's rotation terms sit in g (the thrust's column), and the
    message named a one-symbol f entry instead."""
    from dfeif_codegen.symbolic.flatness import _say
    text = """
[model]
name = "g_heavy"
ts = 0.01
[[states]]
name = "x"
[[states]]
name = "v"
[[inputs]]
name = "T"
[[parameters]]
name = "m"
value = 1.0
[dynamics.f]
x = "v"
v = "-m"
[dynamics.g.T]
v = "cos(x)*sin(v)*cos(x + v)/m"
[[outputs]]
name = "x"
expr = "x"
[measurement.noise]
x = 0.001
"""
    told = []
    _say(model.loads_toml(text, "g.toml"), told.append)("solving")
    assert told == ["solving; largest expression g.toml:18: dynamics.g.T.v"]   # the text opens with a newline


def test_names_sympy_would_read_as_constants_are_the_users(tmp_path):
    """A parameter named e (a restitution), E (a Young's modulus), t or pi is the declared value:
    declared names shadow the expression constants, as [dynamics.definitions] already did. Checked
    against the closed form of the canonical model x'' = -(e + E + t + pi) x + u at the declared
    values (sum 10), not at Euler's number or pi."""
    path = tmp_path / "shadow.toml"
    params = "".join(f'[[parameters]]\nname = "{p}"\nvalue = {v}\n' for p, v in
                     (("e", 1.0), ("E", 2.0), ("t", 3.0), ("pi", 4.0)))
    path.write_text('[model]\nname = "shadow"\nts = 0.01\n[[states]]\nname = "x"\n[[states]]\nname = "xd"\n'
                    f'[[inputs]]\nname = "u"\n{params}[dynamics.f]\nx = "xd"\nxd = "-(e + E + t + pi)*x"\n'
                    '[dynamics.g.u]\nxd = "1"\n[[outputs]]\nname = "y"\nexpr = "x"\n')
    flat = flatness.derive(model.load(str(path)))
    zeta = np.array([0.3, -0.2])
    assert flat.F_num(zeta)[0] == pytest.approx(-10.0 * 0.3, rel=1e-15)
    assert flat.G_num(zeta)[0, 0] == 1.0


def test_coulomb_friction_sign_is_the_models_everywhere(tmp_path):
    """sign(v) in the dynamics (Coulomb friction): sympy's simplify and solve write it as a
    Piecewise (sign(v) = v/|v| off 0), which the toolkit once could neither print nor evaluate
    (the build stopped, and Φ⁻¹ was refused as "not determined by the flat outputs"). Checked
    against the closed forms: f̄ = (k/(J L))(u-side terms aside) at points on both sides of v = 0
    and at v = 0 itself, and Φ⁻¹(Φ(x)) = x there, in double and in the float32 walk."""
    path = tmp_path / "coulomb.toml"
    path.write_text('[model]\nname = "coulomb"\nts = 0.01\n'
                    + "".join(f'[[states]]\nname = "{s}"\nmin = -3.0\nmax = 3.0\n' for s in ("x", "v", "I"))
                    + '[[inputs]]\nname = "u"\n'
                    + "".join(f'[[parameters]]\nname = "{p}"\nvalue = {val}\n'
                              for p, val in (("c", 0.4), ("k", 2.0), ("J", 0.5), ("R", 1.0), ("L", 0.1)))
                    + '[dynamics.f]\nx = "v"\nv = "(k*I - c*sign(v))/J"\nI = "-R*I/L"\n'
                    '[dynamics.g.u]\nI = "1/L"\n[[outputs]]\nname = "y"\nexpr = "x"\n')
    flat = flatness.derive(model.load(str(path)))
    for x in ([0.2, 0.7, -0.3], [-1.0, -0.4, 1.1], [0.5, 0.0, 0.8]):
        v, current = x[1], x[2]
        accel = (2.0 * current - 0.4 * np.sign(v)) / 0.5
        zeta = np.array([x[0], v, accel])
        assert np.allclose(flat.phi_num(np.array(x)), zeta, rtol=1e-14, atol=1e-15)
        assert np.allclose(flat.phi_inv_num(zeta), x, rtol=1e-13, atol=1e-14)
        # d accel / dt = (k/J) I' = (k/J)(-R I / L + u / L), the sign's derivative 0 off v = 0
        assert flat.F_num(zeta)[0] == pytest.approx(2.0 / 0.5 * (-current / 0.1), rel=1e-13)
        assert flat.G_num(zeta)[0, 0] == pytest.approx(2.0 / 0.5 / 0.1, rel=1e-13)
    from dfeif_codegen.symbolic import numeric
    s = sp.Symbol("s")
    piece = sp.Piecewise((0, sp.Eq(s, 0)), (s / sp.Abs(s), True))
    values = np.array([-2.0, 0.0, 3.0], dtype=np.float32)
    with np.errstate(all="ignore"):   # np.where computes s/|s| at 0 too, then drops it
        assert list(numeric.to_casadi(piece, {s: values}, ops=numeric.Float32)) == [-1.0, 0.0, 1.0]


def test_a_reference_stepping_over_a_singular_set_is_named(tmp_path):
    """G = cos θ vanishes at θ = π/2. A reference sampled at 1.50, 1.53, ... never lands within
    1e-6 of it (|cos| ≥ 0.011 at every sample) but crosses it between two samples: the row
    after the crossing (where cos θ first turns negative) is the one named, and a reference that
    stays on one side passes."""
    path = tmp_path / "vanish.toml"
    path.write_text('[model]\nname = "vanish"\nts = 0.01\n[[states]]\nname = "th"\nmin = -2.0\nmax = 2.0\n'
                    '[[states]]\nname = "w"\n[[inputs]]\nname = "u"\n[dynamics.f]\nth = "w"\nw = "-sin(th)"\n'
                    '[dynamics.g.u]\nw = "cos(th)"\n[[outputs]]\nname = "y"\nexpr = "th"\n')
    flat = flatness.derive(model.load(str(path)))
    theta = 1.50 + 0.03 * np.arange(6)
    rows = np.column_stack([theta, np.zeros_like(theta)])
    assert np.all(np.abs(np.cos(theta)) > 0.01)
    k, what = flat.undefined_at(rows)
    assert k == int(np.argmax(np.cos(theta) < 0)) == 3
    assert "changes sign" in what
    assert flat.undefined_at(rows[:3]) is None


def test_a_recover_that_does_not_give_the_output_back_is_refused(tmp_path):
    """The cameras observe pa = x1 and pb = a sin(x2) of the output y = x1 + a sin(x2). The
    right recover (pa + pb) derives; one that drops a channel (pa) built and ran before, every
    filter then fusing x1 for y and diverging. It is refused, naming the entry, at a sampled
    state where the two differ by a sin(x2) ≠ 0."""
    def written(recover: str) -> Path:
        path = tmp_path / f"obs{len(recover)}.toml"
        path.write_text('[model]\nname = "obs"\nts = 0.01\n'
                        + "".join(f'[[states]]\nname = "{s}"\nmin = -2.0\nmax = 2.0\n' for s in ("x1", "x2", "x3"))
                        + '[[inputs]]\nname = "u"\n[[parameters]]\nname = "a"\nvalue = 0.3\n'
                        '[dynamics.f]\nx1 = "x2 - a*cos(x2)*x3"\nx2 = "x3"\nx3 = "-2*x3"\n[dynamics.g.u]\nx3 = "1"\n'
                        '[[outputs]]\nname = "y"\nexpr = "x1 + a*sin(x2)"\n[measurement.observe]\npa = "x1"\n'
                        f'pb = "a*sin(x2)"\n[measurement.noise]\npa = 0.001\npb = 0.001\n'
                        f'[measurement.recover]\ny = "{recover}"\n')
        return path
    flat = flatness.derive(model.load(str(written("pa + pb"))))
    assert flat.n == 3
    with pytest.raises(ModelError) as err:
        flatness.derive(model.load(str(written("pa"))))
    text = str(err.value)
    assert "measurement.recover.y" in text and "does not give the flat output y back" in text
    x2 = float(text.split("x2 = ")[1].split(",")[0])
    got, want = (float(v) for v in (text.split("it gives ")[1].split(",")[0], text.split("y = ")[-1]))
    assert want - got == pytest.approx(0.3 * np.sin(x2), rel=1e-3, abs=1e-3)
