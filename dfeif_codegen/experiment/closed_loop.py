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

from dataclasses import dataclass, field, fields
from functools import lru_cache

import numpy as np

from dfeif_codegen.symbolic import flatness
from dfeif_codegen.symbolic import model as model_mod
from dfeif_codegen.reference.control import FlatController
from dfeif_codegen.reference.fusion import Master
from dfeif_codegen.reference.linalg import wrap
from dfeif_codegen.experiment.model_error import NONE as EXACT_MODEL, ParamError
from dfeif_codegen.experiment.network import Link, Network
from dfeif_codegen.reference.node import NodeFilter
from dfeif_codegen.reference import predictor as predictors
from dfeif_codegen.experiment.plant import Camera, Plant
from dfeif_codegen.experiment.trajectory import Reference, flags

# A run has diverged when the true state leaves its declared domain, or when the master's NEES
# stays above NEES_DIVERGED * n for NEES_STEPS steps in a row. This is not the consistency test
# (the tables do that against the chi-square band); it detects a filter that has lost the state:
# NEES = 1e4 n means errors 100 times the standard deviations P claims. A consistent filter's NEES
# is chi-square with n degrees of freedom (mean n), so P(NEES > 1e4 n) is below 1e-1000, and a
# merely inconsistent baseline (as-current, NEES of a few hundred) is not called diverged.
NEES_DIVERGED = 1e4
NEES_STEPS = 50


class Diverged(FloatingPointError):
    """The closed loop went wrong: the message says when and why."""


class DivergenceWatch:
    """Raises Diverged when the true state leaves its declared domain, a flat output strays from
    its reference by more than its tracking bound (the run stopped tracking), or the master's NEES
    has stayed above NEES_DIVERGED * n for NEES_STEPS steps in a row."""

    def __init__(self, model, nees: bool = True, bound=None):
        self.nees = nees
        self.names = [v.name for v in model.states]
        self.outputs = [o.name for o in model.outputs]
        self.lo = np.array([-np.inf if v.min is None else v.min for v in model.states])
        self.hi = np.array([np.inf if v.max is None else v.max for v in model.states])
        self.bound = np.full(len(self.outputs), np.inf) if bound is None else np.asarray(bound, dtype=float)
        self.high = 0

    def step(self, t: float, x, err, P, track=None) -> None:
        if track is not None and np.any(np.abs(track) > self.bound):
            j = int(np.argmax(np.abs(track) > self.bound))
            raise Diverged(f"stopped tracking at t = {t:.2f} s: output {self.outputs[j]} is {track[j]:.4g} from its "
                           f"reference, beyond the tracking bound {self.bound[j]:.4g} (default twice the "
                           "reference's amplitude; [reference] tracking_bound)")
        if not np.all(np.isfinite(x)):
            raise Diverged(f"diverged at t = {t:.2f} s: the state is not finite")
        outside = np.nonzero((x < self.lo) | (x > self.hi))[0]
        if outside.size:
            i = int(outside[0])
            raise Diverged(f"diverged at t = {t:.2f} s: state {self.names[i]} = {x[i]:.4g} left its domain "
                           f"[{self.lo[i]:g}, {self.hi[i]:g}]")
        if not self.nees:
            return
        n = len(err)
        with np.errstate(all="ignore"):
            nees = float(err @ np.linalg.solve(P, err)) if np.all(np.isfinite(P)) else np.inf
        self.high = self.high + 1 if not nees <= NEES_DIVERGED * n else 0
        if self.high >= NEES_STEPS:
            raise Diverged(f"diverged at t = {t:.2f} s: master NEES above {NEES_DIVERGED:g} n = "
                           f"{NEES_DIVERGED * n:g} for {NEES_STEPS} steps (now {nees:.3g})")


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
    max_lag: int = 32
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


