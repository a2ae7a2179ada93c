"""scripts/kernel_operations.py: the EKF it counts with the upper triangle in and out is the
comparison's EKF, so the two counts it prints measure the same filter."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from dfeif_codegen.codegen.kernels.linalg import packed_index
from dfeif_codegen.experiment import compare

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import kernel_operations  # noqa: E402


def test_packed_ekf_is_the_comparisons_ekf():
    """At a random state, an SPD P and an input, the packed predict and update give the
    comparison's EKF's x and the upper triangle of its P (same operations, other order of the
    symmetrization: 1e-12 of the entries' scale), with fewer instructions."""
    f = compare.filter_of("dc_motor_link", 0.01, (1.0,), 10, "ekf")
    packed = kernel_operations.ekf_packed("dc_motor_link", 0.01, 10)
    n, rng = f.model.n, np.random.default_rng(5)
    a = rng.standard_normal((n, n))
    P = a @ a.T * 1e-2 + np.eye(n) * 1e-3
    upper = [(i, j) for j in range(n) for i in range(j + 1)]
    pp = np.zeros(len(upper))
    for i, j in upper:
        pp[packed_index(i, j)] = P[i, j]
    x, u = np.array([0.3, -0.2, 0.1, 0.05])[:n], np.array([1.5])[:f.model.inputs]
    z, R = np.array([0.31]), np.eye(1) * 1e-5
    for got, want in ((packed["predict"](x, pp, u), f.predict(x, P, u)),
                      (packed["update"](x, pp, z, R), f.update(x, P, z, R))):
        scale = np.max(np.abs(want[1]))
        assert np.allclose(np.asarray(got[0]).ravel(), want[0], rtol=1e-12, atol=1e-12)
        for i, j in upper:
            assert abs(float(got[1][packed_index(i, j)]) - want[1][i, j]) <= 1e-12 * scale
    ops = compare.operations("dc_motor_link", 0.01, (1.0,), kinds=("ekf",))["ekf"]
    assert packed["predict"].n_instructions() < ops["predict"] and packed["update"].n_instructions() < ops["update"]
