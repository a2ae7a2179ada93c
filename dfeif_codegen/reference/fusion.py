"""The master: fuses the nodes' estimates in information form (docs/mathematics.md section 5, order of
operations in docs/algorithms.md "Master").

Three rules: `paper` (the chapter's sum of informations, overconfident because the common prior
is counted once per node), `difference` (information gains over each node's own prediction: equal
to a centralized Kalman filter when every node predicts with the same v), and `ci` (covariance
intersection: consistent whatever the correlation between the nodes' errors).
"""

from __future__ import annotations

import numpy as np

from dfeif_codegen.constants import CI_REGULARISER, CI_TOLERANCE, ci_iterations
from dfeif_codegen.reference.linalg import spd_inv
from dfeif_codegen.reference.node import Packet

RULES = ("paper", "difference", "ci")


def covariance_intersection_weights(Ys: list[np.ndarray], iterations: int | None = None,
                                    tolerance: float = CI_TOLERANCE["double"]) -> np.ndarray:
    """Weights on the simplex minimising tr((sum w_i Y_i)^-1) (docs/algorithms.md, "ci"), in at
    most `iterations` steps (default ci_iterations(len(Ys)); the master passes its node count, as
    the C): Newton steps on the free weights; a weight the step would make negative stops the step
    at zero and is fixed there, and is freed again once its gradient is the smallest. The search
    ends early after a full step that froze or freed no weight and moved none by more than
    `tolerance` (0: always the full count). A small regulariser (rho/2)|w|^2 keeps the optimum
    unique when two Y_i are equal, so the split of weight between equal nodes is not decided by
    round-off, and makes the weights a Lipschitz function of the Y_i, so that single precision
    reproduces them (docs/algorithms.md). One node needs no search: its weight is 1."""
    count = len(Ys)
    iterations = ci_iterations(count) if iterations is None else iterations
    w = np.full(count, 1.0 / count)
    if count == 1:
        return w
    free = np.ones(count, dtype=bool)
    for _ in range(iterations):
        P = spd_inv(sum(wi * Y for wi, Y in zip(w, Ys)))
        pyp = [P @ Y @ P for Y in Ys]
        g = -np.array([np.trace(a) for a in pyp])
        H = 2 * np.array([[np.trace(a @ Y @ P) for Y in Ys] for a in pyp])
        rho = CI_REGULARISER * np.max(np.diag(H))  # rho/2 |w|^2: a unique, well-conditioned optimum
        g, H = g + rho * w, H + rho * np.eye(count)
        freed = ~free & (g < np.min(g[free]))
        free |= freed
        f = np.flatnonzero(free)
        H_f = H[np.ix_(f, f)]
        kkt = np.block([[H_f, np.ones((f.size, 1))], [np.ones((1, f.size)), np.zeros((1, 1))]])
        d = np.zeros(count)
        d[f] = np.linalg.solve(kkt, np.append(-g[f], 0.0))[:f.size]
        shrinking = f[d[f] < 0]
        ratios = w[shrinking] / -d[shrinking]
        if ratios.size and ratios.min() <= 1.0:
            blocking = shrinking[np.argmin(ratios)]
            w = w + ratios.min() * d
            w[blocking], free[blocking] = 0.0, False
        else:
            w = w + d
            if not freed.any() and np.max(np.abs(d)) <= tolerance:
                break
    return w


class Master:
    """Fusion centre. Per step: `fuse` the packets that arrived, then `predict` with the input
    it broadcasts to the nodes."""

    def __init__(self, flat, ts, q, x0, P0, n_nodes: int, rule: str = "difference", max_lag: int = 32):
        if rule not in RULES:
            raise ValueError(f"rule must be one of {RULES}, not {rule!r}")
        self.rule, self.n_nodes, self.max_lag = rule, n_nodes, max_lag
        self.A, self.B, _ = flat.discrete(ts)
        self.Q = flat.process_noise(ts, q)
        self._flat, self._ts, self._q = flat, ts, q
        self._ahead: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.k = 0
        self.x, self.P = np.array(x0, dtype=float), np.array(P0, dtype=float)
        self.x_prior, self.P_prior = self.x, self.P
        self._v: dict[int, np.ndarray] = {}

    def fuse(self, packets: list[Packet | None]) -> None:
        """One entry per node, None when its packet is absent; stale packets (at most max_lag
        steps old) are predicted to the current step, older or future ones are ignored."""
        if len(packets) != self.n_nodes:
            raise ValueError(f"expected {self.n_nodes} entries (None for absent), got {len(packets)}")
        usable = [self._bring(p) for p in packets if p is not None and 0 <= self.k - p.step <= self.max_lag]
        if not usable:
            self.x, self.P = self.x_prior, self.P_prior
            return
        # information about the master's prior c: y = Y (x - c), x = c + P y; the same in exact
        # arithmetic as y = Y x, without cancelling large Y x terms (docs/algorithms.md)
        c = self.x_prior
        Ys = [spd_inv(P) for _, P, _, _ in usable]
        ys = [Y @ (x - c) for Y, (x, _, _, _) in zip(Ys, usable)]
        if self.rule == "paper":
            Y, y = sum(Ys), sum(ys)
        elif self.rule == "difference":
            Y, y = spd_inv(self.P_prior), np.zeros_like(c)
            for Yi, yi, (_, _, xp, Pp) in zip(Ys, ys, usable):
                Y_pred = spd_inv(Pp)
                Y, y = Y + (Yi - Y_pred), y + (yi - Y_pred @ (xp - c))
        else:
            w = covariance_intersection_weights(Ys, ci_iterations(self.n_nodes))
            Y = sum(wi * Yi for wi, Yi in zip(w, Ys))
            y = sum(wi * yi for wi, yi in zip(w, ys))
        self.P = spd_inv(Y)
        self.x = c + self.P @ y

    def predict(self, v) -> None:
        v = np.atleast_1d(np.asarray(v, dtype=float))
        self._v[self.k] = v
        self._v.pop(self.k - self.max_lag, None)
        self.x_prior = self.A @ self.x + self.B @ v
        self.P_prior = self.A @ self.P @ self.A.T + self.Q
        self.k += 1

    def _bring(self, p: Packet):
        """A packet's (x, P, x_pred, P_pred) brought from its step to the current one in one step
        of length N: A(N Ts), Q_d(N Ts) in closed form and the stored inputs' effect (docs/algorithms.md,
        master 1), equal to N one-step predictions."""
        N = self.k - p.step
        if N == 0:
            return p.x, p.P, p.x_pred, p.P_pred
        effect = np.zeros_like(p.x)
        for i in range(p.step, self.k):
            effect = self.A @ effect + self.B @ self._v[i]
        if N not in self._ahead:
            self._ahead[N] = (self._flat.discrete(N * self._ts)[0], self._flat.process_noise(N * self._ts, self._q))
        A, Q = self._ahead[N]
        return A @ p.x + effect, A @ p.P @ A.T + Q, A @ p.x_pred + effect, A @ p.P_pred @ A.T + Q
