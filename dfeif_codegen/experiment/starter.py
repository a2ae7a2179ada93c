"""`codegen scenario MODEL`: a starting scenario for any flat model, without hand tuning.

What a user would otherwise guess, derived from the model:

- poles: every pole of each chain at -0.1/Ts (the paper's lambda Ts = 0.1); with --param-error
  slowed until the loop holds the error's corners under the hardest delays (pole_margin.py);
- P0 per derivative order k: std 0.05 A (2 omega)^k for the reference's amplitude A and angular
  frequency omega (the paper's 3 degrees on the angle, looser on each derivative);
- camera noise: the model's [measurement], else 0.4% of the amplitude per flat output (the
  paper's 4 mrad on 1 rad), node 2 at 1.25 times node 1;
- q per chain: the derivative-free filter's only model error is the canonical model's one-step
  residual r(k) = zeta(k+1) - A zeta(k) - B v(k) (the plant holds u over Ts, the model holds v).
  It is measured first along the reference (the plant driven by the flat feedforward from the
  reference's own states), then along the true trajectory of a 5 s closed loop run with that q
  (ten times larger if that run diverges): q_j = max over the chain's states i of
  mean(r_i^2) / Q_d(Ts, 1)_ii, the smallest white density covering each component's residual.
  One closed-loop round, not a fixed point: the residual grows with q (a noisier u, held by the
  plant), so iterating drifts upwards (motor: 1.4, 17.5, 120, 580, ...); one round gives
  the motor 17.5, where the paper's hand calibration chose 20. That fixes the chains'
  proportions; their common scale is then set so that the master's NEES, averaged over eight 20 s
  closed loops without delays, is n (within 10%), the middle of its 95% band (`match_nees`),
  with the filter the scenario runs (`calibrate(..., **options)`: its closed-loop settings),
  searching both ways after a lost loop (`_after_loss`); none closing is exit 2. Last, q rises
  by half decades until the replay loop closes under the grid's hardest delays too
  (`close_with_delays`).
- a warning naming the plant's fastest mode past 1 rad per period, or 0.3 where a loop was lost,
  a note advising `--predictor scheduled` where it matters and holds the loops
  (scheduled_calibration.note), and the held mean's one-step exactness (mean_exactness.line).
  The residual grows with the relative degree and how fast the dynamics are against Ts.
With `--disturbance` the scenario also gets disturbance states for the held filter, their
densities calibrated to the same NEES target (experiment/disturbance_calibration.py); with
`--scheduled` the scheduled filter's q (experiment/scheduled_calibration.py).
"""

from __future__ import annotations

import dataclasses
import importlib
import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.experiment import closed_loop as ex, derivation, scenario as scenario_mod
from dfeif_codegen.experiment import (baseline_check, disturbance_calibration, disturbance_choice, mean_exactness,
                                     offsets_calibration, pole_margin, scheduled_calibration, shapes)
from dfeif_codegen.experiment.nees_match import (LAST_LOSS, NEES_RUNS, NEES_SECONDS, NEES_TOL, NO_LOOP, close_with_delays,
                                                 fmt as _fmt, match_nees)
from dfeif_codegen.experiment.shapes import toml_list
from dfeif_codegen.symbolic.disturbance import Disturbance

MARKER = "# Starting scenario written by `codegen scenario`"


def _unit_q(flat, ts) -> np.ndarray:
    """diag Q_d(Ts, q = 1) per state, chain by chain."""
    return np.diag(flat.process_noise(ts, np.ones(flat.m)))


def implied_q(flat, ts, zeta, v, u=None, predictor: str = "brunovsky") -> np.ndarray:
    """Per chain, the q whose Q covers every component of the one-step residual of the filters'
    model (zeta (K, n), v and u (K, m): canonical states, the controller's v and the applied u
    along a trajectory): the chapter's Brunovsky chain driven by v, or another predictor of
    reference/predictor.py (the held-input one of issue 22, driven by u) when the run used it."""
    if predictor == "brunovsky":
        A, B, _ = flat.discrete(ts)
        res, unit = zeta[1:] - zeta[:-1] @ A.T - v[:-1] @ B.T, _unit_q(flat, ts)
    else:
        predictors = importlib.import_module("dfeif_codegen.reference.predictor")   # only when asked for
        pred = predictors.make(predictor, flat, ts, np.ones(flat.m))
        res = zeta[1:] - np.array([pred.mean(z, w) for z, w in zip(zeta[:-1], u[:-1])])
        unit = np.diag(pred.Q)
    for c in flat.chains:
        if c.angle:
            res[:, c.offset] = (res[:, c.offset] + math.pi) % (2 * math.pi) - math.pi
    ratio = np.mean(res ** 2, axis=0) / unit
    return np.array([ratio[c.offset:c.offset + c.degree].max() for c in flat.chains])


