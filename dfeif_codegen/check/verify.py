"""`codegen verify`: run the generated C on a recorded scenario and compare it with the reference.

Relative error, per signal (node i's x and P, the master's x and P, u, v), worst over the run:

- a vector signal (x, u, v), component c at step t:
  `|C - ref| / max(|ref|, rms_c)`, where `rms_c` is the root mean square of that component over
  the run: a plain relative error where the value is large, and relative to the component's
  typical size where it crosses zero (a relative error there would divide by ~0).
- a covariance, entry (i, j) at step t: `|C - ref| / sqrt(P_ii P_jj)` with the reference's
  diagonal at that step. For a diagonal entry that is the plain relative error; off the diagonal it
  is the error in correlation units (|P_ij| <= sqrt(P_ii P_jj), so this is again max(|ref|, scale)).
  Covariances shrink by orders of magnitude from P0 to steady state, so no scale fixed over the run
  would do.
A reference that is exactly zero with its scale zero must be matched exactly.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from dfeif_codegen import json_text
from dfeif_codegen.check.yardstick import yardstick
from dfeif_codegen.errors import MismatchError, ScenarioError, SetupError

TINY = np.finfo(float).tiny


@dataclass(frozen=True)
class SignalError:
    signal: str
    worst: float      # worst relative error over the run
    step: int         # where it occurs
    index: tuple      # component (or matrix entry) where it occurs
    tol: float

    @property
    def ok(self) -> bool:
        return bool(self.worst <= self.tol)


def relative_error(got: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Elementwise relative error of a time series (steps first): vectors (K, n) or covariances
    (K, n, n), as documented in the module docstring."""
    got, ref = np.asarray(got, dtype=float), np.asarray(ref, dtype=float)
    if got.shape != ref.shape:
        raise ValueError(f"shape {got.shape} differs from the reference's {ref.shape}")
    diff = np.abs(got - ref)
    if ref.ndim == 3 and ref.shape[1] == ref.shape[2]:
        d = np.sqrt(np.abs(np.diagonal(ref, axis1=1, axis2=2)))
        scale = d[:, :, None] * d[:, None, :]
    else:
        rms = np.sqrt(np.mean(ref ** 2, axis=0, keepdims=True))
        scale = np.maximum(np.abs(ref), rms)
    with np.errstate(invalid="ignore", divide="ignore"):
        err = np.where(scale > 0, diff / np.maximum(scale, TINY), np.where(diff > 0, np.inf, 0.0))
    return np.where(np.isnan(got) & ~np.isnan(ref), np.inf, err)


def compare(got: dict[str, np.ndarray], ref: dict[str, np.ndarray], tol: float | dict) -> list[SignalError]:
    """Worst relative error per signal; `tol` one number or one per signal name."""
    out = []
    for name, want in ref.items():
        err = relative_error(got[name], want)
        at = np.unravel_index(int(np.argmax(err)), err.shape) if err.size else (0,)
        limit = tol[name] if isinstance(tol, dict) else tol
        out.append(SignalError(name, float(err[at]) if err.size else 0.0, int(at[0]),
                               tuple(int(i) for i in at[1:]), float(limit)))
    return out


def table(errors: list[SignalError]) -> str:
    """One line per signal: worst relative error, where, tolerance, PASS/FAIL."""
    rows = [("signal", "worst rel. error", "step", "index", "tolerance", "")]
    rows += [(e.signal, f"{e.worst:.3e}", str(e.step), ",".join(map(str, e.index)) or "-",
              f"{e.tol:.0e}", "PASS" if e.ok else "FAIL") for e in errors]
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows)


def check(errors: list[SignalError]) -> None:
    bad = [e for e in errors if not e.ok]
    if bad:
        # a signal held to 0 (late_applied: accepted/rejected must agree exactly) is the worst
        worst = max(bad, key=lambda e: e.worst / e.tol if e.tol > 0 else np.inf)
        if worst.signal == "late_applied":
            raise MismatchError(f"{len(bad)} signal(s) differ from the reference; worst late_applied: "
                                f"a late measurement accepted on one side and rejected on the other "
                                f"(first at step {worst.step})")
        raise MismatchError(f"{len(bad)} signal(s) differ from the reference; worst {worst.signal}: "
                            f"{worst.worst:.3e} > {worst.tol:.0e} at step {worst.step}")


# --- what is compared ---------------------------------------------------------------------------

# double: everything to round-off. float: the estimates to 1e-4 of their scale; u and v to 1e-3,
# because v = y_d^(r) - sum k e multiplies the position error by the largest gain (lambda^r, 1000
# for the paper's poles) and u = G^-1 (v - F) inherits that.
TOLERANCE = {"double": {"x": 1e-10, "P": 1e-10, "u": 1e-10, "v": 1e-10},
             "float": {"x": 1e-4, "P": 1e-4, "u": 1e-3, "v": 1e-3}}


