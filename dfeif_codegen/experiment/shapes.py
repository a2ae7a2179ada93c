"""The reference a starting scenario tracks, from the flat outputs' declared domains.

A fixed amplitude of 0.5 around 0 sends a magnetic levitation's gap negative and a tank's level
dry; here each flat output that is a state with a declared [min, max] swings by a tenth of that
width around its nominal value (kept inside the domain), other outputs by 0.5 around their value
at the nominal state. `shape` picks how the outputs move together: `sinusoid` (in phase),
`seesaw`, `circle` (the second output a quarter period behind the first: a mobile robot keeps its
speed away from zero) and `figure8` (the second output at twice the frequency). Every number can
be given instead (`codegen scenario --amplitude ... --offset ... --phase ... --period ...`), or
the reference taken from a user's CSV (`--trajectory`: `from_trajectory`, `of_trajectory`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import sympy as sp

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment.trajectory import flags
from dfeif_codegen.symbolic.lie import nominal_state

if TYPE_CHECKING:   # for the annotation only: trajectory_file is imported where it is used
    from dfeif_codegen.experiment.trajectory_file import Trajectory

SHAPES = ("sinusoid", "seesaw", "circle", "figure8")
PERIOD, AMPLITUDE = 5.0, 0.5   # for outputs without a declared domain (the paper's scale)
SWING = 0.1                    # amplitude as a fraction of a declared domain's width: 80 % of it left as margin


@dataclass(frozen=True)
class Shape:
    """Per flat output: amplitude, offset, phase [rad], cycles per period; the period [s]."""

    kind: str
    amplitude: tuple
    offset: tuple
    phase: tuple
    cycles: tuple
    period: float             # for a user's trajectory: the length of its file, in whole steps
    trajectory: Trajectory | None = None  # for kind "trajectory"
    rate: float = 0.0          # its angular frequency [rad/s], measured (from_trajectory)

    def config(self) -> dict:
        """The closed_loop.Config fields of this reference."""
        if self.trajectory is not None:
            return dict(reference="trajectory", trajectory=self.trajectory, amplitude=self.amplitude,
                        offset=self.offset, period=self.period)
        return dict(reference="seesaw" if self.kind == "seesaw" else "sinusoid", amplitude=self.amplitude,
                    offset=self.offset, phase=self.phase, cycles=self.cycles, period=self.period)

    @property
    def omega(self) -> float:
        """The fastest angular frequency of the outputs [rad/s]."""
        return self.rate or 2 * math.pi * max(self.cycles) / self.period

    @property
    def limit(self) -> float:
        """The longest run this reference serves [s]: a periodic one repeats, a file ends."""
        return self.period if self.trajectory is not None else math.inf


def _numbers(text, m: int, flag: str) -> list[float] | None:
    """The option's numbers: a comma-separated string (the command line's), or from Python a
    number or a sequence of numbers."""
    if text is None:
        return None
    items = text if isinstance(text, (list, tuple, np.ndarray)) else str(text).split(",")
    try:
        values = [float(v) for v in items]
    except (TypeError, ValueError):
        raise ScenarioError(f"{flag} {text}: needs a number or {m} comma-separated numbers") from None
    if len(values) not in (1, m) or not all(np.isfinite(values)):
        raise ScenarioError(f"{flag} {text}: needs {'1 finite number' if m == 1 else f'1 or {m} finite numbers'} "
                            "(one per flat output)")
    return values * m if len(values) == 1 else values


def from_domains(flat, shape: str = "sinusoid", amplitude=None, offset=None, phase=None,
                 period=None) -> Shape:
    """The reference of a starting scenario (see the module docstring); given values win."""
    if shape not in SHAPES:
        raise ScenarioError(f"--shape {shape}: one of {', '.join(SHAPES)}")
    mdl, m = flat.model, flat.m
    if shape in ("circle", "figure8") and m < 2:
        raise ScenarioError(f"--shape {shape}: needs two flat outputs, model {mdl.name} has {m}")
    head = flat.phi_num(nominal_state(mdl))[flat.heads]
    amp, off = [], []
    for j, out in enumerate(mdl.outputs):
        state = next((s for s in mdl.states if sp.sympify(out.expr) == sp.Symbol(s.name)), None)
        if state is not None and state.min is not None and state.max is not None:
            a = SWING * (state.max - state.min)
            amp.append(a)
            off.append(float(np.clip(head[j], state.min + a, state.max - a)))
        else:
            amp.append(AMPLITUDE)
            off.append(float(head[j]) if np.isfinite(head[j]) else 0.0)
    if shape in ("circle", "figure8"):   # the two outputs of the plane swing alike
        amp[0] = amp[1] = min(amp[0], amp[1])
    phases = [0.0] * m
    cycles = [1] * m
    if shape == "circle":
        phases[0] = math.pi / 2
    if shape == "figure8":
        cycles[1] = 2
        amp[1] = amp[1] / 2
    amp = _numbers(amplitude, m, "--amplitude") or amp
    off = _numbers(offset, m, "--offset") or off
    phases = _numbers(phase, m, "--phase") or phases
    if period is not None and not (isinstance(period, (int, float)) and math.isfinite(period) and period > 0):
        raise ScenarioError(f"--period {period}: needs a positive number of seconds")
    return Shape(shape, tuple(amp), tuple(off), tuple(phases), tuple(cycles), float(period or PERIOD))


MAX_PERIOD_STEPS = 1e5   # a period's steps: codegen scenario walks the plant along one (1e8 ran for hours)
MIN_SECONDS = 2.0   # a starting scenario measures from 1 s on: a shorter file leaves nothing


def from_trajectory(flat, traj) -> Shape:
    """The reference of a starting scenario that follows a user's CSV (trajectory_file): its
    length in whole steps, each output's half swing and mean, and the angular frequency of a
    sinusoid with the same ratio of rms speed to rms swing (what P0 and the q floor scale with)."""
    from dfeif_codegen.experiment import trajectory_file

    mdl = flat.model
    names, ts = [o.name for o in mdl.outputs], float(mdl.ts)
    span = math.floor((traj.t[-1] + 1e-9 * ts) / ts) * ts
    if span < MIN_SECONDS:
        raise ScenarioError(f"{traj.path}: covers {traj.t[-1]:g} s from t = 0; a starting scenario needs at "
                            f"least {MIN_SECONDS:g} s")
    trajectory_file.check(traj, names, flat.degrees, span - ts, mdl.name)
    refs = traj.outputs(names, flat.degrees)
    grid = np.arange(int(round(span / ts))) * ts
    rates = []
    for ref in refs:
        y = np.array([ref.flags(t, 1) for t in grid])
        swing = float(np.sqrt(np.mean((y[:, 0] - y[:, 0].mean()) ** 2)))
        if swing > 0:
            rates.append(float(np.sqrt(np.mean(y[:, 1] ** 2))) / swing)
    rate = max(rates) if rates and max(rates) > 0 else 2 * math.pi / span
    amp = traj.amplitude(names)
    offset = tuple(float(np.mean(traj.column(n))) for n in names)
    m = flat.m
    return Shape("trajectory", amp, offset, (0.0,) * m, (1,) * m, span, traj, rate)


def read_trajectory(trajectory: str, smoothing, shaped: bool):
    """The user's CSV, read and checked before the model's derivation (which may take a minute):
    a missing or malformed file, or shape options beside it, are said first."""
    from dfeif_codegen.experiment import trajectory_file

    if shaped:
        raise ScenarioError("--trajectory: the file gives the reference; --shape, --amplitude, --offset, --phase "
                            "and --period do not apply")
    if not (isinstance(smoothing, (int, float)) and math.isfinite(smoothing) and smoothing >= 0):
        raise ScenarioError(f"--smoothing {smoothing}: needs a window of 0 or more seconds")
    return trajectory_file.read(Path(trajectory), float(smoothing))


def of_trajectory(flat, traj, trajectory: str, out: Path | None):
    """The read CSV `traj` (from `trajectory`) as the starting scenario's reference, checked over
    its whole length (the transform defined at every sample); and how the scenario will name it."""
    import os

    from dfeif_codegen.experiment import closed_loop as ex
    from dfeif_codegen.experiment.trajectory import flags

    shape = from_trajectory(flat, traj)
    refs = traj.outputs([o.name for o in flat.model.outputs], flat.degrees)
    t = np.arange(int(round(shape.period / flat.model.ts))) * flat.model.ts
    try:
        ex.check_reference(flat, [flags(refs, flat.degrees, tk) for tk in t], t)
    except ArithmeticError as exc:
        raise ScenarioError(f"{trajectory}: {exc}") from None
    return shape, Path(os.path.relpath(Path(trajectory).resolve(),
                                       (out.parent if out else Path(".")).resolve())).as_posix()


PERIODS = tuple(5.0 * 2.0 ** k for k in range(8))   # 5 s to 640 s, tried in order: slower references last
SCALES = (1.0, 0.5, 0.25, 0.1)                      # and smaller swings
CHECK_POINTS = 1000                                 # reference states checked per period


def fitting(flat, spec: str, kind: str = "sinusoid", amplitude=None, offset=None, phase=None,
            period=None) -> Shape:
    """from_domains, and where its reference leaves the transform's domain (a speed or thrust
    outside its limits, the decoupling matrix's singular set) or needs an input past its limits
    (`_check_inputs`), the first slower (PERIODS) or smaller (SCALES) one that stays inside;
    values given are kept as given. When none fits, a ScenarioError naming what the first one
    hit and when."""
    from dfeif_codegen.experiment import closed_loop as ex
    from dfeif_codegen.experiment.trajectory import flags

    base = from_domains(flat, kind, amplitude, offset, phase, period)
    if period is not None:   # the scenario's own bounds, before the calibration walks the period
        ts = float(flat.model.ts)
        if not 2 * ts <= period <= MAX_PERIOD_STEPS * ts:
            raise ScenarioError(f"--period {period:g}: needs {2 * ts:g} to {MAX_PERIOD_STEPS * ts:g} s at the model's "
                                f"Ts = {ts:g} s (two sampling periods to {MAX_PERIOD_STEPS:g} of them)")
    periods = (base.period,) if period is not None else PERIODS
    scales = (1.0,) if amplitude is not None else SCALES
    first = None
    for scale in scales:
        for p in periods:
            shape = Shape(base.kind, tuple(a * scale for a in base.amplitude), base.offset, base.phase,
                          base.cycles, p)
            refs = ex.references(ex.Config(model=spec, **shape.config()), flat.m)
            t = np.linspace(0.0, p, CHECK_POINTS, endpoint=False)   # one period: the reference repeats
            rows = [flags(refs, flat.degrees, tk) for tk in t]
            try:
                ex.check_reference(flat, rows, t)
                _check_inputs(flat, rows, t)
                return shape
            except ArithmeticError as exc:
                first = first or str(exc)
    given = {"--amplitude": amplitude, "--offset": offset, "--period": period}
    said = [flag for flag, value in given.items() if value is not None]
    unsaid = [flag for flag, value in given.items() if value is None] + ["--shape"]
    hint = (f"change {' or '.join(said)}, or " if said else "") + "give " + (
        f"{', '.join(unsaid[:-1])} or {unsaid[-1]}" if len(unsaid) > 1 else unsaid[0])
    raise ScenarioError(f"{flat.model.source}: no {kind} reference around ({', '.join(f'{v:g}' for v in base.offset)}) "
                        f"stays where the transform is defined and the inputs within their limits ({first}); {hint}")


def feedforward(flat, row, p) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The canonical state one row of reference flags describes, the chains' top derivatives it
    asks for, and the input that gives them there, u = G⁻¹(y^(r) - F) (parameters p)."""
    z = ex.state_of_flags(flat, row)
    top = np.array([row[c.offset + j + c.degree] for j, c in enumerate(flat.chains)])
    return z, top, np.linalg.solve(flat.G_num(z, p), top - flat.F_num(z, p))