@dataclass
class Recording:
    """Every input the filters saw and every output they gave, as numpy arrays (`np.savez`).

    Meta: model spec, sizes, methods, ts, q (m), R (M, m, m), initial x0/P0 of the nodes
    (M, n), (M, n, n) and master, controller gains (n, chain by chain k_1..k_r), params, seed.
    Per step k: z (M, K, m) and gamma (M, K) of each node's `update` (z is 0 where gamma is 0),
    ref (K, n + m). Late events in the order applied: late_step, late_node, late_lag, late_z
    (E, m). Packets fused by the master: pkt_step (master step), pkt_node, pkt_src (source step).
    Outputs: late_applied (E), node_x (M, K, n) and node_P after the step's updates, master x, P
    after fuse, u, v.
    """

    model: str
    n: int
    m: int
    nodes: int
    max_lag: int
    method: str           # replay | retrodict | discard | as-current
    oosm: str             # what the node filters were built with
    fusion: str
    predictor: str        # held | brunovsky: the filters predict with u or with v
    ts: float
    q: np.ndarray
    R: np.ndarray
    node_x0: np.ndarray
    node_P0: np.ndarray
    master_x0: np.ndarray
    master_P0: np.ndarray
    gains: np.ndarray
    params: np.ndarray
    seed: int
    z: np.ndarray
    gamma: np.ndarray
    ref: np.ndarray
    late_step: np.ndarray
    late_node: np.ndarray
    late_lag: np.ndarray
    late_z: np.ndarray
    pkt_step: np.ndarray
    pkt_node: np.ndarray
    pkt_src: np.ndarray
    late_applied: np.ndarray
    node_x: np.ndarray
    node_P: np.ndarray
    x: np.ndarray
    P: np.ndarray
    u: np.ndarray
    v: np.ndarray

    def save(self, path) -> None:
        np.savez(path, **{f.name: np.asarray(getattr(self, f.name)) for f in fields(self)})

    @classmethod
    def load(cls, path) -> "Recording":
        with np.load(path) as data:
            values = {f.name: data[f.name] for f in fields(cls) if f.name in data}
        values.setdefault("predictor", np.asarray("brunovsky"))   # recorded before the held predictor
        for name in ("model", "method", "oosm", "fusion", "predictor"):
            values[name] = str(values[name])
        for name in ("n", "m", "nodes", "max_lag", "seed"):
            values[name] = int(values[name])
        values["ts"] = float(values["ts"])
        return cls(**values)


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


# --- the filter side, shared by the closed loop and the replay ----------------------------------

class FilterBank:
    """Nodes, master and controller, stepped exactly as the protocol says."""

    def __init__(self, flat, ts, q, R, node_x0, node_P0, master_x0, master_P0, gains, max_lag, oosm, fusion,
                 node_dtype=np.float64, predictor: str = predictors.DEFAULT):
        self.nodes = [NodeFilter(flat, ts, q, R[i], node_x0[i], node_P0[i], max_lag=max_lag, oosm=oosm,
                                 dtype=node_dtype, predictor=predictor) for i in range(len(R))]
        self.master = Master(flat, ts, q, master_x0, master_P0, len(R), rule=fusion, max_lag=max_lag,
                             predictor=predictor)
        self.takes_v = predictor == "brunovsky"
        held = predictors.held_constants(flat, ts) if predictor == "held" else None
        self.control = FlatController(flat, gains=gains, held=held)   # the law for what the plant holds
        self.max_lag = max_lag
        self.sent: list[dict[int, object]] = [{} for _ in self.nodes]

    def step(self, k, z, gamma, late, sources, ref):
        """`late`: (node, lag, z) in arrival order; `sources[i]`: source step of node i's packet
        fused now (-1: none). Returns (late applied flags, node x, node P, x, P, u, v)."""
        for node, zi, gi in zip(self.nodes, z, gamma):
            node.update(zi if gi else None, bool(gi))
        applied = [self.nodes[i].update_delayed(zl, lag) for i, lag, zl in late]
        for node, sent in zip(self.nodes, self.sent):
            sent[k] = node.packet()
            sent.pop(k - self.max_lag - 1, None)
        self.master.fuse([sent.get(s) if s >= 0 else None for sent, s in zip(self.sent, sources)])
        u, v = self.control(self.master.x, ref)
        out = (applied, [nd.x.copy() for nd in self.nodes], [nd.P.copy() for nd in self.nodes],
               self.master.x.copy(), self.master.P.copy(), u, v)
        w = v if self.takes_v else u      # what the master broadcasts for the nodes' prediction
        for node in self.nodes:
            node.predict(w)
        self.master.predict(w)
        return out


class _Outputs:
    """Collects what FilterBank.step returns into the recording's arrays."""

    def __init__(self, M, K, n, m):
        self.node_x, self.node_P = np.zeros((M, K, n)), np.zeros((M, K, n, n))
        self.x, self.P = np.zeros((K, n)), np.zeros((K, n, n))
        self.u, self.v = np.zeros((K, m)), np.zeros((K, m))
        self.applied: list[bool] = []

    def put(self, k, out):
        applied, nx, nP, x, P, u, v = out
        self.applied += applied
        self.node_x[:, k], self.node_P[:, k] = nx, nP
        self.x[k], self.P[k], self.u[k], self.v[k] = x, P, u, v


