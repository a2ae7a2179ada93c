"""Numbers the numpy reference and the generated C must share, defined once.

Both sides import them from here, so the generator never depends on the reference: a change to
either constant changes the reference and the C together, and the equivalence tests keep holding.
"""

CI_REGULARISER = 1e-2
"""Covariance intersection minimises tr(P(w)) + rho/2 |w|^2 with rho = CI_REGULARISER * max_i H_ii:
the quadratic term makes the optimum unique when nodes carry the same information."""

CI_ITERATIONS = 12
"""The fewest Newton steps of the covariance-intersection weights (see ci_iterations)."""


def ci_iterations(nodes: int) -> int:
    """Newton steps of the covariance-intersection weights for a master of `nodes` nodes: fixed,
    so the C's run time is bounded. The active-set search sets at most one weight to 0 per step,
    so a sparse optimum (most of 16 nodes at weight 0) needs about one step per node plus a few
    for Newton's convergence: measured, M + 8 steps reach the optimum to 1e-10 on random node
    sets where 12 steps left tr P 30% above it at M = 16 (tests/test_ci_weights.py)."""
    return max(CI_ITERATIONS, nodes + 8)