def signals(out: dict, nodes: int) -> dict[str, np.ndarray]:
    """Outputs (as replay_recording returns them) as named time series, steps first."""
    named = {}
    for i in range(nodes):
        named[f"node{i}.x"], named[f"node{i}.P"] = out["node_x"][i], out["node_P"][i]
    named["master.x"], named["master.P"] = out["x"], out["P"]
    named["u"], named["v"] = out["u"], out["v"]
    return named


def tolerances(names, precision: str) -> dict[str, float]:
    tol = TOLERANCE[precision]
    return {name: tol[name.rsplit(".", 1)[-1]] for name in names}


def reference_outputs(rec) -> dict[str, np.ndarray]:
    """What the Python reference computed in the closed loop (replay_recording gives the same
    numbers bit for bit, see experiment/closed_loop.py)."""
    return {k: np.asarray(getattr(rec, k)) for k in ("late_applied", "node_x", "node_P", "x", "P", "u", "v")}


def compare_run(got: dict, rec, precision: str) -> list[SignalError]:
    """Every signal of a C run against the recording; late measurements accepted/rejected must
    agree exactly (a disagreement is reported as an infinite error on 'late_applied')."""
    want = reference_outputs(rec)
    named_ref = signals(want, rec.nodes)
    errors = compare(signals(got, rec.nodes), named_ref, tolerances(named_ref, precision))
    same = np.array_equal(np.asarray(got["late_applied"], bool), np.asarray(want["late_applied"], bool))
    bad = np.nonzero(np.asarray(got["late_applied"], bool) != np.asarray(want["late_applied"], bool))[0]
    step = int(rec.late_step[bad[0]]) if bad.size else 0
    errors.append(SignalError("late_applied", 0.0 if same else np.inf, step, (), 0.0))
    return errors


def nudged(rec, eps: float, seed: int):
    """The recording with its nodes' P0 moved by one ulp (`eps`, random signs, symmetrized): a
    perturbation as small as one rounding, so a rerun's distance from the reference measures how
    much the problem itself amplifies rounding."""
    rng = np.random.default_rng(seed)
    P0 = rec.node_P0 * (1 + eps * rng.choice([-1, 1], rec.node_P0.shape))
    return replace(rec, node_P0=(P0 + np.swapaxes(P0, 1, 2)) / 2)


def worst_of(runs) -> list[SignalError]:
    """Signal by signal, the worst of several comparisons (each a compare_run list)."""
    worst: dict[str, SignalError] = {}
    for errors in runs:
        for e in errors:
            if e.signal not in worst or e.worst > worst[e.signal].worst:
                worst[e.signal] = e
    return list(worst.values())


def float32_reference_errors(rec, nudges: int = 0, recorded: bool = True) -> list[SignalError]:
    """A second single-precision implementation on the same recording: the reference's nodes
    and master in float32 (numpy and LAPACK; the held mean instruction by instruction,
    numeric.SinglePrecision), compared with the float64 reference like the C is, predicting
    with the inputs the C predicted with (`recorded`: the recorded ones, else its own
    controller's). The two are not alike: a filter predicting with its own controller's input
    closes the loop on its own estimate, whose poles contract its rounding, where the recorded
    input leaves that to the filter's gain alone (the arm, one camera at 4x noise, CI: master x
    in float32 1.6e-5 from the reference with its own inputs, 1.2e-4 with the recorded ones,
    the C 8.1e-5; the first made `codegen verify` blame the C).
    With `nudges`, the worst of that run and as many more with P0 nudged by one float ulp:
    where a one-ulp change moves the result by up to the budget, one float32 run is one draw
    (the arm's CI master: 2.9e-5 to 1.0e-4 with the association alone), and the ensemble's
    worst is the size."""
    from dfeif_codegen.check.driver_io import broadcast
    from dfeif_codegen.experiment import closed_loop as experiment

    eps = float(np.finfo(np.float32).eps)
    inputs = broadcast(rec) if recorded else None
    recs = [rec] + [nudged(rec, eps, seed) for seed in range(nudges)]
    return worst_of(compare_run(experiment.replay_recording(r, dtype=np.float32, inputs=inputs), rec, "float")
                    for r in recs)


def double_twin_errors(rec, recorded: bool) -> list[SignalError]:
    """A second double implementation on the same recording: the reference with every
    covariance product associated the other way (Φ (P Φᵀ) for (Φ P) Φᵀ: the same filter, other
    roundings), predicting with the inputs the C predicted with (`recorded`: the recorded ones,
    else its own controller's), compared with the reference like the C is."""
    from dfeif_codegen.check.driver_io import broadcast
    from dfeif_codegen.experiment import closed_loop as experiment

    inputs = broadcast(rec) if recorded else None
    return compare_run(experiment.replay_recording(rec, inputs=inputs, right_first=True), rec, "double")


