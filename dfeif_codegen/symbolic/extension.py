"""Dynamic extension: integrators on input channels until the decoupling matrix is invertible.

A unicycle with flat outputs (x, y) or a planar quadrotor with (x, z) has a singular decoupling
matrix: one input (the speed, the thrust) enters both outputs' derivatives, the other (the turn
rate, the torque) enters neither yet. The dynamic extension algorithm (Descusse and Moog 1985;
Isidori, *Nonlinear Control Systems*, 3rd ed., sec. 5.4) delays the input channels that enter
the decoupling matrix by one integrator each, and repeats on the extended system until its
decoupling matrix is invertible; the extended system is then static-feedback linearizable when
its relative degrees add up to its dimension. This module delays, at each step, the channels
that enter the matrix's dependent rows (the outputs whose derivatives add no direction the
others lack), not those entering rows of their own: the minimal extension for mobile robots and
planar quadrotors, and for a robot with an independent extra actuator (a unicycle's turret). A
3-D quadrotor's extension is derived too (two integrators on the thrust); its Phi^-1 (a
rotation's trigonometry) is beyond the symbolic solver and comes from the model's [inverse]
table (docs/mathematics.md §1).
Where integrators do not cure the matrix, it says why it stops.

The integrators' states are the controller's: it integrates them and applies the first of each
chain (the original input) to the plant; the filters estimate the extended canonical state.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import sympy as sp

from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic import lie
from dfeif_codegen.symbolic.model import Model, Variable


@dataclass(frozen=True)
class Delay:
    """One step of the algorithm: integrators added on these channels, and why."""

    channels: tuple[str, ...]   # the input names delayed in this step (as named before it)
    reason: str


@dataclass(frozen=True)
class Extension:
    """What the algorithm added: per original input, its integrator states in order (the first is
    the input applied to the plant, each next one the derivative of the previous) and the
    extended system's input that drives the chain; the steps and why."""

    chains: dict[str, tuple[str, ...]]   # original input -> its controller states (empty: none)
    inputs: tuple[str, ...]              # the extended system's inputs, in the original order
    steps: tuple[Delay, ...]

    @property
    def states(self) -> list[str]:
        return [s for chain in self.chains.values() for s in chain]

    def describe(self) -> list[str]:
        return [f"step {k + 1}: one integrator on {', '.join(d.channels)}: {d.reason}"
                for k, d in enumerate(self.steps)]


def _delayed_name(name: str) -> str:
    """`u` -> `u_d1`, `u_dk` -> `u_d(k+1)`: the input that drives the added integrator."""
    stem, _, k = name.rpartition("_d")
    return f"{stem}_d{int(k) + 1}" if stem and k.isdigit() else f"{name}_d1"


def delay(model: Model, channels: list[int]) -> Model:
    """The model with one integrator on each listed input: the input becomes a state (its domain
    the actuator's limits, its nominal the input's), driven by a new input, its derivative."""
    states, f, g = list(model.states), list(model.f), model.g
    inputs, made_of = list(model.inputs), dict(model.made_of_input)
    g_cols = [g.col(j) for j in range(model.m)]
    for j in channels:
        u = model.inputs[j]
        f = [fi + gi * sp.Symbol(u.name) for fi, gi in zip(f, g_cols[j])]
    g_rows = [[g_cols[j][i] if j not in channels else sp.Integer(0) for j in range(model.m)] for i in range(model.n)]
    for j in channels:
        u = model.inputs[j]
        made_of[len(states)] = j
        states.append(Variable(u.name, u.unit, u.description or f"input {u.name} (controller state)",
                               u.min, u.max, u.nominal))
        f.append(sp.Integer(0))
        g_rows.append([sp.Integer(1) if k == j else sp.Integer(0) for k in range(model.m)])
        inputs[j] = Variable(_delayed_name(u.name), f"({u.unit})/s" if u.unit else "",
                             f"derivative of {u.name}")
    return replace(model, states=states, inputs=inputs, f=sp.Matrix(f), g=sp.Matrix(g_rows),
                   made_of_input=made_of)


