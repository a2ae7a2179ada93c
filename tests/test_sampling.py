"""The held-input predictor's build-time constants and mean map (symbolic/sampling.py,
reference/predictor.py) against independent methods: scipy's matrix exponential, the Brunovsky
closed forms (the constants with L₀ = 0 must reduce to them), quadrature of the Van Loan
integral, and a tight-tolerance ODE solution of the same canonical model."""

from functools import lru_cache
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import sympy as sp
from scipy.integrate import quad_vec, solve_ivp
from scipy.linalg import expm as scipy_expm

from dfeif_codegen.errors import ModelError
from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.symbolic import discretize, flatness, model, sampling
from dfeif_codegen.symbolic.flatness import nominal_state

MODELS = ("dc_motor_link", "two_link_arm")


@lru_cache(maxsize=None)
def flat_system(name):
    return flatness.derive(model.load(name))


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def test_expm_equals_scipy_on_random_and_stiff_matrices():
    rng = np.random.default_rng(0)
    for scale in (1e-3, 1.0, 30.0):
        M = scale * rng.standard_normal((5, 5))
        # scaling and squaring in double: ~ (squarings) ε ‖e^M‖ on both sides
        assert rel(sampling.expm(M), scipy_expm(M)) < 1e-12
    A = sampling.held_sampling(flat_system("dc_motor_link"), 0.01).A * 0.01   # a fast stable mode
    assert rel(sampling.expm(A), scipy_expm(A)) < 1e-12


@pytest.mark.parametrize("degrees", [[3], [2, 3], [4, 1]])
def test_constants_reduce_to_the_brunovsky_closed_forms_when_L0_is_zero(degrees):
    """With L₀ = 0, A = A_c: E = A_d, Γ₁ = B_d (∫ e^{A_c s} B_c ds), Γ₂ = ∫ e^{A_c (h-s)} B_c s ds / h
    and U_j the chain's Q_d for unit density (discretize.py's closed forms)."""
    ts = 0.03
    Ac, Bc, _ = discretize.brunovsky(degrees)
    m, n = len(degrees), sum(degrees)
    H = sampling.assemble(Ac, Bc, np.zeros((m, n)), np.zeros(n), np.zeros(m), ts)
    Ad, Bd, _ = discretize.discrete(degrees, ts)
    assert np.allclose(H.E, Ad, rtol=0, atol=1e-15) and np.allclose(H.G1, Bd, rtol=1e-13, atol=1e-18)
    G2 = quad_vec(lambda s: scipy_expm(Ac * (ts - s)) @ Bc * s, 0, ts, epsabs=1e-16)[0] / ts
    assert rel(H.G2, G2) < 1e-12
    assert rel(H.Q(np.arange(1.0, m + 1)), discretize.process_noise(degrees, ts, np.arange(1.0, m + 1))) < 1e-12


@pytest.mark.parametrize("name", MODELS)
def test_noise_matches_quadrature_and_stays_accurate_over_many_periods(name):
    """U_j by quadrature of e^{A s} b bᵀ e^{Aᵀ s}; over 32 periods the plain Van Loan exponential
    would cancel (e^{-A t} of the fast mode), the doublings must not."""
    H = sampling.held_sampling(flat_system(name), 0.01)
    for steps in (1, 32):
        t = steps * H.ts
        for j in range(H.Bc.shape[1]):
            b = H.Bc[:, j]
            want = quad_vec(lambda s: (lambda e: np.outer(e, e))(scipy_expm(H.A * s) @ b), 0, t,
                            epsabs=0, epsrel=1e-13, limit=400)[0]
            assert rel(H.ahead(steps).U[j], want) < 1e-9, (steps, j)
        # and the noise of N periods is the sum of N one-period noises through E
        Q1, E = H.Q(1.0), H.E
        acc = np.zeros_like(Q1)
        for _ in range(steps):
            acc = E @ acc @ E.T + Q1
        assert rel(H.ahead(steps).Q(1.0), acc) < 1e-10


