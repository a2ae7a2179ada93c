"""Flatness-based control: the gains are the chosen polynomial, `u` makes F + G u equal the
commanded v, and on a perfect model the tracking error follows the closed-form solution of the
linear error ODE with every pole at -lam."""

from functools import lru_cache
from math import comb, factorial

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dfeif_codegen.symbolic import flatness, model
from dfeif_codegen.reference.control import FlatController, hurwitz_gains

MODELS = ("dc_motor_link", "two_link_arm")


@lru_cache(maxsize=None)
def flat_system(name):
    return flatness.derive(model.load(name))


@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
@pytest.mark.parametrize("lam", [0.5, 3.0, 40.0])
def test_hurwitz_gains_are_the_coefficients_of_the_repeated_pole(degree, lam):
    want = np.poly(np.full(degree, -lam))[1:]
    # binomials times powers of lam: exact integers up to lam^r rounding, a few ulps
    assert np.allclose(hurwitz_gains(degree, lam), want, rtol=1e-9, atol=0)


def test_gains_layout_and_explicit_gains():
    flat = flat_system("two_link_arm")
    ctrl = FlatController(flat, poles=[2.0, 5.0])
    assert np.array_equal(ctrl.gains, [6, 12, 8, 15, 75, 125])      # chain by chain, k_1 .. k_r
    explicit = FlatController(flat, gains=ctrl.gains)
    x, ref = np.linspace(-0.4, 0.7, 6), np.linspace(0.3, -0.2, 8)
    assert all(np.array_equal(a, b) for a, b in zip(ctrl(x, ref), explicit(x, ref)))
    with pytest.raises(ValueError):
        FlatController(flat, poles=-1.0)


@pytest.mark.parametrize("name", MODELS)
def test_input_reproduces_the_commanded_v(name):
    flat, rng = flat_system(name), np.random.default_rng(0)
    ctrl = FlatController(flat, poles=4.0)
    for _ in range(50):
        x = rng.uniform(-1.5, 1.5, flat.n) * np.tile([1, 3, 20], flat.m)
        u, v = ctrl(x, rng.uniform(-2, 2, flat.n + flat.m))
        top = flat.F_num(x) + flat.G_num(x) @ u
        # F + G u = v after one solve with G (cond < 1e3 on this box): the residual of a backward
        # stable solve is ~n eps (|F| + |v|), so 1e-12 of that scale holds on any IEEE machine
        assert np.abs(top - v).max() <= 1e-12 * (np.abs(flat.F_num(x)).max() + np.abs(v).max())


def reference(t, degree, amp, omega, bias):
    """y_d = bias + amp sin(omega t) and its first `degree` derivatives."""
    return np.array([(bias if k == 0 else 0.0) + amp * omega ** k * np.sin(omega * t + k * np.pi / 2)
                     for k in range(degree + 1)])


def error_closed_form(t, e0, lam):
    """Solution of (d/dt + lam)^r e = 0: e = exp(-lam t) p(t), p of degree r-1 fitted to the
    initial derivatives; returns [e, e', ..., e^(r-1)] at t."""
    r = len(e0)
    # e^(k)(0) = sum_i C(k,i) (-lam)^(k-i) i! c_i, lower triangular in the coefficients c_i
    T = np.array([[comb(k, i) * (-lam) ** (k - i) * factorial(i) if i <= k else 0.0 for i in range(r)]
                  for k in range(r)])
    c = np.linalg.solve(T, e0)
    p_deriv = [sum(c[l] * factorial(l) / factorial(l - i) * t ** (l - i) for l in range(i, r)) for i in range(r)]
    return np.exp(-lam * t) * np.array([sum(comb(k, i) * (-lam) ** (k - i) * p_deriv[i] for i in range(k + 1))
                                        for k in range(r)])