def _singular_reason(model: Model, io: lie.IOStructure, entering: list[int], rows: list[int]) -> str:
    names = [model.inputs[j].name for j in entering]
    outputs = ", ".join(model.outputs[i].name for i in rows)
    return (f"decoupling matrix rank {io.rank} < {model.m} at relative degrees {io.degrees}; "
            f"{', '.join(names)} enter{'s' if len(names) == 1 else ''} the dependent rows ({outputs})")


def _entering_dependent_rows(io: lie.IOStructure) -> tuple[list[int], list[int]]:
    """The input channels to delay: those entering a dependent row of the decoupling matrix (a row
    whose removal leaves its generic rank, so that its output's derivative adds no direction the
    others lack). A row of its own (a yaw driven by its torques) keeps its inputs undelayed: the
    minimal extension (a 3-D quadrotor's two integrators on the thrust, not on the yaw torque
    too); an input entering only rows of their own is needed there as it is. Also the rows."""
    m = io.samples.shape[1]
    dependent = [i for i in range(m)
                 if max(lie.rank(np.delete(a, i, axis=0)) for a in io.samples) == io.rank]
    nonzero = np.isfinite(io.samples) & (np.abs(io.samples) > lie.ZERO_TOL)        # (points, rows, cols)
    return [j for j in range(m) if np.any(nonzero[:, dependent, j])], dependent


def extend(model: Model, say=lambda text: None) -> tuple[Model, Extension, lie.IOStructure]:
    """Apply the algorithm; the extended model (the model itself when nothing is needed), what was
    added, and the extended system's relative degrees and decoupling matrix. Refuses, naming the
    reason, a singular decoupling matrix that integrators on input channels do not cure and flat
    outputs that leave internal (zero) dynamics."""
    original, current, steps = model, model, []
    chains: list[list[str]] = [[] for _ in model.inputs]   # per input channel, its integrator states
    for _ in range(model.n + 1):
        io = lie.structure(current, lie.Sampler(current), say)
        if io.rank < 0:
            raise ModelError(f"{model.where('dynamics.g')}: the decoupling matrix is undefined (not finite) at "
                             "every sampled state of the declared domain")
        if io.rank == current.m:
            break
        entering, rows = _entering_dependent_rows(io)
        if not entering or len(entering) == current.m:
            # an integrator on every input gives back the same matrix one derivative later
            raise ModelError(
                f"{model.where('dynamics.g')}: the decoupling matrix is singular (rank {io.rank} < {current.m} at "
                f"relative degrees {io.degrees}) and integrators on input channels do not cure it: every input "
                "enters its dependent rows, and delaying them all leaves it as it is: the outputs are not "
                "independent (not flat with these outputs), or an input transformation is needed first")
        say(f"extending the model dynamically: one integrator on {', '.join(current.inputs[j].name for j in entering)}")
        reason = _singular_reason(current, io, entering, rows)
        steps.append(Delay(tuple(current.inputs[j].name for j in entering), reason))
        for j in entering:
            chains[j].append(current.inputs[j].name)
        current = delay(current, entering)
    if io.rank < current.m:
        raise ModelError(f"{model.where('dynamics.g')}: the decoupling matrix is singular (rank {io.rank} < "
                         f"{current.m}) and stays singular after {len(steps)} dynamic extension step(s): the flat "
                         "outputs are not independent (not flat with these outputs)")
    io.check_nominal(current)
    if sum(io.degrees) != current.n:
        grown = f" after the dynamic extension ({len(current.states) - original.n} integrator(s))" if steps else ""
        raise ModelError(f"{model.where('outputs')}: relative degrees {io.degrees} sum to {sum(io.degrees)}, not "
                         f"n = {current.n}{grown}: the flat outputs leave internal (zero) dynamics of dimension "
                         f"{current.n - sum(io.degrees)} (not flat with these outputs)")
    ext = Extension({u.name: tuple(c) for u, c in zip(original.inputs, chains)},
                    tuple(v.name for v in current.inputs), tuple(steps))
    return current, ext, io
