"""The extended Kalman filter on the physical model: the baseline the chapter says the
derivative-free filter beats. Jacobians are exact (CasADi AD of the RK4 step and of `h`), so what
the EKF loses is linearization, not differentiation error. Predict and update are each one CasADi
function (physical.FusedFilter)."""

from __future__ import annotations

import casadi as ca

from dfeif_codegen.reference.physical import FusedFilter


class EKF(FusedFilter):
    """predict/update on (x, P); nodes and master use it through physical.ReplayNode / PhysicalMaster."""

    def predict_sx(self, x, P, u):
        xn = self.model.step_sx(x, u)
        F = ca.jacobian(xn, x)
        return xn, F @ P @ F.T + self.model.Qx_sx(x)

    def _output(self, x):
        y = self.model.h_sx(x)
        return y, ca.jacobian(y, x)

    def innovation_sx(self, x, P, z, R):
        """The innovation e and its covariance S (an innovation gate's test, FusedFilter.distance)."""
        y, H = self._output(x)
        return self.model.wrap_sx(z - y), H @ P @ H.T + R

    def update_sx(self, x, P, z, R):
        _, H = self._output(x)
        e, S = self.innovation_sx(x, P, z, R)
        K = ca.solve(S, H @ P).T
        L = ca.SX.eye(self.model.n) - K @ H
        return x + K @ e, L @ P @ L.T + K @ R @ K.T           # Joseph form
