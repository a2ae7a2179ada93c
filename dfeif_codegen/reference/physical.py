"""Filters on the physical model (the EKF and UKF the chapter compares itself with): the model's
functions, rewind-and-replay of late frames, and fusion, shared by `ekf.py` and `ukf.py`.

- Prediction integrates `x' = f(x) + g(x) u` with `u` held over Ts (classical RK4, the same
  substeps as the true plant), by CasADi, which also gives the exact Jacobian of that step (AD).
- Measurement: the flat outputs `y = h(x)` the nodes recover from the camera (the same `z` and
  `R_i` as the derivative-free nodes).
- Process noise: the derivative-free filter's assumption mapped to physical coordinates,
  `Q_x = J Q_d Jᵀ` with `J = dPhi^-1/dzeta` at the current estimate: both filters assume the same
  disturbance, so the comparison is of the filters, not of their tuning.
- Late frames: the exact method, as the derivative-free nodes' `replay`: each frame is put into
  its step's slot and the filter is re-run from there (re-linearizing on the way). All frames
  arriving at one step are placed first and the filter re-run once from the earliest: the same
  result as one re-run per frame, with less work.
- Fusion: the information-difference rule in *physical* coordinates,
  `Y = Y⁻ + Σ (Y_i - Y_pred_i)`, about the master's own prediction `x⁻` (made with the same filter).
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import tempfile

import casadi as ca
import numpy as np
import sympy as sp

from dfeif_codegen import angles
from dfeif_codegen.reference.linalg import spd_inv
from dfeif_codegen.symbolic import numeric
from dfeif_codegen.reference.node import measurement_covariance

def _sx(args: list[sp.Symbol], exprs, values: list[ca.SX]) -> ca.SX:
    """sympy expressions (parameters already substituted) evaluated on casadi symbols, through
    the one sympy -> CasADi bridge."""
    table = dict(zip(args, values))
    return ca.vertcat(*[numeric.to_casadi(sp.sympify(e), table, f"physical model [{i}]") for i, e in enumerate(exprs)])


class PhysicalModel:
    """One model at one sampling period as CasADi SX pieces (`step_sx`, `h_sx`, `Qx_sx`: the RK4
    step, the outputs and the process noise as SX functions, for a filter to compose into one
    function per predict or update) and the maps Phi, Phi^-1 with their Jacobians."""

    def __init__(self, flat, ts: float, q, substeps: int = 10):
        model = flat.model
        vals = model.param_values
        n, m = model.n, model.m
        self.n, self.m, self.ts = n, m, float(ts)
        self.inputs = m          # the length of what `predict` takes (the applied input)
        self.angle_out = np.array([c.angle for c in flat.chains])
        x, u, z = ca.SX.sym("x", n), ca.SX.sym("u", m), ca.SX.sym("z", n)
        xs, us = list(model.x), list(model.u)
        rhs = [sp.sympify(e).subs(vals) for e in (model.f + model.g * model.u)]
        f = ca.Function("f", [x, u], [_sx(xs + us, rhs, [x[i] for i in range(n)] + [u[j] for j in range(m)])])
        h_step, xn = self.ts / substeps, x
        for _ in range(substeps):
            k1 = f(xn, u)
            k2 = f(xn + h_step / 2 * k1, u)
            k3 = f(xn + h_step / 2 * k2, u)
            k4 = f(xn + h_step * k3, u)
            xn = xn + h_step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        xl = [x[i] for i in range(n)]
        hx = _sx(xs, [sp.sympify(o.expr).subs(vals) for o in model.outputs], xl)
        phi = _sx(xs, [sp.sympify(e).subs(vals) for e in flat.phi], xl)
        phi_inv = _sx(list(flat.zeta), [sp.sympify(e).subs(vals) for e in flat.phi_inv], [z[i] for i in range(n)])
        self.Qd = flat.process_noise(self.ts, q)
        self.step_sx = ca.Function("step", [x, u], [xn])
        self.h_sx = ca.Function("h", [x], [hx])
        J = ca.Function("J", [z], [ca.jacobian(phi_inv, z)])(phi)      # dPhi^-1/dzeta at zeta = Phi(x)
        self.Qx_sx = ca.Function("Qx", [x], [J @ ca.DM(self.Qd) @ J.T])
        self._phi = _packed("phi", [x], phi, ca.jacobian(phi, x))
        self._phi_inv = _packed("phi_inv", [z], phi_inv, ca.jacobian(phi_inv, z))

    def phi(self, x) -> tuple[np.ndarray, np.ndarray]:
        return _unpack(self._phi(x), self.n)

    def phi_inv(self, zeta) -> tuple[np.ndarray, np.ndarray]:
        return _unpack(self._phi_inv(zeta), self.n)

    def wrap_sx(self, e: ca.SX) -> ca.SX:
        """linalg.wrap on SX: the same wrap on the angle outputs, the others untouched."""
        return ca.vertcat(*[angles.wrap_sx(e[i]) if a else e[i]
                            for i, a in enumerate(self.angle_out)])


class CanonicalMaps:
    """`phi`, `phi_inv` and `wrap_sx` of a filter whose state is the canonical one, possibly
    extended by states after it (disturbances, parameter offsets): the identity on the canonical
    part, so that the comparison's driver maps its estimates as it maps a PhysicalModel's.
    Needs `n` (the filter's state), `canonical_n` and `angle_out`."""

    wrap_sx = PhysicalModel.wrap_sx

    def phi(self, x):
        x = np.asarray(x, float)
        return x[:self.canonical_n], np.eye(self.n)[:self.canonical_n]

    def phi_inv(self, x):
        return np.asarray(x, float), np.eye(self.canonical_n)


def _packed(name: str, inputs: list, vec: ca.SX, mat: ca.SX) -> numeric.Numeric:
    """`vec` and `mat` as one column (vec, then mat column-major), called through Numeric's buffer."""
    return numeric.Numeric(ca.Function(name, inputs, [ca.densify(ca.vertcat(vec, ca.vec(mat)))], {"cse": True}))


CC_FLAGS = ("-O1", "-ffp-contract=off", "-fPIC", "-shared")


def compiled_function(fn: ca.Function, cc: str | None = None) -> ca.Function:
    """`fn` as C from CasADi's code generator, compiled to a shared library and loaded back.
    The C does the interpreter's operations in the same order on IEEE doubles, and
    `-ffp-contract=off` forbids fused multiply-adds, so the results are the interpreter's; the
    EKF's and UKF's predict (10 RK4 substeps and their Jacobian, or 2n + 1 of them) run 3-5x
    faster. The library is cached in a folder of the temp folder private to this user (a library
    another user could plant would run in this process), under the hash of its source and flags;
    built in a private folder, then renamed: concurrent workers never see half a file."""
    cc = cc or os.environ.get("CC", "cc")
    gen = ca.CodeGenerator(f"{fn.name()}.c", {"with_header": False})
    gen.add(fn)
    source = gen.dump()
    key = hashlib.sha256("\0".join((source, cc, *CC_FLAGS)).encode()).hexdigest()[:20]
    cache = os.path.join(tempfile.gettempdir(), f"dfeif-casadi-{os.getuid()}")
    os.makedirs(cache, mode=0o700, exist_ok=True)
    info = os.stat(cache)
    if info.st_uid != os.getuid() or info.st_mode & 0o022:
        raise RuntimeError(f"{cache}: not a folder private to this user; remove it")
    lib = os.path.join(cache, f"{key}.so")
    if not os.path.exists(lib):
        with tempfile.TemporaryDirectory(dir=cache) as work:
            c_file, tmp_lib = os.path.join(work, "f.c"), os.path.join(work, "f.so")
            with open(c_file, "w", encoding="utf-8") as fh:
                fh.write(source)
            done = subprocess.run([cc, *CC_FLAGS, "-o", tmp_lib, c_file], capture_output=True, text=True)
            if done.returncode:
                raise RuntimeError(f"{cc} failed on {fn.name()}: {done.stderr.strip()[:300]}")
            os.replace(tmp_lib, lib)      # the same folder's file system: atomic
    return ca.external(fn.name(), lib)


def _unpack(out: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    return out[:n], out[n:].reshape((n, -1), order="F")


class FusedFilter:
    """A filter whose predict and update are each one CasADi function (built by a subclass from
    the model's SX pieces) called through Numeric's buffer: ~10 us a call instead of a dozen
    numpy and CasADi calls. A matrix argument is passed column-major (CasADi's order).
    `compiled`: both functions as compiled C (`compiled_function`; the same results, less time)."""

    def __init__(self, model: PhysicalModel, compiled: bool = False):
        self.model = model
        n, m = model.n, model.m
        x, P, u = ca.SX.sym("x", n), ca.SX.sym("P", n, n), ca.SX.sym("u", model.inputs)
        z, R = ca.SX.sym("z", m), ca.SX.sym("R", m, m)
        xn, Pn = self.predict_sx(x, P, u)
        xu, Pu = self.update_sx(x, P, z, R)
        interpreted = (_packed("predict", [x, P, u], xn, (Pn + Pn.T) / 2),
                       _packed("update", [x, P, z, R], xu, (Pu + Pu.T) / 2))
        self._operations = {"predict": interpreted[0].function.n_instructions(),
                            "update": interpreted[1].function.n_instructions()}
        if compiled:
            interpreted = tuple(numeric.Numeric(compiled_function(f.function)) for f in interpreted)
        self._predict, self._update = interpreted

    def predict(self, x, P, u):
        return _unpack(self._predict(x, np.asarray(P).T, u), self.model.n)

    def update(self, x, P, z, R):
        return _unpack(self._update(x, np.asarray(P).T, z, np.asarray(R).T), self.model.n)

    def distance(self, x, P, z, R) -> float:
        """e' S^-1 e of a measurement z at the prior (x, P): an innovation gate's test (built on
        first use, outside the counted operations: a gate is an option of every filter alike)."""
        if not hasattr(self, "_distance"):
            n, m = self.model.n, self.model.m
            xs, Ps, zs, Rs = ca.SX.sym("x", n), ca.SX.sym("P", n, n), ca.SX.sym("z", m), ca.SX.sym("R", m, m)
            e, S = self.innovation_sx(xs, Ps, zs, Rs)
            self._distance = ca.Function("distance", [xs, Ps, zs, Rs], [e.T @ ca.solve(S, e)])
        return float(self._distance(x, np.asarray(P), z, np.asarray(R)))

    def operations(self) -> dict:
        """Elementary operations of one predict and one update (CasADi's instruction count of the
        SX function, after common-subexpression elimination): a cost independent of the machine."""
        return dict(self._operations)


class ReplayNode:
    """One camera node on the physical model: `update` once per step, `update_delayed` with the
    frames arriving at this step, `predict` with the input applied. `filt` supplies
    `predict(x, P, u)` and `update(x, P, z, R)` (ekf.EKF or ukf.UKF)."""

    def __init__(self, filt, R, x0, P0, max_lag: int = 32, gate: float | None = None):
        """`gate`: refuse a frame whose e' S^-1 e passes gate^2, as the derivative-free nodes do
        (reference/node.py), on time and late (counted in `outliers`); None: no gate."""
        self.filt, self.max_lag, self.gate = filt, max_lag, gate
        self.R = measurement_covariance(R, filt.model.m)
        self.k = 0
        self.x, self.P = np.array(x0, dtype=float), np.array(P0, dtype=float)
        self.x_pred, self.P_pred = self.x, self.P
        self.applied = self.rejected = self.outliers = 0
        self._slots: dict[int, list] = {0: [self.x, self.P, None, None]}   # prior x, P, z, u

    def update(self, z, gamma: bool) -> None:
        slot = self._slots[self.k]
        slot[2] = np.asarray(z, dtype=float) if gamma and not self._outlier(slot, z) else None
        self.x, self.P = self._correct(slot[0], slot[1], slot[2])

    def _outlier(self, slot, z) -> bool:
        out = self.gate is not None and self.filt.distance(slot[0], slot[1], z, self.R) > self.gate ** 2
        self.outliers += out
        return out

    def update_delayed(self, frames) -> list[bool]:
        """`frames`: (z, lag) pairs arriving now; the same rejections as the derivative-free nodes."""
        ok, start = [], None
        for z, lag in frames:
            j = self.k - int(lag)
            good = 1 <= lag <= self.max_lag and j >= 0 and self._slots[j][2] is None
            if good and self._outlier(self._slots[j], z):   # refused: counted as an outlier only
                ok.append(False)
                continue
            if good:
                self._slots[j][2] = np.asarray(z, dtype=float)
                start = j if start is None else min(start, j)
            self.applied, self.rejected = self.applied + good, self.rejected + (not good)
            ok.append(good)
        if start is not None:
            x, P = self._slots[start][0], self._slots[start][1]
            for j in range(start, self.k + 1):
                slot = self._slots[j]
                slot[0], slot[1] = x, P
                x, P = self._correct(x, P, slot[2])
                if j < self.k:
                    x, P = self.filt.predict(x, P, slot[3])
            self.x, self.P = x, P
        return ok

    def predict(self, u) -> None:
        u = np.atleast_1d(np.asarray(u, dtype=float))
        self._slots[self.k][3] = u
        self.x, self.P = self.filt.predict(self.x, self.P, u)
        self.k += 1
        self._slots[self.k] = [self.x, self.P, None, None]
        self._slots.pop(self.k - self.max_lag - 1, None)
        self.x_pred, self.P_pred = self.x, self.P

    def _correct(self, x, P, z):
        return (x, P) if z is None else self.filt.update(x, P, z, self.R)


class PhysicalMaster:
    """The information-difference rule in physical coordinates, with the filter's own prediction."""

    def __init__(self, filt, x0, P0):
        self.filt = filt
        self.x, self.P = np.array(x0, dtype=float), np.array(P0, dtype=float)
        self.x_prior, self.P_prior = self.x, self.P

    def fuse(self, packets) -> None:
        """`packets`: per node (x, P, x_pred, P_pred) of this step, or None."""
        used = [p for p in packets if p is not None]
        if not used:
            self.x, self.P = self.x_prior, self.P_prior
            return
        c = self.x_prior
        Y, y = spd_inv(self.P_prior), np.zeros_like(c)
        for x, P, xp, Pp in used:
            Yi, Yp = spd_inv(P), spd_inv(Pp)
            Y, y = Y + Yi - Yp, y + Yi @ (x - c) - Yp @ (xp - c)
        self.P = spd_inv(Y)
        self.x = c + self.P @ y

    def predict(self, u) -> None:
        self.x_prior, self.P_prior = self.filt.predict(self.x, self.P, np.atleast_1d(np.asarray(u, dtype=float)))
