"""One closed-loop run of the chapter's experiment (section 7), and its complete recording.

Order of one step k (docs/algorithms.md): cameras measure the true plant -> each node `update`s
with its on-time frame (or a drop) -> each node applies the late frames arriving at k, in arrival
order -> node packets travel to the master (maybe late or lost) -> master `fuse` -> control on the
fused estimate -> the plant integrates over [k Ts, (k+1) Ts] with u held -> master and nodes
`predict` with the broadcast input (u for the default held predictor, v for the Brunovsky one).

Everything the filters see goes into a `Recording`, and `replay_recording` re-runs the filters
and the controller from it alone (open loop, no plant): the scenario format the C harness
consumes, and a proof that the recording is complete (the replay equals the run bit for bit).

Baselines: `discard` throws late frames away; `as-current` feeds the freshest late frame to the
step's update as if taken now (when the step has no on-time frame; one frame per update).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from dfeif_codegen.symbolic import flatness
from dfeif_codegen.reference.control import FlatController
from dfeif_codegen.experiment.derivation import _flat, by_model
from dfeif_codegen.experiment.divergence import DivergenceWatch
from dfeif_codegen.experiment.metrics import _errors, _per_chain, metrics, state_of_flags, tracking_bound, tracking_errors
from dfeif_codegen.experiment.model_error import NONE as EXACT_MODEL, ParamError
from dfeif_codegen.experiment.network import Link, Network
from dfeif_codegen.experiment.recording import FilterBank, Recording, _Outputs
from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.reference.offsets import Offsets
from dfeif_codegen.symbolic.disturbance import Disturbance
from dfeif_codegen.experiment.plant import Camera, Plant
from dfeif_codegen.experiment.trajectory import Reference, flags
from dfeif_codegen.experiment.trajectory_file import KIND as TRAJECTORY, Trajectory


class UndefinedReference(ArithmeticError):
    """The reference asks for flat outputs (derivatives) where Phi^-1 is undefined or leaves the domain."""


def check_reference(flat, ref_rows, t) -> None:
    """Every reference state must map back to a state in the declared domain."""
    bad = flat.undefined_at(state_of_flags(flat, np.asarray(ref_rows)))
    if bad is not None:
        k, what = bad
        raise UndefinedReference(f"the reference at t = {t[k]:.3f} s asks for flat outputs where {what}")


def check_reference_of(cfg: "Config") -> None:
    """check_reference for a configuration's reference, without running it."""
    flat = _flat(cfg.model)
    ts = float(cfg.ts or flat.model.ts)
    t = np.arange(int(round(cfg.duration / ts))) * ts
    refs = references(cfg, flat.m)
    check_reference(flat, [flags(refs, flat.degrees, tk) for tk in t], t)


OOSM = ("replay", "retrodict")
BASELINES = ("discard", "as-current")
METHODS = OOSM + BASELINES


MAX_LAG = 32  # the late-measurement window of a run (steps), unless a scenario or option says


