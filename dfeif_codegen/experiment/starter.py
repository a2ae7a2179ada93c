"""`codegen scenario MODEL`: a starting scenario for any flat model, without hand tuning.

What a user would otherwise guess, derived from the model:

- poles: every pole of each chain at -0.1/Ts (the paper's lambda Ts = 0.1), whatever the degree;
- P0 per derivative order k: std 0.05 A (2 omega)^k for the reference's amplitude A and angular
  frequency omega (the paper's 3 degrees on the angle, looser on each derivative);
- camera noise: the model's [measurement]; a model without one gets 0.4% of the amplitude per flat
  output (the paper's 4 mrad on 1 rad), node 2 at 1.25 times node 1;
- q per chain: the derivative-free filter's only model error is the canonical model's one-step
  residual r(k) = zeta(k+1) - A zeta(k) - B v(k) (the plant holds u over Ts, the model holds v).
  It is measured first along the reference (the plant driven by the flat feedforward from the
  reference's own states), then along the true trajectory of a 5 s closed loop run with that q
  (ten times larger if that run diverges): q_j = max over the chain's states i of
  mean(r_i^2) / Q_d(Ts, 1)_ii, the smallest white-noise density that covers every component's
  residual variance. One closed-loop round, not a fixed point: the residual grows with q (a
  noisier estimate makes a noisier u, which the plant holds and the model does not), so
  iterating drifts upwards without settling (motor: 1.4, 17.5, 120, 580, ...); one round gives
  the motor 17.5, where the paper's hand calibration chose 20. That fixes the chains'
  proportions; their common scale is then set so that the master's NEES, averaged over two 20 s
  closed loops without delays, is n (within 10%), the middle of its 95% band (`match_nees`),
  with the filter the scenario runs (`calibrate(..., **options)`: its closed-loop settings).
- a warning, as a comment, when an oscillatory mode of the plant (eigenvalues of its Jacobian
  along the reference) turns by more than 0.3 rad per period: the flat controller holds u over
  Ts and cannot cancel such a mode, whatever q (the comment says which Ts would do).

With `--disturbance` the scenario also gets disturbance states for the held filter, their
densities calibrated to the same NEES target (experiment/disturbance_calibration.py).

The residual grows with the relative degree and with how fast the dynamics are against Ts: a
stiff flexible joint (relative degree 4, 94 rad/s at Ts = 10 ms) needs q near 1e7, the motor ~20.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
from pathlib import Path

import numpy as np

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import derivation
from dfeif_codegen.experiment import scenario as scenario_mod
from dfeif_codegen.experiment import disturbance_calibration, shapes
from dfeif_codegen.experiment.trajectory import flags
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


def _reference_q(flat, spec, ts, substeps, shape: shapes.Shape) -> np.ndarray:
    """Residual along the reference: the plant started on each reference state, driven one step
    by the feedforward input of that state."""
    plant = ex._plant(spec, ts, substeps)
    cfg = ex.Config(model=spec, **shape.config())
    refs = ex.references(cfg, flat.m)
    t = np.arange(int(round(shape.period / ts)) + 1) * ts
    zeta, v = [], []
    p = flat.param_vector
    for tk in t:
        fl = flags(refs, flat.degrees, tk)
        z = ex.state_of_flags(flat, fl)
        top = np.array([fl[c.offset + j + c.degree] for j, c in enumerate(flat.chains)])
        u = np.linalg.solve(flat.G_num(z, p), top - flat.F_num(z, p))
        zn = flat.phi_num(plant.step(flat.phi_inv_num(z, p), u), p)
        zeta.append(np.stack([z, zn]))
        v.append(top)
    A, B, _ = flat.discrete(ts)
    res = np.array([zz[1] - A @ zz[0] - B @ vv for zz, vv in zip(zeta, v)])
    ratio = np.mean(res ** 2, axis=0) / _unit_q(flat, ts)
    return np.array([ratio[c.offset:c.offset + c.degree].max() for c in flat.chains])


def calibrate(flat, spec: str, ts: float, poles, p0_std, noise_std, substeps: int = 10,
              duration: float = 5.0, seed: int = 1000, rounds: int = 3,
              shape: shapes.Shape | None = None, **options) -> tuple:
    """q per chain and a log of the rounds (see the module docstring). `options`: the filters'
    settings of the closed loops (closed_loop.Config fields, e.g. the predictor the scenario
    selects), so q is calibrated for the filter that will run. With `disturbance` among them
    (a Disturbance, its densities ignored): (q, log, the Disturbance with calibrated densities)."""
    shape = shape or shapes.from_domains(flat)
    q = _reference_q(flat, spec, ts, substeps, shape)
    floor = 1e-6 * np.array([(a * shape.omega ** c.degree) ** 2 * shape.period
                             for a, c in zip(shape.amplitude, flat.chains)])
    q = np.maximum(q, floor)
    log = [f"along the reference: q = {_fmt(q)}"]

    def config(q, run_seed, duration=duration):
        return ex.Config(model=spec, ts=ts, duration=duration, substeps=substeps, q=tuple(q), poles=tuple(poles),
                         p0_std=tuple(p0_std), **shape.config(),
                         noise_std=tuple(None if s is None else tuple(s) for s in noise_std),
                         noise_scale=(1.0, 1.25), seed=run_seed, watch_nees=False, **options)
        # too small a q is what these loops are run to measure: their NEES is meant to be high,
        # only a plant that leaves its domain or overflows ends one

    dist = options.pop("disturbance", None)
    if dist is not None:      # the loops are closed by the chapter's filter (module docstring)
        options["predictor"] = "brunovsky"
    for _ in range(rounds):
        cfg = config(q, seed)
        try:
            res = ex.run(cfg)
        except (ArithmeticError, FloatingPointError, np.linalg.LinAlgError):
            q = q * 10
            log.append(f"closed loop diverged: q x 10 -> {_fmt(q)}")
            continue
        k0 = int(round(cfg.metrics_from / ts))
        rec = res.recording      # the residual of the predictor the loop ran (the chapter's on main)
        if dist is not None:
            held = _held_residual_q(flat, ts, cfg, res, k0)
            q = np.maximum(implied_q(flat, ts, res.zeta[k0:], rec.v[k0:], rec.u[k0:]), q)
            log.append(f"along the closed loop: q = {_fmt(held)} (held), {_fmt(q)} (the loop's filter)")
            # a model error drawn per run makes each run's NEES another (1.6 to 21 over 10 seeds at
            # 20% on the motor): more runs than the fixed model's two
            seeds = [seed + i for i in range(DRAWN_RUNS if cfg.plant_error.draw != "none" else NEES_RUNS)]
            loops = [ex.run(config(q, s, NEES_SECONDS)) for s in seeds]
            match = lambda qq, lg, nees: match_nees(flat, qq, None, seeds, lg, nees)  # noqa: E731
            return disturbance_calibration.densities(flat, held, loops, dist, match, NEES_TOL, log)
        q = np.maximum(implied_q(flat, ts, res.zeta[k0:], rec.v[k0:], rec.u[k0:],
                                 getattr(rec, "predictor", "brunovsky")), q)
        log.append(f"along the closed loop: q = {_fmt(q)}")
        break
    if dist is not None:
        raise ArithmeticError(f"every closed loop of the calibration diverged (q up to {_fmt(q)})")
    return match_nees(flat, q, config, [seed + i for i in range(NEES_RUNS)], log)


def _held_residual_q(flat, ts, cfg, res, k0) -> np.ndarray:
    """The held filter's q from its one-step residual along the loop `cfg` (its result `res`),
    on the exact model: what white noise describes; a model error is the disturbances'."""
    if cfg.plant_error.active:
        res = ex.run(dataclasses.replace(cfg, plant_error=ex.EXACT_MODEL))
    rec = res.recording
    return implied_q(flat, ts, res.zeta[k0:], rec.v[k0:], rec.u[k0:], "held")


