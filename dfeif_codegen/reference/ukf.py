"""The unscented Kalman filter on the physical model: 2n + 1 sigma points x ± sqrt(n) L
(L L' = P; alpha = 1, kappa = 0, beta = 2: every mean weight 1/(2n), the centre's covariance
weight 2), propagated through the same RK4 step as the EKF and the outputs `h`. Angle outputs are
averaged and differenced on the circle (wrap about the centre). Predict and update are each one
CasADi function (physical.FusedFilter); a P that is not positive definite makes the Cholesky
factor, and so the run, not finite."""

from __future__ import annotations

import casadi as ca
import numpy as np

from dfeif_codegen.reference.physical import FusedFilter


class UKF(FusedFilter):
    def __init__(self, model, compiled: bool = False):
        n = model.n
        self.wm = np.full(2 * n + 1, 1 / (2 * n))
        self.wm[0] = 0.0
        self.wc = self.wm.copy()
        self.wc[0] = 2.0
        super().__init__(model, compiled)

    def _sigma(self, x, P):
        L = np.sqrt(self.model.n) * ca.chol((P + P.T) / 2).T      # chol gives the upper factor
        return [x] + [x + L[:, j] for j in range(self.model.n)] + [x - L[:, j] for j in range(self.model.n)]

    def _moments(self, cols, centre):
        mean = sum((w * c for w, c in zip(self.wm, cols)), ca.SX.zeros(cols[0].shape))
        return mean, [c - centre(mean) for c in cols]

    def _cross(self, a, b):
        return sum((w * ai @ bi.T for w, ai, bi in zip(self.wc, a, b)), ca.SX.zeros(a[0].shape[0], b[0].shape[0]))

    def predict_sx(self, x, P, u):
        Y = [self.model.step_sx(c, u) for c in self._sigma(x, P)]
        mean, d = self._moments(Y, lambda mu: mu)
        return mean, self._cross(d, d) + self.model.Qx_sx(x)

    def _outputs(self, x, P):
        """Sigma points, their outputs' mean (on the circle for angles) and deviations from it."""
        X = self._sigma(x, P)
        Z = [self.model.h_sx(c) for c in X]
        wrap = self.model.wrap_sx
        zm = Z[0] + sum((w * wrap(c - Z[0]) for w, c in zip(self.wm, Z)), ca.SX.zeros(Z[0].shape))
        return X, zm, [wrap(c - zm) for c in Z]

    def innovation_sx(self, x, P, z, R):
        """The innovation and its covariance (an innovation gate's test, FusedFilter.distance)."""
        _, zm, dZ = self._outputs(x, P)
        return self.model.wrap_sx(z - zm), self._cross(dZ, dZ) + R

    def update_sx(self, x, P, z, R):
        X, zm, dZ = self._outputs(x, P)
        dX = [c - x for c in X]
        S = self._cross(dZ, dZ) + R
        K = ca.solve(S, self._cross(dX, dZ).T).T
        return x + K @ self.model.wrap_sx(z - zm), P - K @ S @ K.T
