"""The numpy reference filters against independent methods: a plain time-ordered Kalman filter
(batch re-run), a naive O(N^2) evaluation of the retrodiction sums, a centralized stacked
Kalman filter, a grid search for covariance intersection, and a Monte Carlo for consistency."""

import dataclasses
from functools import lru_cache

import numpy as np
import pytest
from scipy.stats import chi2

from dfeif_codegen.symbolic import flatness, model
from dfeif_codegen.constants import CI_REGULARISER
from dfeif_codegen.reference.fusion import Master, covariance_intersection_weights
from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.reference.node import NodeFilter

TS, Q_DENSITY = 0.01, 50.0
MODELS = ("dc_motor_link", "two_link_arm")
PREDICTORS = ("held", "brunovsky")
INPUT_STD = {"held": 1.0, "brunovsky": 5.0}   # random u [V] or v [rad/s^3] driving the truth


@lru_cache(maxsize=None)
def prediction(name, kind):
    """The predictor object the filters use (its mean map and constant Phi, Q): the oracles
    below run the textbook recursions on it."""
    return predictors.make(kind, flat_system(name), TS, Q_DENSITY)


@lru_cache(maxsize=None)
def flat_system(name):
    return flatness.derive(model.load(name))


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def angle_wrap(e):
    return np.angle(np.exp(1j * e))   # (-pi, pi], deliberately not the code's formula


def random_spd(rng, m, scale):
    a = rng.standard_normal((m, m))
    return scale * (a @ a.T / m + np.eye(m))


def start(flat):
    """x0 with the angles near pi (so wrapping happens), P0 wide."""
    x0 = np.zeros(flat.n)
    x0[flat.heads] = 3.1
    return x0, np.diag(np.tile([0.1, 1.0, 10.0], flat.m)[:flat.n])


def simulate(flat, steps, rng, Rs, common=None, kind="brunovsky"):
    """Truth with process noise, random inputs (u for the held predictor, v for the Brunovsky
    one) through the predictor's mean map, and for each R in Rs a measurement sequence wrapped
    like a camera's atan2; `common` adds a noise component shared by every node."""
    pred = prediction(flat.model.name, kind)
    C = flat.discrete(TS)[2]
    Q = pred.Q
    lam, vec = np.linalg.eigh(Q)
    q_half = vec * np.sqrt(np.clip(lam, 0, None))
    x0, P0 = start(flat)
    x = x0 + np.linalg.cholesky(P0) @ rng.standard_normal(flat.n)
    angle = np.array([c.angle for c in flat.chains])
    xs, vs, zs = [], [], [[] for _ in Rs]
    for _ in range(steps):
        shared = np.zeros(flat.m) if common is None else np.linalg.cholesky(common) @ rng.standard_normal(flat.m)
        for i, R in enumerate(Rs):
            z = C @ x + shared + np.linalg.cholesky(R) @ rng.standard_normal(flat.m)
            zs[i].append(np.where(angle, angle_wrap(z), z))
        xs.append(x)
        vs.append(INPUT_STD[kind] * rng.standard_normal(flat.m))
        x = pred.mean(x, vs[-1]) + q_half @ rng.standard_normal(flat.n)
    return np.array(xs), np.array(vs), [np.array(z) for z in zs]


def batch_kf(flat, R, zs, has, vs, x0, P0, kind="brunovsky"):
    """Plain Kalman filter over time-ordered measurements (`has[t]`: step t has one).
    Returns per step the posterior and what the update used (for the naive retrodiction)."""
    pred = prediction(flat.model.name, kind)
    A, Q, C = pred.Phi, pred.Q, flat.discrete(TS)[2]
    angle = np.array([c.angle for c in flat.chains])
    x, P, out = x0, P0, []
    for t in range(len(has)):
        S = C @ P @ C.T + R
        e = zs[t] - C @ x
        e = np.where(angle, angle_wrap(e), e)
        K = P @ C.T @ np.linalg.inv(S) if has[t] else np.zeros((flat.n, flat.m))
        x, P = x + K @ e, (np.eye(flat.n) - K @ C) @ P
        out.append(dict(x=x, P=P, K=K, S=S, e=e, measured=bool(has[t])))
        if t < len(has) - 1:
            x, P = pred.mean(x, vs[t]), A @ P @ A.T + Q
    return out


def delay_plan(steps, rng, max_lag, p_drop, p_late):
    """Per step: 0 on time, -1 lost, d > 0 arrives d steps late."""
    u = rng.random(steps)
    lags = rng.integers(1, max_lag + 1, steps)
    return np.where(u < p_drop, -1, np.where(u < p_drop + p_late, lags, 0))


