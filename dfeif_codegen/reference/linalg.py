"""The two numerical primitives the filters share with the generated C: inverses of symmetric
positive definite matrices by Cholesky (a non-positive pivot is an error, not a silent NaN), and
the angle wrap of innovations (the same formula as the C, so both round the same way).
"""

from __future__ import annotations

import numpy as np

from dfeif_codegen import angles


class SingularMatrixError(ArithmeticError):
    """A matrix that must be symmetric positive definite is not (a non-positive Cholesky pivot)."""


def cholesky(a: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.cholesky(a)
    except np.linalg.LinAlgError as exc:
        raise SingularMatrixError("singular matrix: non-positive Cholesky pivot") from exc


def spd_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """`a^-1 b` for symmetric positive definite `a`, as `L^-T (L^-1 b)`."""
    low = cholesky(a)
    return np.linalg.solve(low.T, np.linalg.solve(low, b))


def spd_inv(a: np.ndarray) -> np.ndarray:
    return spd_solve(a, np.eye(a.shape[0], dtype=a.dtype))


def wrap(e: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Wrap the entries of `e` flagged in `angle` to (-pi, pi] (dfeif_codegen/angles.py)."""
    if not np.any(angle):
        return e
    return np.where(angle, angles.wrap_np(e), e)
