"""Numbers the numpy reference and the generated C must share, defined once.

Both sides import them from here, so the generator never depends on the reference: a change to
either constant changes the reference and the C together, and the equivalence tests keep holding.
"""

CI_REGULARISER = 1e-2
"""Covariance intersection minimises tr(P(w)) + rho/2 |w|^2 with rho = CI_REGULARISER * max_i H_ii:
the quadratic term makes the optimum unique when nodes carry the same information."""

CI_ITERATIONS = 12
"""The fewest Newton steps of the covariance-intersection weights (see ci_iterations)."""


CI_TOLERANCE = {"double": 1e-12, "float": 1e-6}
"""The search stops early after a full Newton step (no weight stopped at 0 or freed) of at most
this size in every weight. In the tail the steps shrink by ~1e-2 each (rho follows the iterate,
docs/algorithms.md), so the weights are then ~1e-2 of the tolerance from the fixed point: 1e-14 in
double, where the reference and the C stay equal even when one of them stops a step earlier. In
single precision 1e-6, near its rounding floor for the steps: measured (from w = 1/M), 3e-6
already moved the float CI master from 9.2e-5 to 1.09e-4 of the double reference
(tests/test_equivalence.py, two_link_arm), 1e-6 leaves it where the full count of steps puts it."""


def ci_iterations(nodes: int) -> int:
    """The most Newton steps of the covariance-intersection weights for a master of `nodes`
    nodes: fixed, so the C's run time is bounded (the worst case). Set when the active-set search
    fixed one weight at 0 per step (a sparse 16-node optimum needed about one step per node plus a
    few for Newton's convergence); the projected step fixes several at once, and with the 1/tr P_i
    start the searches stopped after at most 14 steps at M = 8 and 13 at M = 16 (100 sparse node
    sets each), so the cap is kept as a margin, not lowered on that sample."""
    return max(CI_ITERATIONS, nodes + 8)
