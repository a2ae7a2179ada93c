"""The closed-loop experiment in compiled C: `codegen simulate`'s default engine.

Why: a run of 2,000 steps costs ~0.6 CPU-s in numpy and a few ms in C. Everything random is drawn
in Python by `experiment.closed_loop.prepare` (the same draws the numpy engine uses, from the same
seed); one C call then runs the whole loop: cameras, the generated nodes, master and controller in
the protocol's order, and the true plant's RK4 period as CasADi-generated C. `finish` turns the
outputs into the same Recording, Result and metrics as the numpy engine's.

The compiled code travels as the shared library's bytes (`Compiled`), so a worker on another
machine needs no shared filesystem: it writes the bytes to a private temporary file, loads it and
removes the file. `ENGINE` is this engine as the sweep (experiment/sweep.py) takes it.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import tempfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path
from types import SimpleNamespace

import casadi as ca
import numpy as np

from dfeif_codegen.check import driver_io, harness, loader
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import derivation, divergence
from dfeif_codegen.experiment.plant import Camera, Plant, _fixed, parametric_step
from dfeif_codegen.reference.node import COUNTERS
from dfeif_codegen.symbolic import numeric
from dfeif_codegen.symbolic.disturbance import Disturbance

FAILED_PLANT = 7        # failed_call of the closed-loop driver: the plant's state is not finite
ERR_NONFINITE = -3      # <P>_ERR_NONFINITE of every generated library (templates/model.h.j2)


class CEngineError(ArithmeticError):
    """A generated filter call failed inside the compiled loop (a failed run, like numpy's errors)."""


@dataclass(frozen=True)
class Compiled:
    """One compiled closed loop: what it was built for and the shared library's bytes."""

    key: tuple
    blob: bytes


def build_key(cfg: ex.Config) -> tuple:
    """The build options a run needs: runs with the same key share one library."""
    flat = ex._flat(cfg.model)
    ts = float(cfg.ts or flat.model.ts)
    oosm = cfg.method if cfg.method in ex.OOSM else "replay"
    dist = None if cfg.disturbance is None else (cfg.disturbance.kind, cfg.disturbance.tau)   # what the C bakes in
    return (cfg.model, ts, int(cfg.substeps), len(cfg.sensor), int(cfg.max_lag), oosm, cfg.fusion, cfg.predictor, dist,
            cfg.gate or None)


def plant_source(flat, ts: float, substeps: int, prefix: str) -> tuple[str, int]:
    """C for the true plant's period, the camera and Phi (CasADi's code generator) and the size of
    the work array they need. The period and Phi come twice: with the model's parameters built in
    (a run without model error: the numbers the numpy engine's plant uses) and as functions of
    the parameter vector (`_p`: a run whose plant differs from the model, experiment/model_error.py)."""
    model = flat.model
    plant = Plant(model, ts, substeps, flat.extension)
    n, m = model.n, model.m
    xs, us = ca.SX.sym("x", n), ca.SX.sym("u", m)
    step = ca.Function(f"{prefix}_plant_step", [xs, us], [plant._step.function(xs, us)])
    observe, recover_syms, recover = _camera(model).expressions
    es = ca.SX.sym("e", len(observe))
    obs = numeric.sx_function("observe", [list(model.x)], observe)(xs) + es
    z = numeric.sx_function("recover", [recover_syms], recover)(obs)
    camera = ca.Function(f"{prefix}_plant_camera", [xs, es], [z])
    phi = ca.Function(f"{prefix}_plant_phi", [xs], [numeric.sx_function("phi", [list(model.x)], _fixed(model, flat.phi))(xs)])
    ps = ca.SX.sym("p", len(model.p))
    period_p = parametric_step(model, ts, substeps, flat.extension)
    step_p = ca.Function(f"{prefix}_plant_step_p", [xs, us, ps], [period_p(xs, us, ps)])
    phi_p = ca.Function(f"{prefix}_plant_phi_p", [xs, ps],
                        [numeric.sx_function("phi", [list(model.x), list(model.p)], flat.phi)(xs, ps)])
    cg = ca.CodeGenerator(f"{prefix}_plant", {"casadi_int": "int", "casadi_real": "double", "main": False,
                                               "mex": False, "with_header": False, "with_export": False,
                                               "verbose": False, "include_math": True})
    work = 1
    for f in (step, camera, phi, step_p, phi_p):
        if f.sz_iw() != 0:
            raise RuntimeError(f"{f.name()}: integer work, unexpected for SX")
        work = max(work, f.sz_w())
        cg.add(f)
    return cg.dump(), work


def _camera(model) -> Camera:
    """A camera of the model, for its expressions (the noise std is applied in Python)."""
    return Camera(model, std=None if model.measurement is not None else [1.0] * len(model.outputs))


def compile_loop(key: tuple) -> Compiled:
    """Build the model with the run's options, render the drivers, generate the plant and compile
    them into one shared library; returns its bytes."""
    from dfeif_codegen import __version__
    from dfeif_codegen.codegen import render

    spec, ts, substeps, nodes, max_lag, oosm, fusion, predictor, dist, gate = key
    flat = ex._flat(spec)
    with tempfile.TemporaryDirectory(prefix="codegen-loop-") as tmp:
        work = Path(tmp)
        md = harness.build_model(spec, work / "model", "double", oosm, fusion, nodes, max_lag, ts, predictor,
                                 None if dist is None else Disturbance(dist[0], (1.0,), dist[1]), gate)
        harness.render_driver(md, work)
        plant, plant_w = plant_source(flat, ts, substeps, md.name)
        (work / f"{md.name}_plant.c").write_text(plant)
        env = render.environment("double")
        observe = _camera(flat.model).expressions[0]
        text = env.get_template("harness/closed_loop.c.j2").render(
            p=md.name, P=md.name.upper(), channels=len(observe), plant_w=plant_w,
            banner=render.banner("harness/closed_loop.c.j2", md.name, __version__))
        (work / f"{md.name}_closed_loop.c").write_text(text)
        out = harness.compile_shared([*md.sources(), work / f"{md.name}_closed_loop.c", work / f"{md.name}_plant.c"],
                                     work / f"lib{md.name}_loop.so", [md.path, work])
        return Compiled(key, out.read_bytes())


@lru_cache(maxsize=None)
def _toolkit_digest() -> bytes:
    """Every file of this toolkit (code, templates, built-in models): what the library is made of."""
    digest = hashlib.sha256()
    for package in ("dfeif_codegen", "dfeif_codegen.templates"):
        root = Path(str(resources.files(package)))
        for path in sorted(root.rglob("*")):
            if path.is_file() and "__pycache__" not in path.parts:
                digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.digest()


@derivation.by_model
@lru_cache(maxsize=None)
def compiled(key: tuple) -> Compiled:
    """compile_loop, once per process and key, and once per user (the cache of check/loader.py)
    for as long as the toolkit, the model file and the compiler stay the same: a library is a
    pure function of those, and building one takes a derivation and two compiler runs (~2 s)."""
    spec = key[0]
    text = derivation.MODEL_TEXT.get(spec) or (Path(spec).read_text(encoding="utf-8") if Path(spec).is_file() else "")
    digest = hashlib.sha256(_toolkit_digest())
    for part in [repr(key), text, harness.host_compiler(), *harness.HOST_CFLAGS]:
        digest.update(part.encode() + b"\0")
    path = loader.cache_dir() / f"loop-{digest.hexdigest()[:20]}.so"
    if path.is_file():
        return Compiled(key, path.read_bytes())
    code = compile_loop(key)
    try:   # a cache that cannot be written costs the next run its build, nothing else
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
        with os.fdopen(fd, "wb") as f:
            f.write(code.blob)
        os.replace(tmp, path)   # atomic: a concurrent run sees the whole library or none
    except OSError:
        pass
    return code


class _Loop:
    """A loaded library: ctypes prototypes and the argument structures."""

    def __init__(self, key: tuple, blob: bytes, prefix: str):
        fd, path = tempfile.mkstemp(prefix="codegen-loop-", suffix=".so")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(blob)
            self.lib = ctypes.CDLL(path)
        finally:
            os.unlink(path)       # the mapping stays; nothing is left on the worker's disk
        self.key = key
        self.p = prefix
        for name in ("harness_size", "node_size"):
            getattr(self.lib, f"{self.p}_{name}").restype = ctypes.c_size_t
        self.harness_size = int(getattr(self.lib, f"{self.p}_harness_size")())
        self.node_size = int(getattr(self.lib, f"{self.p}_node_size")())
        vp = ctypes.c_void_p

        class Scenario(ctypes.Structure):
            _fields_ = [("steps", ctypes.c_int32), ("n_late", ctypes.c_int32)] + \
                [(k, vp) for k in ("x0", "noise", "upd", "late_step", "late_node", "late_lag", "source", "ref",
                                   "params")]

        class Outputs(ctypes.Structure):
            _fields_ = [(k, vp) for k in harness.Harness._RESULTS] + \
                [("failed_step", ctypes.c_int32), ("failed_call", ctypes.c_int32)]

        class Results(ctypes.Structure):
            _fields_ = [(k, vp) for k in ("x_true", "zeta", "frames", "late_z")] + [("out", Outputs)]

        self.Scenario, self.Outputs, self.Results = Scenario, Outputs, Results


_LOADED: dict[tuple, _Loop] = {}


def _load(c: Compiled) -> _Loop:
    loop = _LOADED.get(c.key)
    if loop is None:
        loop = _LOADED[c.key] = _Loop(c.key, c.blob, ex._flat(c.key[0]).model.name)
    return loop


def _c(a: np.ndarray, dtype) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=dtype)


