"""Disturbance states (symbolic/disturbance.py, scenario [disturbance]): the augmented constants
against closed forms, and an oracle run: a plant whose input carries a constant unknown bias,
integrated by a tight ODE solver, measured through its flat outputs. The held filter without
disturbance states keeps a steady bias on each chain's top state; with a random-walk state per
chain it estimates the bias (G times the input offset) and the top state's bias goes."""

from functools import lru_cache

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from dfeif_codegen.experiment import scenario
from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.reference.node import NodeFilter
from dfeif_codegen.symbolic import flatness, model, sampling
from dfeif_codegen.symbolic.disturbance import Disturbance, augment

TS = 0.01


@lru_cache(maxsize=None)
def flat_system(name):
    return flatness.derive(model.load(name))


@pytest.mark.parametrize("kind,tau", [("random_walk", None), ("gauss_markov", 0.5)])
def test_augmented_transition_is_the_exponential_of_the_extended_dynamics(kind, tau):
    """Φ₀ = e^{A Ts} of A = [[A_c + B_c L₀, B_c], [0, D]] (scipy's expm), and the disturbance's own
    noise block equals the scalar closed form: q Ts (random walk), q tau/2 (1 - e^{-2 Ts/tau})."""
    flat = flat_system("dc_motor_link")
    dist = Disturbance(kind, (3.0,), tau)
    H = sampling.held_sampling(flat, TS, disturbance=dist)
    base = sampling.held_sampling(flat, TS)
    n, m = flat.n, flat.m
    A = np.zeros((n + m, n + m))
    A[:n, :n], A[:n, n:], A[n:, n:] = base.A, base.Bc, dist.drift(m)
    # two scaling-and-squaring exponentials of a matrix with a fast mode (|A Ts| ~ 150): each is
    # accurate to ~ 2^s eps of its norm, s ~ 10 squarings; 1e-11 of the norm on any IEEE machine
    scale = np.abs(H.E).max()
    assert np.abs(H.E - expm(A * TS)).max() < 1e-11 * scale
    assert np.abs(H.E[:n, :n] - base.E).max() < 1e-11 * scale
    Q = H.Q(0.0, 3.0)
    want = 3.0 * TS if tau is None else 3.0 * tau / 2 * (1 - np.exp(-2 * TS / tau))
    assert abs(Q[n, n] - want) < 1e-12 * want
    assert np.allclose(H.Q(5.0, 0.0)[:n, :n], base.Q(5.0), rtol=1e-12, atol=0)


def test_integrated_random_walk_block_is_its_closed_form():
    """d̈ = w: the disturbance block of Φ₀ is [[1, Ts], [0, 1]] and its noise q [[Ts³/3, Ts²/2],
    [Ts²/2, Ts]] (the integrals of a white d̈ over one period); d enters the top derivative as
    the random walk's does, so Φ₀ is e^{A Ts} of the extended A (scipy's expm)."""
    flat = flat_system("dc_motor_link")
    dist = Disturbance("integrated_random_walk", (3.0,))
    H = sampling.held_sampling(flat, TS, disturbance=dist)
    base = sampling.held_sampling(flat, TS)
    n = flat.n
    A = np.zeros((n + 2, n + 2))
    A[:n, :n], A[:n, n:n + 1], A[n, n + 1] = base.A, base.Bc, 1.0
    scale = np.abs(H.E).max()     # as above: 1e-11 of the norm for two scaling-and-squaring expm's
    assert np.abs(H.E - expm(A * TS)).max() < 1e-11 * scale
    assert np.abs(H.E[n:, n:] - [[1.0, TS], [0.0, 1.0]]).max() < 1e-15
    Q = H.Q(0.0, 3.0)[n:, n:]
    want = 3.0 * np.array([[TS ** 3 / 3, TS ** 2 / 2], [TS ** 2 / 2, TS]])
    assert np.abs(Q - want).max() < 1e-12 * want.max()
    x0, P0 = augment(np.zeros(n), np.eye(n), dist, 1)       # default start: 1 s of the density
    assert np.allclose(np.diag(P0)[n:], [3.0 / 3, 3.0], rtol=1e-15) and x0.shape == (n + 2,)