def replay_recording(rec: Recording, node_dtype=np.float64) -> dict[str, np.ndarray]:
    """Re-run only the filters and the controller from a recording (no plant, no network) and
    return the outputs: late_applied, node_x, node_P, x, P, u, v. `node_dtype=np.float32` runs
    the node filters in single precision: a second single-precision implementation to judge the C's."""
    flat = _flat(rec.model)
    bank = FilterBank(flat, rec.ts, rec.q, rec.R, rec.node_x0, rec.node_P0, rec.master_x0, rec.master_P0,
                      rec.gains, rec.max_lag, rec.oosm, rec.fusion, node_dtype, rec.predictor)
    K = rec.ref.shape[0]
    out = _Outputs(rec.nodes, K, rec.n, rec.m)
    late_at = np.searchsorted(rec.late_step, np.arange(K + 1))
    sources = np.full((K, rec.nodes), -1, dtype=int)
    sources[rec.pkt_step, rec.pkt_node] = rec.pkt_src
    for k in range(K):
        late = [(int(rec.late_node[e]), int(rec.late_lag[e]), rec.late_z[e]) for e in range(late_at[k], late_at[k + 1])]
        out.put(k, bank.step(k, rec.z[:, k], rec.gamma[:, k], late, sources[k], rec.ref[k]))
    return {"late_applied": np.array(out.applied, dtype=bool), "node_x": out.node_x, "node_P": out.node_P,
            "x": out.x, "P": out.P, "u": out.u, "v": out.v}


# --- the closed loop ------------------------------------------------------------------------------

# model files' text by spec, set on workers that may not see the caller's files (sweep.py)
MODEL_TEXT: dict[str, str] = {}
# derivations by spec: this process's, or the caller's shipped to a worker (sweep.py), which then
# spends no second of sympy per process
FLATS: dict = {}


def _flat(spec: str):
    if spec not in FLATS:
        text = MODEL_TEXT.get(spec)
        FLATS[spec] = flatness.derive(model_mod.loads_toml(text, spec) if text is not None else model_mod.load(spec))
    return FLATS[spec]


def derive(spec: str, max_seconds: float | None = None, max_memory: float | None = None):
    """The derivation `_flat` returns, made now under the budget (CPU seconds, GB; None: the
    process's default, see budget.configure): a command calls this before its runs start."""
    from dfeif_codegen import budget
    budget.configure(max_seconds, max_memory)
    if spec not in FLATS:
        text = MODEL_TEXT.get(spec)
        mdl = model_mod.loads_toml(text, spec) if text is not None else model_mod.load(spec)
        FLATS[spec] = budget.bounded(flatness.derive, (mdl,), None, None, f"deriving {mdl.source}")
    return FLATS[spec]


@lru_cache(maxsize=64)
def _plant(spec: str, ts: float, substeps: int, params: tuple | None = None) -> Plant:
    """The plant, with the model's parameters or (model error) the given vector."""
    return Plant(_flat(spec).model, ts, substeps, _flat(spec).extension, params)


@lru_cache(maxsize=None)
def _camera(spec: str, scale: float, std) -> Camera:
    return Camera(_flat(spec).model, std=std, scale=scale)


def _per_chain(values, m) -> np.ndarray:
    return np.broadcast_to(np.asarray(values, dtype=float), (m,)).copy()


def initial_covariance(flat, p0_std) -> np.ndarray:
    """P0 = diag(std^2), std per derivative order, the same for every chain."""
    std = np.asarray(p0_std, dtype=float)
    if std.size < max(flat.degrees):
        raise ValueError(f"p0_std needs {max(flat.degrees)} entries (one per derivative order)")
    return np.diag(np.concatenate([std[:r] for r in flat.degrees]) ** 2)


@lru_cache(maxsize=64)
def _reference_table(spec, kind, amplitude, period, offset, harmonics, ts, K, phase=(0.0,),
                     cycles=(1,)) -> np.ndarray:
    """The reference flags of every step, checked to map into the domain (the same for every seed
    and method of a row: computed and checked once per process)."""
    flat = _flat(spec)
    cfg = Config(model=spec, reference=kind, amplitude=amplitude, period=period, offset=offset, harmonics=harmonics,
                 phase=phase, cycles=cycles)
    refs = references(cfg, flat.m)
    t = np.arange(K) * ts
    table = np.array([flags(refs, flat.degrees, tk) for tk in t])
    check_reference(flat, table, t)
    table.flags.writeable = False
    return table