def _reference_q(flat, ts, steps: mean_exactness.Steps) -> np.ndarray:
    """Residual along the reference: the plant started on each reference state, driven one step
    by the feedforward input of that state (`steps`)."""
    A, B, _ = flat.discrete(ts)
    res = np.array([zn - A @ z - B @ v for z, v, zn in zip(steps.starts, steps.tops, steps.ends)])
    ratio = np.mean(res ** 2, axis=0) / _unit_q(flat, ts)
    return np.array([ratio[c.offset:c.offset + c.degree].max() for c in flat.chains])


class Calibrated(NamedTuple):
    """What `calibrate` settles on, and its log."""
    q: np.ndarray
    log: list[str]
    poles: list[float]
    disturbance: Disturbance | None = None
    offsets: object = None          # reference/offsets.Offsets
    q_scheduled: np.ndarray | None = None   # the scheduled filter's (reference/scheduled.py)
    loop: object = None            # seed -> the scenario's closed loop at the calibrated q (closed_loop.Config)


def calibrate(flat, spec: str, ts: float, poles, p0_std, noise_std, substeps: int = 10,
              duration: float = 5.0, seed: int = 1000, rounds: int = 3, shape: shapes.Shape | None = None,
              delays: tuple | None = None, progress=None, **options) -> Calibrated:
    """q per chain and a log of the rounds (see the module docstring). `options`: the filters'
    settings of the closed loops (closed_loop.Config fields, e.g. the predictor the scenario
    selects), so q is calibrated for the filter that will run; `delays`: the camera links
    (network.Link per node) of the scenario's hardest delay row, which q must also close, and
    with a `plant_error` the poles too (pole_margin). With `disturbance` among the options (a
    Disturbance, its densities ignored): its calibrated densities, and the `offsets` option
    (reference/offsets.Offsets) with its chains' q calibrated; with `scheduled=True` the scheduled
    filter's q (scheduled_calibration). `progress(line)` hears each stage
    as it starts and each NEES evaluation (a stiff model's loops take minutes)."""
    say = progress or (lambda line: None)
    shape = shape or shapes.from_domains(flat)
    say("q from the one-step residual along the reference")
    steps = mean_exactness.reference_steps(flat, spec, ts, substeps, shape)
    q = _reference_q(flat, ts, steps)
    floor = 1e-6 * np.array([(a * shape.omega ** c.degree) ** 2 * shape.period
                             for a, c in zip(shape.amplitude, flat.chains)])
    q = np.maximum(q, floor)
    log = [f"along the reference: q = {_fmt(q)}"]
    if options.get("predictor") != "brunovsky":     # the held mean's own exactness, for mean_substeps
        log.append(mean_exactness.line(flat, ts, steps))

    def config(q, run_seed, duration=duration):   # a file's trajectory ends: no run beyond it
        return ex.Config(model=spec, ts=ts, duration=min(duration, shape.limit), substeps=substeps, q=tuple(q),
                         poles=tuple(poles), p0_std=tuple(p0_std), **shape.config(),
                         noise_std=tuple(None if s is None else tuple(s) for s in noise_std),
                         noise_scale=(1.0, 1.25), seed=run_seed, watch_nees=False, **options)
        # too small a q is what these loops measure (a high NEES); only a plant out of its domain ends one

    dist = options.pop("disturbance", None)
    offsets = options.pop("offsets", None)
    scheduled = options.pop("scheduled", False)
    if dist is not None:      # the loops are closed by the chapter's filter (module docstring)
        options["predictor"] = "brunovsky"
    reason = None      # the last loop's: it names what to change (the reference, or an error it cannot hold)
    for k in range(rounds):
        say(f"closed-loop round {k + 1} of at most {rounds}: q from the residual along a {duration:g} s loop")
        cfg = config(q, seed)
        try:
            res = ex.run(cfg)
        except (ArithmeticError, FloatingPointError, np.linalg.LinAlgError) as exc:
            q, reason = q * 10, exc
            log.append(f"closed loop diverged: q x 10 -> {_fmt(q)}")
            continue
        if dist is not None:
            return _with_disturbance(flat, cfg, res, q, config, seed, poles, delays, dist, offsets, scheduled, log, say)
        k0 = int(round(cfg.metrics_from / ts))
        rec = res.recording      # the residual of the predictor the loop ran
        q = np.maximum(implied_q(flat, ts, res.zeta[k0:], rec.v[k0:], rec.u[k0:],
                                 getattr(rec, "predictor", "brunovsky")), q)
        log.append(f"along the closed loop: q = {_fmt(q)}")
        break
    if dist is not None:
        raise ArithmeticError(f"every closed loop of the calibration diverged (q up to {_fmt(q)}; the last: {reason})")
    seeds = [seed + i for i in range(NEES_RUNS)]
    say(f"scaling q until the master's NEES over {NEES_RUNS} runs of {NEES_SECONDS:g} s without delays is n")
    q, log = match_nees(flat, q, config, seeds, log, progress=say)
    if delays is not None and NO_LOOP not in log[-1]:
        q, log = close_with_delays(q, config, seeds, delays, log, progress=say)
        poles, log = pole_margin.hold(lambda j: config(q, seed + j, NEES_SECONDS), poles,
                                      options.get("plant_error"), flat.model, delays, log, progress=say)
    q_scheduled = None
    if scheduled and NO_LOOP not in log[-1]:
        q_scheduled, log = scheduled_calibration.q_scheduled(flat, q, config, seeds, log, say)
    return Calibrated(q, log, list(poles), q_scheduled=q_scheduled, loop=lambda s: config(q, s, NEES_SECONDS))