@dataclass(frozen=True)
class Config:
    """Everything one run needs, as plain picklable data (per-chain values broadcast)."""

    model: str = "dc_motor_link"
    ts: float | None = None           # None: the model's
    duration: float = 20.0
    substeps: int = 10                # RK4 steps per sampling period
    q: tuple = (1.0,)                 # process-noise density per chain
    poles: tuple = (5.0,)             # controller: every pole of chain j at -poles[j]
    p0_std: tuple = (0.05, 0.1, 1.0)  # initial std per derivative order (y, y', y'', ...)
    initial_error: bool = True        # draw the true initial state from N(estimate, P0)
    reference: str = "sinusoid"
    amplitude: tuple = (1.0,)
    period: float = 5.0
    offset: tuple = (0.0,)
    harmonics: int = 4
    tracking_bound: tuple = ()        # per output: a run straying further has stopped tracking (default 2 A)
    phase: tuple = (0.0,)             # per output [rad]: (pi/2, 0) with equal amplitudes is a circle
    cycles: tuple = (1,)              # per output, cycles per period: (1, 2) is a figure eight
    noise_scale: tuple = (1.0, 1.0)   # per node, times the model's camera noise
    noise_std: tuple = (None, None)   # per node: std per channel, or None for the model's
    sensor: tuple = (Link(), Link())  # camera -> node link per node
    uplink: tuple = (Link(), Link())  # node -> master link per node
    max_lag: int = MAX_LAG
    method: str = "replay"            # one of METHODS
    fusion: str = "difference"
    predictor: str | None = None      # the filters' prediction (reference/predictor.py); None: held,
                                      # brunovsky with retrodict (the only one it takes)

    def __post_init__(self) -> None:
        oosm = self.method if self.method in OOSM else "replay"
        object.__setattr__(self, "predictor", predictors.for_method(self.predictor, oosm))
    seed: int = 0
    metrics_from: float = 1.0         # [s] metrics skip the initial transient
    watch_nees: bool = True           # a run whose master NEES stays huge has diverged (off: calibration)
    # the plant's parameters against the model's (experiment/model_error.py); out of repr, so a
    # run without model error keeps its id in --results files (sweep.run_id adds it when set)
    plant_error: ParamError = field(default=EXACT_MODEL, repr=False)
    # the chapter's filter's q where the comparison re-runs it on the recordings (--filters
    # brunovsky; empty: q): its q covers what the held filter's model leaves out
    q_brunovsky: tuple = field(default=(), repr=False)
    # the EKF's and UKF's q where the comparison runs them (--filters ekf,ukf; empty: q): a
    # held filter with disturbance states is consistent at a q far below what theirs needs
    q_ekf: tuple = field(default=(), repr=False)
    # the scheduled-transition filter's q where the comparison runs it (--filters scheduled;
    # empty: q): a transition that follows the configuration leaves less for q to cover
    q_scheduled: tuple = field(default=(), repr=False)
    # the filters' disturbance states (symbolic/disturbance.py), None: none; out of repr as above
    disturbance: Disturbance | None = field(default=None, repr=False)
    # reference "trajectory": the user's CSV (experiment/trajectory_file.py); out of repr like
    # plant_error (sweep.run_id adds it when set)
    trajectory: Trajectory | None = field(default=None, repr=False)
    # what the comparison's "offsets" filter estimates (reference/offsets.py), None: no such
    # filter asked for; out of repr (sweep.run_id adds it for that filter's runs)
    offsets: Offsets | None = field(default=None, repr=False)
    # the nodes' innovation gate [standard deviations] (the C's --gate; 0: none); out of repr as above
    gate: float = field(default=0.0, repr=False)
    # camera outliers per node: (fraction of frames, offset in camera standard deviations); (): none
    outliers: tuple = field(default=(), repr=False)


@dataclass
class Result:
    """One run: the recording, the true canonical state, time series for figures, metrics."""

    config: Config
    t: np.ndarray
    zeta: np.ndarray          # true canonical state (K, n)
    x_true: np.ndarray        # true physical state (K, n)
    delays: np.ndarray        # camera lag per node and step (-1 dropped)
    recording: Recording
    counters: list[dict]
    metrics: dict = field(default_factory=dict)


# --- the replay ------------------------------------------------------------------------------------