@lru_cache(maxsize=None)
def _tight_steps(name, ts):
    """Canonical states along a closed-loop-like input sequence and, for each, the exact state one
    period later with u held (DOP853 at rtol 1e-12)."""
    flat = flat_system(name)
    top = sampling.remainder_function(flat)
    Ac, Bc, _ = flat.canonical()
    p = flat.param_vector
    rng = np.random.default_rng(7)
    zeta0, u0 = sampling.nominal_point(flat)
    out = []
    for _ in range(12):
        x = nominal_state(flat.model) + rng.normal(0, 0.3, flat.n)
        z = flat.phi_num(x)
        u = u0 + rng.normal(0, 2.0, flat.m)
        end = solve_ivp(lambda t, s: Ac @ s + Bc @ np.asarray(top(s, u, p)[0]).ravel(), (0, ts), z,
                        method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
        out.append((z, u, end))
    return out


@pytest.mark.parametrize("name", MODELS)
def test_mean_map_is_second_order_exact_sampling_of_the_held_input(name):
    """One period against the tight ODE solution of the same canonical model with u held, at Ts
    and Ts/2: far below the Brunovsky model's error (which holds v instead of u), and shrinking
    with the period faster than first order overall (the fast stable mode's components reduce the
    order of the top derivative's error, as usual for exponential integrators on stiff parts)."""
    flat = flat_system(name)
    errs = {}
    for ts in (0.01, 0.005):
        pred = predictors.make("held", flat, ts, 1.0)
        bru = predictors.make("brunovsky", flat, ts, 1.0)
        e_held, e_bru = [], []
        for z, u, end in _tight_steps(name, ts):
            v = flat.F_num(z) + flat.G_num(z) @ u
            e_held.append(np.abs(pred.mean(z, u) - end))
            e_bru.append(np.abs(bru.mean(z, v) - end))
        errs[ts] = np.max(e_held, axis=0)
        # at least 30 times more exact than holding v, on every state
        assert np.all(errs[ts] * 30 < np.max(e_bru, axis=0)), (errs[ts], np.max(e_bru, axis=0))
    ratio = errs[0.01] / errs[0.005]
    print(f"\n{name}: held mean, worst one-step error at Ts = 0.01 {errs[0.01]}, ratio to Ts/2 {ratio}")
    assert np.linalg.norm(errs[0.01]) / np.linalg.norm(errs[0.005]) > 2.5, ratio


def test_linearization_point_can_be_moved_and_is_reported_when_undefined():
    flat = flat_system("dc_motor_link")
    base = sampling.held_sampling(flat, 0.01)
    moved = sampling.held_sampling(flat, 0.01, x=[0.7, 0.0, 0.0])
    # F has -(R m g l / (J L)) sin ζ₀ - (m g l / J) cos(ζ₀) ζ₁: its derivative in ζ₀ scales by cos 0.7
    assert moved.L0[0, 0] == pytest.approx(base.L0[0, 0] * np.cos(0.7), rel=1e-12)
    assert base.u0 == pytest.approx([0.0], abs=1e-12)   # the nominal state is an equilibrium
    with pytest.raises(ModelError, match="cannot be linearized"):
        sampling.held_sampling(flat, 0.01, x=[0.0, 0.0, np.nan])


def test_retrodiction_needs_the_brunovsky_predictor():
    with pytest.raises(ValueError, match="--oosm retrodict needs --predictor brunovsky"):
        predictors.check("held", "retrodict")
    with pytest.raises(ValueError, match="predictor must be one of held, scheduled, brunovsky"):
        predictors.check("rk4")
    predictors.check("brunovsky", "retrodict")


def test_second_stage_sines_by_angle_addition_are_libm_s_within_their_truncation():
    """TrigCarry's sin(α + δ), cos(α + δ) from sin α, cos α against numpy's sin and cos of the
    sum: within a few ulp while the Taylor truncation |δ|¹³/13! is below rounding (|δ| ≤ 0.25),
    and within that bound beyond (0.6 rad: 2e-13, 1 rad: 1.6e-10). The operands are exact doubles, so numpy's
    sin and cos (accurate to about 1 ulp) are the oracle; 8 ulp covers the sum of a few roundings."""
    th = sp.Symbol("th")
    a, b = ca.SX.sym("a"), ca.SX.sym("b")
    carry = sampling.TrigCarry([th])
    carry.first(sp.sin, th, a)
    f = ca.Function("f", [a, b], [carry.second(sp.sin, th, b), carry.second(sp.cos, th, b)])
    alpha = np.linspace(-4.0, 4.0, 41)
    ulp8 = 8 * 2.2e-16
    for delta, tol in ((1e-3, ulp8), (0.05, ulp8), (-0.25, ulp8), (0.6, 0.6 ** 13 / 6227020800 + 1e-15),
                       (1.0, 1 / 6227020800 + 1e-15)):
        s, c = (np.array(v).ravel() for v in f(alpha, alpha + delta))
        assert np.max(np.abs(s - np.sin(alpha + delta))) <= tol, delta
        assert np.max(np.abs(c - np.cos(alpha + delta))) <= tol, delta
    # an argument without a state is the same at both stages: the first stage's value, no polynomial
    k = sp.Symbol("k")
    carry.first(sp.cos, k, ca.SX(0.3))
    assert float(carry.second(sp.cos, k, ca.SX(0.3))) == np.cos(0.3)


@pytest.mark.parametrize("name", ("dc_motor_link", "two_link_arm", "pvtol"))
def test_carried_sines_change_the_etd2rk_step_by_rounding_only(name):
    """The mean map (trigonometric functions of the second stage carried from the first) against
    the same ETD2RK step with every sine and cosine from libm, written here from
    remainder_function: equal to 1e-13 relative (or 1e-12 of the state's scale) at states and
    inputs that move an angle by up to ~0.1 rad in a period, where the truncation (< 1e-18) is
    far below rounding and the rest is the reordered sums' rounding (~ 10 ulp times the terms'
    cancellation in F, measured 1.2e-14 on the arm)."""
    flat = flat_system(name)
    H = sampling.held_sampling(flat, flat.model.ts)
    n = len(H.A)
    z, u, p = ca.SX.sym("z", n), ca.SX.sym("u", flat.m), ca.DM(flat.param_vector)
    carried = ca.Function("carried", [z, u], [sampling.held_increment_sx(flat, H, z, z, u, p)])
    top = sampling.remainder_function(flat)
    v0 = top(z, u, p)[0]
    d = ca.mtimes(ca.DM(H.Psi), ca.mtimes(ca.DM(H.Ac), z) + ca.mtimes(ca.DM(H.Bc), v0))
    step = d + ca.mtimes(ca.DM(H.G2), top(z + d, u, p)[0] - v0 - ca.mtimes(ca.DM(H.L0), d))
    plain = ca.Function("plain", [z, u], [step])
    rng = np.random.default_rng(3)
    u0 = sampling.nominal_point(flat)[1]
    for _ in range(40):
        zz = flat.phi_num(nominal_state(flat.model) + rng.normal(0, 3.0, len(nominal_state(flat.model))))
        uu = u0 + rng.normal(0, 1.0, flat.m)
        got, want = (np.array(f(zz, uu)).ravel() for f in (carried, plain))
        scale = np.maximum(np.abs(want), 1e-12 * np.max(np.abs(zz)))
        assert np.max(np.abs(got - want) / scale) < 1e-13, (zz, uu)


# tests/data/pmsm.toml: a permanent-magnet synchronous motor in its rotor frame, the rotor angle
# and the d current flat (relative degrees 3 and 1). The currents' pole, R/L = 800 rad/s, is fast
# against Ts = 1 ms, and the speed multiplies the currents (p w L i terms): within a period the
# remainder moves with the currents' transient, which one ETD2RK step resolves to a few digits.
PMSM = (Path(__file__).parent / "data" / "pmsm.toml").read_text()


def test_mean_substeps_converge_to_the_held_input_solution_at_second_order():
    """[model] mean_substeps = N takes N ETD2RK steps of Ts/N per period: against DOP853 at rtol
    1e-12 on the same canonical model with u held, the worst one-step error falls about 4x per
    doubling of N (second order: N steps of local error C (Ts/N)^3); at least 3x is asserted,
    the margin for the stiff mode's order reduction. And N steps are exactly the single step at
    Ts/N composed N times (the constants are the shorter period's), to rounding."""
    rng = np.random.default_rng(3)
    assert "\nts = 0.001\n" in PMSM
    flats = {n: flatness.derive(model.loads_toml(PMSM.replace("\nts = 0.001\n", f"\nts = 0.001\nmean_substeps = {n}\n")))
             for n in (1, 2, 4, 8)}
    flat = flats[1]
    top = sampling.remainder_function(flat)
    Ac, Bc, _ = flat.canonical()
    p = flat.param_vector
    cases = []
    for _ in range(8):
        x = np.array([rng.normal(0, 0.5), rng.normal(0, 20.0), rng.normal(0, 2.0), rng.normal(0, 2.0)])
        z, u = flat.phi_num(x), rng.normal(0, 5.0, 2)
        end = solve_ivp(lambda t, s: Ac @ s + Bc @ np.asarray(top(s, u, p)[0]).ravel(), (0, 0.001), z,
                        method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1]
        cases.append((z, u, end))
    scale = np.max([np.abs(end - z) for z, _, end in cases], axis=0)   # a period's change, per state
    worst = {}
    for n, fl in flats.items():
        pred = predictors.make("held", fl, 0.001, 1.0)
        worst[n] = max(np.max(np.abs(pred.mean(z, u) - end) / scale) for z, u, end in cases)
    print("\nworst one-step error over a period's change, N = 1, 2, 4, 8:", worst)
    for n in (1, 2, 4):
        assert worst[n] / worst[2 * n] > 3.0, worst
    assert worst[1] > 1e-4 and worst[8] < worst[1] / 40     # a few digits, then most of them
    short = predictors.make("held", flat, 0.001 / 4, 1.0)
    for z, u, _ in cases:
        composed = z
        for _ in range(4):
            composed = short.mean(composed, u)
        four = predictors.make("held", flats[4], 0.001, 1.0).mean(z, u)
        assert np.all(np.abs(four - composed) <= 1e-12 * scale + 1e-15 * np.abs(composed))