def _with_disturbance(flat, cfg, res, q, config, seed, poles, delays, dist, offsets, scheduled, log, say):
    """`calibrate` with disturbance states, from its first closed loop `cfg` (result `res`, q `q`, closed
    by the chapter's filter): the held filter's white q, the densities (of `dist`'s kind, or the kind
    chosen), the poles; with `offsets`, its chains' q; `scheduled`, the scheduled filter's white q."""
    ts = cfg.ts
    k0 = int(round(cfg.metrics_from / ts))
    rec = res.recording      # the residual of the predictor the loop ran
    held = _held_residual_q(flat, ts, cfg, res, k0)
    q = np.maximum(implied_q(flat, ts, res.zeta[k0:], rec.v[k0:], rec.u[k0:]), q)
    log.append(f"along the closed loop: q = {_fmt(held)} (held), {_fmt(q)} (the loop's filter)")
    held, log = _white_q(flat, held * np.min(q / held), config, seed, log, say)
    # a drawn error makes each run's NEES another: the draw's orthogonal array stands in for it (ParamError.design)
    drawn = cfg.plant_error.draw != "none"
    errors = cfg.plant_error.design(flat.model) if drawn else [cfg.plant_error] * NEES_RUNS
    seeds = [seed + i for i in range(len(errors))]
    loops, log = disturbance_calibration.error_loops(config, q, held, seeds, errors, log, say)
    match = lambda qq, lg, nees: match_nees(flat, qq, None, seeds, lg, nees, progress=say)  # noqa: E731
    hold = lambda qq, d, lg, start=tuple(poles): pole_margin.hold(  # noqa: E731  (from the scenario's poles)
        lambda j: dataclasses.replace(config(qq, seed + j, NEES_SECONDS), predictor="held", disturbance=d),
        start, cfg.plant_error, flat.model, delays, lg, progress=say)
    say(f"disturbance densities ({dist.kind}): scaled until the held filter's NEES on those loops, then on its own, is n")
    if dist.kind == disturbance_calibration.AUTO:
        held, log, dist, poles = disturbance_choice.choose(flat, held, loops, match, NEES_TOL, log, hold,
                                                              dist.tau)
    else:
        held, log, dist = disturbance_calibration.densities(flat, held, loops, dist, match, NEES_TOL, log)
        poles, log = hold(held, dist, log)
    dist, poles, log = disturbance_calibration.settle(flat, held, dist, poles, hold, config, errors, seeds, log, say)
    if offsets is not None:     # a reference filter that closes no loop here: no floor
        say("the offset filter's chains: q scaled until its NEES on those loops is n")
        free = lambda qq, lg, nees: match_nees(flat, qq, None, seeds, lg, nees, floor=None, progress=say)  # noqa: E731
        offsets, log = offsets_calibration.chains_q(held, loops, offsets, free, log)
    q_s, log = (scheduled_calibration.under_model_error(flat, held, loops, seeds, dist, log, say) if scheduled
                else (None, log))
    loop = lambda s: dataclasses.replace(config(held, s, NEES_SECONDS), plant_error=ex.EXACT_MODEL)  # noqa: E731
    return Calibrated(held, log, poles, dist, offsets, q_s, loop)