def run(cfg: ex.Config, code: Compiled | None = None) -> ex.Result:
    """One closed-loop run in C; the same Result as `experiment.closed_loop.run` on the same seed."""
    s = ex.prepare(cfg)
    key = build_key(cfg)
    if code is None or code.key != key:
        code = compiled(key)
    loop = _load(code)
    lib, p = loop.lib, loop.p
    flat, K, M = s.flat, s.K, len(cfg.sensor)
    n, m = flat.n, flat.m
    f64, i32 = np.float64, np.int32
    # the filters' start as the driver takes it (with disturbance states: extended, q their densities too)
    start = driver_io.filter_start(SimpleNamespace(
        m=m, q=s.q, node_x0=s.node_x0, node_P0=s.node_P0, master_x0=s.x_hat0, master_P0=s.P0,
        disturbance="" if cfg.disturbance is None else cfg.disturbance.to_json()))
    N = len(start["master_x0"])
    init = [_c(a, f64) for a in (start["node_x0"], start["node_P0"], s.R, start["q"], start["master_x0"],
                                 start["master_P0"], s.gains, flat.param_vector)]
    state = (ctypes.c_uint8 * loop.harness_size)()
    rc = getattr(lib, f"{p}_harness_init")(state, *(ctypes.c_void_p(a.ctypes.data) for a in init))
    if rc != 0:
        raise CEngineError(f"{p}_harness_init failed with error {rc}")
    noise = _c(np.stack([c.std * nz for c, nz in zip(s.cams, s.noise)]), f64)
    late = _c(s.late, i32)
    inputs = {"x0": _c(s.x0, f64), "noise": noise, "upd": _c(s.upd, i32), "late_step": _c(late[:, 0], i32),
              "late_node": _c(late[:, 1], i32), "late_lag": _c(late[:, 2], i32),
              "source": _c(s.net.source.T, i32), "ref": _c(s.ref, f64)}
    params = None if s.plant_p is None else _c(s.plant_p, f64)   # NULL: the model's own
    E = late.shape[0]
    out: dict[str, np.ndarray] = {"x_true": np.zeros((K, n)), "zeta": np.zeros((K, n)), "frames": np.zeros((M, K, m)),
           "late_z": np.zeros((E, m)), "node_x": np.zeros((M, K, N)), "node_P": np.zeros((M, K, N, N)),
           "x": np.zeros((K, N)), "P": np.zeros((K, N, N)), "u": np.zeros((K, m)), "v": np.zeros((K, m)),
           "late_applied": np.zeros(E, dtype=i32)}
    scen = loop.Scenario(K, E, *(inputs[k].ctypes.data for k in ("x0", "noise", "upd", "late_step", "late_node",
                                                                   "late_lag", "source", "ref")),
                         None if params is None else params.ctypes.data)
    res = loop.Results(*(out[k].ctypes.data for k in ("x_true", "zeta", "frames", "late_z")),
                       loop.Outputs(*(out[k].ctypes.data for k in harness.Harness._RESULTS), -1, 0))
    err = getattr(lib, f"{p}_loop_run")(state, ctypes.byref(scen), ctypes.byref(res))
    out = driver_io.canonical(out, n)       # the filters' canonical part, as the reference records it
    if err != 0:
        step, call = res.out.failed_step, res.out.failed_call
        # an earlier cause first, as numpy's loop meets it: the watch runs every step before the call
        divergence.check_divergence(s, out["x_true"], out["zeta"], out["x"], out["P"], steps=step)
        if call == FAILED_PLANT or err == ERR_NONFINITE:   # where numpy's loop sees the plant diverge
            divergence.check_tracking_at(s, out["zeta"], step)   # the watch's first check at this step
            what = "the plant's state" if call == FAILED_PLANT else f"the result of {driver_io.CALLS.get(call, 'init')}"
            raise divergence.Diverged(f"diverged at t = {s.t[step]:.2f} s: {what} is not finite")
        raise CEngineError(driver_io.failure({"failed_step": step, "failed_call": call, "status": err}))
    counters = []
    health = (ctypes.c_uint32 * len(COUNTERS))()   # the reference's counters, the C struct's order
    for i in range(M):
        getattr(lib, f"{p}_node_health")(ctypes.c_void_p(ctypes.addressof(state) + i * loop.node_size), health)
        counters.append(dict(zip(COUNTERS, map(int, health))))
    divergence.check_divergence(s, out["x_true"], out["zeta"], out["x"], out["P"])
    return ex.finish(s, out["x_true"], out["zeta"], out["frames"], out["node_x"], out["node_P"], out["x"],
                     out["P"], out["u"], out["v"], out["late_applied"].astype(bool), counters)


class CEngine:
    """The compiled closed loop as an engine of experiment/sweep.py (picklable: a module-level class)."""

    name = "c"

    def key(self, cfg: ex.Config) -> tuple:
        return build_key(cfg)

    def compile(self, keys: list) -> dict:
        """Each distinct library once, in parallel threads (the compiler runs outside the GIL)."""
        harness.host_compiler()
        with ThreadPoolExecutor(max_workers=max(1, min(len(keys), os.cpu_count() or 1))) as pool:
            return dict(zip(keys, pool.map(compiled, keys)))

    def run(self, cfg: ex.Config, code: Compiled | None) -> ex.Result:
        return run(cfg, code)


ENGINE = CEngine()
