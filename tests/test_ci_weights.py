"""Covariance-intersection weights against independent oracles: a general-purpose solver
(scipy's SLSQP) on the same regularised criterion, and closed forms for two nodes.

The criterion (docs/algorithms.md, master "ci") is f(w) = tr((sum w_i Y_i)^-1) + rho/2 |w|^2 on
the simplex, rho = CI_REGULARISER * max_i H_ii at the search's start w_i = 1/M. f is strongly
convex with modulus >= rho, so the weights w found are the minimiser exactly when every other
point w' of the simplex has f(w') - f(w) >= rho/2 |w' - w|^2; the tests check that against the
solver's answer (a point the solver could not improve on) and against random points.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from dfeif_codegen.constants import CI_REGULARISER, ci_iterations
from dfeif_codegen.reference.fusion import covariance_intersection_weights


def random_spd(rng, n, scale):
    a = rng.standard_normal((n, n))
    return scale * (a @ a.T / n + 0.1 * np.eye(n))


def node_set(rng, M, n):
    """M nodes' informations as a master sees them: a common prior's information plus each
    node's own, of sizes spread over two decades (so some weights go to 0)."""
    common = np.linalg.inv(random_spd(rng, n, 1.0))
    return [common + np.linalg.inv(random_spd(rng, n, 10 ** rng.uniform(-1, 1))) for _ in range(M)]


def rho_at(Ys, w=None):
    """The regulariser's weight from the Hessian's diagonal at w (default: the start, 1/M)."""
    w = np.full(len(Ys), 1 / len(Ys)) if w is None else w
    P = np.linalg.inv(sum(a * Y for a, Y in zip(w, Ys)))
    return CI_REGULARISER * max(2 * np.trace(P @ Y @ P @ Y @ P) for Y in Ys)


def criterion(Ys, rho):
    def f(w):
        return np.trace(np.linalg.inv(sum(a * Y for a, Y in zip(w, Ys)))) + rho / 2 * (w @ w)

    def grad(w):
        P = np.linalg.inv(sum(a * Y for a, Y in zip(w, Ys)))
        return np.array([-np.trace(P @ Y @ P) for Y in Ys]) + rho * w
    return f, grad


def slsqp(Ys, rho):
    M = len(Ys)
    f, grad = criterion(Ys, rho)
    res = minimize(f, np.full(M, 1 / M), jac=grad, method="SLSQP", bounds=[(0, 1)] * M,
                   constraints=[{"type": "eq", "fun": lambda w: w.sum() - 1, "jac": lambda w: np.ones(M)}],
                   options={"ftol": 1e-15, "maxiter": 2000})
    return np.clip(res.x, 0, None) / np.clip(res.x, 0, None).sum()


@pytest.mark.parametrize("M", [1, 2, 8, 16])
def test_weights_minimise_the_criterion_like_a_general_solver(M):
    rng = np.random.default_rng(100 + M)
    for trial in range(12):
        n = 3 + trial % 2
        Ys = node_set(rng, M, n)
        w = covariance_intersection_weights(Ys, ci_iterations(M))
        assert np.all(w >= 0) and abs(w.sum() - 1) < 1e-12
        rho = rho_at(Ys)
        f, _ = criterion(Ys, rho)
        ws = slsqp(Ys, rho)
        others = np.vstack([ws, rng.dirichlet(np.ones(M), 200)])
        # strong convexity: f(w') - f(w) >= rho/2 |w' - w|^2 at the minimiser w; the slack is the
        # rounding of f (a 3x3 or 4x4 inverse, cond < 1e4: ~1e-12 relative on any IEEE machine)
        for other in others:
            gap = f(other) - f(w)
            assert gap >= rho / 2 * np.sum((other - w) ** 2) - 1e-12 * f(w), (trial, other, w)
        # and the solver's answer is the same point (the bound above with its gap, which SLSQP's
        # ftol of 1e-15 keeps below 1e-12 f): |ws - w| <= sqrt(2 gap / rho)
        assert np.sum((ws - w) ** 2) <= 2 * (max(f(ws) - f(w), 0) + 1e-12 * f(w)) / rho