def _white_q(flat, start, config, seed: int, log: list[str], say) -> tuple[np.ndarray, list[str]]:
    """The held filter's q for the white part: NEES-matched on loops the held filter closes on
    the exact model, as a scenario without disturbance states gets it; the disturbance states
    then take only what the model error adds. `start`: the held one-step residual's proportions
    at the magnitude of the q the calibration loops' filter needs. The residual itself is what a
    near-exact predictor misses, decades below (motor 5.7e-7): on the exact model the held
    filter's NEES hardly depends on q down there (motor: 3.08 at 8.5e-6), so a match started from it
    stays at a q where the master's information cancels so many digits that the C no longer equals
    the reference to 1e-10 (2.5e-7 at 5.7e-7) and the arm's filters fail (all lost at 7e-6)."""
    def exact(q, run_seed, duration=NEES_SECONDS):
        return dataclasses.replace(config(q, run_seed, duration), predictor="held", plant_error=ex.EXACT_MODEL)
    say("the held filter's white part: q scaled until its NEES on the exact model is n")
    q, log = match_nees(flat, start, exact, [seed + i for i in range(NEES_RUNS)], log, progress=say)
    log[-1] = "the held filter's white part: " + log[-1]
    return q, log


def _held_residual_q(flat, ts, cfg, res, k0) -> np.ndarray:
    """The held filter's q from its one-step residual along the loop `cfg` (its result `res`),
    on the exact model: what white noise describes; a model error is the disturbances'."""
    if cfg.plant_error.active:
        res = ex.run(dataclasses.replace(cfg, plant_error=ex.EXACT_MODEL))
    rec = res.recording
    return implied_q(flat, ts, res.zeta[k0:], rec.v[k0:], rec.u[k0:], "held")