@pytest.mark.parametrize("tau", [0.05, 0.3])
def test_integrated_gauss_markov_block_is_its_closed_form(tau):
    """d̈ = -ḋ/tau + w (a = 1/tau): the disturbance block of Φ₀ is [[1, (1 - e^{-a Ts})/a], [0,
    e^{-a Ts}]] and its noise the integrals over one period of the impulse responses (1 -
    e^{-a t})/a of d and e^{-a t} of the rate, times q; the default start has the rate's
    stationary spread q tau/2. A second method: at tau = 1e6 s the block is the integrated
    random walk's to the limit's first order (a Ts = 1e-8)."""
    flat = flat_system("dc_motor_link")
    q, a, T, n = 3.0, 1.0 / tau, TS, flat.n
    H = sampling.held_sampling(flat, TS, disturbance=Disturbance("integrated_gauss_markov", (q,), tau))
    e1, e2 = -np.expm1(-a * T), -np.expm1(-2 * a * T)     # 1 - e^{-aT}, 1 - e^{-2aT} without cancelling
    # the extended exponential by scaling and squaring of a matrix with a fast mode (|A Ts| ~ 150):
    # 1e-11 of its norm on any IEEE machine, as in the tests above
    assert np.abs(H.E[n:, n:] - [[1.0, e1 / a], [0.0, 1.0 - e1]]).max() < 1e-11 * np.abs(H.E).max()
    want = q * np.array([[(T - 2 * e1 / a + e2 / (2 * a)) / a ** 2, (e1 - e2 / 2) / a ** 2],
                         [(e1 - e2 / 2) / a ** 2, e2 / (2 * a)]])
    # Q by Van Loan's exponential against the closed form: its d entry (q T³/3 ~ 1e-6 against the
    # 1-scale block) cancels ~ 1e4 of the closed form's terms, ~ 1e-12 relative on IEEE doubles
    assert np.abs(H.Q(0.0, q)[n:, n:] - want).max() < 1e-9 * want.max()
    assert abs(H.Q(0.0, q)[n, n] - want[0, 0]) < 1e-8 * want[0, 0]
    _, P0 = augment(np.zeros(n), np.eye(n), Disturbance("integrated_gauss_markov", (q,), tau), 1)
    assert np.allclose(np.diag(P0)[n:], [q / 3, q * tau / 2], rtol=1e-15)
    walk = sampling.held_sampling(flat, TS, disturbance=Disturbance("integrated_random_walk", (q,)))
    slow = sampling.held_sampling(flat, TS, disturbance=Disturbance("integrated_gauss_markov", (q,), 1e6))
    assert np.abs(slow.E - walk.E).max() < 1e-7 and np.abs(slow.Q(0.0, q) - walk.Q(0.0, q)).max() < 1e-7 * q * TS


def _biased_run(flat, bias, dist, steps=1500, seed=4, ramp=0.0):
    """A node filter on a plant whose input is u + bias (the model's u without it); returns the
    filter's estimates and the truth per step."""
    top = sampling.remainder_function(flat)
    Ac, Bc, _ = flat.canonical()
    p = flat.param_vector
    zeta, u0 = sampling.nominal_point(flat)
    rng = np.random.default_rng(seed)
    R = 1e-6
    x0, P0 = augment(zeta.copy(), np.diag(np.tile([1e-4, 1e-2, 1.0], flat.m)[:flat.n]), dist, flat.m)
    node = NodeFilter(flat, TS, 20.0, R, x0, P0, predictor="held", disturbance=dist)
    xs, truth = [], []
    for k in range(steps):
        node.update(zeta[flat.heads] + np.sqrt(R) * rng.standard_normal(flat.m), True)
        xs.append(node.x.copy())
        truth.append(zeta.copy())
        u = u0 + 0.5 * np.sin(2 * np.pi * k * TS / 2.0) * np.ones(flat.m)
        node.predict(u)
        off = bias + ramp * (k + 0.5) * TS          # a ramp: its midpoint over the period
        zeta = solve_ivp(lambda t, s: Ac @ s + Bc @ np.asarray(top(s, u + off, p)[0]).ravel(), (0, TS), zeta,
                         method="DOP853", rtol=1e-11, atol=1e-12).y[:, -1]
    return np.array(xs), np.array(truth)