def replay_recording(rec: Recording, dtype=np.float64, inputs=None, right_first: bool = False) -> dict[str, np.ndarray]:
    """Re-run only the filters and the controller from a recording (no plant, no network) and
    return the outputs: late_applied, node_x, node_P, x, P, u, v. `dtype=np.float32` runs
    the nodes and the master in single precision: a second single-precision implementation to judge
    the C's (the controller stays in double). `inputs` (K rows): the inputs the filters predict
    with, as the C harness's recorded inputs (None: the replay's own controller's);
    `right_first`: the covariance products associated the other way (FilterBank)."""
    flat = _flat(rec.model)
    bank = FilterBank(flat, rec.ts, rec.q, rec.R, rec.node_x0, rec.node_P0, rec.master_x0, rec.master_P0,
                      rec.gains, rec.max_lag, rec.oosm, rec.fusion, dtype, rec.predictor,
                      Disturbance.from_json(rec.disturbance), right_first, gate=rec.gate or None)
    K = rec.ref.shape[0]
    out = _Outputs(rec.nodes, K, rec.n, rec.m)
    late_at = np.searchsorted(rec.late_step, np.arange(K + 1))
    sources = np.full((K, rec.nodes), -1, dtype=int)
    sources[rec.pkt_step, rec.pkt_node] = rec.pkt_src
    for k in range(K):
        late = [(int(rec.late_node[e]), int(rec.late_lag[e]), rec.late_z[e]) for e in range(late_at[k], late_at[k + 1])]
        out.put(k, bank.step(k, rec.z[:, k], rec.gamma[:, k], late, sources[k], rec.ref[k],
                             None if inputs is None else inputs[k]))
    return {"late_applied": np.array(out.applied, dtype=bool), "node_x": out.node_x, "node_P": out.node_P,
            "x": out.x, "P": out.P, "u": out.u, "v": out.v}


# --- the closed loop ------------------------------------------------------------------------------

@by_model
@lru_cache(maxsize=64)
def _plant(spec: str, ts: float, substeps: int, params: tuple | None = None) -> Plant:
    """The plant, with the model's parameters or (model error) the given vector."""
    return Plant(_flat(spec).model, ts, substeps, _flat(spec).extension, params)


@by_model
@lru_cache(maxsize=None)
def _camera(spec: str, scale: float, std) -> Camera:
    return Camera(_flat(spec).model, std=std, scale=scale)


def initial_covariance(flat, p0_std) -> np.ndarray:
    """P0 = diag(std^2), std per derivative order, the same for every chain."""
    std = np.asarray(p0_std, dtype=float)
    if std.size < max(flat.degrees):
        raise ValueError(f"p0_std needs {max(flat.degrees)} entries (one per derivative order)")
    return np.diag(np.concatenate([std[:r] for r in flat.degrees]) ** 2)


@by_model
@lru_cache(maxsize=64)
def _reference_table(spec, kind, amplitude, period, offset, harmonics, ts, K, phase=(0.0,),
                     cycles=(1,), trajectory=None) -> np.ndarray:
    """The reference flags of every step, checked to map into the domain (the same for every seed
    and method of a row: computed and checked once per process)."""
    flat = _flat(spec)
    cfg = Config(model=spec, reference=kind, amplitude=amplitude, period=period, offset=offset, harmonics=harmonics,
                 phase=phase, cycles=cycles, trajectory=trajectory)
    refs = references(cfg, flat.m)
    t = np.arange(K) * ts
    table = np.array([flags(refs, flat.degrees, tk) for tk in t])
    check_reference(flat, table, t)
    table.flags.writeable = False
    return table


def references(cfg: Config, m: int) -> list:
    """Per flat output, its reference (anything with `flags(t, r)`)."""
    if cfg.reference == TRAJECTORY:
        flat = _flat(cfg.model)
        if cfg.trajectory is None:
            raise ValueError("reference 'trajectory' needs Config.trajectory (a CSV read by trajectory_file.read)")
        return cfg.trajectory.outputs([o.name for o in flat.model.outputs], flat.degrees)
    amp, off, phase = _per_chain(cfg.amplitude, m), _per_chain(cfg.offset, m), _per_chain(cfg.phase, m)
    cycles = _per_chain(cfg.cycles, m)
    return [Reference(cfg.reference, amp[j], cfg.period, off[j], cfg.harmonics, phase[j], int(cycles[j]))
            for j in range(m)]