DRAWN_RUNS = 8
NEES_RUNS, NEES_TOL, NEES_EVALS, NEES_SECONDS = 2, 1.1, 8, 20.0


def _master_nees(config, q, seeds) -> float:
    """The master's NEES averaged over the steps and the runs (inf when a run fails)."""
    values = []
    for s in seeds:
        try:
            values.append(float(np.mean(ex.run(config(q, s, NEES_SECONDS)).metrics["nees_master"])))
        except (ArithmeticError, FloatingPointError, np.linalg.LinAlgError):
            return math.inf
    return float(np.mean(values)) if np.all(np.isfinite(values)) else math.inf


def match_nees(flat, q, config, seeds, log, nees=None) -> tuple[np.ndarray, list[str]]:
    """Scale q (every chain alike, keeping the residual's proportions) until the master's NEES,
    averaged over `seeds` closed loops without delays of NEES_SECONDS (the length of a
    scenario's runs: the NEES of a filter with little process noise drifts over a run, so a
    shorter run would match another q), is n within a factor NEES_TOL: the middle of its 95%
    band for any number of runs. A secant on log NEES against log scale (NEES falls as q
    grows); at most NEES_EVALS evaluations, keeping the closest. The residual alone does not get
    there: it is coloured (correlated from step to step), which white noise of the same variance
    does not describe, and the estimate's own error feeds back through u. `nees(q)`: another
    measure of the master's NEES at q than `seeds` closed loops of `config`."""
    n = flat.n
    nees_at = nees or (lambda qq: _master_nees(config, qq, seeds))
    tried = []                                   # (log scale, log NEES / n)
    scale = 0.0
    for _ in range(NEES_EVALS):
        value = nees_at(q * math.exp(scale))
        if not math.isfinite(value):
            scale += math.log(10.0)             # too small a q lost a run: ten times more
            continue
        tried.append((scale, math.log(value / n)))
        if abs(tried[-1][1]) <= math.log(NEES_TOL):
            break
        if len(tried) < 2 or tried[-1][0] == tried[-2][0]:
            slope = -1.0                         # NEES ~ 1/q, the first guess
        else:
            (s0, e0), (s1, e1) = tried[-2], tried[-1]
            slope = (e1 - e0) / (s1 - s0) if s1 != s0 else -1.0
            slope = min(slope, -0.05)            # NEES falls with q; a flat stretch takes large steps
        scale = tried[-1][0] - max(-3.0, min(3.0, tried[-1][1] / slope))   # within e^+-3 per step
    if not tried:
        log.append("master NEES: every scale of q lost a closed loop; q kept from the residual")
        return q, log
    best = min(tried, key=lambda t: abs(t[1]))
    q = q * math.exp(best[0])
    inside = abs(best[1]) <= math.log(NEES_TOL)
    log.append(f"master NEES over {len(seeds)} runs without delays: {n * math.exp(best[1]):.3g} at q = {_fmt(q)} "
               f"(x{math.exp(best[0]):.3g}; target n = {n}" + ("" if inside else f", not reached in {len(tried)} tries")
               + ")")
    return q, log