def test_random_walk_state_removes_the_bias_of_a_constant_input_offset():
    flat = flat_system("dc_motor_link")
    bias = np.array([0.5])                        # V on the motor's 12 V scale
    gain = flat.G_num(sampling.nominal_point(flat)[0]) @ bias   # what it adds to theta''' (G constant here)
    top_state = flat.heads[0] + flat.degrees[0] - 1
    tail = slice(700, None)                       # after the transient (7 s)
    plain, truth = _biased_run(flat, bias, None)
    err_plain = np.mean(plain[tail, top_state] - truth[tail, top_state])
    with_d, truth_d = _biased_run(flat, bias, Disturbance("random_walk", (50.0,)))
    err_d = np.mean(with_d[tail, top_state] - truth_d[tail, top_state])
    d_est = np.mean(with_d[tail, flat.n])
    spread = np.std(with_d[tail, top_state] - truth_d[tail, top_state])
    print(f"\nbias of theta'': without d {err_plain:.3e}, with d {err_d:.3e} (spread {spread:.2e}); "
          f"d {d_est:.3f} against G*bias {gain[0]:.3f}")
    assert abs(err_plain) > 10 * abs(err_d)       # the steady bias is gone
    assert abs(err_d) < 0.2 * spread + 1e-9 or abs(err_d) < 0.05 * abs(err_plain)
    assert abs(d_est - gain[0]) < 0.05 * abs(gain[0])   # the disturbance state is the offset's effect


def test_integrated_random_walk_follows_a_ramping_input_offset_that_the_random_walk_lags():
    """An input offset growing at a constant rate: a random walk state follows it with a steady
    lag (its estimate trails a ramp by about rate / its bandwidth), the integrated random walk
    has no steady error on a ramp (a type-2 loop) and its rate state is G times the offset's rate."""
    flat = flat_system("dc_motor_link")
    rate = np.array([0.1])                        # V/s: 1.5 V over the 15 s run
    gain = flat.G_num(sampling.nominal_point(flat)[0]) @ rate
    top_state = flat.heads[0] + flat.degrees[0] - 1
    tail = slice(700, None)
    rw, truth_rw = _biased_run(flat, 0.0, Disturbance("random_walk", (50.0,)), ramp=rate)
    irw, truth_irw = _biased_run(flat, 0.0, Disturbance("integrated_random_walk", (50.0,)), ramp=rate)
    lag_rw = np.mean(rw[tail, top_state] - truth_rw[tail, top_state])
    lag_irw = np.mean(irw[tail, top_state] - truth_irw[tail, top_state])
    rate_est = np.mean(irw[tail, flat.n + 1])
    print(f"\nramp: theta'' bias with a random walk {lag_rw:.3e}, integrated {lag_irw:.3e}; "
          f"rate {rate_est:.3f} against G*rate {gain[0]:.3f}")
    assert abs(lag_irw) < 0.2 * abs(lag_rw)
    assert abs(rate_est - gain[0]) < 0.1 * abs(gain[0])