@dataclass
class Setup:
    """Everything a run draws or derives before its first step: the same for every engine, so the
    numpy loop and the compiled one see the same noise, network and initial state."""

    cfg: Config
    flat: flatness.FlatSystem
    ts: float
    K: int
    t: np.ndarray
    ref: np.ndarray           # (K, n + m) reference flags
    net: Network
    cams: list
    noise: list               # per node (K, channels), standard normal
    x0: np.ndarray            # true initial physical state
    q: np.ndarray
    gains: np.ndarray
    R: np.ndarray
    oosm: str
    node_x0: np.ndarray
    node_P0: np.ndarray
    x_hat0: np.ndarray
    P0: np.ndarray
    upd: np.ndarray           # (M, K) lag of the frame node i's update at k uses, -1: none
    late: np.ndarray          # (E, 3) late events (step, node, lag) in the order applied
    plant_p: np.ndarray | None = None   # the plant's parameters; None: the model's (no model error)

    @property
    def plant_key(self) -> tuple | None:
        return None if self.plant_p is None else tuple(self.plant_p.tolist())

    def bank(self) -> "FilterBank":
        return FilterBank(self.flat, self.ts, self.q, self.R, self.node_x0, self.node_P0, self.x_hat0, self.P0,
                          self.gains, self.cfg.max_lag, self.oosm, self.cfg.fusion, predictor=self.cfg.predictor,
                          disturbance=self.cfg.disturbance, gate=self.cfg.gate or None)


def prepare(cfg: Config) -> Setup:
    """Draw and derive everything of one run that does not depend on the loop's state."""
    if cfg.method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, not {cfg.method!r}")
    flat = _flat(cfg.model)
    model = flat.model
    ts = float(cfg.ts or model.ts)
    n, m, M = flat.n, flat.m, len(cfg.sensor)
    K = int(round(cfg.duration / ts))
    cams = [_camera(cfg.model, float(s), None if std is None else tuple(std))
            for s, std in zip(cfg.noise_scale, cfg.noise_std)]
    t = np.arange(K) * ts
    ref = _reference_table(cfg.model, cfg.reference, cfg.amplitude, cfg.period, cfg.offset, cfg.harmonics, ts, K,
                           tuple(cfg.phase), tuple(cfg.cycles), cfg.trajectory)

    net_rng, noise_rng, init_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(3))
    net = Network(list(cfg.sensor), list(cfg.uplink), K, net_rng)
    noise = outlying([noise_rng.standard_normal((K, len(c.channels))) for c in cams], cfg)
    P0 = initial_covariance(flat, cfg.p0_std)
    x_hat0 = state_of_flags(flat, ref[0])     # everyone starts at the reference's start
    zeta0 = x_hat0 + (np.linalg.cholesky(P0) @ init_rng.standard_normal(n) if cfg.initial_error else 0.0)

    q, gains = _per_chain(cfg.q, m), FlatController(flat, poles=_per_chain(cfg.poles, m)).gains
    R = np.array([c.R for c in cams])
    oosm = cfg.method if cfg.method in OOSM else "replay"
    predictors.check(cfg.predictor, oosm, cfg.disturbance)
    # which frame each update takes, and the late frames applied: fixed by the network alone
    upd = np.where(net.lag == 0, 0, -1)
    if cfg.method == "as-current":   # a step without its frame takes the freshest late one arriving
        step, node, lag = net.events.T
        freshest = np.full_like(upd, K)
        np.minimum.at(freshest, (node, step), lag)
        upd = np.where((upd < 0) & (freshest < K), freshest, upd)
    late = net.events if cfg.method in OOSM else np.zeros((0, 3), dtype=int)
    # the truth's canonical state is the plant's own flat outputs and derivatives: Phi with the
    # plant's parameters (the model's without model error)
    plant_p = cfg.plant_error.values(model, cfg.seed)
    return Setup(cfg, flat, ts, K, t, ref, net, cams, noise, flat.phi_inv_num(zeta0, plant_p), q, gains, R, oosm,
                 np.tile(x_hat0, (M, 1)), np.tile(P0, (M, 1, 1)), x_hat0, P0, upd, late, plant_p)


def outlying(noise: list, cfg: Config) -> list:
    """The cameras' standard-normal noise with `cfg.outliers` added: each node's frames hit with
    probability `fraction` move by `size` standard deviations, a random sign per channel (a
    tracker locked onto the wrong feature). Drawn from a stream of their own, so the noise, the
    network and the initial state of a run without outliers stay as they were."""
    if not cfg.outliers:
        return noise
    rng = np.random.default_rng(np.random.SeedSequence(cfg.seed).spawn(4)[3])
    out = []
    for nz, (fraction, size) in zip(noise, cfg.outliers):
        hit = rng.random(nz.shape[0]) < fraction
        out.append(nz + hit[:, None] * size * rng.choice([-1.0, 1.0], nz.shape))
    return out