def fastest_oscillation(flat, spec: str, ts: float, points: int = 12, shape: shapes.Shape | None = None) -> float:
    """Largest |imaginary part| of the plant Jacobian's eigenvalues along the reference [rad/s]."""
    shape = shape or shapes.from_domains(flat)
    plant = ex._plant(spec, ts, 1)
    cfg = ex.Config(model=spec, **shape.config())
    refs = ex.references(cfg, flat.m)
    p, n, worst = flat.param_vector, flat.n, 0.0
    for tk in np.linspace(0, shape.period, points, endpoint=False):
        fl = flags(refs, flat.degrees, tk)
        z = ex.state_of_flags(flat, fl)
        top = np.array([fl[c.offset + j + c.degree] for j, c in enumerate(flat.chains)])
        u = np.linalg.solve(flat.G_num(z, p), top - flat.F_num(z, p))
        x = flat.phi_inv_num(z, p)
        h = 1e-6 * np.maximum(1.0, np.abs(x))
        jac = np.column_stack([(plant.rhs(x + h[i] * np.eye(n)[i], u) - plant.rhs(x - h[i] * np.eye(n)[i], u))
                               / (2 * h[i]) for i in range(n)])
        worst = max(worst, float(np.abs(np.linalg.eigvals(jac).imag).max()))
    return worst