def test_one_step_fixes_several_weights_on_a_sparse_sixteen_node_optimum():
    """The cap does not grow with M because a step can fix any number of weights at 0: on sparse
    16-node optima with more zero weights than the search has steps (so one per step could not
    reach them), the weights found are the general solver's to 1e-12 of the criterion."""
    rng = np.random.default_rng(7)
    sparse = 0
    for _ in range(6):
        Ys = node_set(rng, 16, 3)
        w = covariance_intersection_weights(Ys, ci_iterations(16))
        f, _ = criterion(Ys, rho_at(Ys))
        assert f(w) <= f(slsqp(Ys, rho_at(Ys))) * (1 + 1e-12)
        sparse += np.count_nonzero(w == 0) > ci_iterations(16)
    assert sparse >= 5


def test_the_early_stop_is_within_reach_of_the_fixed_point():
    """The search stops after a step below CI_TOLERANCE; Newton's steps after it shrink
    quadratically (rho is fixed, constants.py), so the weights equal those of 60 steps without
    the stop to 1e-13 (weights are O(1): a few hundred ulps). One node: weight 1 without a search."""
    rng = np.random.default_rng(3)
    for M in (2, 4, 8):
        for _ in range(10):
            Ys = node_set(rng, M, 3)
            w = covariance_intersection_weights(Ys)
            assert np.max(np.abs(w - covariance_intersection_weights(Ys, 60, tolerance=0.0))) <= 1e-13
    assert covariance_intersection_weights([np.eye(3)]).tolist() == [1.0]


def test_two_scalar_nodes_match_the_stationary_point():
    """n = 1, M = 2: f(w) = 1/(w a + (1 - w) b) + rho/2 (w^2 + (1 - w)^2), f'(w) = 0 is the cubic
    rho (2w - 1)(b + w (a - b))^2 = a - b, whose root in [0, 1] is the weight (or a vertex)."""
    for a, b in [(1.0, 2.0), (3.0, 2.9), (10.0, 9.0), (1e3, 999.0), (5.0, 5.0)]:
        Ys = [np.array([[a]]), np.array([[b]])]
        w = covariance_intersection_weights(Ys, ci_iterations(2))
        rho = rho_at(Ys)
        c = a - b
        # rho (2w - 1)(c^2 w^2 + 2 b c w + b^2) - c: coefficients of w^3 .. w^0
        poly = rho * np.array([2 * c * c, 4 * b * c - c * c, 2 * b * b - 2 * b * c, -b * b]) - np.array([0, 0, 0, c])
        roots = [r.real for r in np.roots(poly) if abs(r.imag) < 1e-12 and -1e-12 <= r.real <= 1 + 1e-12]
        expected = roots[0] if roots else (1.0 if a > b else 0.0)
        # a cubic's root on O(1) coefficients: 1e-10 is ~1e6 ulps of margin for the Newton steps
        assert w[0] == pytest.approx(expected, abs=1e-10), (a, b)


def test_two_diagonal_nodes_closed_forms():
    """Mirror images (diag(a, b, d), diag(b, a, d)) get 1/2 each by symmetry. Y_1 = c Y, Y_2 = Y,
    t = tr Y^-1: at the start w = (1/2, 1/2), P = 2 Y^-1 / (c + 1) and the Hessian's diagonal is
    16 c^2 t / (c + 1)^3 and 16 t / (c + 1)^3, so rho = 16 CI_REGULARISER c^2 t / (c + 1)^3; at
    w = (1, 0), g_1 + rho = -t/c + rho and g_2 = -t/c^2, and the vertex is the minimiser when
    moving weight to node 2 does not pay: rho <= t (c - 1)/c^2 (c = 2: 0.024 t <= 0.25 t)."""
    w = covariance_intersection_weights([np.diag([4.0, 1.0, 2.0]), np.diag([1.0, 4.0, 2.0])])
    assert w == pytest.approx([0.5, 0.5], abs=1e-15)
    Y = np.diag([2.0, 0.5, 1.0])
    w = covariance_intersection_weights([2.0 * Y, Y])
    assert w[0] == 1.0 and w[1] == 0.0


