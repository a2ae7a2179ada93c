"""The master: fuses the nodes' estimates in information form (docs/mathematics.md section 5, order of
operations in docs/algorithms.md "Master").

Three rules: `paper` (the chapter's sum of informations, overconfident because the common prior
is counted once per node), `difference` (information gains over each node's own prediction: equal
to a centralized Kalman filter when every node predicts with the same v), and `ci` (covariance
intersection: consistent whatever the correlation between the nodes' errors).
"""

from __future__ import annotations

import numpy as np

from dfeif_codegen.constants import CHANNEL_RESTART_RATIO, CI_REGULARISER, CI_TOLERANCE, ci_iterations
from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.reference.linalg import cholesky, spd_inv, wrap
from dfeif_codegen.reference.node import Packet

RULES = ("paper", "difference", "ci")


def _ci_derivatives(Ys: list[np.ndarray], w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gradient and Hessian of tr((sum w_i Y_i)^-1) in w."""
    P = spd_inv(sum(wi * Y for wi, Y in zip(w, Ys)))
    pyp = [P @ Y @ P for Y in Ys]
    return -np.array([np.trace(a) for a in pyp]), 2 * np.array([[np.trace(a @ Y @ P) for Y in Ys] for a in pyp])


def covariance_intersection_weights(Ys: list[np.ndarray], iterations: int | None = None,
                                    tolerance: float = CI_TOLERANCE["double"],
                                    start: np.ndarray | None = None) -> np.ndarray:
    """Weights on the simplex minimising tr((sum w_i Y_i)^-1) + rho/2 |w|^2 (docs/algorithms.md,
    "ci"), in at most `iterations` Newton steps (default ci_iterations(len(Ys)), as the C) from
    `start` (the master passes its last weights, renormalised; w_i = 1/M if None or all 0), the
    weights at 0 fixed. rho = CI_REGULARISER * max_i H_ii at w_i = 1/M, whatever the start: fixed
    for the search and independent of history, so Newton converges quadratically. The term makes
    the optimum unique when two Y_i are equal (no split decided by round-off) and the weights a
    Lipschitz function of the Y_i, so that single precision reproduces them. Each step minimises the quadratic model over
    the simplex by active-set pivots: a weight the step would make negative stops it at zero and
    is fixed there, the model's gradient moves with the step and the rest is solved again, so one
    step can fix several weights; a fixed weight is freed once its gradient is the smallest. The
    search ends early after a step that froze or freed no weight and moved none by more than
    `tolerance` (0: always the full count). One node needs no search: its weight is 1."""
    count = len(Ys)
    iterations = ci_iterations(count) if iterations is None else iterations
    uniform = np.full(count, 1.0 / count)
    if count == 1:
        return uniform
    total = 0.0 if start is None else float(np.sum(start))
    w = uniform if total <= 0 else np.asarray(start, dtype=float) / total
    free = w > 0
    at_uniform = _ci_derivatives(Ys, uniform)
    rho = CI_REGULARISER * np.max(np.diag(at_uniform[1]))
    for step in range(iterations):
        g, H = at_uniform if step == 0 and w is uniform else _ci_derivatives(Ys, w)
        g, H = g + rho * w, H + rho * np.eye(count)
        freed = ~free & (g < np.min(g[free]))
        free |= freed
        pivoted = False
        while True:
            f = np.flatnonzero(free)
            kkt = np.block([[H[np.ix_(f, f)], np.ones((f.size, 1))], [np.ones((1, f.size)), np.zeros((1, 1))]])
            d = np.zeros(count)
            d[f] = np.linalg.solve(kkt, np.append(-g[f], 0.0))[:f.size]
            shrinking = f[d[f] < 0]
            ratios = w[shrinking] / -d[shrinking]
            if not (ratios.size and ratios.min() <= 1.0):
                break
            blocking, r = shrinking[np.argmin(ratios)], ratios.min()
            w = w + r * d
            w[blocking], free[blocking] = 0.0, False
            g = g + r * (H @ d)
            pivoted = True
        w = w + d
        if not (freed.any() or pivoted) and np.max(np.abs(d)) <= tolerance:
            break
    return w


class Master:
    """Fusion centre. Per step: `fuse` the packets that arrived, then `predict` with the input
    it broadcasts to the nodes."""

    def __init__(self, flat, ts, q, x0, P0, n_nodes: int, rule: str = "difference", max_lag: int = 32,
                 predictor: str = predictors.DEFAULT, disturbance=None, dtype=np.float64):
        """`dtype`: the precision of every stored value and operation (float32: the single-precision
        twin check/verify.py judges a float build by)."""
        if rule not in RULES:
            raise ValueError(f"rule must be one of {RULES}, not {rule!r}")
        self.rule, self.n_nodes, self.max_lag = rule, n_nodes, max_lag
        self.predictor = predictors.make(predictor, flat, ts, q, dtype, disturbance=disturbance)
        self.A, self.Q = self.predictor.Phi, self.predictor.Q
        self.heads = np.array(flat.heads)
        self.angle = np.array([c.angle for c in flat.chains])
        self.k = 0
        self.x, self.P = np.array(x0, dtype=dtype), np.array(P0, dtype=dtype)
        self.x_prior, self.P_prior = self.x, self.P
        self._v: dict[int, np.ndarray] = {}
        self.weights = np.zeros(n_nodes)     # the last CI weights, node by node
        self.weighed = np.zeros(n_nodes, dtype=bool)     # the nodes the last CI fuse used
        # difference rule: per node, the last packet fused (its step, x and P): the channel
        self.last: list[Packet | None] = [None] * n_nodes

    def fuse(self, packets: list[Packet | None]) -> None:
        """One entry per node, None when its packet is absent; stale packets (at most max_lag
        steps old) are predicted to the current step, older or future ones are ignored. The
        difference rule also ignores a packet not newer than the last one fused from its node,
        takes the gain of one after lost packets over that last one (`_channel`), and adds to
        the estimate: called again in a step it adds the packets not yet fused (the paper and
        ci rules fuse the packets given from the prediction each time)."""
        if len(packets) != self.n_nodes:
            raise ValueError(f"expected {self.n_nodes} entries (None for absent), got {len(packets)}")
        picked = [i for i, p in enumerate(packets) if p is not None and 0 <= self.k - p.step <= self.max_lag
                  and not self._covered(i, p)]
        usable = [self._on_branch(self._channel(i, self._bring(packets[i]), packets[i].step), self.x_prior)
                  for i in picked]
        # the difference rule adds information to the estimate (the prediction at the step's first
        # call): a second call in the step adds the packets the first did not fuse, the others
        # fuse the packets given from the prediction again
        c = self.x if self.rule == "difference" else self.x_prior
        if self.rule == "difference":   # the C writes them once the whole fuse has succeeded
            for i in picked:
                self.last[i] = packets[i]
        if not usable:
            if self.rule != "difference":
                self.x, self.P = self.x_prior, self.P_prior
            return
        # information about the master's prior c: y = Y (x - c), x = c + P y; the same in exact
        # arithmetic as y = Y x, without cancelling large Y x terms (docs/algorithms.md)
        Ys = [spd_inv(P) for _, P, _, _ in usable]
        ys = [Y @ (x - c) for Y, (x, _, _, _) in zip(Ys, usable)]
        if self.rule == "paper":
            Y, y = sum(Ys), sum(ys)
        elif self.rule == "difference":
            D, y = np.zeros_like(self.P), np.zeros_like(c)
            for Yi, yi, (_, _, xp, Pp) in zip(Ys, ys, usable):
                Y_pred = spd_inv(Pp)
                D, y = D + (Yi - Y_pred), y + (yi - Y_pred @ (xp - c))
            # (P^-1 + D)^-1 in the factor P = L L' of the estimate it adds to, without inverting
            # it twice (the C's order, kernels/fusion.py fuse_finish_difference)
            L = cholesky(self.P)
            self.P = L @ spd_inv(np.eye(len(c), dtype=c.dtype) + L.T @ D @ L) @ L.T
            self.x = c + self.P @ y
            return
        else:
            # from the last fuse's weights if it used every node used now: the nodes' covariances
            # move little between steps, so the search starts near its optimum (a start on a few
            # nodes, as after drops, converges slowly: then from 1/M; docs/algorithms.md)
            warm = bool(np.all(self.weighed[picked]))
            w = covariance_intersection_weights(Ys, ci_iterations(self.n_nodes),
                                                start=self.weights[picked] if warm else None)
            self.weights, self.weighed = np.zeros(self.n_nodes), np.zeros(self.n_nodes, dtype=bool)
            self.weights[picked], self.weighed[picked] = w, True
            Y = sum(wi * Yi for wi, Yi in zip(w, Ys))
            y = sum(wi * yi for wi, yi in zip(w, ys))
        self.P = spd_inv(Y.astype(c.dtype, copy=False))
        self.x = c + self.P @ y.astype(c.dtype, copy=False)

    def predict(self, v) -> None:
        """Predict with the input it broadcasts (u for the held predictor, v for the Brunovsky one),
        the one the nodes predict with."""
        v = np.atleast_1d(np.asarray(v, dtype=self.x.dtype))
        self._v[self.k] = v
        self._v.pop(self.k - self.max_lag, None)
        self.x_prior = self.predictor.mean(self.x, v)
        self.P_prior = self.predictor.covariance(self.P, v)
        self.x, self.P = self.x_prior, self.P_prior   # the estimate until a fuse adds to it
        self.k += 1

    def _covered(self, i: int, p: Packet) -> bool:
        """Difference rule: a packet not newer than the last one fused from its node brings
        nothing the master lacks (that one's gain, taken over a gap, covered its step)."""
        last = self.last[i]   # written by the difference rule only
        return last is not None and p.step <= last.step

    def _channel(self, i: int, item, step: int):
        """Difference rule: where packets of node i were lost since the last one fused (step j),
        the gain is taken over its prediction of that packet's estimate, not over the node's own
        prediction: (x_j, P_j) brought to the current step stands for x_pred, P_pred, so the
        gain holds every frame the node used since j, which the lost packets carried (a channel
        filter; docs/algorithms.md, master). Only while step j's inputs are kept, and not where
        that prediction is far better informed on a diagonal entry than the node's own
        (CHANNEL_RESTART_RATIO): after a node restarts, its own prediction holds less than its
        old estimate did, and the gain is then its own."""
        last = self.last[i]
        if last is None or step - last.step <= 1 or self.k - last.step > self.max_lag:
            return item
        x, P, x_pred, P_pred = item
        inputs = [self._v[s] for s in range(last.step, self.k)]
        xc, = self.predictor.bring([last.x], inputs)
        Pc, = self.predictor.carry([last.P], inputs)
        # without a restart diag(Pc) >= diag(P_pred) but for rounding (equal: no frame in the gap)
        if np.all(np.diag(Pc) >= np.diag(P_pred) * CHANNEL_RESTART_RATIO):
            return x, P, xc, Pc
        return item

    def _on_branch(self, item, c: np.ndarray):
        """A node's (x, P, x_pred, P_pred) with each angle head moved by whole turns to the branch
        nearest the master's prediction c (x and x_pred by the same turns, so a node's gain is
        kept): 6.383 and 0.1 are the same angle and fuse as such (docs/algorithms.md, master)."""
        if not np.any(self.angle):
            return item
        x, P, xp, Pp = item
        d = x[self.heads] - c[self.heads]
        turns = np.where(self.angle, d - wrap(d, self.angle), 0.0)
        x, xp = x.copy(), xp.copy()
        x[self.heads] -= turns
        xp[self.heads] -= turns
        return x, P, xp, Pp

    def _bring(self, p: Packet):
        """A packet's (x, P, x_pred, P_pred) brought from its step to the current one with the
        stored inputs, by the predictor: the covariances in one step of length N where the
        transition is constant (Φ over N periods and the noise of N periods in closed form, equal
        to N one-step predictions), else step by step; the means step by step unless linear
        (docs/algorithms.md, master 1)."""
        N = self.k - p.step
        if N == 0:
            return p.x, p.P, p.x_pred, p.P_pred
        inputs = [self._v[i] for i in range(p.step, self.k)]
        x, x_pred = self.predictor.bring([p.x, p.x_pred], inputs)
        P, P_pred = self.predictor.carry([p.P, p.P_pred], inputs)
        return x, P, x_pred, P_pred