def run_with_delays(nodes, zs, vs, plan, rng, check=None):
    """Drive nodes through the protocol; late arrivals of a step in random order."""
    arrivals = {}
    for t, d in enumerate(plan):
        if d > 0:
            arrivals.setdefault(t + d, []).append(t)
    for k in range(len(plan)):
        late = arrivals.get(k, [])
        rng.shuffle(late)
        for node in nodes:
            node.update(zs[k], plan[k] == 0)
            for t in late:
                assert node.update_delayed(zs[t], k - t)
        if check is not None:
            check(k, [t for t in range(k + 1) if plan[t] == 0 or (plan[t] > 0 and t + plan[t] <= k)])
        for node in nodes:
            node.predict(vs[k])
    return arrivals


# 1. replay is exactly a time-ordered Kalman filter ------------------------------------------------
@pytest.mark.parametrize("kind", PREDICTORS)
@pytest.mark.parametrize("name", MODELS)
def test_replay_equals_batch_kalman_filter(name, kind):
    """Replay with the inputs each step kept equals the filter re-run with every measurement on
    time, for the held predictor's nonlinear mean map as for the Brunovsky one."""
    flat, rng, steps, max_lag = flat_system(name), np.random.default_rng(1), 120, 24
    R = random_spd(rng, flat.m, 1e-4)
    _, vs, (zs,) = simulate(flat, steps, rng, [R], kind=kind)
    plan = delay_plan(steps, rng, max_lag, 0.15, 0.7)
    x0, P0 = start(flat)
    node = NodeFilter(flat, TS, Q_DENSITY, R, x0, P0, max_lag=max_lag, oosm="replay", predictor=kind)
    worst = []

    def check(k, known):
        has = np.zeros(k + 1, bool)
        has[known] = True
        ref = batch_kf(flat, R, zs, has, vs, x0, P0, kind)[k]
        worst.append(max(rel(node.x, ref["x"]), rel(node.P, ref["P"])))

    arrivals = run_with_delays([node], zs, vs, plan, rng, check)
    assert max(len(a) for a in arrivals.values()) >= 3        # several late ones in one step
    assert node.counters["late_applied"] == sum(len(a) for k, a in arrivals.items() if k < steps)
    print(f"\n{name}, {kind}: replay vs batch Kalman filter, worst relative error {max(worst):.1e}")
    # replay and the batch filter perform the same Kalman steps in a different order; on these
    # well-conditioned 3x3 (cond(P) < 1e4) each step moves the rounding by ~n cond eps ~1e-11
    # relative and the filter contracts it: 1e-10 holds on any IEEE machine
    assert max(worst) <= 1e-10


def test_posterior_equals_the_joseph_form():
    """The node's posterior covariance (P - K C P, the heads' rows as R K') against the Joseph
    form, on random priors of two chains (heads 0 and 3 of 5 states) with a correlated 2x2 R.
    Equal in exact arithmetic; both take a few dozen float64 operations per entry on a well-
    conditioned P (cond < 1e3, checked), so 1e-12 of max |P| holds on any IEEE machine. The
    result is symmetric bit for bit (each entry computed once)."""
    from dfeif_codegen.reference.node import posterior
    rng, heads = np.random.default_rng(5), [0, 3]
    C = np.eye(5)[heads]
    for _ in range(50):
        P, R = random_spd(rng, 5, 1.0), random_spd(rng, 2, rng.uniform(0.01, 1.0))
        assert np.linalg.cond(P) < 1e3
        K = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
        IKC = np.eye(5) - K @ C
        got = posterior(P, K, R, heads)
        assert np.array_equal(got, got.T)
        np.testing.assert_allclose(got, IKC @ P @ IKC.T + K @ R @ K.T, rtol=0, atol=1e-12 * np.abs(P).max())