def starting_scenario(spec: str, shape: shapes.Shape | None = None, file: str | None = None,
                      disturbance: Disturbance | None = None, plant_error=None,
                      offsets=None, progress=None, scheduled: bool = False) -> tuple[str, list[str]]:
    """The TOML text of a starting scenario for model `spec`, and the calibration log; `file`:
    how the scenario names a trajectory shape's CSV; `disturbance` (its densities ignored):
    calibrated for the held filter with those states; `plant_error` (model_error.ParamError):
    the calibration's plants have it, and so has the scenario (its [model_error] table);
    `offsets` (reference/offsets.Offsets, with a disturbance): the [offsets] table, its chains'
    q calibrated on the same loops; `scheduled`: the scheduled filter's q too (q_scheduled);
    `progress` as calibrate's."""
    flat = ex._flat(spec)
    shape = shape or shapes.from_domains(flat)
    model = flat.model
    ts = float(model.ts)
    poles = [round(0.1 / ts, 6)]
    scale = max(abs(a) for a in shape.amplitude)
    p0_std = [float(f"{0.05 * scale * (2 * shape.omega) ** k:.3g}") for k in range(max(flat.degrees))]
    noise_std: list[list[float] | None] = [None, None]
    if model.measurement is None:
        std = [float(f"{0.004 * abs(a):.3g}") for a in shape.amplitude]
        noise_std = [std, [1.25 * s for s in std]]
    paper = scenario_mod.load("paper")   # its delay grid is the starting scenario's
    options = ({} if plant_error is None else {"plant_error": plant_error}) | \
        ({} if disturbance is None else {"predictor": "held", "disturbance": disturbance}) | \
        ({} if offsets is None else {"offsets": offsets}) | ({"scheduled": True} if scheduled else {})
    q, log, poles, disturbance, offsets, q_scheduled, loop = calibrate(
        flat, spec, ts, poles, p0_std, noise_std, shape=shape, delays=paper.grid[-1].links(len(noise_std)),
        progress=progress, **options)
    omega = shapes.fastest_oscillation(flat, spec, ts, shape=shape)
    fast = shapes.fast_mode(omega, ts)
    if NO_LOOP in log[-1]:     # no closed loop of the NEES stage survived: nothing was calibrated
        why = log[-1].partition(LAST_LOSS)[2]
        raise ScenarioError(f"{model.source}: every calibration round of the starting scenario diverged or lost "
                            f"its closed loop (q up to {_fmt(q)} on a {shape.kind} of amplitude "
                            f"{_fmt(shape.amplitude)} around {_fmt(shape.offset)}"
                            + (f"; the last: {why}" if why else "") + "): the loop does not close on that "
                            "reference; try --amplitude, --offset, --period or --shape"
                            + (", or a smaller --param-error" if plant_error else "") + (f"; {fast}" if fast else ""))
    lost = any(entry.startswith("WARNING") for entry in log)     # a loop lost under delays or model error
    warn = [f"# WARNING: {fast}."] if fast and (lost or omega * ts > 1.0) else []
    warn += [] if scheduled else scheduled_calibration.note(flat, spec, ts, shape, progress, loop)
    lines = [
        MARKER + f" for model {model.name}.",
        "# Every number below comes from the model (docs/experiment.md, \"A starting scenario\"):",
        "# q from the canonical model's one-step residual, poles from Ts (and the error), P0 from the reference.",
        *(f"#   calibration: {entry}" for entry in log),
        *warn,
        "",
        "[scenario]",
        f'name = "{model.name}_start"',
        f'description = "starting scenario for {model.name}, generated by codegen scenario"',
        f"duration = {shape.period if shape.trajectory is not None else max(20.0, shape.period):g}",
        "runs = 4",
        "substeps = 10",
        "metrics_from = 1.0",
        f'references = ["{shape.config()["reference"]}"]',
        'oosm = ["replay"]',
        'fusion = ["difference", "paper"]',
        'baselines = ["discard", "as-current"]',
        "",
        "[filter]",
        f"q = {toml_list(q)}               # per chain: the one-step residual, scaled toward NEES = n (above)",
        *([] if q_scheduled is None else [f"q_scheduled = {toml_list(q_scheduled)}   # simulate --filters scheduled: "
                                          "its own q, scaled toward NEES = n"]),
        f"p0_std = {toml_list(p0_std)}   # per derivative order",
        "initial_error = true", "",
        "[control]",
        f"poles = {poles[0]:g}              # every pole at -{poles[0] * ts:.3g}/Ts",
        "",
        *shapes.reference_table(shape, file),
    ]
    for i, node_std in enumerate(noise_std):
        lines += ["[[nodes]]", f"noise_scale = {1.0 if i == 0 else 1.25:g}" if node_std is None
                  else f"noise_std = {toml_list(node_std)}", ""]
    lines += ["[uplink]", "p = 0.0", "d = 0", "p_drop = 0.0", ""]
    for row in paper.grid:
        lines += ["[[grid]]", f"d = {row.d}", f"p = {row.p:g}", ""]
    lines += _extra_tables(plant_error, disturbance)
    lines += [] if offsets is None else offsets_calibration.table(offsets, model, plant_error)
    return "\n".join(lines), log


def _extra_tables(plant_error, disturbance: Disturbance | None) -> list[str]:
    """The [model_error] and [disturbance] tables of a starting scenario, when asked for."""
    lines: list[str] = []
    if plant_error is not None:
        lines += ["# the plant's parameters against the model's (--param-error), as calibrated", "[model_error]"]
        lines += [f"relative = {{ {', '.join(f'{k} = {v:g}' for k, v in plant_error.relative)} }}"] \
            if plant_error.relative else []
        lines += [f'draw = "{plant_error.draw}"', f"spread = {dict(plant_error.spread)['*']:g}", ""] \
            if plant_error.spread else [""]
    if disturbance is not None:
        lines += ["# a disturbance per chain on its top derivative" + (" and its rate" if disturbance.order == 2 else "")
                  + " (run with --predictor held);",
                  "# q: their densities, scaled so that the master's NEES averages n",
                  "[disturbance]", f'kind = "{disturbance.kind}"', f"q = {toml_list(disturbance.q)}"]
        lines += ([f"tau = {disturbance.tau:g}"] if disturbance.tau is not None else []) + (
            [f"p0_std = {toml_list(disturbance.p0_std)}   # the d's initial spread: their size on those loops"]
            if disturbance.p0_std else []) + [""]
    return lines