def _check_inputs(flat, rows, t) -> None:
    """The feedforward of the reference, u = G⁻¹(y^(r) - F) at its own states (what the plant
    needs to follow it exactly), inside each input's declared limits less a tenth of their range
    at both ends, left to the feedback. Why: past a limit the input is clamped and the loop stops
    tracking (a tank whose 5 s reference asked for 2.9 times its inflow tracked to 55% of the
    swing); ArithmeticError at the first point outside, like check_reference."""
    inputs = flat.model.inputs
    lo = np.array([-np.inf if w.min is None else w.min for w in inputs], dtype=float)
    hi = np.array([np.inf if w.max is None else w.max for w in inputs], dtype=float)
    if not (np.isfinite(lo).any() or np.isfinite(hi).any()):
        return
    margin = np.where(np.isfinite(hi - lo), 0.1 * (hi - lo), 0.0)
    p = flat.param_vector
    for k, row in enumerate(rows):
        u = feedforward(flat, row, p)[2]
        out = np.flatnonzero((u < lo + margin) | (u > hi - margin))
        if out.size:
            i = int(out[0])
            raise ArithmeticError(f"the reference at t = {t[k]:.3f} s needs {inputs[i].name} = {u[i]:.3g}, outside "
                                  f"[{lo[i]:g}, {hi[i]:g}] less a tenth of that range for the feedback")


