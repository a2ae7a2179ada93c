"""The true plant and the cameras, in physical coordinates.

The plant integrates `x' = f(x) + g(x) u` with `u` held over each sampling period, by classical
RK4 with `substeps` steps per period: the filters' canonical model (v held, chain of integrators)
is an approximation of this, and the experiment should show what that costs, not hide it. One
period is a single CasADi function call (all substeps unrolled), because the plant runs 2000
steps per run and hundreds of runs per table.

A camera observes `model.measurement.observe(x)` plus white Gaussian noise per channel and the
node turns that into the flat outputs with `recover`. A model without `[measurement]` gets a
camera that observes the flat outputs `h(x)` directly, with the given noise.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import sympy as sp

from dfeif_codegen.symbolic.model import Model

_CASADI = {"sin": ca.sin, "cos": ca.cos, "tan": ca.tan, "exp": ca.exp, "log": ca.log, "sqrt": ca.sqrt,
           "atan2": ca.atan2, "atan": ca.atan, "asin": ca.asin, "acos": ca.acos, "sinh": ca.sinh,
           "cosh": ca.cosh, "tanh": ca.tanh, "Abs": ca.fabs, "sign": ca.sign, "pi": math.pi, "E": math.e}


def _fixed(model: Model, exprs) -> list[sp.Expr]:
    """Expressions with the parameters replaced by their values."""
    values = model.param_values
    return [sp.sympify(e).subs(values) for e in exprs]


def _casadi_fn(args: list[sp.Symbol], exprs: list[sp.Expr]):
    """A sympy expression list as a function of casadi SX arguments."""
    return sp.lambdify([args], exprs, modules=[_CASADI], cse=True)


class Plant:
    """True plant: `step(x, u)` integrates one sampling period with `u` held."""

    def __init__(self, model: Model, ts: float | None = None, substeps: int = 10):
        self.model, self.ts, self.substeps = model, float(ts or model.ts), int(substeps)
        n, m = model.n, model.m
        rhs = model.f + model.g * model.u
        fn = _casadi_fn(list(model.x) + list(model.u), _fixed(model, rhs))
        xs, us = ca.SX.sym("x", n), ca.SX.sym("u", m)
        f = ca.Function("f", [xs, us], [ca.vertcat(*fn([xs[i] for i in range(n)] + [us[j] for j in range(m)]))])
        h = self.ts / self.substeps
        x = xs
        for _ in range(self.substeps):
            k1 = f(x, us)
            k2 = f(x + h / 2 * k1, us)
            k3 = f(x + h / 2 * k2, us)
            k4 = f(x + h * k3, us)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        self._f = f
        self._step = ca.Function("step", [xs, us], [x])

    def rhs(self, x, u) -> np.ndarray:
        return np.asarray(self._f(x, u), dtype=float).reshape(-1)

    def step(self, x, u) -> np.ndarray:
        return np.asarray(self._step(x, u), dtype=float).reshape(-1)


class Camera:
    """What one camera node sees, and the flat outputs it recovers from that.

    `std` scales per channel (default: the model's `[measurement.noise]`; required when the model
    has no `[measurement]`, then one std per flat output). `R` is the covariance of the recovered
    outputs, from the linearized `recover` at `x_nominal` (for isotropic position noise on points,
    as in both built-in models, the angle noise does not depend on the configuration).
    """

    def __init__(self, model: Model, std=None, scale: float = 1.0, x_nominal=None):
        meas = model.measurement
        values = model.param_values
        if meas is None:
            if std is None:
                raise ValueError("a model without [measurement] needs the camera noise std per flat output")
            self.channels = [o.name for o in model.outputs]
            observe = list(model.h)
            recover_syms = [sp.Symbol(c) for c in self.channels]
            recover = recover_syms
        else:
            self.channels = list(meas.observe)
            observe = [meas.observe[c] for c in self.channels]
            recover_syms = [sp.Symbol(c) for c in self.channels]
            recover = [meas.recover[o.name] for o in model.outputs]
            if std is None:
                std = [meas.noise[c] for c in self.channels]
        self.std = scale * np.broadcast_to(np.asarray(std, dtype=float), (len(self.channels),)).copy()
        observe, recover = _fixed(model, observe), [sp.sympify(e).subs(values) for e in recover]
        self.expressions = (observe, recover_syms, recover)  # for the compiled closed loop
        self._observe = sp.lambdify([list(model.x)], observe, modules="math")
        self._recover = sp.lambdify([recover_syms], recover, modules="math")
        jac = sp.Matrix(recover).jacobian(recover_syms)
        self._jac = sp.lambdify([recover_syms], jac.tolist(), modules="math")
        x_nominal = np.zeros(model.n) if x_nominal is None else np.asarray(x_nominal, float)
        self.R = self.covariance(x_nominal)

    def observe(self, x) -> np.ndarray:
        return np.array(self._observe(list(map(float, x))), dtype=float)

    def recover(self, obs) -> np.ndarray:
        return np.array(self._recover(list(map(float, obs))), dtype=float)

    def measure(self, x, noise) -> np.ndarray:
        """Flat outputs recovered from one noisy frame; `noise` is standard normal per channel."""
        return self.recover(self.observe(x) + self.std * np.asarray(noise))

    def covariance(self, x) -> np.ndarray:
        jac = np.array(self._jac(list(self.observe(x))), dtype=float)
        return jac @ np.diag(self.std ** 2) @ jac.T
