"""The node's posterior covariance in single precision, three forms side by side (docs/algorithms.md,
"The posterior covariance"): the Joseph form, the node's `P - K C P` with the heads' rows as
`R K'` (`reference.node.posterior`), and the plain `P - K C P`.

`python scripts/posterior_rounding.py [PRIORS]`: for random 3x3 priors with chain-like scales
(standard deviations about 1, 10, 100) and R / P_hh from 1 down to 1e-10, each form evaluated in
float32 on float32 inputs and compared with the exact posterior of those same inputs (float64,
heads' rows as R K', which is exact there): the median and worst entry error in units of
sigma_i sigma_j, and how many posteriors are not positive definite (Cholesky).

`python scripts/posterior_rounding.py --node MODEL`: the generated float C node (host compiler)
against the double reference on 400 on-time steps from x0 = 0, P0 = I, q = 20, with measurements
of standard deviation 1e-2 down to 1e-6 (R = std^2 (0.1 I + 0.9): correlated when m > 1): the
worst P and x errors in units of the reference's sigma, and the smallest eigenvalue of the C's
correlation matrix.
"""

from __future__ import annotations

import sys

import numpy as np


def joseph(P, K, R, h):
    IKC = np.eye(P.shape[0], dtype=P.dtype)
    IKC[:, h] -= K
    return IKC @ P @ IKC.T + K @ R @ K.T


def plain(P, K, R, h):
    out = P - K @ P[h, :]
    return np.triu(out) + np.triu(out, 1).T


def main(priors: int = 2000) -> None:
    from dfeif_codegen.reference.node import posterior

    rng = np.random.default_rng(0)
    forms = {"Joseph": joseph, "P - K C P, heads' rows R K'": posterior, "plain P - K C P": plain}
    h = [0]
    print("| R / P_hh | " + " | ".join(f"{f}: median, worst, not PD" for f in forms) + " |")
    print("|---:|" + "---:|" * len(forms))
    for ratio in (1.0, 1e-2, 1e-4, 1e-6, 1e-8, 1e-10):
        errors = {f: [] for f in forms}
        indefinite = dict.fromkeys(forms, 0)
        for _ in range(priors):
            G = rng.standard_normal((3, 3)) * np.logspace(0, 2, 3)
            P = (G @ G.T + 1e-3 * np.eye(3)).astype(np.float32)
            R = np.array([[ratio * P[0, 0]]], dtype=np.float32)
            K = P[:, h] / (P[0, 0] + R[0, 0])                       # float32, as the C computes it
            P64, R64 = P.astype(float), R.astype(float)
            exact = posterior(P64, P64[:, h] / (P64[0, 0] + R64[0, 0]), R64, h)
            sigma = np.sqrt(np.diag(exact))
            for name, form in forms.items():
                got = form(P, K, R, h).astype(float)
                errors[name].append(np.max(np.abs(got - exact) / np.outer(sigma, sigma)))
                try:
                    np.linalg.cholesky(got)
                except np.linalg.LinAlgError:
                    indefinite[name] += 1
        print(f"| {ratio:.0e} | " + " | ".join(f"{np.median(errors[f]):.1e}, {np.max(errors[f]):.1e}, {indefinite[f]}"
                                               for f in forms) + " |")


def node(name: str) -> None:
    import tempfile
    from pathlib import Path

    from dfeif_codegen.check import harness, loader
    from dfeif_codegen.reference.node import NodeFilter
    from dfeif_codegen.symbolic import flatness, model

    flat = flatness.derive(model.load(name))
    n, m, ts = flat.n, flat.m, flat.model.ts
    A, B, _ = flat.discrete(ts)
    with tempfile.TemporaryDirectory() as tmp:
        md = harness.build_model(name, Path(tmp) / "b", "float")
        lib = loader.load(md.path, cache=Path(tmp) / "cache")
        print("| measurement std | P error / (sigma_i sigma_j) | x error / sigma | smallest eigenvalue, correlation of P |")
        print("|---:|---:|---:|---:|")
        for std in (1e-2, 1e-3, 1e-4, 1e-5, 1e-6):
            R, q = (0.1 * np.eye(m) + 0.9) * std**2, np.full(m, 20.0)
            ref = NodeFilter(flat, ts, q, R, np.zeros(n), np.eye(n))
            c = lib.Node(np.zeros(n), np.eye(n), R, q)
            rng = np.random.default_rng(1)
            truth, worst_P, worst_x, smallest = np.zeros(n), 0.0, 0.0, np.inf
            for k in range(400):
                z = truth[list(flat.heads)] + std * rng.standard_normal(m)
                ref.update(z, True)
                c.update(z, 1)
                x, P = (a.astype(float) for a in c.estimate())
                sigma = np.sqrt(np.diag(ref.P))
                worst_P = max(worst_P, np.max(np.abs(P - ref.P) / np.outer(sigma, sigma)))
                worst_x = max(worst_x, np.max(np.abs(x - ref.x) / sigma))
                smallest = min(smallest, np.linalg.eigvalsh(P / np.outer(sigma, sigma)).min())
                v = np.full(m, np.sin(0.01 * k))
                truth = A @ truth + B @ v
                ref.predict(v)
                c.predict(v)
            print(f"| {std:.0e} | {worst_P:.1e} | {worst_x:.1e} | {smallest:.1e} |")


if __name__ == "__main__":
    if sys.argv[1:2] == ["--node"]:
        node(sys.argv[2])
    else:
        main(*(int(a) for a in sys.argv[1:2]))
