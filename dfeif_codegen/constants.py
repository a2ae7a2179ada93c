"""Numbers the numpy reference and the generated C must share, defined once.

Both sides import them from here, so the generator never depends on the reference: a change to
either constant changes the reference and the C together, and the equivalence tests keep holding.
"""

CI_REGULARISER = 1e-2
"""Covariance intersection minimises tr(P(w)) + rho/2 |w|^2 with rho = CI_REGULARISER * max_i H_ii:
the quadratic term makes the optimum unique when nodes carry the same information."""

CI_ITERATIONS = 12
"""Newton steps of the covariance-intersection weights: fixed, so the C's run time is bounded."""