# 2. retrodiction -------------------------------------------------------------------------------
def naive_retrodiction(flat, R, hist, vs, k, N, z, x, P):
    """docs/mathematics.md section 4 evaluated term by term, O(N^2), with matrix powers and inverses."""
    A, B, C = flat.discrete(TS)
    Q = flat.process_noise(TS, Q_DENSITY)
    n, I = flat.n, np.eye(flat.n)
    Ap = lambda i: np.linalg.matrix_power(A, i)  # noqa: E731
    L = lambda j: I - hist[k - j]["K"] @ C       # noqa: E731
    phi1 = np.linalg.inv(Ap(N))
    terms = []
    for nn in range(N):
        if not hist[k - nn]["measured"]:
            continue
        ct = Ap(nn) @ Q
        for j in range(nn + 2, N + 1):
            prod = I
            for mm in range(nn + 1, j):
                prod = prod @ (A @ L(mm))
            ct = ct + Ap(j - 1) @ Q @ prod.T
        prod = I
        for j in range(nn, N - 1):
            prod = prod @ (L(j + 1) @ A)
        S_inv = np.linalg.inv(hist[k - nn]["S"])
        terms.append((ct @ C.T, C @ A @ prod, S_inv, hist[k - nn]["e"]))
    w_a = -phi1 @ sum((ct @ Si @ e for ct, _, Si, e in terms), np.zeros(n))
    q_sum = sum(Ap(j - 1) @ Q @ Ap(j - 1).T for j in range(1, N + 1))
    q_star = phi1 @ q_sum @ phi1.T - phi1 @ sum((ct @ Si @ ct.T for ct, _, Si, _ in terms), np.zeros((n, n))) @ phi1.T
    P_old = hist[k - N]["P"]
    P_xw = Ap(N) @ sum((P_old @ D.T @ Si @ ct.T for ct, D, Si, _ in terms), np.zeros((n, n))) @ phi1.T - Ap(N) @ q_star
    forced = sum((Ap(N - j) @ B @ vs[k - N + j - 1] for j in range(1, N + 1)), np.zeros(n))
    x_back = phi1 @ (x - forced) + w_a
    W = C @ (phi1 @ P @ phi1.T + phi1 @ P_xw + (phi1 @ P_xw).T + q_star) @ C.T + R
    M = (P @ phi1.T + P_xw) @ C.T @ np.linalg.inv(W)
    angle = np.array([c.angle for c in flat.chains])
    innov = z - C @ x_back
    return x + M @ np.where(angle, angle_wrap(innov), innov), P - M @ W @ M.T


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("max_lag", [4, 32])
def test_retrodict_equals_replay_for_one_late_measurement(name, max_lag):
    flat, rng = flat_system(name), np.random.default_rng(max_lag)
    R = random_spd(rng, flat.m, 1e-4)
    x0, P0 = start(flat)
    steps = max_lag + 6
    worst_replay = worst_naive = 0.0
    for lag in range(1, max_lag + 1):
        _, vs, (zs,) = simulate(flat, steps, rng, [R])
        k = steps - 1
        has = rng.random(steps) > 0.3          # intermediate drops
        has[k - lag] = False                   # this one arrives late
        nodes = [NodeFilter(flat, TS, Q_DENSITY, R, x0, P0, max_lag=max_lag, oosm=o,
                            predictor="brunovsky") for o in ("replay", "retrodict")]
        for t in range(steps):
            for node in nodes:
                node.update(zs[t], has[t])
                if t < k:
                    node.predict(vs[t])
        hist = batch_kf(flat, R, zs, has, vs, x0, P0)
        x_n, P_n = naive_retrodiction(flat, R, hist, vs, k, lag, zs[k - lag], nodes[1].x, nodes[1].P)
        for node in nodes:
            assert node.update_delayed(zs[k - lag], lag)
        replay, retro = nodes
        worst_replay = max(worst_replay, rel(retro.x, replay.x), rel(retro.P, replay.P))
        worst_naive = max(worst_naive, rel(retro.x, x_n), rel(retro.P, P_n))
    print(f"\n{name} N_max={max_lag}: one late measurement, retrodict vs replay {worst_replay:.1e}, "
          f"recursion vs naive sums {worst_naive:.1e}")
    # retrodiction back-propagates through A^-N (entries <= N Ts) and one gain solve: algebraically
    # equal to replay, rounding ~N n cond eps ~1e-10 at N_max = 32; the naive sums differ only in
    # summation order of the same terms (a few ulps times the number of terms)
    assert worst_replay <= 1e-9
    assert worst_naive <= 1e-11


@pytest.mark.parametrize("name", MODELS)
def test_retrodict_with_several_late_measurements_is_approximate(name):
    """Stale history makes it approximate. (Much denser delays, e.g. 30 % late with lags up to
    20, can drive its P indefinite: use replay there.)"""
    flat, rng, steps, max_lag = flat_system(name), np.random.default_rng(7), 150, 10
    R = random_spd(rng, flat.m, 1e-4)
    _, vs, (zs,) = simulate(flat, steps, rng, [R])
    plan = delay_plan(steps, rng, max_lag, 0.1, 0.2)
    x0, P0 = start(flat)
    nodes = [NodeFilter(flat, TS, Q_DENSITY, R, x0, P0, max_lag=max_lag, oosm=o,
                            predictor="brunovsky") for o in ("replay", "retrodict")]
    errs = []

    def check(k, known):
        errs.append((rel(nodes[1].x, nodes[0].x), rel(nodes[1].P, nodes[0].P)))

    arrivals = run_with_delays(nodes, zs, vs, plan, rng, check)
    assert max(len(a) for a in arrivals.values()) >= 2 and sum(plan > 0) >= 15
    ex, eP = np.max(errs, axis=0)
    print(f"\n{name}: several late measurements, retrodict vs replay worst relative error x {ex:.1e}, P {eP:.1e}")
    assert 1e-8 < max(ex, eP) < 1e-1


