"""The comparison's `scheduled` filter (reference/scheduled.py): the held mean with the covariance
moved by Φ(σ) = Φ₀ + Γ₁ (L(σ) - L₀), L taken at the nominal point with its flat-output entries
set to the master's broadcast flat outputs σ."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dfeif_codegen import cli
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import compare
from dfeif_codegen.experiment.network import Link
from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.reference.physical import ReplayNode
from dfeif_codegen.reference.scheduled import ScheduledModel
from dfeif_codegen.symbolic import sampling

MODEL = "two_link_arm"
BASE = dict(model=MODEL, duration=2.0, q=(3.48, 10.2), poles=(10.0,), noise_scale=(1.0, 1.25),
            metrics_from=0.5, seed=4, reference="sinusoid")
ON_TIME = (Link(0.0, 0), Link(0.0, 0))


def _step(model, z, u):
    return np.array(model.step_sx(z, np.concatenate([u, np.zeros(model.m)]))).ravel()


def _central_difference(step, point, h=1e-5):
    return np.column_stack([(step(point + h * e) - step(point - h * e)) / (2 * h) for e in np.eye(len(point))])


def test_transition_is_the_exponential_step_jacobian_at_the_broadcast_outputs():
    """Φ(σ) = Φ₀ + Γ₁ (L(σ) - L₀) against a central difference of the exponential-Euler step
    ζ + Ψ (A_c ζ + B_c (F + G u₀)) at the point ζ₀ with q1, q2 set to σ: the difference's
    truncation (h² ζ‴/6) and rounding (ε |ζ⁺| / h) are both below 1e-7 of a column's scale at
    h = 1e-5 on any IEEE machine. At the nominal it is Φ₀ (the same L evaluated twice: equal to
    rounding, 1e-12 of Φ₀'s scale). Away from it, it moves by more than Φ₀'s own scale at
    σ = (0.6, -0.8) and stays within 5% of that scale of the Jacobian of the held mean's
    second-order step (measured 1.7%): the first-order step's transition, at a third of the
    cost. It depends on σ only (not on the applied input, the first entries predict takes)."""
    flat = ex._flat(MODEL)
    model = ScheduledModel(flat, 0.01, (1.0, 1.0))
    H = predictors.held_constants(flat, 0.01)
    zeta0, u0 = sampling.nominal_point(flat)
    top = sampling.remainder_function(flat)
    sigma = np.array([0.6, -0.8])
    point = zeta0.copy()
    point[[0, 3]] = sigma
    Phi = np.array(model.transition_sx(np.concatenate([[5.0, -3.0], sigma])))

    def exponential_euler(z):
        return z + H.Psi @ (H.Ac @ z + H.Bc @ np.array(top(z, u0, flat.param_vector)[0]).ravel())
    fd = _central_difference(exponential_euler, point)
    for j in range(flat.n):
        np.testing.assert_allclose(Phi[:, j], fd[:, j], rtol=0, atol=1e-7 * np.abs(fd[:, j]).max())
    nominal = np.array(model.transition_sx(np.concatenate([u0, zeta0[[0, 3]]])))
    np.testing.assert_allclose(nominal, H.E, rtol=0, atol=1e-12 * np.abs(H.E).max())
    assert np.abs(Phi - H.E).max() > np.abs(H.E).max()
    held = _central_difference(lambda z: _step(model, z, u0), point)
    assert np.abs(Phi - held).max() <= 0.05 * np.abs(held).max()
    np.testing.assert_array_equal(Phi, np.array(model.transition_sx(np.concatenate([u0, sigma]))))


def test_master_equals_the_centralized_filter_without_delays():
    """Every frame on time and every packet fused: the information-difference master of the
    scheduled filters equals one filter taking all frames, because the nodes and the master move
    their covariances by the same Φ(σ) (σ the master's fused outputs). The two differ by rounding
    through the information matrices (cond(P) near 1e8 here, mrad against rad/s²), so the bound
    is 1e-8 of each state's spread rather than ε."""
    res = ex.run(ex.Config(**BASE, sensor=ON_TIME))
    rec = res.recording
    assert rec.gamma.all()
    out = compare.run_on_recording(rec, compare.SCHEDULED, q=(0.01, 0.03))
    filt = compare.filter_of(MODEL, float(rec.ts), (0.01, 0.03), 10, compare.SCHEDULED)
    x, P = rec.master_x0, rec.master_P0
    X = np.zeros((rec.ref.shape[0], rec.n))
    for k in range(rec.ref.shape[0]):
        for i in range(rec.nodes):
            if rec.gamma[i, k]:
                x, P = filt.update(x, P, rec.z[i, k], np.atleast_2d(rec.R[i]))
        X[k] = x
        x, P = filt.predict(x, P, filt.model.input(rec.u[k], x))
    spread = np.sqrt(np.diagonal(out["P"], axis1=1, axis2=2))
    assert np.all(np.abs(out["x"] - X) <= 1e-8 * spread)


def test_replay_keeps_the_broadcast_transition_of_each_step():
    """A node given step k0's frame three steps late ends where a node given it on time does:
    replay re-runs the steps with the (u, σ) each one received, so the late frame passes through
    the transitions of its own steps, not the current one. Same Kalman steps in the same order
    from the restored slot: equal to 1e-10 of each state's spread (rounding of a handful of
    6x6 products)."""
    res = ex.run(ex.Config(**BASE, sensor=ON_TIME))
    rec = res.recording
    filt = compare.filter_of(MODEL, float(rec.ts), (0.01, 0.03), 10, compare.SCHEDULED)
    on_time, late = (ReplayNode(filt, rec.R[0], rec.master_x0, rec.master_P0) for _ in range(2))
    k0, lag = 60, 3
    for k in range(k0 + lag + 1):
        on_time.update(rec.z[0, k], True)
        late.update(rec.z[0, k], k != k0)
        if k == k0 + lag:
            assert late.update_delayed([(rec.z[0, k0], lag)]) == [True]
        if k < k0 + lag:
            w = filt.model.input(rec.u[k], rec.x[k])
            on_time.predict(w)
            late.predict(w)
    spread = np.sqrt(np.diagonal(on_time.P))
    assert np.all(np.abs(late.x - on_time.x) <= 1e-10 * spread)
    np.testing.assert_allclose(late.P, on_time.P, rtol=1e-10, atol=0)
    # without the late frame the node would differ: the check can fail
    skipped = ReplayNode(filt, rec.R[0], rec.master_x0, rec.master_P0)
    for k in range(k0 + lag + 1):
        skipped.update(rec.z[0, k], k != k0)
        if k < k0 + lag:
            skipped.predict(filt.model.input(rec.u[k], rec.x[k]))
    assert np.abs(skipped.P - on_time.P).max() > 1e-6 * np.abs(on_time.P).max()


def test_simulate_runs_the_scheduled_filter_at_its_own_q(tmp_path, capsys):
    """`--filters df,scheduled` with the scenario's q_scheduled: the JSON records it, the table
    pairs the scheduled filter with the held one, and its operations are counted."""
    path = tmp_path / "arm.toml"
    path.write_text('[scenario]\nduration = 1.5\nruns = 1\nreferences = ["sinusoid"]\nbaselines = []\n'
                    'fusion = ["difference"]\n[filter]\nq = [3.48, 10.2]\nq_scheduled = [0.01, 0.03]\n'
                    '[[grid]]\nd = [0, 0]\np = 0.0\n')
    assert cli.main(["simulate", MODEL, "--scenario", str(path), "--quiet", "--filters", "df,scheduled",
                     "--json", "-"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["settings"]["q_scheduled"] == [0.01, 0.03]
    assert doc["settings"]["filters"] == ["df", "scheduled"]
    ops = doc["settings"]["operations"]
    assert ops["scheduled"]["update"] == ops["df"]["update"]          # the same Kalman update
    assert ops["scheduled"]["predict"] > ops["df"]["predict"]        # Φ(σ) is evaluated per step
    (paired,) = [p for p in doc["paired"] if p["filter"] == "scheduled"]
    assert paired["pairs"] == 1 and len(paired["mean"]) == 6


def test_calibration_matches_the_scheduled_filters_nees_to_n():
    """`codegen scenario --scheduled`'s stage: q_scheduled scaled from the held filter's q until
    the master NEES of loops the scheduled filter closes itself is n within NEES_TOL. Checked on
    those loops run again here at the q found (the same deterministic loops: the tolerance is the
    search's own); the first stage (the held filter's loops re-filtered) gave the start."""
    import math

    from dfeif_codegen.experiment import scheduled_calibration
    from dfeif_codegen.experiment.nees_match import NEES_SECONDS, NEES_TOL

    def config(q, seed, duration):
        return ex.Config(**{**BASE, "duration": duration, "seed": seed, "q": tuple(q)}, sensor=ON_TIME)

    flat, seeds, held = ex._flat(MODEL), [7, 8], np.array([3.48, 10.2])
    q, log = scheduled_calibration.q_scheduled(flat, held, config, seeds, [], lambda line: None)
    assert log[-1].startswith("the scheduled filter, on its own loops: ") and np.all(q < held / 10)
    own = scheduled_calibration.closed_by_scheduled(config)
    nees = np.mean([np.mean(ex.run(own(q, s, NEES_SECONDS)).metrics["nees_master"]) for s in seeds])
    assert abs(math.log(nees / flat.n)) <= math.log(NEES_TOL)
    assert any(line.startswith("the scheduled filter: ") for line in log)   # the first stage ran


def test_transition_with_disturbance_states_is_the_extended_step_jacobian():
    """With disturbance states (random walk and integrated random walk, one or two per chain after
    the canonical state) Φ(σ) is the central difference of the extended exponential-Euler step
    x + Ψ (A x + B_c (F + G u₀ - L₀ ζ)), A the extended A_c + B_c L₀ (the disturbances enter the
    top derivatives and drift by their own law), at ζ₀ with σ set and the disturbances away from 0:
    the same 1e-7 of a column's scale as the plain test above, for the same reasons. Its canonical
    block moves with σ, and at the nominal it is the held filter's extended Φ₀."""
    from dfeif_codegen.symbolic.disturbance import Disturbance
    flat = ex._flat(MODEL)
    zeta0, u0 = sampling.nominal_point(flat)
    top = sampling.remainder_function(flat)
    sigma = np.array([0.6, -0.8])
    for kind in ("random_walk", "integrated_random_walk"):
        dist = Disturbance(kind, (1.0, 1.0))
        model = ScheduledModel(flat, 0.01, (1.0, 1.0), dist)
        H = sampling.held_sampling(flat, 0.01, disturbance=dist)
        n = len(H.A)
        assert n == flat.n + dist.order * flat.m and model.n == n
        point = np.concatenate([zeta0, 0.3 * np.ones(n - flat.n)])
        point[[0, 3]] = sigma
        Phi = np.array(model.transition_sx(np.concatenate([[5.0, -3.0], sigma])))

        def exponential_euler(x):
            F = np.array(top(x[:flat.n], u0, flat.param_vector)[0]).ravel()
            return x + H.Psi @ (H.A @ x + H.Bc @ (F - H.L0 @ x))
        fd = _central_difference(exponential_euler, point)
        for j in range(n):
            np.testing.assert_allclose(Phi[:, j], fd[:, j], rtol=0, atol=1e-7 * np.abs(fd[:, j]).max())
        nominal = np.array(model.transition_sx(np.concatenate([u0, zeta0[[0, 3]]])))
        np.testing.assert_allclose(nominal, H.E, rtol=0, atol=1e-12 * np.abs(H.E).max())
        assert np.abs(Phi - H.E)[:flat.n, :flat.n].max() > np.abs(H.E).max()


def test_simulate_compares_the_scheduled_filter_with_disturbance_states(tmp_path, capsys):
    """`--filters df,scheduled` on a scenario with a [disturbance] table and a model error: the
    scheduled filter carries the same disturbance states as the held one (its update, a Kalman
    update on the extended state, counts the same operations; its prediction more), and pairs."""
    path = tmp_path / "arm.toml"
    path.write_text('[scenario]\nduration = 1.5\nruns = 1\nreferences = ["sinusoid"]\nbaselines = []\n'
                    'fusion = ["difference"]\n[filter]\nq = [3.48, 10.2]\nq_scheduled = [1.0, 3.0]\n'
                    '[[grid]]\nd = [0, 0]\np = 0.0\n[disturbance]\nkind = "random_walk"\nq = [1e5, 1e5]\n')
    assert cli.main(["simulate", MODEL, "--scenario", str(path), "--quiet", "--filters", "df,scheduled",
                     "--param-error", "0.05", "--json", "-"]) == 0
    doc = json.loads(capsys.readouterr().out)
    ops = doc["settings"]["operations"]
    assert ops["scheduled"]["update"] == ops["df"]["update"]
    assert ops["scheduled"]["predict"] > ops["df"]["predict"]
    plain = compare.operations(MODEL, 0.01, (1.0, 3.0), kinds=(compare.SCHEDULED,))[compare.SCHEDULED]
    assert ops["scheduled"]["update"] > plain["update"]               # eight states, not six
    (paired,) = [p for p in doc["paired"] if p["filter"] == "scheduled"]
    assert paired["pairs"] == 1 and len(paired["mean"]) == 6


def test_calibration_with_disturbance_states_matches_the_scheduled_filters_nees_to_n():
    """`codegen scenario --scheduled --disturbance`'s stage (scheduled_calibration.
    under_model_error): the scheduled filter's white q, the disturbance densities kept, scaled
    until its master NEES re-filtering the held filter's loops under a model error (the motor,
    J +20% and m -20% in the plant) is n within NEES_TOL. Checked on a second path: those loops
    closed by the scheduled filter itself at the q found (reference/predictor.Scheduled with the
    disturbance states in the nodes and the master, not the comparison's filter) average within
    NEES_TOL² of n; they differ from the held filter's loops only in which estimate the law read."""
    import math

    from dfeif_codegen.experiment import model_error, scheduled_calibration
    from dfeif_codegen.experiment.nees_match import NEES_SECONDS, NEES_TOL
    from dfeif_codegen.symbolic.disturbance import Disturbance

    flat, seeds, held = ex._flat("dc_motor_link"), [3, 4], np.array([16.9])
    dist = Disturbance("random_walk", (2.3e5,))

    def config(q, seed, predictor="held"):
        return ex.Config(model="dc_motor_link", duration=NEES_SECONDS, q=tuple(q), poles=(10.0,),
                         noise_scale=(1.0, 1.25), metrics_from=1.0, seed=seed, reference="sinusoid",
                         sensor=ON_TIME, predictor=predictor, disturbance=dist,
                         plant_error=model_error.from_option("J=0.2,m=-0.2"))

    loops = [ex.run(config(held, s)) for s in seeds]
    q, log = scheduled_calibration.under_model_error(flat, held, loops, seeds, dist, [], lambda line: None)
    assert log[-1].startswith("the scheduled filter, with the disturbance states: ")
    refiltered = scheduled_calibration.nees(loops, q, dist)
    assert abs(math.log(refiltered / flat.n)) <= math.log(NEES_TOL)
    own = np.mean([np.mean(ex.run(config(q, s, "scheduled")).metrics["nees_master"]) for s in seeds])
    print(f"q {q}, NEES re-filtered {refiltered:.3f}, on its own loops {own:.3f}")
    assert abs(math.log(own / flat.n)) <= 2 * math.log(NEES_TOL)


def test_transition_swing_and_the_scenarios_advice():
    """`codegen scenario`'s advice (scheduled_calibration.advice) rests on how far Φ(σ) leaves
    Φ₀ along the reference, in units of Φ₀'s own step. Oracles: at the nominal outputs Φ(σ₀) is
    Φ₀ (the swing is 0 up to the rounding of one evaluation of L), and where L does not depend
    on σ (the unicycle and the PVTOL: their canonical dynamics after the extension are linear in
    the flat outputs' derivatives) it is 0 everywhere. Measured on the default references (the
    values the threshold sits between): the arm 1.45 (its inertia and gravity move with q2),
    advised; the motor 0.12 (gravity's cos θ alone), not advised."""
    from dfeif_codegen.experiment import derivation, scheduled_calibration as sc

    swings = {}
    for model in ("dc_motor_link", "two_link_arm", "unicycle", "pvtol"):
        flat = derivation.derive(model)
        H = predictors.held_constants(flat, float(flat.model.ts))
        assert sc.transition_swing(flat, float(flat.model.ts), [H.zeta0[list(flat.heads)]]) < 1e-12
        swings[model] = sc.swing_along_reference(flat, model, float(flat.model.ts))
    print(f"\n{swings}")
    assert swings["unicycle"] < 1e-12 and swings["pvtol"] < 1e-12
    assert swings["two_link_arm"] > 2 * sc.SWING_ADVICE and swings["dc_motor_link"] < sc.SWING_ADVICE / 2
    assert "--predictor scheduled" in sc.advice(swings["two_link_arm"]) and sc.advice(swings["dc_motor_link"]) == ""


SQRT_MOTOR = str(Path(__file__).parent / "data" / "sqrt_motor.toml")


def test_transition_is_the_held_ones_where_the_scheduling_point_leaves_the_domain():
    """The reluctance motor's current is sqrt((J θ'' + c θ' + ks θ) / k), declared in [0.05, 5] A.
    The scheduling point keeps the nominal θ' = θ'' = 0, so at σ = θ its current is
    sqrt(ks σ / k): 0 at σ = 0 (an infinite slope: the filter's NaN ended the loop before),
    NaN below, 0.045 A (under the domain) at σ = 0.001. There Φ(σ) is Φ₀ (L taken at the nominal
    point: equal to rounding, 1e-12 of Φ₀'s scale, as at the arm's nominal above). Inside
    (σ = 0.146: 0.54 A) it is the exponential-Euler step's Jacobian at the point, against a
    central difference as in the arm's test above (1e-7 of a column's scale), and not Φ₀."""
    flat = ex._flat(SQRT_MOTOR)
    model = ScheduledModel(flat, 0.01, (1.0,))
    H = predictors.held_constants(flat, 0.01)
    zeta0, u0 = sampling.nominal_point(flat)
    for sigma in (0.0, -0.3, 0.001):
        Phi = np.array(model.transition_sx(np.concatenate([u0, [sigma]])))
        np.testing.assert_allclose(Phi, H.E, rtol=0, atol=1e-12 * np.abs(H.E).max())
    top = sampling.remainder_function(flat)
    point = zeta0.copy()
    point[0] = 0.146
    Phi = np.array(model.transition_sx(np.concatenate([u0, [0.146]])))
    fd = _central_difference(lambda z: z + H.Psi @ (H.Ac @ z + H.Bc @ np.array(
        top(z, u0, flat.param_vector)[0]).ravel()), point)
    for j in range(flat.n):
        np.testing.assert_allclose(Phi[:, j], fd[:, j], rtol=0, atol=1e-7 * np.abs(fd[:, j]).max())
    assert np.abs(Phi - H.E).max() > 0.5 * np.abs(H.E).max()     # measured 0.85: not Φ₀ there


def test_the_scenario_advises_the_scheduled_predictor_only_where_it_holds_its_loops():
    """Its transition swings along the reluctance motor's reference too (4.4 of Φ₀'s step), but
    there the scheduled filter's covariance grows threefold a step near θ = 0.07 and the loop is
    lost (measured): not advised, and said why. The arm's holds its loops (the paper scenario's
    first row, seeds 0-1): advised."""
    from dfeif_codegen.experiment import derivation, scenario, scheduled_calibration as sc, simulate

    said = []
    for spec, file, advised in ((SQRT_MOTOR, str(Path(__file__).parent / "data" / "sqrt_motor_scenario.toml"), False),
                                ("two_link_arm", "paper", True)):
        flat, scn = derivation.derive(spec), scenario.load(file)
        assert sc.swing_along_reference(flat, spec, float(flat.model.ts)) > 2 * sc.SWING_ADVICE

        def loop(seed):
            return simulate.make_config(scn, spec, 2, 32, "sinusoid", scn.grid[0], "replay", "difference", seed)
        note = sc.note(flat, spec, float(flat.model.ts), None, said.append, loop)
        assert (len(note) == 1 and "--predictor scheduled" in note[0]) if advised else note == [], (spec, note)
    assert "lost its loop" in said[0] and "not advised" in said[0]