def test_a_warm_start_reaches_the_cold_start_weights():
    """The master starts each search from its last weights when the last fuse used every node it
    uses now (docs/algorithms.md, "ci"). rho does not depend on the start, so the objective, and
    its minimiser, are the same: from the optimum of a nearby node set (each Y_i moved by ~1%, as
    from one step to the next), alone or with a random half of its nodes left out (the nodes whose
    packets are lost now), the weights equal the cold search's to 1e-13 (weights are O(1): a few
    hundred ulps of the quadratically converged fixed point)."""
    rng = np.random.default_rng(5)
    for M in (2, 4, 8):
        for _ in range(10):
            Ys = node_set(rng, M, 3)
            last = covariance_intersection_weights(Ys)
            moved = [Y @ (np.eye(3) + 0.01 * rng.standard_normal((3, 3))) for Y in Ys]
            moved = [(Y + Y.T) / 2 for Y in moved]
            cold = covariance_intersection_weights(moved)
            warm = covariance_intersection_weights(moved, start=last)
            assert np.max(np.abs(warm - cold)) <= 1e-13, (M, warm, cold)
            kept = np.flatnonzero(rng.random(M) < 0.5)
            if kept.size > 1 and last[kept].sum() > 0:
                part = [moved[i] for i in kept]
                warm = covariance_intersection_weights(part, start=last[kept])
                assert np.max(np.abs(warm - covariance_intersection_weights(part))) <= 1e-13


def optimality_bound(Ys, w):
    """An upper bound on |w - w*| from the optimality conditions alone, w* the minimiser of the
    criterion on the simplex (independent of how w was found). With G = grad f(w) and lambda the
    mean of G over w's support, e_i = G_i - lambda where w_i > 0 and max(0, lambda - G_i) where
    w_i = 0 (a zero weight whose gradient is below lambda should grow). f is strongly convex with
    modulus rho and w* optimal, so rho |w - w*|^2 <= <G, w - w*> = <G - lambda 1, w - w*> <= |e| |w - w*|:
    |w - w*| <= |e| / rho."""
    rho = rho_at(Ys)
    G = criterion(Ys, rho)[1](w)
    on = w > 0
    lam = G[on].mean()
    e = np.where(on, G - lam, np.maximum(0.0, lam - G))
    return np.linalg.norm(e) / rho


@pytest.mark.parametrize("M", [2, 3, 4, 6, 8, 12, 16])
def test_the_step_cap_reaches_the_optimum_from_the_cold_start(M):
    """constants.ci_iterations rests on a measurement: from w_i = 1/M (the cold start, the
    longest search), that many Newton steps reach the minimiser. Pinned here against the
    optimality conditions, which do not depend on the search: after exactly ci_iterations(M)
    steps with the early stop off, every weight is within 1e-12 of the minimiser on node sets of
    n = 2..6 spread over two decades (node_set). 1e-12: a hundred times below the 1e-10 the
    double C is held to against the reference, and above the bound's own rounding (~1e-15 |g| /
    rho; measured at most 1.7e-14 here). The cap is tight: at M = 16 one step fewer leaves a set
    further than 1e-12 (measured 1.6e-11), two fewer further than 1e-10 at M >= 8 (1e-6)."""
    rng = np.random.default_rng(2000 + M)
    one_fewer, two_fewer = [], []
    for trial in range(40):
        Ys = node_set(rng, M, 2 + trial % 5)
        w = covariance_intersection_weights(Ys, ci_iterations(M), tolerance=0.0)
        assert np.all(w >= 0) and abs(w.sum() - 1) < 1e-12
        assert optimality_bound(Ys, w) <= 1e-12, (trial, w)
        for fewer, out in ((1, one_fewer), (2, two_fewer)):
            out.append(optimality_bound(Ys, covariance_intersection_weights(Ys, ci_iterations(M) - fewer,
                                                                            tolerance=0.0)))
    if M == 16:
        assert max(one_fewer) > 1e-12
    if M >= 8:
        assert max(two_fewer) > 1e-10