# 3. rejections -----------------------------------------------------------------------------------
@pytest.mark.parametrize("oosm,kind", [("replay", "held"), ("replay", "brunovsky"), ("retrodict", "brunovsky")])
def test_rejected_late_measurements_change_nothing(oosm, kind):
    flat, rng = flat_system("dc_motor_link"), np.random.default_rng(3)
    R = 1e-4
    _, vs, (zs,) = simulate(flat, 30, rng, [np.eye(1) * R])
    x0, P0 = start(flat)
    for max_lag, k_test, bad_lags in [(8, 12, [0, -1, 9, 13]), (32, 5, [0, 6, 33])]:
        has = np.ones(30, bool)
        has[[k_test - 2, k_test - 3]] = False
        node, twin = (NodeFilter(flat, TS, Q_DENSITY, R, x0, P0, max_lag=max_lag, oosm=oosm, predictor=kind)
                      for _ in range(2))
        for t in range(30):
            for nd in (node, twin):
                nd.update(zs[t], has[t])
            if t == k_test:
                for nd in (node, twin):
                    assert nd.update_delayed(zs[t - 2], 2)
                before = (node.x.copy(), node.P.copy(), dict(node.counters))
                dup_lags = [1, 2]                  # on time at k-1; already applied late at k-2
                for lag in bad_lags + dup_lags:
                    assert node.update_delayed(zs[t - 1], lag) is False
                assert np.array_equal(node.x, before[0]) and np.array_equal(node.P, before[1])
                assert node.counters == {**before[2], "late_rejected": len(bad_lags) + len(dup_lags)}
                assert node.update_delayed(zs[t - 3], 3)   # the window still works afterwards
                assert twin.update_delayed(zs[t - 3], 3)
            for nd in (node, twin):
                nd.predict(vs[t])
            assert np.array_equal(node.x, twin.x) and np.array_equal(node.P, twin.P)


# 4. the information-difference rule is the centralized Kalman filter ----------------------------
@pytest.mark.parametrize("kind", PREDICTORS)
@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("n_nodes", [2, 3])
@pytest.mark.parametrize("calls", ["once", "in pieces"])
def test_difference_fusion_equals_centralized_kalman_filter(name, n_nodes, kind, calls):
    """Exact also with the held predictor's nonlinear mean: a node's information gain does not
    depend on its prior mean, and the master predicts its own estimate with the same map and u.
    `in pieces`: each step's packets fused as they might arrive, a random part first, then the
    rest alone or every packet again (those already fused are ignored): information adds, so the
    same filter."""
    flat, rng, steps = flat_system(name), np.random.default_rng(10 + n_nodes), 80
    Rs = [random_spd(rng, flat.m, s) for s in (1e-4, 4e-4, 2.5e-5)[:n_nodes]]
    _, vs, zs = simulate(flat, steps, rng, Rs, kind=kind)
    has = rng.random((n_nodes, steps)) > 0.25
    x0, P0 = start(flat)
    nodes = [NodeFilter(flat, TS, Q_DENSITY, R, x0, P0, predictor=kind) for R in Rs]
    master = Master(flat, TS, Q_DENSITY, x0, P0, n_nodes, rule="difference", predictor=kind)
    pred = prediction(name, kind)
    A, Q, C = pred.Phi, pred.Q, flat.discrete(TS)[2]
    angle = np.array([c.angle for c in flat.chains])
    x, P, worst = x0, P0, 0.0
    for k in range(steps):
        for i, node in enumerate(nodes):
            node.update(zs[i][k], has[i, k])
        packets = [node.packet() for node in nodes]
        if calls == "in pieces":
            first = rng.random(n_nodes) < 0.5
            master.fuse([p if f else None for p, f in zip(packets, first)])
            packets = packets if k % 2 else [None if f else p for p, f in zip(packets, first)]
        master.fuse(packets)
        present = [i for i in range(n_nodes) if has[i, k]]
        if present:                                           # centralized: stacked measurement
            Cs = np.vstack([C] * len(present))
            Rs_blk = np.zeros((len(present) * flat.m,) * 2)
            for j, i in enumerate(present):
                Rs_blk[j * flat.m:(j + 1) * flat.m, j * flat.m:(j + 1) * flat.m] = Rs[i]
            e = np.concatenate([zs[i][k] - C @ x for i in present])
            e = np.where(np.tile(angle, len(present)), angle_wrap(e), e)
            K = P @ Cs.T @ np.linalg.inv(Cs @ P @ Cs.T + Rs_blk)
            x, P = x + K @ e, (np.eye(flat.n) - K @ Cs) @ P
        worst = max(worst, rel(master.x, x), rel(master.P, P))
        for node in nodes:
            node.predict(vs[k])
        master.predict(vs[k])
        x, P = pred.mean(x, vs[k]), A @ P @ A.T + Q
    print(f"\n{name}, {kind}, {n_nodes} nodes: difference rule vs centralized, worst relative error {worst:.1e}")
    # difference fusion vs the centralized filter: information-form inversions of 3x3 with
    # cond < 1e4 (~n cond eps = 7e-12 each, contracted by the filter): 1e-9 on any IEEE machine
    assert worst <= 1e-9