def _fmt(values) -> str:
    return "[" + ", ".join(f"{v:.3g}" for v in np.atleast_1d(values)) + "]"


def starting_scenario(spec: str, shape: shapes.Shape | None = None, disturbance: Disturbance | None = None,
                      plant_error=None) -> tuple[str, list[str]]:
    """The TOML text of a starting scenario for model `spec`, and the calibration log;
    `disturbance` (its densities ignored): calibrated for the held filter with those states;
    `plant_error` (model_error.ParamError): the calibration's plants have it, and so has the
    scenario (its [model_error] table)."""
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
    options = ({} if plant_error is None else {"plant_error": plant_error}) | \
        ({} if disturbance is None else {"predictor": "held", "disturbance": disturbance})
    q, log, *calibrated = calibrate(flat, spec, ts, poles, p0_std, noise_std, shape=shape, **options)
    disturbance = calibrated[0] if calibrated else None
    if all(entry.startswith("closed loop diverged") for entry in log[1:]):
        raise ScenarioError(f"{model.source}: every calibration round of the starting scenario diverged "
                            f"(q up to {_fmt(q)} on a {shape.kind} of amplitude {_fmt(shape.amplitude)} around "
                            f"{_fmt(shape.offset)}): the loop does not close on that reference; try "
                            "--amplitude, --offset, --period or --shape")
    omega_max = fastest_oscillation(flat, spec, ts, shape=shape)
    warn = []
    if omega_max * ts > 0.3:
        warn = [f"# WARNING: the plant oscillates at up to {omega_max:.3g} rad/s, {omega_max * ts:.2f} rad per "
                f"period at Ts = {ts:g} s:",
                "# the flat controller holds u over Ts and cannot cancel that mode; expect the loop not to",
                f"# close whatever q. A period of about {0.1 / omega_max:.2g} s (scenario.ts) would, at "
                f"{ts * omega_max / 0.1:.0f} times the work."]
        log.append(f"fastest oscillation {omega_max:.3g} rad/s: too fast for Ts = {ts:g} s")
    paper = scenario_mod.load("paper")
    lines = [
        MARKER + f" for model {model.name}.",
        "# Every number below comes from the model (docs/experiment.md, \"A starting scenario\"):",
        "# q from the canonical model's one-step residual, poles from Ts, P0 from the reference.",
        *(f"#   calibration: {entry}" for entry in log),
        *warn,
        "",
        "[scenario]",
        f'name = "{model.name}_start"',
        f'description = "starting scenario for {model.name}, generated by codegen scenario"',
        f"duration = {max(20.0, shape.period):g}",
        "runs = 4",
        "substeps = 10",
        "metrics_from = 1.0",
        f'references = ["{shape.config()["reference"]}"]',
        'oosm = ["replay"]',
        'fusion = ["difference", "paper"]',
        'baselines = ["discard", "as-current"]',
        "",
        "[filter]",
        f"q = {_toml_list(q)}               # per chain: the one-step residual, scaled to NEES = n",
        f"p0_std = {_toml_list(p0_std)}   # per derivative order",
        "initial_error = true",
        "",
        "[control]",
        f"poles = {poles[0]:g}              # every pole at -0.1/Ts",
        "",
        f"[reference]           # {shape.kind}, from the flat outputs' declared domains",
        f"amplitude = {_toml_list(shape.amplitude)}",
        f"period = {shape.period:g}",
        f"offset = {_toml_list(shape.offset)}",
        f"phase = {_toml_list(shape.phase)}",
        f"cycles = {_toml_list(shape.cycles)}",
        "harmonics = 4",
        "",
    ]
    for i, node_std in enumerate(noise_std):
        lines += ["[[nodes]]", f"noise_scale = {1.0 if i == 0 else 1.25:g}" if node_std is None
                  else f"noise_std = {_toml_list(node_std)}", ""]
    lines += ["[uplink]", "p = 0.0", "d = 0", "p_drop = 0.0", ""]
    for row in paper.grid:
        lines += ["[[grid]]", f"d = {row.d}", f"p = {row.p:g}", ""]
    lines += _extra_tables(plant_error, disturbance)
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
        lines += ["# one disturbance state per chain on its top derivative (run with --predictor held);",
                  "# q: their densities, scaled so that the master's NEES averages n",
                  "[disturbance]", f'kind = "{disturbance.kind}"', f"q = {_toml_list(disturbance.q)}"]
        lines += [f"tau = {disturbance.tau:g}"] if disturbance.tau is not None else []
        lines += [""]
    return lines