def scenario(model: str, out: str | None = None, max_seconds: float | None = None,
             max_memory: float | None = None, shape: str = "sinusoid", amplitude=None, offset=None,
             phase=None, period: float | None = None, trajectory: str | None = None,
             smoothing: float = 0.0, disturbance: str | None = None, tau: float | None = None,
             param_error: str | None = None, offsets: str | None = None, progress=None,
             scheduled: bool = False) -> str:
    """`codegen scenario MODEL [--out FILE]`: the starting scenario's text, checked against the
    model; written to `out` when given (only over a file this command wrote before). The
    derivation runs under `max_seconds` CPU seconds and `max_memory` GB (`amplitude`, `offset`,
    `phase`: the options' text, or numbers). `trajectory`: a CSV of the flat outputs to track
    (experiment/trajectory_file.py), named relative to `out`'s folder. `disturbance`
    (one of disturbance.KINDS; `tau` the Gauss-Markov time constant [s]): the scenario adds
    disturbance states and calibrates their densities; `param_error` (as `simulate
    --param-error`): the calibration's plants and the scenario get that model error; `offsets`
    ("NAME,..."; with both): an [offsets] table for those parameters (offsets_calibration);
    `scheduled`: q_scheduled for simulate --filters scheduled (scheduled_calibration).
    `progress(line)` hears each stage of the calibration as it starts and each NEES evaluation:
    after every check of the input, so that bad input stays one line."""
    dist = disturbance_calibration.from_options(disturbance, tau)
    plant_error = None
    if param_error is not None:
        from dfeif_codegen.experiment import model_error
        plant_error = model_error.from_option(param_error)
        plant_error = plant_error if plant_error.active else None
    if offsets is not None and (dist is None or plant_error is None):
        raise ScenarioError(f"--offsets {offsets}: needs --disturbance and a non-zero --param-error (its chains' q is "
                            "calibrated on the loops the disturbance calibration runs under that error)")
    path = Path(out) if out else None
    if path is not None:
        from dfeif_codegen.paths import first_line, replaceable_file
        replaceable_file(path, "--out", "scenario", lambda p: first_line(p).startswith(MARKER),
                         {"model file": model, "trajectory file": trajectory})
    shaped = shape != "sinusoid" or any(v is not None for v in (amplitude, offset, phase, period))
    traj = None if trajectory is None else shapes.read_trajectory(trajectory, smoothing, shaped)
    flat = derivation.derive(model, max_seconds, max_memory)
    if plant_error is not None:
        plant_error.check(flat.model, lambda key: "--param-error")
    wanted = None if offsets is None else offsets_calibration.from_option(flat, offsets, plant_error)
    file = None
    if trajectory is None:
        ref = shapes.fitting(flat, model, shape, amplitude, offset, phase, period)
    else:
        ref, file = shapes.of_trajectory(flat, traj, trajectory, path)
    say = progress and (lambda line: progress(f"codegen scenario: {line}"))    # after every check of the input
    try:
        text, _ = starting_scenario(model, ref, file, dist, plant_error, wanted, say, scheduled)
        text, _ = baseline_check.kept(text, model, str(path or "<generated>"), say)
    except (ArithmeticError, FloatingPointError, np.linalg.LinAlgError) as exc:
        raise ScenarioError(f"{flat.model.source}: the starting scenario's calibration failed on a {ref.kind} of "
                            f"amplitude {_fmt(ref.amplitude)} around {_fmt(ref.offset)}: {exc}; try --amplitude, "
                            "--offset, --period or --shape" + (", or a smaller --param-error" if plant_error else "")) from None
    scenario_mod.loads(text, str(path or "<generated>")).check_model(ex._flat(model))
    if path is not None:
        path.write_text(text + "\n", encoding="utf-8")
    return text