@pytest.mark.parametrize("name", MODELS)
def test_difference_fusion_over_lost_packets_equals_centralized_without_process_noise(name, monkeypatch):
    """Node 1's packets of steps 20-29 never reach the master. Over that gap the master takes
    node 1's gain over its prediction of the last packet it fused (the channel). With a linear
    mean (the Brunovsky chain) and no process noise, information adds over steps, so that gain
    holds exactly node 1's frames of the gap and the master is again the centralized filter of
    every frame once packets arrive. Without the channel (each gain over the node's own
    prediction) those frames are lost. (The held predictor takes the same path; its mean is not
    linear, so its oracle is the C: tests/test_equivalence.py, lossy links.)"""
    kind, flat, rng, steps = "brunovsky", flat_system(name), np.random.default_rng(3), 50
    Rs = [random_spd(rng, flat.m, s) for s in (1e-4, 4e-4)]
    _, vs, zs = simulate(flat, steps, rng, Rs, kind=kind)
    has = rng.random((2, steps)) > 0.25
    lost = np.zeros((2, steps), dtype=bool)
    lost[1, 20:30] = True
    pred = predictors.make(kind, flat, TS, 0.0)
    A, C = pred.Phi, flat.discrete(TS)[2]
    angle = np.array([c.angle for c in flat.chains])

    conds = []

    def run():
        x0, P0 = start(flat)
        nodes = [NodeFilter(flat, TS, 0.0, R, x0, P0, predictor=kind) for R in Rs]
        master = Master(flat, TS, 0.0, x0, P0, 2, rule="difference", predictor=kind)
        x, P, worst = x0, P0, 0.0
        for k in range(steps):
            for i, node in enumerate(nodes):
                node.update(zs[i][k], has[i, k])
            master.fuse([None if lost[i, k] else node.packet() for i, node in enumerate(nodes)])
            for i in np.flatnonzero(has[:, k]):   # centralized: every frame, one node at a time
                e = zs[i][k] - C @ x
                K = P @ C.T @ np.linalg.inv(C @ P @ C.T + Rs[i])
                x, P = x + K @ np.where(angle, angle_wrap(e), e), (np.eye(flat.n) - K @ C) @ P
            if k >= 30:
                worst = max(worst, rel(master.x, x), rel(master.P, P))
                conds.append(np.linalg.cond(P))
            for node in nodes:
                node.predict(vs[k])
            master.predict(vs[k])
            x, P = pred.mean(x, vs[k]), A @ P @ A.T
        return worst

    worst = run()
    monkeypatch.setattr(Master, "_channel", lambda self, i, item, step: item)
    without = run()
    print(f"\n{name}: after the gap, master vs centralized {worst:.1e} (cond P up to {max(conds):.1e}); "
          f"without the channel {without:.1e}")
    # the two differ by the rounding of the information-form inversions, n cond(P) eps each:
    # cond(P) stays below 1e7 here (asserted), so 1e-8 per inversion, contracted by the filter
    assert max(conds) < 1e7 and worst <= 1e-7
    assert without > 1e-3


def test_channel_is_skipped_for_a_restarted_node_and_covered_packets_are_ignored(monkeypatch):
    """After a gap, a node whose own prediction holds less than the master's prediction of its
    last fused packet (it restarted from its start-up prior) gets its own gain: the master then
    equals one without the channel. A node that kept filtering through the gap gets the channel
    (the master differs). A packet not newer than the last one fused changes nothing."""
    flat = flat_system("dc_motor_link")
    x0, P0 = start(flat)
    v = np.zeros(flat.m)
    R = np.eye(flat.m) * 1e-4

    def fused(restarted: bool, channel: bool = True, repeat: bool = False):
        node = NodeFilter(flat, TS, Q_DENSITY, R, x0, P0, predictor="brunovsky")
        fresh = NodeFilter(flat, TS, Q_DENSITY, R, x0, P0, predictor="brunovsky")   # no frame before 5
        master = Master(flat, TS, Q_DENSITY, x0, P0, 1, rule="difference", predictor="brunovsky")
        if not channel:
            monkeypatch.setattr(master, "_channel", lambda i, item, step: item)
        first = None
        for k in range(8):
            if restarted and k == 5:   # back from a restart: its start-up prior predicted to now
                node = fresh
            node.update(x0[flat.heads] + 0.01 * k, True)
            if node is not fresh:
                fresh.update(None, False)
            first = node.packet() if k == 0 else first
            master.fuse([node.packet() if k in (0, 5) else (first if repeat and k == 6 else None)])
            node.predict(v)
            if node is not fresh:
                fresh.predict(v)
            master.predict(v)
        return master.x, master.P

    kept, kept_own = fused(False), fused(False, channel=False)
    assert kept[1][0, 0] < 0.8 * kept_own[1][0, 0]   # the gap's frames reach the master (1.36e-4 vs 2.07e-4)
    back, back_own = fused(True), fused(True, channel=False)
    assert np.array_equal(back[0], back_own[0]) and np.array_equal(back[1], back_own[1])
    again = fused(False, repeat=True)             # step 0's packet once more at step 6
    assert np.array_equal(again[0], kept[0]) and np.array_equal(again[1], kept[1])