def _toml_list(values) -> str:
    return "[" + ", ".join(f"{float(v):.4g}" for v in values) + "]"


def scenario(model: str, out: str | None = None, max_seconds: float | None = None,
             max_memory: float | None = None, shape: str = "sinusoid", amplitude=None, offset=None,
             phase=None, period: float | None = None, disturbance: str | None = None,
             tau: float | None = None, param_error: str | None = None) -> str:
    """`codegen scenario MODEL [--out FILE]`: the starting scenario's text, checked against the
    model; written to `out` when given (only over a file this command wrote before). The
    derivation runs under `max_seconds` CPU seconds and `max_memory` GB. `disturbance`
    ("random_walk" or "gauss_markov", `tau` its time constant [s]): the scenario adds
    disturbance states and calibrates their densities; `param_error` (as `simulate
    --param-error`): the calibration's plants and the scenario get that model error."""
    dist = disturbance_calibration.from_options(disturbance, tau)
    plant_error = None
    if param_error is not None:
        from dfeif_codegen.experiment import model_error
        plant_error = model_error.from_option(param_error)
        plant_error = plant_error if plant_error.active else None
    path = Path(out) if out else None
    if path is not None and path.exists():
        try:
            first = path.read_text(encoding="utf-8").split("\n", 1)[0]
        except (OSError, UnicodeDecodeError):
            first = ""
        if not first.startswith(MARKER):
            raise ScenarioError(f"--out {path}: exists and was not written by `codegen scenario`; not overwriting it")
    if path is not None:
        from dfeif_codegen.paths import writable_file
        writable_file(path, "--out")
    flat = derivation.derive(model, max_seconds, max_memory)
    if plant_error is not None:
        plant_error.check(flat.model, lambda key: "--param-error")
    ref = shapes.fitting(flat, model, shape, amplitude, offset, phase, period)
    try:
        text, _ = starting_scenario(model, ref, dist, plant_error)
    except (ArithmeticError, FloatingPointError, np.linalg.LinAlgError) as exc:
        raise ScenarioError(f"{flat.model.source}: the starting scenario's calibration failed on a {ref.kind} of "
                            f"amplitude {_fmt(ref.amplitude)} around {_fmt(ref.offset)}: {exc}; try --amplitude, "
                            "--offset, --period or --shape") from None
    scenario_mod.loads(text, str(path or "<generated>")).check_model(ex._flat(model))
    if path is not None:
        path.write_text(text + "\n", encoding="utf-8")
    return text

