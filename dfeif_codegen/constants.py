"""Numbers the numpy reference and the generated C must share, defined once.

Both sides import them from here, so the generator never depends on the reference: a change to
either constant changes the reference and the C together, and the equivalence tests keep holding.
"""

CI_REGULARISER = 1e-2
"""Covariance intersection minimises tr(P(w)) + rho/2 |w|^2 with rho = CI_REGULARISER * max_i H_ii
at the search's start (w_i = 1/M): the quadratic term makes the optimum unique when nodes carry the
same information."""

CI_ITERATIONS = 8
"""Newton steps of the covariance-intersection weights, at most (see ci_iterations)."""


CI_TOLERANCE = {"double": 1e-12, "float": 0.0}
"""The search stops early after a step that fixed and freed no weight and moved none by more than
this. rho is fixed for the search, so Newton's steps shrink quadratically in the tail: the step
after one of 1e-12 is ~1e-24, and the weights are then at the fixed point to rounding, where the
reference and the C stay equal even when one of them stops a step earlier. Single precision runs
the full count (0: it stops only on a step of exactly 0, after which every step is 0): there the
steps' rounding floor is ~1e-6, and stopping near it re-draws the rounding of the weights at the
float CI master's hardest steps (measured: 1e-6 moved a user model's float master from within
1e-4 of the reference to 1.48e-4; tests/test_user_models.py)."""


def ci_iterations(nodes: int) -> int:
    """Newton steps of the covariance-intersection weights for a master of `nodes` nodes: fixed,
    so the C's run time is bounded, and the same for every M, because one step can fix any number
    of weights at 0 (its active-set pivots). Measured from the cold start w_i = 1/M on 1,200 random
    node sets of M = 2, 4, 8, 16 and n = 2..6 (tests/test_ci_weights.py's generator): the fixed
    point to 1e-13 took at most 5 steps at M = 2, 7 at M = 4 and 8 at M = 8 and 16 (1e-10: 5, 7,
    7, 7); tests/test_ci_weights.py checks the optimality conditions after this many steps. It was
    10 before (two steps past the measured need: 20% of the worst-case fuse at M = 8). The cap is
    the worst case; most searches stop earlier (warm starts in two or three steps)."""
    del nodes
    return CI_ITERATIONS


CHANNEL_RESTART_RATIO = 0.5
"""The difference rule's channel (docs/algorithms.md, master) is skipped for a node whose own
prediction holds less than the master's prediction of its last fused packet: some diagonal entry
of that prediction below this fraction of the node's. Without a restart the node's prediction
holds that packet's information and more, so in exact arithmetic it is never larger; on an
entry the gap's frames barely moved (none came, or late ones that told little of it) the two
are equal but for rounding, which the carry over N steps in one (docs/algorithms.md, master 1)
makes far larger than one ulp (4.5e-13 relative on the arm, three nodes, a packet three steps
on): the decision must lie far from 1, where no rounding reaches it. A node back from a restart
predicts from its start-up prior, many times wider."""

NODES_LIMIT = 16
"""Camera nodes a module is built for, at most: a scenario's [[nodes]] and --nodes alike."""