@pytest.mark.parametrize("table,words", [
    ('kind = "random_walk"\nq = -1.0', "disturbance.q: must be a number >= 0"),
    ('kind = "gauss_markov"\nq = 1.0\ntau = 0', "disturbance.tau: the Gauss-Markov time constant must be"),
    ('kind = "gauss_markov"\nq = 1.0\ntau = -2.0', "disturbance.tau: the Gauss-Markov time constant must be"),
    ('kind = "gauss_markov"\nq = 1.0', "disturbance.tau"),
    ('kind = "integrated_gauss_markov"\nq = 1.0', "disturbance.tau: the Gauss-Markov time constant must be"),
    ('kind = "integrated_random_walk"\nq = 1.0\ntau = 1.0', "disturbance.tau: applies to kind"),
    ('kind = "walk"\nq = 1.0', "disturbance.kind: must be one of random_walk, gauss_markov, integrated_random_walk"),
    ('kind = "integrated_random_walk"\nq = 0.0', "disturbance.p0_std: needed when a density"),
    ('kind = "random_walk"\nq = 1.0\ntau = 1.0', "disturbance.tau: applies to kind"),
    ('kind = "random_walk"\nqq = 1.0', "disturbance.qq: unknown field"),
])
def test_bad_disturbance_tables_are_one_line_errors_naming_the_field(table, words):
    with pytest.raises(ScenarioError) as err:
        scenario.loads(f"[disturbance]\n{table}\n", "s.toml")
    assert words in str(err.value) and "\n" not in str(err.value) and str(err.value).startswith("s.toml:")


@pytest.mark.parametrize("table,words", [
    ('kind = "random_walk"\nq = [1.0, 2.0, 3.0]', "disturbance.q: needs 1 or 2 values"),
    ('kind = "random_walk"\nq = 1.0\np0_std = [1.0, 2.0, 3.0, 4.0]', "disturbance.p0_std: needs 1 or 2 values"),
    ('kind = "integrated_random_walk"\nq = 1.0\np0_std = [1.0, 2.0, 3.0]', "needs 1 or 2 or 4 values"),
    ('kind = "integrated_random_walk"\nq = [0.0, 1.0]\np0_std = [1.0, 2.0]', "needs 4 values (the d's, then"),
])
def test_disturbance_tables_sized_for_another_model_are_refused_naming_the_field(table, words):
    """The two-chain arm: one density per chain, one initial std per state (the integrated
    random walk's rates too, and those are needed when a density is 0)."""
    sc = scenario.loads(f"[disturbance]\n{table}\n", "s.toml")
    with pytest.raises(ScenarioError) as err:
        sc.check_model(flat_system("two_link_arm"))
    assert words in str(err.value) and "\n" not in str(err.value) and str(err.value).startswith("s.toml")


def test_the_law_cancels_the_estimated_disturbance_under_model_error(monkeypatch):
    """dc_motor_link whose plant has R 20% above and J 20% below the model's, closed loops of 10 s
    (numpy engine): the held filter with random-walk disturbance states and the law that cancels
    them (u - G⁻¹ d) tracks θ more than 4x better than the same filter whose law ignores them,
    than the held filter without them and than the chapter's filter and law (measured: 1.0e-2
    against 6.4e-2 and 8.0e-2 for the last two)."""
    from dfeif_codegen.experiment import closed_loop as ex, model_error as me, recording

    base = dict(model="dc_motor_link", duration=10.0, poles=(10.0,), amplitude=(0.5,), seed=1, metrics_from=3.0,
                plant_error=me.from_option("R=0.2,J=-0.2"))
    held_d = dict(q=(5.74e-7,), disturbance=Disturbance("random_walk", (2.7e5,)), predictor="held")

    def theta_tracking(**kw) -> float:
        return float(ex.run(ex.Config(**base, **kw)).metrics["rmse_tracking"][0])

    cancelled = theta_tracking(**held_d)
    others = [theta_tracking(q=(20.0,), predictor="held", watch_nees=False),
              theta_tracking(q=(20.0,), predictor="brunovsky")]
    made = recording.FilterBank.__init__

    def ignoring(self, *args, **kwargs):
        made(self, *args, **kwargs)
        self.compensate = False
    monkeypatch.setattr(recording.FilterBank, "__init__", ignoring)
    others.append(theta_tracking(**held_d, watch_nees=False))
    print(f"\ntheta tracking RMSE: cancelled {cancelled:.2e}, others {others}")
    assert all(cancelled < other / 4 for other in others)