@pytest.mark.parametrize("kind", ["brunovsky", "held"])
def test_channel_decision_does_not_turn_on_rounding(kind):
    """Node 0's packets of steps 1-3 are lost; at step 3 it applied a late frame of step 1. Its
    own prediction of step 4 then holds more than the master's prediction of its last fused
    packet (step 0) on every diagonal entry, by little on some: in exact arithmetic never less,
    so that the channel is the node's gain; where a late frame adds next to nothing, a rounding
    can put the node's entry on either side of the master's. The master must fuse the same
    whichever side it falls on: one diagonal entry of the node's prediction set to the master's
    (a twin node without the late frame: the same carry in exact arithmetic) times 1 + 1e-9 or
    1 - 1e-9 gives the same master (both the channel, which does not read that prediction). A
    decision taken at 64 ulps put the C and the reference on opposite sides (the arm, three
    nodes, a packet three steps on, 4.5e-13 apart: their masters 0.12 apart); here it moved the
    master's x by 3e-5 (brunovsky) and 7e-4 (held): the gain over the node's own prediction.
    A restart (the prediction 100 times wider) is the node's own gain, far from the channel's."""
    flat = flat_system("dc_motor_link")
    x0, P0 = start(flat)
    v = np.zeros(flat.m)
    R = np.eye(flat.m) * 1e-4
    frame = x0[flat.heads] + 0.01

    def node_at_4(late: bool):
        node = NodeFilter(flat, TS, Q_DENSITY, R, x0, P0, predictor=kind)
        for k in range(4):
            node.update(frame if k == 0 else None, k == 0)
            if late and k == 3:
                node.update_delayed(frame, 2)
            node.predict(v)
        return node

    twin = node_at_4(False).packet().P_pred        # = the master's carry of step 0's packet
    d = int(np.argmax(np.diag(node_at_4(True).packet().P_pred) / np.diag(twin)))   # the entry the frame moved least

    def fused(scale: float | None = None, wide: float = 1.0):
        node = NodeFilter(flat, TS, Q_DENSITY, R, x0, P0, predictor=kind)
        master = Master(flat, TS, Q_DENSITY, x0, P0, 1, rule="difference", predictor=kind)
        for k in range(5):
            node.update(frame if k in (0, 4) else None, k in (0, 4))
            if k == 3:
                node.update_delayed(frame, 2)
            p = node.packet()
            if k == 4:
                Pp = p.P_pred * wide
                if scale is not None:
                    Pp = Pp.copy()
                    Pp[d, d] = twin[d, d] * scale
                p = dataclasses.replace(p, P_pred=Pp)
            master.fuse([p if k in (0, 4) else None])
            node.predict(v)
            master.predict(v)
        return master.x, master.P

    above, below, plain = fused(1 + 1e-9), fused(1 - 1e-9), fused()
    assert rel(above[0], below[0]) <= 1e-12 and rel(above[1], below[1]) <= 1e-12
    assert rel(above[1], plain[1]) <= 1e-12
    assert rel(fused(wide=100.0)[1], plain[1]) > 1e-2


