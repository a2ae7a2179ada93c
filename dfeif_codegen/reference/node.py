"""One camera node: the derivative-free Kalman filter in canonical coordinates, with packet drops
and late measurements, exactly in the order of docs/algorithms.md ("Node filter").

No Jacobian appears at run time: the covariance moves by constant matrices and the mean by the
predictor's map (predictor.py: by default the canonical dynamics integrated with the applied u
held; `brunovsky`, the chapter's linear chain driven by the broadcast v = F + G u). A window of
the last `max_lag + 1` steps is kept so that a late measurement can either be replayed in time
order (exact) or, with the Brunovsky predictor, folded in at once by Xia et al.'s retrodiction
(docs/mathematics.md section 4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.reference.linalg import SingularMatrixError, cholesky, spd_solve, wrap

COUNTERS = ("updates", "drops", "late_applied", "late_rejected", "outliers")


@dataclass
class Packet:
    """What a node sends to the master after all updates of `step`."""

    step: int
    x: np.ndarray
    P: np.ndarray
    x_pred: np.ndarray
    P_pred: np.ndarray


@dataclass
class _Slot:
    """One step of history: its prior, its measurement, what its update computed, and the
    input used to predict out of it (u, or v with the Brunovsky predictor)."""

    x_prior: np.ndarray
    P_prior: np.ndarray
    z: np.ndarray | None = None
    gamma: bool = False
    e: np.ndarray | None = None
    S: np.ndarray | None = None
    K: np.ndarray | None = None
    P_post: np.ndarray | None = None
    v: np.ndarray | None = None


def measurement_covariance(R, m: int) -> np.ndarray:
    """R given as an (m, m) matrix, or as a scalar / 1-D diagonal."""
    R = np.asarray(R, dtype=float)
    if R.ndim < 2:
        R = np.diag(np.broadcast_to(R, (m,)))
    if R.shape != (m, m):
        raise ValueError(f"R must be ({m}, {m}), a length-{m} diagonal or a scalar, got shape {R.shape}")
    return R


def posterior(P: np.ndarray, K: np.ndarray, R: np.ndarray, heads) -> np.ndarray:
    """P - K C P (docs/algorithms.md, node update), with the entries in a head's row or column
    as R K' (equal in exact arithmetic: I - P_HH S^-1 = R S^-1), the upper triangle mirrored."""
    out = P - K @ P[heads, :]
    RK = R @ K.T
    out[heads, :] = RK
    out[:, heads] = RK.T
    return np.triu(out) + np.triu(out, 1).T