def along_reference(flat, spec: str, points: int = 12, shape: Shape | None = None) -> list[tuple]:
    """The canonical state and the feedforward input at `points` instants of one period of the
    reference (the model's own parameters)."""
    shape = shape or from_domains(flat)
    refs = ex.references(ex.Config(model=spec, **shape.config()), flat.m)
    out = []
    for tk in np.linspace(0, shape.period, points, endpoint=False):
        z, _, u = feedforward(flat, flags(refs, flat.degrees, tk), flat.param_vector)
        out.append((z, u))
    return out


def fastest_oscillation(flat, spec: str, ts: float, points: int = 12, shape: Shape | None = None) -> float:
    """Largest |imaginary part| of the plant Jacobian's eigenvalues along the reference [rad/s]
    (`codegen scenario` names it when it turns by more than 0.3 rad per period: fast_mode)."""
    plant = ex._plant(spec, ts, 1)
    p, n, worst = flat.param_vector, flat.n, 0.0
    for z, u in along_reference(flat, spec, points, shape):
        x = flat.phi_inv_num(z, p)
        h = 1e-6 * np.maximum(1.0, np.abs(x))
        jac = np.column_stack([(plant.rhs(x + h[i] * np.eye(n)[i], u) - plant.rhs(x - h[i] * np.eye(n)[i], u))
                               / (2 * h[i]) for i in range(n)])
        worst = max(worst, float(np.abs(np.linalg.eigvals(jac).imag).max()))
    return worst