def test_master_predicts_stale_packets_and_ignores_old_ones():
    flat, rng = flat_system("dc_motor_link"), np.random.default_rng(5)
    _, vs, (zs,) = simulate(flat, 12, rng, [np.eye(1) * 1e-4])
    x0, P0 = start(flat)
    node = NodeFilter(flat, TS, Q_DENSITY, 1e-4, x0, P0, predictor="brunovsky")
    fresh = Master(flat, TS, Q_DENSITY, x0, P0, 1, rule="paper", max_lag=4, predictor="brunovsky")
    stale = Master(flat, TS, Q_DENSITY, x0, P0, 1, rule="paper", max_lag=4, predictor="brunovsky")
    packets = []
    for k in range(12):
        node.update(zs[k], True)
        packets.append(node.packet())
        if k == 10:
            fresh.fuse([packets[7]])         # 3 steps old, predicted with the stored v
            x, P = packets[7].x, packets[7].P
            A, B, _ = flat.discrete(TS)
            for i in range(7, 10):
                x, P = A @ x + B @ vs[i], A @ P @ A.T + flat.process_noise(TS, Q_DENSITY)
            assert rel(fresh.x, x) < 1e-9 and rel(fresh.P, P) < 1e-9   # through Y = P^-1 and back
            stale.fuse([packets[5]])         # 5 steps old > max_lag: ignored, the prior is kept
            assert np.array_equal(stale.x, stale.x_prior) and np.array_equal(stale.P, stale.P_prior)
        node.predict(vs[k])
        fresh.predict(vs[k])
        stale.predict(vs[k])


@pytest.mark.parametrize("kind", PREDICTORS)
@pytest.mark.parametrize("name", MODELS)
def test_a_packet_as_old_as_the_window_is_brought_forward_in_one_step(name, kind):
    """The master brings a stale packet's covariances N steps forward in one step (Φ over N
    periods and the noise of N periods in closed form: A(N Ts), Q_d(N Ts) for Brunovsky, the
    exponential and Van Loan integral over N Ts for the held predictor) and its means with the
    stored inputs: the same as N one-step predictions, for every age up to the window."""
    flat, rng = flat_system(name), np.random.default_rng(11)
    pred = prediction(name, kind)
    A, Q = pred.Phi, pred.Q
    window = 32
    _, vs, _ = simulate(flat, window + 1, rng, [np.eye(flat.m) * 1e-4], kind=kind)
    x0, P0 = start(flat)
    node = NodeFilter(flat, TS, Q_DENSITY, 1e-4, x0, P0, predictor=kind)
    packet = node.packet()
    master = Master(flat, TS, Q_DENSITY, x0, P0, 1, rule="difference", max_lag=window, predictor=kind)
    for age in range(1, window + 1):
        master.predict(vs[age - 1])
        got = master._bring(packet)
        want = [packet.x, packet.P, packet.x_pred, packet.P_pred]
        for i in range(age):
            want = [pred.mean(want[0], vs[i]), A @ want[1] @ A.T + Q, pred.mean(want[2], vs[i]),
                    A @ want[3] @ A.T + Q]
        # N products of A against one closed form (Φ entries O(1) over the window, P growing by
        # < 100x): they differ by a few ulps per step, well inside 1e-10 on any IEEE machine
        for g, w in zip(got, want):
            assert rel(g, w) < 1e-10, (age, g, w)



@pytest.mark.parametrize("name", MODELS)
def test_held_stale_packet_equals_the_master_that_fused_it_on_time(name):
    """Oracle for the held master's stale-packet step: one node, whose packet of step s reaches
    the master N steps late with nothing in between, must leave the master where a master that
    fused it on time and then only predicted is (the centralized filter of that information).
    Both means go through the held mean map with the stored inputs; moving x by Φ₀^N about the
    predicted x_pred instead (x' = f^N(x_pred) + Φ₀^N (x - x_pred)) is 0.4-1% off here."""
    flat, rng, s, N = flat_system(name), np.random.default_rng(3), 10, 8
    _, us, (zs,) = simulate(flat, s + N + 1, rng, [np.eye(flat.m) * 1e-4], kind="held")
    x0, P0 = start(flat)
    node = NodeFilter(flat, TS, Q_DENSITY, 1e-4, x0, P0, predictor="held")
    on_time, late = (Master(flat, TS, Q_DENSITY, x0, P0, 1, rule="difference", predictor="held") for _ in range(2))
    for k in range(s + N + 1):
        node.update(zs[k], k <= s)
        packet = node.packet()
        if k == s:
            kept = packet
        on_time.fuse([packet if k <= s else None])
        late.fuse([packet if k < s else (kept if k == s + N else None)])
        node.predict(us[k])
        if k < s + N:
            on_time.predict(us[k])
            late.predict(us[k])
    # the same operations in another order (an inverse of a 3x3 or 6x6 SPD matrix, cond < 1e6,
    # through information form and back): 1e-10 on any IEEE machine; measured ~1e-15
    assert rel(late.x, on_time.x) < 1e-10 and rel(late.P, on_time.P) < 1e-10


# 5. covariance intersection ---------------------------------------------------------------------
def trace_at(Ys, w):
    """tr((sum w_i Y_i)^-1); w may be a stack of weight vectors (one row each)."""
    w = np.atleast_2d(w)
    return np.trace(np.linalg.inv(np.einsum("gi,ijk->gjk", w, np.array(Ys))), axis1=1, axis2=2).squeeze()