# --- recorded scenarios ---------------------------------------------------------------------------

def record(*args, **kw):
    """The Recording of `closed_loop(...)`: every input event and every reference output."""
    return closed_loop(*args, **kw).recording


def closed_loop(model: str, oosm: str = "replay", fusion: str = "difference", reference: str = "sinusoid",
                row: int = 2, nodes: int = 2, max_lag: int = 32, seed: int = 0, duration: float | None = None,
                uplink=None, sensor_drop: float | None = None, scenario_spec: str = "paper",
                predictor: str | None = None, gate: float | None = None):
    """One closed-loop run of a scenario (default the built-in paper one) with the Python reference
    (an experiment.Result). `row` indexes the scenario's delay grid; `uplink` (a network Link) makes
    node -> master packets late or lost; `sensor_drop` adds camera frame drops; `predictor` None:
    held, brunovsky with retrodict; `gate`: the nodes' innovation gate (None: the scenario's)."""
    import dataclasses

    from dfeif_codegen.experiment import plan, scenario
    from dfeif_codegen.experiment import closed_loop as experiment

    sc = scenario.load(scenario_spec)
    cfg = plan.make_config(sc, model, nodes, max_lag, reference, sc.grid[row], oosm, fusion, seed, predictor)
    changes: dict[str, Any] = {} if gate is None else {"gate": gate}
    if duration is not None:
        changes["duration"] = duration
        changes["metrics_from"] = min(cfg.metrics_from, duration / 2)
    if uplink is not None:
        changes["uplink"] = tuple(uplink for _ in range(nodes))
    if sensor_drop is not None:
        changes["sensor"] = tuple(dataclasses.replace(s, p_drop=sensor_drop) for s in cfg.sensor)
    return experiment.run(dataclasses.replace(cfg, **changes))


# --- the command ------------------------------------------------------------------------------------

def verify_row(sc) -> int:
    """The scenario's first delay row with late frames (the paper grid's (4, 6, 0.8), which every
    method survives), or its first row if none has any."""
    return next((i for i, row in enumerate(sc.grid) if row.p > 0), 0)


@dataclass
class Verification:
    """What `verify` found: the settings, the scenario, the worst error per signal and, on the
    Cortex-M4F, the target's figures; after a mismatch the yardstick."""

    settings: str
    scenario: str
    errors: list[SignalError]
    target_report: str = ""
    yardstick: str = ""

    @property
    def ok(self) -> bool:
        return all(e.ok for e in self.errors)

    def report(self) -> str:
        return "\n".join(t for t in (table(self.errors), self.target_report, self.yardstick) if t)

    def to_dict(self) -> dict:
        return {"settings": self.settings, "scenario": self.scenario, "ok": self.ok,
                "errors": errors_as_dicts(self.errors), "target_report": self.target_report,
                "yardstick": self.yardstick}

    def to_json(self) -> str:
        return json_text.dumps(self.to_dict())


def errors_as_dicts(errors: list[SignalError]) -> list[dict]:
    """The comparison table as data: per signal its worst relative error, where, the tolerance."""
    return [{"signal": e.signal, "worst": float(e.worst), "step": int(e.step), "index": [int(i) for i in e.index],
             "tol": float(e.tol), "ok": e.ok} for e in errors]