def fast_mode(omega: float, ts: float) -> str:
    """What to say of a plant mode turning more than 0.3 rad per period (eigenvalues of the plant's
    Jacobian along the reference): said where loops were lost or past 1 rad, since the held
    predictor samples such a mode exactly (a stiff flexible joint tracks to 0.5% of its swing at
    0.94 rad per period, 18% at 1.8, not at all at 3.7); the period proposed turns it 0.3 rad."""
    return "" if omega * ts <= 0.3 else (f"the plant oscillates at up to {omega:.3g} rad/s, {omega * ts:.2f} rad per "
                                         f"period at Ts = {ts:g} s: a period of about {0.3 / omega:.2g} s "
                                         f"(scenario.ts) may close it, at {ts * omega / 0.3:.0f} times the work")


def reference_table(shape: Shape, file: str | None) -> list[str]:
    """The [reference] table: the shape's numbers, or the user's CSV (`file`: relative to it)."""
    if shape.trajectory is not None:
        smoothing = [f"smoothing = {shape.trajectory.smoothing:g}"] if shape.trajectory.smoothing else []
        return ["[reference]           # the user's trajectory (columns t, each flat output, <name>_d<k>)",
                f"file = {json.dumps(file)}", *smoothing, ""]
    return [f"[reference]           # {shape.kind}, from the flat outputs' declared domains",
            f"amplitude = {toml_list(shape.amplitude)}", f"period = {shape.period:g}",
            f"offset = {toml_list(shape.offset)}", f"phase = {toml_list(shape.phase)}",
            f"cycles = {toml_list(shape.cycles)}", "harmonics = 4", ""]


def toml_list(values) -> str:
    """A TOML list of numbers to four significant digits, as a starting scenario writes them."""
    return "[" + ", ".join(f"{float(v):.4g}" for v in values) + "]"
