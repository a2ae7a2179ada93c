"""The extended Kalman filter on the physical model: the baseline the chapter says the
derivative-free filter beats. Jacobians are exact (CasADi AD of the RK4 step and of `h`), so what
the EKF loses is linearization, not differentiation error."""

from __future__ import annotations

import numpy as np

from dfeif_codegen.reference.linalg import spd_solve, wrap
from dfeif_codegen.reference.physical import PhysicalModel


class EKF:
    """predict/update on (x, P); nodes and master use it through physical.ReplayNode / PhysicalMaster."""

    def __init__(self, model: PhysicalModel):
        self.model = model
        self._eye = np.eye(model.n)

    def predict(self, x, P, u):
        xn, F = self.model.step(x, u)
        Pn = F @ P @ F.T + self.model.Qx(x)
        return xn, (Pn + Pn.T) / 2

    def update(self, x, P, z, R):
        y, H = self.model.h(x)
        e = wrap(z - y, self.model.angle_out)
        S = H @ P @ H.T + R
        K = spd_solve(S, H @ P).T
        L = self._eye - K @ H
        return x + K @ e, L @ P @ L.T + K @ R @ K.T