def verify(model: str = "dc_motor_link", *, target: str = "host", precision: str | None = None,
           sanitize: bool = False, scenario: str = "paper", inputs: str = "recorded", max_lag: int = 32,
           nodes: int | None = None, oosm: str = "replay", fusion: str = "difference", progress=None,
           max_seconds: float | None = None, max_memory: float | None = None,
           predictor: str | None = None, gate: float | None = None) -> Verification:
    """Build into a temporary folder, record a scenario (default the paper one, its first delay
    row with late frames, its first reference (the paper's sinusoid), 20 s) with the reference, run the C on it (host: ctypes, or a
    program under ASan+UBSan with `sanitize`; cortex-m4f: QEMU) and compare. `progress(line)` is
    told the settings and the scenario as soon as they are known. The derivations (the
    reference's and the build's) run under `max_seconds` CPU seconds and `max_memory` GB. A
    mismatch is in the result (`ok`, `check(result.errors)` raises it); bad input and missing
    tools raise before any work. `gate`: the build's and the reference's innovation gate (None:
    the scenario's [filter] gate, if any)."""
    import tempfile
    from pathlib import Path

    from dfeif_codegen.check import driver_io, harness, stages, target as targets
    from dfeif_codegen.experiment import derivation, scenario as scenarios

    from dfeif_codegen.codegen.options import Options
    from dfeif_codegen.symbolic.sampling import for_method

    say = progress or (lambda line: None)
    predictor = for_method(predictor, oosm)
    Options(ts=1.0, oosm=oosm, fusion=fusion, predictor=predictor, gate=gate)   # bad combinations: exit 2 now
    if target not in ("host", "cortex-m4f"):
        raise SetupError(f"--target must be host or cortex-m4f, got {target!r}")
    driver_io.recorded_inputs(inputs)
    sc = scenarios.load(scenario)
    nodes = len(sc.noise_scale) if nodes is None else nodes   # the scenario's [[nodes]], as simulate's
    gate = sc.gate or None if gate is None else gate          # the scenario's [filter] gate, unless given
    sc.check_predictor(predictor, oosm)
    if sc.disturbance is not None:    # the C carries the scenario's disturbance states
        Options(ts=1.0, oosm=oosm, fusion=fusion, predictor=predictor, disturbance=sc.disturbance.kind,
                tau=sc.disturbance.tau)
    sc.check_model(derivation.derive(model, max_seconds, max_memory))   # the derivation the recording reuses (cached)
    row, ref = verify_row(sc), sc.references[0]   # the paper's: sinusoid; a CSV's: trajectory
    scenarios.check_window(sc, max_lag, nodes, rows=[row])
    precision = precision or ("float" if target == "cortex-m4f" else "double")
    if target == "host":
        harness.host_compiler()
    else:
        for tool in ("arm-none-eabi-gcc", "arm-none-eabi-size", "qemu-system-arm"):
            targets.require(tool)
        targets.require_newlib()
        if sanitize:
            raise SetupError("--sanitize applies to --target host only")
    with tempfile.TemporaryDirectory(prefix="codegen-verify-") as tmp:
        work = Path(tmp)
        # the C is built at the sampling period the scenario records at (its ts, else the model's)
        built = harness.build_model(model, work / "gen", precision, oosm, fusion, nodes, max_lag, ts=sc.ts or None,
                                    predictor=predictor, disturbance=sc.disturbance, gate=gate)
        dist = ("" if sc.disturbance is None else f", disturbance {sc.disturbance.kind}") + \
            ("" if gate is None else f", gate {gate:g}")
        settings = (f"{built.name}, {precision}, oosm {oosm}, fusion {fusion}, predictor {predictor}{dist}, {nodes} nodes, "
                    f"max lag {max_lag}, "
                    f"target {target}, {inputs} inputs{' with ASan+UBSan' if sanitize else ''}")
        say(f"codegen verify: {settings}")
        try:
            rec = record(model, oosm, fusion, ref, row, nodes, max_lag, scenario_spec=scenario,
                         predictor=predictor, gate=gate)
        except (ArithmeticError, np.linalg.LinAlgError) as exc:
            own = (f"; the built-in scenario may not suit model {built.name}: write one for it with `codegen "
                   f"scenario {model} --out FILE` and pass it with --scenario FILE" if scenario in scenarios.BUILTIN
                   else "")
            raise ScenarioError(f"{sc.source}: run {ref} row {row + 1} seed 0: the Python reference itself "
                                f"failed ({type(exc).__name__}: {exc}), so there is nothing to compare the C "
                                f"with{own}") from None
        whole = rec.ref.shape[0]
        rec, K = targets.fitting(rec, built, inputs) if target == "cortex-m4f" else (rec, whole)
        about = (f"scenario: {sc.name}, {ref}, delays d = {tuple(sc.grid[row].d)}, p = {sc.grid[row].p}, "
                 f"{K} steps, {len(rec.late_step)} late measurements ({int(np.sum(rec.late_applied))} applied)"
                 + (f"; the first {K} of its {whole} steps: the emulated board's RAM holds its inputs that far"
                    if K < whole else ""))
        say(about)
        compiled = stages.compile(built, target, sanitize, work)    # compile -> run -> compare, once each
        ran = stages.run(compiled, rec, inputs)
        return compare_outputs(settings, about, ran, rec, precision, driver_io.recorded_inputs(inputs))


FLOAT_NUDGES = 4   # the float yardstick's ensemble: the recording and 4 nudges, replayed only after a mismatch


def compare_outputs(settings: str, about: str, ran, rec, precision: str, recorded: bool = True) -> Verification:
    """The third step: the C's outputs against the reference's, signal by signal; after a
    mismatch, how far a second implementation of the reference itself lands (the yardstick:
    in float32, or in double with other roundings; `recorded`: the C predicted with the
    recorded inputs)."""
    result = Verification(settings, about, compare_run(ran.outputs, rec, precision), ran.target_report)
    if not result.ok:
        twin = (float32_reference_errors(rec, FLOAT_NUDGES, recorded) if precision == "float"
                else double_twin_errors(rec, recorded))
        result.yardstick = yardstick(result.errors, twin, precision)
    return result
