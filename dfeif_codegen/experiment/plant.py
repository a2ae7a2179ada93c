"""The true plant and the cameras, in physical coordinates.

The plant integrates `x' = f(x) + g(x) u` with `u` held over each sampling period, by classical
RK4 with `substeps` steps per period: the filters' canonical model (v held, chain of integrators)
is an approximation of this, and the experiment should show what that costs, not hide it. One
period is a single CasADi function call (all substeps unrolled, called through its buffer),
because the plant runs 2000 steps per run and hundreds of runs per table. Every expression goes
through `symbolic.numeric`, the bridge the generated C is printed from.

For a dynamically extended model (symbolic/extension.py) the added integrators are the
controller's: it integrates them exactly over the period under its held input and applies the
first of each chain to the plant, held like any input. `step` does the same: the physical states
see those controller states frozen at the period's start; the chains advance in closed form.

A camera observes `model.measurement.observe(x)` plus white Gaussian noise per channel and the
node turns that into the flat outputs with `recover`. A model without `[measurement]` gets a
camera that observes the flat outputs `h(x)` directly, with the given noise.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import sympy as sp

from dfeif_codegen.symbolic import numeric
from dfeif_codegen.symbolic.model import Model

def _fixed(model: Model, exprs, values=None) -> list[sp.Expr]:
    """Expressions with the parameters replaced by their values (default: the model's)."""
    values = model.param_values if values is None else values
    return [sp.sympify(e).subs(values) for e in exprs]


def rk4_period(f: ca.Function, model: Model, ts: float, substeps: int, extension=None, extra=()) -> ca.Function:
    """One sampling period of `x' = f(x, u, *extra)` with u held: `substeps` classical RK4 steps,
    unrolled into one function of (x, u, *extra); a dynamic extension's controller states are
    frozen for the RK4 and advanced exactly as the chains of integrators they are."""
    n = model.n
    xs, us = ca.SX.sym("x", n), ca.SX.sym("u", model.m)
    h = ts / substeps
    names = [s.name for s in model.states]
    chains = [[names.index(s) for s in c] for c in (extension.chains.values() if extension else [])]
    held = sorted(i for c in chains for i in c)   # controller states: frozen for the plant's RK4
    free = ca.SX(n, 1)
    for i in range(n):
        free[i] = 0.0 if i in held else 1.0
    x = xs
    for _ in range(substeps):
        k1 = f(x, us, *extra) * free
        k2 = f(x + h / 2 * k1, us, *extra) * free
        k3 = f(x + h / 2 * k2, us, *extra) * free
        k4 = f(x + h * k3, us, *extra) * free
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    for j, chain in enumerate(chains):   # xi_i(Ts) = sum_k xi_k Ts^(k-i)/(k-i)! + u_j Ts^(r-i)/(r-i)!
        r = len(chain)
        for a, i in enumerate(chain):
            x[i] = sum(xs[chain[b]] * ts ** (b - a) / math.factorial(b - a) for b in range(a, r)) \
                + us[j] * ts ** (r - a) / math.factorial(r - a)
    return ca.Function("step", [xs, us, *extra], [x])


class Plant:
    """True plant: `step(x, u)` integrates one sampling period with `u` held. `params`: the
    plant's parameter vector in model order when it differs from the model's (model error,
    experiment/model_error.py); the values are substituted like the model's own, so a plant with
    the model's parameters is the same function whichever way it was asked for."""

    def __init__(self, model: Model, ts: float | None = None, substeps: int = 10, extension=None, params=None):
        self.model, self.ts, self.substeps = model, float(ts or model.ts), int(substeps)
        values = None if params is None else dict(zip(model.p, map(float, params)))
        f = numeric.sx_function("f", [list(model.x), list(model.u)],
                                _fixed(model, model.f + model.g * model.u, values))
        self._f = numeric.Numeric(f)
        self._step = numeric.Numeric(rk4_period(f, model, self.ts, self.substeps, extension))

    def rhs(self, x, u) -> np.ndarray:
        return self._f(x, np.atleast_1d(u))

    def step(self, x, u) -> np.ndarray:
        return self._step(x, np.atleast_1d(u))


def parametric_step(model: Model, ts: float, substeps: int, extension=None) -> ca.Function:
    """The plant's period as a function of (x, u, p), p the parameter vector in model order: what
    the compiled closed loop calls for a run whose plant differs from the model."""
    f = numeric.sx_function("f", [list(model.x), list(model.u), list(model.p)], model.f + model.g * model.u)
    return rk4_period(f, model, ts, substeps, extension, (ca.SX.sym("p", len(model.p)),))


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
        self._n_outputs = len(recover)
        self.expressions = (observe, recover_syms, recover)  # for the compiled closed loop
        self._observe = numeric.Numeric.of("observe", [list(model.x)], observe)
        self._recover = numeric.Numeric.of("recover", [recover_syms], recover)
        self._jac = numeric.Numeric.of("recover_jacobian", [recover_syms], sp.Matrix(recover).jacobian(recover_syms))
        x_nominal = np.zeros(model.n) if x_nominal is None else np.asarray(x_nominal, float)
        self.R = self.covariance(x_nominal)

    def observe(self, x) -> np.ndarray:
        return self._observe(x)

    def recover(self, obs) -> np.ndarray:
        return self._recover(obs)

    def measure(self, x, noise) -> np.ndarray:
        """Flat outputs recovered from one noisy frame; `noise` is standard normal per channel."""
        return self.recover(self.observe(x) + self.std * np.asarray(noise))

    def covariance(self, x) -> np.ndarray:
        """J diag(std^2) J^T at x, symmetric bit for bit: the product rounds its two triangles
        apart (an arm at 84 of 200 random states), and the C's node_init refuses an R that is not
        symmetric (a three-output user model's every C run failed on it)."""
        jac = self._jac(self.observe(x)).reshape(self._n_outputs, len(self.channels))
        R = jac @ np.diag(self.std ** 2) @ jac.T
        return (R + R.T) / 2
