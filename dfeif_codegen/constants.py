"""Numbers the numpy reference and the generated C must share, defined once.

Both sides import them from here, so the generator never depends on the reference: a change to
either constant changes the reference and the C together, and the equivalence tests keep holding.
"""

CI_REGULARISER = 1e-2
"""Covariance intersection minimises tr(P(w)) + rho/2 |w|^2 with rho = CI_REGULARISER * max_i H_ii:
the quadratic term makes the optimum unique when nodes carry the same information."""

CI_ITERATIONS = 12
"""The fewest Newton steps of the covariance-intersection weights (see ci_iterations)."""


CI_TOLERANCE = {"double": 1e-12, "float": 0.0}
"""The search stops early after a full Newton step (no weight fixed at 0 or freed) of at most
this size in every weight. In the tail the steps shrink by ~1e-2 each (rho follows the iterate,
docs/algorithms.md), so the weights are then ~1e-2 of the tolerance from the fixed point: 1e-14 in
double, where the reference and the C stay equal even when one of them stops a step earlier.
Single precision runs the full count (0: it stops only on a step of exactly 0, after which every
step is 0): there the steps' rounding floor is ~1e-6, and stopping near it re-draws the rounding
of the weights at the float CI master's hardest steps (measured: 1e-6 moved a user model's float
master from within 1e-4 of the reference to 1.48e-4; tests/test_user_models.py)."""


def ci_iterations(nodes: int) -> int:
    """Newton steps of the covariance-intersection weights for a master of `nodes` nodes: fixed,
    so the C's run time is bounded. The active-set search sets at most one weight to 0 per step,
    so a sparse optimum (most of 16 nodes at weight 0) needs about one step per node plus a few
    for Newton's convergence: measured, M + 8 steps reach the optimum to 1e-10 on random node
    sets where 12 steps left tr P 30% above it at M = 16 (tests/test_ci_weights.py). The cap is the worst case;
most searches stop earlier (CI_TOLERANCE)."""
    return max(CI_ITERATIONS, nodes + 8)