def references(cfg: Config, m: int) -> list[Reference]:
    amp, off, phase = _per_chain(cfg.amplitude, m), _per_chain(cfg.offset, m), _per_chain(cfg.phase, m)
    cycles = _per_chain(cfg.cycles, m)
    return [Reference(cfg.reference, amp[j], cfg.period, off[j], cfg.harmonics, phase[j], int(cycles[j]))
            for j in range(m)]


def state_of_flags(flat, ref_flags) -> np.ndarray:
    """The canonical state the reference flags describe (drop each chain's top derivative);
    `ref_flags` may hold one step per row."""
    idx = np.concatenate([np.arange(c.offset + j, c.offset + j + c.degree) for j, c in enumerate(flat.chains)])
    return np.asarray(ref_flags)[..., idx]


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
                          self.gains, self.cfg.max_lag, self.oosm, self.cfg.fusion, predictor=self.cfg.predictor)


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
                           tuple(cfg.phase), tuple(cfg.cycles))

    net_rng, noise_rng, init_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(3))
    net = Network(list(cfg.sensor), list(cfg.uplink), K, net_rng)
    noise = [noise_rng.standard_normal((K, len(c.channels))) for c in cams]
    P0 = initial_covariance(flat, cfg.p0_std)
    x_hat0 = state_of_flags(flat, ref[0])     # everyone starts at the reference's start
    zeta0 = x_hat0 + (np.linalg.cholesky(P0) @ init_rng.standard_normal(n) if cfg.initial_error else 0.0)

    q, gains = _per_chain(cfg.q, m), FlatController(flat, poles=_per_chain(cfg.poles, m)).gains
    R = np.array([c.R for c in cams])
    oosm = cfg.method if cfg.method in OOSM else "replay"
    predictors.check(cfg.predictor, oosm)
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


def check_divergence(s: "Setup", x_true, zeta, x, P, steps: int | None = None) -> None:
    """The divergence watch over a run's arrays (an engine that ran the loop elsewhere), over its
    first `steps` steps (default all): the state after step k is the next step's x_true, so the
    last step's successor goes unchecked. Vectorized over the steps to find the first one that
    trips a criterion; the step-by-step watch then runs over the steps leading to it, so the
    message is the one the numpy engine's watch gives."""
    K = min(s.K, s.K if steps is None else steps + 1) - 1
    if K <= 0:
        return
    watch = DivergenceWatch(s.flat.model, s.cfg.watch_nees, tracking_bound(s.cfg, s.flat.m))
    xs = np.asarray(x_true[1:K + 1], dtype=float)
    track = tracking_errors(s.flat, np.asarray(zeta[:K], dtype=float), s.ref[:K])
    with np.errstate(invalid="ignore"):
        bad = ~np.all(np.isfinite(xs), axis=1) | np.any((xs < watch.lo) | (xs > watch.hi), axis=1) \
            | np.any(np.abs(track) > watch.bound, axis=1)
    first = int(np.argmax(bad)) if bad.any() else K
    if watch.nees:
        high = ~(_batch_nees(_errors(s.flat, np.array(x[:K], dtype=float), zeta[:K]), P[:K])
                 <= NEES_DIVERGED * s.flat.n)
        steps_k = np.arange(K)
        run = steps_k - np.maximum.accumulate(np.where(high, -1, steps_k))   # highs in a row up to k
        tripped = run >= NEES_STEPS
        if tripped.any():
            first = min(first, int(np.argmax(tripped)))
    if first == K:
        return
    for k in range(max(0, first - NEES_STEPS + 1), first + 1):   # raises at `first`
        watch.step(s.t[k], x_true[k + 1], _errors(s.flat, x[k], zeta[k]), P[k], track[k])


def _batch_nees(err, P) -> np.ndarray:
    """NEES per step; inf where P is not finite or singular (the watch's `not nees <= limit`)."""
    out = np.full(len(err), np.inf)
    ok = np.all(np.isfinite(P), axis=(1, 2)) & np.all(np.isfinite(err), axis=1)
    if ok.any():
        with np.errstate(all="ignore"):
            try:
                out[ok] = _nees(err[ok], P[ok])
            except np.linalg.LinAlgError:   # a singular P somewhere: step by step
                for k in np.nonzero(ok)[0]:
                    try:
                        out[k] = float(err[k] @ np.linalg.solve(P[k], err[k]))
                    except np.linalg.LinAlgError:
                        out[k] = np.inf
    return out


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
        late_applied=applied, node_x=node_x, node_P=node_P, x=x, P=P, u=u, v=v)
    result = Result(cfg, s.t, zeta, x_true, s.net.lag.copy(), rec, counters)
    result.metrics = metrics(result)
    return result