class NodeFilter:
    """Local filter of one node. Per step: `update` once, `update_delayed` any number of times,
    then `predict` with the input the master broadcast: the applied u (the default `held`
    predictor), u and the master's flat outputs (`scheduled`) or v = F + G u (`brunovsky`)."""

    def __init__(self, flat, ts: float, q, R, x0, P0, max_lag: int = 32, oosm: str = "replay",
                 dtype=np.float64, predictor: str = predictors.DEFAULT, disturbance=None,
                 mid_run: bool = False, gate: float | None = None):
        """`dtype` is the precision of every stored value and operation: float64 for the
        reference; float32 gives a second single-precision implementation (numpy and LAPACK
        instead of the generated C), to tell the method's conditioning from the C's rounding
        (the held mean instruction by instruction in float32: numeric.SinglePrecision). `mid_run`: the node
        starts later than step 0 with the prior of step 0 (a restart; the C's node_mid_run):
        late frames of steps before its first measurement are refused (`update_delayed`).
        `gate`: the innovation gate in standard deviations (the C's --gate; None: none)."""
        if oosm not in ("replay", "retrodict"):
            raise ValueError(f"oosm must be 'replay' or 'retrodict', not {oosm!r}")
        predictors.check(predictor, oosm, disturbance)
        if max_lag < 1:
            raise ValueError("max_lag must be at least 1")
        self.flat, self.ts, self.q, self.oosm, self.max_lag = flat, ts, q, oosm, max_lag
        self.gate = None if gate is None else float(gate)
        self.dtype = np.dtype(dtype)
        self.predictor = predictors.make(predictor, flat, ts, q, self.dtype, disturbance)
        self.A, self.Q = self.predictor.Phi, self.predictor.Q
        self.n = len(self.A)     # flat.n, plus the disturbance states if asked for
        self.B, self.C = (a.astype(self.dtype) for a in flat.discrete(ts)[1:])
        self.R = measurement_covariance(R, flat.m).astype(self.dtype)
        self.heads = np.array(flat.heads)
        self.angle = np.array([c.angle for c in flat.chains])
        self._head_block = np.ix_(self.heads, self.heads)   # hot path: index arrays made once
        self.k, self._updated = 0, False
        self.x, self.P = np.array(x0, dtype=self.dtype), np.array(P0, dtype=self.dtype)
        self.x_pred, self.P_pred = self.x, self.P
        self.counters = dict.fromkeys(COUNTERS, 0)
        self._ring: list[_Slot | None] = [_Slot(self.x, self.P)] + [None] * max_lag
        self.first: int | None = None if mid_run else 0   # the first step a late frame may be of

    # protocol ---------------------------------------------------------------------------------
    def update(self, z, gamma: bool) -> bool:
        """The on-time update of step k (`gamma` False: the measurement was dropped or is late;
        `z` is then ignored and may be None). False if the innovation gate refused z: the step
        then goes on without it, as the C's caller does after ERR_OUTLIER."""
        if self._updated:
            raise RuntimeError(f"update called twice at step {self.k}")
        slot = self._slot(self.k)
        if gamma and self._outlier(slot.x_prior, slot.P_prior, self._z(z)):
            gamma = False
        slot.gamma = bool(gamma)
        slot.z = self._z(z) if gamma else np.full(self.flat.m, np.nan, dtype=self.dtype)
        self.x, self.P = self._correct(slot)
        self.counters["updates" if gamma else "drops"] += 1
        if gamma and self.first is None:
            self.first = self.k
        self._updated = True
        return bool(gamma)

    def update_delayed(self, z, lag: int) -> bool:
        """Apply the measurement taken at step k - lag. False (and counted) if it is outside the
        window, from the future or the present, its step already has a measurement, or (a node
        started `mid_run`) it is of a step before the first measurement `update` applied: there
        the node holds the prior of step 0 alone. After a restart that prior was 18 sigma from
        the plant (`codegen network`'s node-restart fault), a late frame there corrected it by
        0.89 rad, the held predictor's mean over that correction departed from the Φ₀ the
        master's difference rule assumes, and the master's θ'' went 28 sigma off
        (docs/mathematics.md section 3)."""
        if not self._updated:
            raise RuntimeError(f"update_delayed before update at step {self.k}")
        lag = int(lag)
        if (lag < 1 or lag > self.max_lag or lag > self.k or self.first is None or self.k - lag < self.first
                or self._slot(self.k - lag).gamma):
            self.counters["late_rejected"] += 1
            return False
        slot = self._slot(self.k - lag)
        if self.oosm == "replay":
            if self._outlier(slot.x_prior, slot.P_prior, self._z(z)):
                return False
            slot.z, slot.gamma = self._z(z), True
            self._replay(self.k - lag)
        else:
            try:
                x, P, e, W = self._retrodict(lag, self._z(z))
            except SingularMatrixError:   # a stale history made W or P* indefinite: reject
                self.counters["late_rejected"] += 1
                return False
            if self._refused(e, W):
                return False
            self.x, self.P = x, P
            slot.z, slot.gamma = self._z(z), True
        self.counters["late_applied"] += 1
        return True

    def predict(self, v) -> None:
        """Predict to step k + 1 with the input the master broadcast for step k (u for the held
        predictor, v for the Brunovsky one)."""
        if not self._updated:
            raise RuntimeError(f"predict before update at step {self.k}")
        v = np.atleast_1d(np.asarray(v, dtype=self.dtype))
        self._slot(self.k).v = v
        self.x, self.P = self._propagate(self.x, self.P, v)
        self.k += 1
        self._ring[self.k % (self.max_lag + 1)] = _Slot(self.x, self.P)
        self.x_pred, self.P_pred = self.x, self.P
        self._updated = False

    def packet(self) -> Packet:
        return Packet(self.k, self.x.copy(), self.P.copy(), self.x_pred.copy(), self.P_pred.copy())

    # steps ------------------------------------------------------------------------------------
    def _slot(self, step: int) -> _Slot:
        return self._ring[step % (self.max_lag + 1)]

    def _z(self, z) -> np.ndarray:
        return np.atleast_1d(np.asarray(z, dtype=self.dtype)).reshape(self.flat.m)

    def _outlier(self, x_prior, P_prior, z) -> bool:
        """Whether the gate refuses z at a step with this prior (counted)."""
        return self.gate is not None and self._refused(wrap(z - x_prior[self.heads], self.angle),
                                                       P_prior[self._head_block] + self.R)

    def _refused(self, e, S) -> bool:
        """e' S^-1 e > gate^2, as the C tests it (a NaN passes: the update then fails on it), counted."""
        out = self.gate is not None and float(e @ spd_solve(S, e)) > self.gate ** 2
        self.counters["outliers"] += int(out)
        return out

    def _propagate(self, x, P, v):
        return self.predictor.mean(x, v), self.predictor.covariance(P, v)

    def _correct(self, slot: _Slot):
        """The update of one step from its slot's prior; fills e, S, K, P_post."""
        h, xp, Pp = self.heads, slot.x_prior, slot.P_prior
        slot.e = wrap(slot.z - xp[h], self.angle)
        slot.S = Pp[self._head_block] + self.R
        if slot.gamma:
            slot.K = spd_solve(slot.S, Pp[:, h].T).T
            x, P = xp + slot.K @ slot.e, posterior(Pp, slot.K, self.R, h)
        else:
            slot.K = np.zeros((self.n, self.flat.m), dtype=self.dtype)
            x, P = xp, Pp
        slot.P_post = P
        return x, P

    def _replay(self, start: int) -> None:
        """Re-run steps start..k from the stored priors, rewriting every slot on the way."""
        for j in range(start, self.k + 1):
            slot = self._slot(j)
            x, P = self._correct(slot)
            if j < self.k:
                nxt = self._slot(j + 1)
                nxt.x_prior, nxt.P_prior = self._propagate(x, P, slot.v)
        self.x, self.P = x, P

    def _retrodict(self, N: int, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Xia et al.'s one-shot update (docs/mathematics.md section 4) by the O(N) backward recursion
        of algorithms.md: the corrected (x, P). Only steps updated in sequence (nonzero K)
        contribute a term, and the innovation and its covariance W (the gate's test). Raises
        SingularMatrixError if W or the corrected P is indefinite."""
        A, Q, h, n, k, dt = self.A, self.Q, self.heads, self.flat.n, self.k, self.dtype
        eye = np.eye(n, dtype=dt)

        def apow(i: int) -> np.ndarray:   # A^i in closed form, exact also for negative i
            return self.flat.discrete(i * self.ts)[0].astype(dt)

        def lmat(i: int) -> np.ndarray:   # L_i = I - K(k-i) C
            out = eye.copy()
            out[:, h] -= self._slot(k - i).K
            return out

        P_old = self._slot(k - N).P_post
        sum_w, sum_q, sum_xw = np.zeros(n, dt), np.zeros((n, n), dt), np.zeros((n, n), dt)
        T, E = apow(N - 1) @ Q, eye
        for i in range(N - 1, -1, -1):
            if i < N - 1:
                T = apow(i) @ Q + T @ (A @ lmat(i + 1)).T
                E = lmat(i + 1) @ A @ E
            slot = self._slot(k - i)
            if slot.K.any():
                Ct = T[:, h]                       # C~(i) = T(i) C^T
                D = (A @ E)[h, :]                  # D(i) = C A E(i)
                s_ct = spd_solve(slot.S, Ct.T)     # S^-1 C~^T
                sum_w += Ct @ spd_solve(slot.S, slot.e)
                sum_q += Ct @ s_ct
                sum_xw += P_old @ D.T @ s_ct
        phi1, a_n = apow(-N), apow(N)
        w_a = -phi1 @ sum_w
        q_star = phi1 @ (self.flat.process_noise(N * self.ts, self.q).astype(dt) - sum_q) @ phi1.T
        P_xw = a_n @ sum_xw @ phi1.T - a_n @ q_star
        forced = np.zeros(n, dt)                   # sum_j A^(N-j) B v(k-N+j-1)
        for j in range(k - N, k):
            forced = A @ forced + self.B @ self._slot(j).v
        x_back = phi1 @ (self.x - forced) + w_a
        phi_pxw = phi1 @ P_xw
        W = (phi1 @ self.P @ phi1.T + phi_pxw + phi_pxw.T + q_star)[np.ix_(h, h)] + self.R
        M = spd_solve(W, (self.P @ phi1.T + P_xw)[:, h].T).T
        P_star = self.P - M @ W @ M.T
        P_star = (P_star + P_star.T) / 2          # rounding makes it asymmetric; see algorithms.md
        cholesky(P_star)                           # raises if P* lost definiteness
        e = wrap(z - x_back[h], self.angle)
        return self.x + M @ e, P_star, e, W