@pytest.mark.parametrize("name", MODELS)
def test_tracking_error_follows_the_chosen_poles(name):
    """Canonical model integrated with the plant's own F + G u (perfect model)."""
    flat = flat_system(name)
    lams = [3.0, 6.0][:flat.m]
    ctrl = FlatController(flat, poles=lams)
    Ac, Bc, _ = flat.canonical()
    refs = [(0.4, 1.5, 0.2), (0.3, 2.0, -0.5)][:flat.m]

    def flags(t):
        return np.concatenate([reference(t, c.degree, *r) for c, r in zip(flat.chains, refs)])

    def rhs(t, zeta):
        u, _ = ctrl(zeta, flags(t))
        return Ac @ zeta + Bc @ (flat.F_num(zeta) + flat.G_num(zeta) @ u)

    zeta0 = np.concatenate([[0.5, -0.4, 1.0][:c.degree] for c in flat.chains])
    times = np.linspace(0, 3, 31)
    sol = solve_ivp(rhs, (0, 3), zeta0, t_eval=times, method="DOP853", rtol=1e-11, atol=1e-11)
    assert sol.success
    worst = 0.0
    for j, (c, lam) in enumerate(zip(flat.chains, lams)):
        span = slice(c.offset, c.offset + c.degree)
        e0 = zeta0[span] - flags(0.0)[c.offset + j:c.offset + j + c.degree]
        for t, zeta in zip(times, sol.y.T):
            e = zeta[span] - flags(t)[c.offset + j:c.offset + j + c.degree]
            worst = max(worst, np.abs(e - error_closed_form(t, e0, lam)).max() / np.abs(e0).max())
    # DOP853 at rtol = atol = 1e-11 over 3 s: global error ~1e-10 relative to |e0|; 1e-7 leaves
    # three orders for the error ODE's growth (poles at -lam, so it only decays)
    assert worst < 1e-7


@pytest.mark.parametrize("name", MODELS)
def test_held_input_gives_the_top_derivatives_the_increment_of_v(name):
    """The held law's u, held over Ts on the physical plant (integrated by DOP853, an independent
    oracle), moves each chain's top derivative by Ts v, the increment the chapter's model gives it;
    the chapter's u = G^-1 (v - F) misses it where the dynamics are fast against Ts."""
    import sympy as sp
    from dfeif_codegen.symbolic import sampling
    flat, rng = flat_system(name), np.random.default_rng(3)
    ts, mdl = flat.model.ts, flat.model
    H = sampling.held_sampling(flat, ts)
    laws = {"held": FlatController(flat, poles=10.0, held=H), "chapter": FlatController(flat, poles=10.0)}
    rhs = sp.lambdify((list(mdl.x), list(mdl.u)), list((mdl.f + mdl.g * mdl.u).subs(mdl.param_values)), "numpy")
    tops = [c.offset + c.degree - 1 for c in flat.chains]
    worst = {"held": 0.0, "chapter": 0.0}
    for _ in range(10):
        x0 = flat.phi_inv_num(H.zeta0) + rng.normal(0, 0.1, flat.n) * np.tile([1, 3, 20], flat.m)[:flat.n]
        z = flat.phi_num(x0)
        ref = np.concatenate([np.r_[z[c.offset:c.offset + c.degree], 0.0] + rng.normal(0, 0.05, c.degree + 1)
                              for c in flat.chains])
        for key, law in laws.items():
            u, v = law(z, ref)
            sol = solve_ivp(lambda t, x: np.asarray(rhs(x, u), float).ravel(), (0, ts), x0, method="DOP853",
                            rtol=1e-12, atol=1e-12)
            gained = (flat.phi_num(sol.y[:, -1]) - z)[tops]
            scale = ts * (np.abs(v).max() + np.abs(flat.F_num(z)).max())
            worst[key] = max(worst[key], np.abs(gained - ts * v).max() / scale)
    # ETD2RK's local error is third order: relative to the increment O(Ts^2) = 1e-4 times the
    # dynamics' curvature (measured 5e-7 motor, 6e-4 arm); the integration's own 1e-12 is far below
    assert worst["held"] < 2e-3
    assert worst["held"] < worst["chapter"] / 20       # measured: 0.02 and 0.10 for the chapter's law


def test_held_law_is_the_chapters_without_a_linear_term():
    """s'' = F: F + G u has no linear part, A = A_c, and the held law is u = G^-1 (v - F) = v."""
    from pathlib import Path
    from dfeif_codegen.symbolic import sampling
    flat = flatness.derive(model.load(str(Path(__file__).parent / "data" / "free_cart.toml")))
    held = FlatController(flat, poles=2.0, held=sampling.held_sampling(flat, flat.model.ts))
    rng = np.random.default_rng(5)
    for _ in range(20):
        x, ref = rng.normal(size=2), rng.normal(size=3)
        u, v = held(x, ref)
        # the solve with S Γ₁ G = Ts (a constant): u = Ts v / Ts, one rounding of each
        assert abs(u[0] - v[0]) <= 4e-16 * abs(v[0]) + 1e-300