def run(cfg: Config) -> Result:
    """One closed-loop run, reproducible from `cfg.seed` (the numpy reference engine)."""
    s = prepare(cfg)
    flat, K, M, n, m = s.flat, s.K, len(cfg.sensor), s.flat.n, s.flat.m
    plant = _plant(cfg.model, s.ts, cfg.substeps, s.plant_key)
    bank = s.bank()
    frames = np.zeros((M, K, m))
    zeta, x_true = np.zeros((K, n)), np.zeros((K, n))
    out = _Outputs(M, K, n, m)
    late_at = np.searchsorted(s.late[:, 0], np.arange(K + 1))
    x = s.x0
    watch = DivergenceWatch(flat.model, cfg.watch_nees, tracking_bound(cfg, m))
    for k in range(K):
        x_true[k], zeta[k] = x, flat.phi_num(x, s.plant_p)
        for i in range(M):
            frames[i, k] = s.cams[i].measure(x, s.noise[i][k])
        z = np.array([frames[i, k - s.upd[i, k]] if s.upd[i, k] >= 0 else np.zeros(m) for i in range(M)])
        late = [(int(i), int(lag), frames[i, k - lag]) for _, i, lag in s.late[late_at[k]:late_at[k + 1]]]
        out.put(k, bank.step(k, z, (s.upd[:, k] >= 0).astype(np.int8), late, s.net.source[:, k], s.ref[k]))
        x = plant.step(x, out.u[k])
        watch.step(s.t[k], x, _errors(flat, out.x[k], zeta[k]), out.P[k],
                   tracking_errors(flat, zeta[k], s.ref[k]))
    return finish(s, x_true, zeta, frames, out.node_x, out.node_P, out.x, out.P, out.u, out.v,
                  np.array(out.applied, dtype=bool), [dict(nd.counters) for nd in bank.nodes])


def finish(s: Setup, x_true, zeta, frames, node_x, node_P, x, P, u, v, applied, counters) -> Result:
    """The recording, the result and its metrics from one run's loop outputs (any engine)."""
    cfg, flat = s.cfg, s.flat
    n, m, M = flat.n, flat.m, len(cfg.sensor)
    gamma = (s.upd >= 0).astype(np.int8)
    rows = np.arange(M)[:, None]
    z = np.where(gamma[..., None] > 0, frames[rows, np.arange(s.K)[None] - np.maximum(s.upd, 0)], 0.0)
    late_step, late_node, late_lag = s.late.T
    pk, pn = np.nonzero(s.net.source.T >= 0)
    rec = Recording(
        model=cfg.model, n=n, m=m, nodes=M, max_lag=cfg.max_lag, method=cfg.method, oosm=s.oosm,
        fusion=cfg.fusion, predictor=cfg.predictor, ts=s.ts, q=s.q, R=s.R, node_x0=s.node_x0,
        node_P0=s.node_P0, master_x0=s.x_hat0,
        master_P0=s.P0, gains=s.gains, params=flat.param_vector, seed=cfg.seed, z=z, gamma=gamma, ref=s.ref,
        late_step=late_step.copy(), late_node=late_node.copy(), late_lag=late_lag.copy(),
        late_z=frames[late_node, late_step - late_lag].reshape(-1, m),
        pkt_step=pk, pkt_node=pn, pkt_src=s.net.source.T[pk, pn],
        late_applied=applied, node_x=node_x, node_P=node_P, x=x, P=P, u=u, v=v,
        disturbance="" if cfg.disturbance is None else cfg.disturbance.to_json(), heads=tuple(flat.heads),
        gate=cfg.gate)
    result = Result(cfg, s.t, zeta, x_true, s.net.lag.copy(), rec, counters)
    result.metrics = metrics(result)
    return result
