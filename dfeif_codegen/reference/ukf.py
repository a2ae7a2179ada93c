"""The unscented Kalman filter on the physical model: 2n + 1 sigma points x ± sqrt(n) L
(L L' = P; alpha = 1, kappa = 0, beta = 2: every mean weight 1/(2n), the centre's covariance
weight 2), propagated through the same RK4 step as the EKF (one batched CasADi call) and the
outputs `h`. Angle outputs are averaged and differenced on the circle (wrap about the centre)."""

from __future__ import annotations

import numpy as np

from dfeif_codegen.reference.linalg import cholesky, spd_solve, wrap
from dfeif_codegen.reference.physical import PhysicalModel


class UKF:
    def __init__(self, model: PhysicalModel):
        self.model = model
        n = model.n
        self.wm = np.full(2 * n + 1, 1 / (2 * n))
        self.wm[0] = 0.0
        self.wc = self.wm.copy()
        self.wc[0] = 2.0
        self._scale = np.sqrt(n)

    def _sigma(self, x, P):
        L = self._scale * cholesky((P + P.T) / 2)
        return np.column_stack([x, x[:, None] + L, x[:, None] - L])

    def predict(self, x, P, u):
        X = self._sigma(x, P)
        Y = np.asarray(self.model.step_many(X, np.tile(np.reshape(u, (-1, 1)), X.shape[1])))
        mean = Y @ self.wm
        d = Y - mean[:, None]
        Pn = (d * self.wc) @ d.T + self.model.Qx(x)
        return mean, (Pn + Pn.T) / 2

    def update(self, x, P, z, R):
        X = self._sigma(x, P)
        Z = np.asarray(self.model.h_many(X))
        angle = self.model.angle_out[:, None]
        zm = Z[:, 0] + wrap(Z - Z[:, :1], angle) @ self.wm
        dZ = wrap(Z - zm[:, None], angle)
        dX = X - x[:, None]
        S = (dZ * self.wc) @ dZ.T + R
        Pxz = (dX * self.wc) @ dZ.T
        K = spd_solve(S, Pxz.T).T
        Pn = P - K @ S @ K.T
        return x + K @ wrap(z - zm, self.model.angle_out), (Pn + Pn.T) / 2