# --- metrics ----------------------------------------------------------------------------------------

def tracking_errors(flat, zeta, ref) -> np.ndarray:
    """y - y_d per flat output (angles wrapped): zeta (..., n) true canonical states, ref
    (..., n + m) reference flags of the same steps."""
    e = zeta[..., flat.heads] - ref[..., [c.offset + j for j, c in enumerate(flat.chains)]]
    for j, c in enumerate(flat.chains):
        if c.angle:
            e[..., j] = wrap(e[..., j], True)
    return e


def tracking_bound(cfg: "Config", m: int) -> np.ndarray:
    """Per flat output: the scenario's tracking_bound, else twice the reference's amplitude (a
    run whose output strays by more than the reference's whole swing has stopped tracking); no
    bound for a constant reference."""
    if cfg.tracking_bound:
        return _per_chain(cfg.tracking_bound, m)
    amp = np.abs(_per_chain(cfg.amplitude, m))
    return np.where(amp > 0, 2 * amp, np.inf)


def _errors(flat, est, zeta) -> np.ndarray:
    err = est - zeta
    for c in flat.chains:
        if c.angle:
            err[..., c.offset] = wrap(err[..., c.offset], True)
    return err


def _nees(err, P) -> np.ndarray:
    return np.einsum("...i,...i->...", err, np.linalg.solve(P, err[..., None])[..., 0])


def metrics(res: Result) -> dict:
    """Per run, from `metrics_from` on: estimation RMSE per canonical state (nodes, master),
    mean tr P, NEES per step (averaged later over runs), tracking RMSE of the true plant and of
    the estimates (x_hat - x_d per node and master, what the chapter's tables report)."""
    flat = _flat(res.config.model)
    rec = res.recording
    k0 = min(int(round(res.config.metrics_from / rec.ts)), len(res.t) - 1)
    zeta = res.zeta[k0:]
    node_err = _errors(flat, rec.node_x[:, k0:], zeta[None])
    err = _errors(flat, rec.x[k0:], zeta)
    desired = state_of_flags(flat, rec.ref[k0:])
    track = _errors(flat, zeta, desired)
    return {
        "rmse_nodes": np.sqrt(np.mean(node_err ** 2, axis=1)),
        "rmse_master": np.sqrt(np.mean(err ** 2, axis=0)),
        "trace_nodes": np.trace(rec.node_P[:, k0:], axis1=2, axis2=3).mean(axis=1),
        "trace_master": np.trace(rec.P[k0:], axis1=1, axis2=2).mean(),
        "nees_nodes": _nees(node_err, rec.node_P[:, k0:]),
        "nees_master": _nees(err, rec.P[k0:]),
        "rmse_tracking": np.sqrt(np.mean(track ** 2, axis=0)),
        # the chapter's literal quantity (Tables II-IV): the *estimated* tracking error x_hat - x_d
        "rmse_est_tracking_nodes": np.sqrt(np.mean(_errors(flat, rec.node_x[:, k0:], desired[None]) ** 2, axis=1)),
        "rmse_est_tracking_master": np.sqrt(np.mean(_errors(flat, rec.x[k0:], desired) ** 2, axis=0)),
        "late_applied": sum(c["late_applied"] for c in res.counters),
        "late_rejected": sum(c["late_rejected"] for c in res.counters),
        "saturated_steps": saturated_steps(flat, rec.u),
    }


def saturated_steps(flat, u: np.ndarray) -> int:
    """Steps (whole run) whose input the controller clamped to a declared limit: a clamped input
    equals its limit, up to single precision's rounding of the limit (1e-6 relative) in a float build."""
    inputs = flat.model.inputs
    lo = np.array([-np.inf if w.min is None else w.min for w in inputs])
    hi = np.array([np.inf if w.max is None else w.max for w in inputs])
    tol = 1e-6 * np.maximum(1.0, np.abs(np.where(np.isfinite(lo), lo, 0.0)))
    tol_hi = 1e-6 * np.maximum(1.0, np.abs(np.where(np.isfinite(hi), hi, 0.0)))
    at = (u[:, :len(inputs)] <= lo + tol) | (u[:, :len(inputs)] >= hi - tol_hi)
    return int(np.count_nonzero(at.any(axis=1)))