def objective_at(Ys, w):
    """The regularised objective the weights minimise (docs/algorithms.md, "ci"): tr P plus
    rho/2 |w|^2, rho = CI_REGULARISER * max_i H_ii with the Hessian's diagonal at the search's
    start, w_i = 1/M."""
    P = np.linalg.inv(np.mean(np.array(Ys), axis=0))
    rho = CI_REGULARISER * max(2 * np.trace(P @ Y @ P @ Y @ P) for Y in Ys)
    return trace_at(Ys, w) + rho / 2 * np.sum(np.atleast_2d(w) ** 2, axis=1).squeeze()


def test_ci_weights_are_optimal_on_a_grid():
    rng = np.random.default_rng(11)
    grid = np.linspace(0, 1, 20001)
    excess = []
    for trial in range(40):
        n = 3 + trial % 4
        Ys = [np.linalg.inv(random_spd(rng, n, 10.0 ** rng.uniform(-3, 1))) for _ in range(2)]
        w = covariance_intersection_weights(Ys)
        assert np.all(w >= 0) and abs(w.sum() - 1) < 1e-12
        ws = np.column_stack([grid, 1 - grid])
        assert objective_at(Ys, w) <= objective_at(Ys, ws).min() * (1 + 1e-12)
        excess.append(trace_at(Ys, w) / trace_at(Ys, ws).min() - 1)
    print(f"tr P above its unregularised minimum: median {np.median(excess):.1e}, worst {max(excess):.1e}")
    assert max(excess) < 0.01


def test_ci_weights_three_nodes_edge_cases():
    rng = np.random.default_rng(12)
    Y = np.linalg.inv(random_spd(rng, 4, 1.0))
    w = covariance_intersection_weights([1e3 * Y, Y, np.linalg.inv(random_spd(rng, 4, 1.0))])
    assert w[0] > 1 - 1e-6 and np.all(w >= 0) and abs(w.sum() - 1) < 1e-12
    w = covariance_intersection_weights([Y, Y.copy()])           # equal nodes: no singular step
    assert np.allclose(w, 0.5, atol=1e-12)
    w = covariance_intersection_weights([Y, Y.copy(), Y.copy()])
    assert np.allclose(w, 1 / 3, atol=1e-12)
    rng_w = rng.dirichlet(np.ones(3), 20000)                        # no random weights do better,
    for scales in [(1.0, 2.0, 0.5), (1.0, 30.0, 0.03)]:             # interior and on a face
        Ys = [np.linalg.inv(random_spd(rng, 4, s)) for s in scales]
        w = covariance_intersection_weights(Ys)
        assert np.all(w >= 0) and abs(w.sum() - 1) < 1e-12
        assert objective_at(Ys, w) <= objective_at(Ys, rng_w).min() * (1 + 1e-12)


def test_ci_is_consistent_and_paper_is_not_with_correlated_nodes():
    """Two nodes watch the same truth (common process noise) with a measurement noise component
    they share: each node is consistent, their errors are strongly correlated."""
    flat, rng = flat_system("dc_motor_link"), np.random.default_rng(13)
    trials, steps = 300, 20
    shared, own = np.eye(1) * 1e-4, [np.eye(1) * 2e-5, np.eye(1) * 4e-5]
    x0, P0 = start(flat)
    nees = {"paper": [], "ci": []}
    for _ in range(trials):
        # the Brunovsky model: exactly linear, so each node is exactly consistent and the test
        # is of the fusion rule alone
        xs, vs, zs = simulate(flat, steps, rng, own, common=shared)
        nodes = [NodeFilter(flat, TS, Q_DENSITY, shared + R, x0, P0, predictor="brunovsky") for R in own]
        masters = {r: Master(flat, TS, Q_DENSITY, x0, P0, 2, rule=r, predictor="brunovsky") for r in nees}
        for k in range(steps):
            for node, z in zip(nodes, zs):
                node.update(z[k], True)
            if k < steps - 1:
                for node in nodes:
                    node.predict(vs[k])
                for m in masters.values():
                    m.predict(vs[k])
        for r, m in masters.items():
            m.fuse([node.packet() for node in nodes])
            e = m.x - xs[-1]
            e[flat.heads] = angle_wrap(e[flat.heads])
            nees[r].append(e @ np.linalg.solve(m.P, e))
    upper = chi2.ppf(0.975, flat.n * trials) / trials
    avg = {r: np.mean(v) for r, v in nees.items()}
    print(f"\naverage NEES over {trials} runs (n = {flat.n}, 95% upper bound {upper:.2f}): "
          + ", ".join(f"{r} {a:.2f}" for r, a in avg.items()))
    assert avg["ci"] <= upper
    assert avg["paper"] > upper
