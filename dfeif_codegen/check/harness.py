"""Compile a generated model folder with the host C compiler and run it from Python.

Two ways in: a shared library loaded with ctypes (the equivalence tests and the closed loop), and a
stand-alone program that reads the scenario from a file (sanitizers, valgrind, the Cortex-M4F).
Both contain the scenario driver rendered from `templates/harness/driver.c.j2`, which replays a
whole recorded scenario in one call, so a comparison is not dominated by ctypes call overhead.
"""

from __future__ import annotations

import ctypes
import json
import os
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Iterable, Sequence

import numpy as np

from dfeif_codegen.check.driver_io import (CHUNK, canonical, failure, filter_size, output_arrays, read_results,
                                          recorded_inputs, scenario_arrays, write_scenario)
from dfeif_codegen.errors import MismatchError, SetupError
from dfeif_codegen.reference.node import COUNTERS

HOST_CFLAGS = ["-O2", "-Wall", "-Wextra", "-g"]
SANITIZE_FLAGS = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer"]


def host_compiler_name() -> str:
    return os.environ.get("CC", "cc")


def host_compiler() -> str:
    """The host C compiler ($CC, else cc), or a SetupError naming the package to install."""
    name = host_compiler_name()
    path = shutil.which(name)
    if path is None:
        raise SetupError(f"C compiler '{name}' not found: install the Debian package gcc "
                         "(apt-get install gcc) or set CC")
    return path


def _cc(args: Sequence, cwd: Path | None = None) -> None:
    cmd = [host_compiler(), *map(str, args)]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=cwd)
    if proc.returncode != 0:
        raise SetupError(f"compiling failed: {' '.join(cmd)}\n{proc.stderr.strip()[-4000:]}")


def compile_shared(sources: Iterable[Path], out: Path, include_dirs: Iterable[Path] = (),
                   extra: Sequence[str] = ()) -> Path:
    """Build a shared library from C sources. -Bsymbolic keeps each library's calls inside it:
    every build of a model exports the same names, and a test session loads many builds.
    No sanitizers here: ctypes cannot load ASan builds without LD_PRELOAD (see compile_program)."""
    incs = [f"-I{d}" for d in include_dirs]
    _cc([*HOST_CFLAGS, "-fPIC", "-shared", "-Wl,-Bsymbolic", *incs, *extra, *sources, "-lm", "-o", out])
    return out


def compile_program(sources: Iterable[Path], out: Path, include_dirs: Iterable[Path] = (),
                    extra: Sequence[str] = (), sanitize: bool = False) -> Path:
    incs = [f"-I{d}" for d in include_dirs]
    flags = [*HOST_CFLAGS, *(SANITIZE_FLAGS if sanitize else ())]
    _cc([*flags, *incs, *extra, *sources, "-lm", "-o", out])
    return out


# Programs whose instructions are counted resolve their library calls (libm's ceil, sin, ...) when
# they load: bound lazily, the first call of each would count the dynamic linker's lookup (several
# hundred instructions) as the caller's.
BIND_NOW = "-Wl,-z,now"


def callgrind_dumps(exe: Path, work: Path) -> tuple[list[tuple[str, int, int]], str]:
    """(section, calls, instructions) of every dump a program makes with valgrind client requests
    (`CALLGRIND_DUMP_STATS_AT("name:calls")`), counted by callgrind (deterministic for the same
    binary and inputs), and the program's stdout."""
    valgrind = shutil.which("valgrind")
    if valgrind is None:
        raise SetupError("valgrind not found: install the Debian package valgrind (apt-get install valgrind)")
    for old in work.glob("callgrind.out*"):
        old.unlink()
    proc = subprocess.run([valgrind, "--tool=callgrind", "--collect-atstart=no", "--callgrind-out-file=callgrind.out",
                           str(exe)], cwd=work, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SetupError(f"callgrind run failed:\n{proc.stderr[-3000:]}")
    dumps = []
    for dump in sorted(work.glob("callgrind.out*")):
        text = dump.read_text(errors="replace")
        desc = re.search(r"^desc: Trigger: Client Request: (\S+):(\d+)$", text, re.M)
        total = re.search(r"^(?:summary|totals): (\d+)", text, re.M)
        if desc and total:
            dumps.append((desc.group(1), int(desc.group(2)), int(total.group(1))))
    return dumps, proc.stdout


def callgrind(exe: Path, work: Path) -> tuple[dict[str, float], str]:
    """Instructions per call of each section a program marks (`callgrind_dumps`), and its stdout."""
    dumps, stdout = callgrind_dumps(exe, work)
    return {name: total / calls for name, calls, total in dumps}, stdout


def load(path: Path) -> ctypes.CDLL:
    return ctypes.CDLL(str(Path(path).resolve()))


# --- the generated model folder and the scenario driver -------------------------------------

@dataclass(frozen=True)
class ModelDir:
    """A folder written by `codegen build`: its manifest says the model name and build options."""

    path: Path
    name: str
    options: dict
    input_nominal: tuple = ()     # the held predictor's linearization input (manifest), () without

    @classmethod
    def open(cls, path: Path) -> "ModelDir":
        path = Path(path)
        manifest = path / "manifest.json"
        if not manifest.is_file():
            raise SetupError(f"{path} is not a folder written by `codegen build` (no manifest.json)")
        data = json.loads(manifest.read_text())
        return cls(path, data["model"], data.get("options", {}), tuple(data.get("input_nominal", ())))

    @property
    def precision(self) -> str:
        return self.options.get("precision", "double")

    @property
    def dtype(self):
        return np.float32 if self.precision == "float" else np.float64

    def sources(self) -> list[Path]:
        """The library's C files (not the example program)."""
        return sorted(p for p in self.path.glob("*.c") if p.name != "example_main.c")


def build_model(model: str, out: Path, precision: str = "double", oosm: str = "replay",
                fusion: str = "difference", nodes: int = 2, max_lag: int = 32, ts: float | None = None,
                predictor: str | None = None, disturbance=None, gate: float | None = None) -> ModelDir:
    """Build a model into `out` through the public build API and open what it wrote (`predictor`
    None: Brunovsky with retrodiction, else the default; `disturbance`: a Disturbance whose
    states the C carries; `gate`: the nodes' innovation gate)."""
    from dfeif_codegen.codegen.build import build
    from dfeif_codegen.reference import predictor as predictors

    module = build(model, out, precision=precision, oosm=oosm, fusion=fusion, nodes=nodes, max_lag=max_lag, ts=ts,
                   predictor=predictors.for_method(predictor, oosm),
                   disturbance=None if disturbance is None else disturbance.kind,
                   tau=None if disturbance is None else disturbance.tau, gate=gate)
    return ModelDir.open(module.path)


def render_driver(model: ModelDir, out_dir: Path) -> Path:
    """The scenario driver for this model, from templates/harness/driver.c.j2."""
    from dfeif_codegen import __version__
    from dfeif_codegen.codegen import render

    env = render.environment(model.precision)
    text = env.get_template("harness/driver.c.j2").render(
        p=model.name, P=model.name.upper(), chunk=CHUNK,
        banner=render.banner("harness/driver.c.j2", model.name, __version__))
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{model.name}_harness.c"
    path.write_text(text)
    return path


# --- the compiled model in this process --------------------------------------------------------

class Library:
    """The generated library plus its scenario driver, compiled into one shared object."""

    def __init__(self, model: ModelDir, work_dir: Path, extra: Sequence[str] = (), reuse: bool = False):
        self.model, self.p = model, model.name
        work_dir = Path(work_dir)
        self.path = work_dir / f"lib{self.p}_harness.so"
        if not (reuse and self.path.is_file()):
            driver = render_driver(model, work_dir)
            compile_shared([*model.sources(), driver], self.path, [model.path], extra)
        self.lib = load(self.path)
        self.real = ctypes.c_float if model.precision == "float" else ctypes.c_double
        self.dtype = model.dtype
        for name in ("harness_size", "node_size", "master_size", "packet_size"):
            getattr(self.lib, f"{self.p}_{name}").restype = ctypes.c_size_t
        getattr(self.lib, f"{self.p}_harness_step").argtypes = [ctypes.c_void_p] * 3 + [ctypes.c_int32] + \
            [ctypes.c_void_p] * 9 + [ctypes.c_size_t] + [ctypes.c_void_p] * 5

    def sizeof(self, what: str) -> int:
        """sizeof of a state struct: node, master, packet, harness."""
        return int(getattr(self.lib, f"{self.p}_{what}_size")())

    def start(self, rec) -> "Harness":
        return Harness(self, rec)

    def run(self, rec, inputs: str = "recorded") -> dict[str, np.ndarray]:
        """Replay the whole recording in one C call; the outputs, shaped as replay_recording's.
        `inputs`: predict with the recorded v, or with the C controller's own ("own")."""
        return self.start(rec).run(inputs)


def _ptr(a: np.ndarray) -> int:
    return a.ctypes.data


class Harness:
    """One initialized harness state (nodes, master, packet history) inside a Library."""

    _INIT = ("node_x0", "node_P0", "R", "q", "master_x0", "master_P0", "gains", "params")
    _SCENARIO = ("z", "gamma", "ref", "late_step", "late_node", "late_lag", "late_z", "source", "v_in")
    _RESULTS = ("node_x", "node_P", "x", "P", "u", "v", "late_applied")

    def __init__(self, library: Library, rec):
        self.library, self.rec, self.lib, p = library, rec, library.lib, library.p
        self.arrays = scenario_arrays(rec, library.dtype)
        self.state = (ctypes.c_uint8 * library.sizeof("harness"))()
        rc = getattr(self.lib, f"{p}_harness_init")(self.state, *(ctypes.c_void_p(_ptr(self.arrays[k])) for k in self._INIT))
        if rc != 0:
            names = dict((int(v), k) for k, v in re.findall(rf"#define {p.upper()}_(ERR_\w+) \((-\d+)\)",
                                                            (library.model.path / f"{p}.h").read_text()))
            raise MismatchError(f"{p}_harness_init failed: {names.get(rc, f'code {rc}')}")

    def counters(self, i: int) -> dict:
        """Node i's health counters (node[i] is the harness struct's first member)."""
        health = (ctypes.c_uint32 * len(COUNTERS))()   # the reference's counters, the C struct's order
        node = ctypes.addressof(self.state) + i * self.library.sizeof("node")
        getattr(self.lib, f"{self.library.p}_node_health")(ctypes.c_void_p(node), health)
        return dict(zip(COUNTERS, map(int, health)))
    def run(self, inputs: str = "recorded") -> dict[str, np.ndarray]:
        a, rec = dict(self.arrays), self.rec
        if not recorded_inputs(inputs):
            a["v_in"] = None
        out = output_arrays(rec, self.library.dtype)

        class Scenario(ctypes.Structure):
            _fields_ = [("steps", ctypes.c_int32), ("n_late", ctypes.c_int32)] + \
                [(k, ctypes.c_void_p) for k in Harness._SCENARIO]

        class Results(ctypes.Structure):
            _fields_ = [(k, ctypes.c_void_p) for k in Harness._RESULTS] + \
                [("failed_step", ctypes.c_int32), ("failed_call", ctypes.c_int32)]

        s = Scenario(rec.ref.shape[0], len(rec.late_step),
                     *(None if a[k] is None else _ptr(a[k]) for k in self._SCENARIO))
        r = Results(*(_ptr(out[k]) for k in self._RESULTS), -1, 0)
        err = getattr(self.lib, f"{self.library.p}_harness_run")(self.state, ctypes.byref(s), ctypes.byref(r))
        if err != 0:
            raise MismatchError(failure({"failed_step": r.failed_step, "failed_call": r.failed_call,
                                         "status": err}))
        out["late_applied"] = out["late_applied"].astype(bool)
        return canonical(out, rec.n)

    def step(self, z, gamma, late, sources, ref):
        """One closed-loop step, with FilterBank.step's arguments and results:
        (late applied flags, node x list, node P list, x, P, u, v)."""
        lib, dt = self.library, self.library.dtype
        M, n, m = self.rec.nodes, filter_size(self.rec), self.rec.m
        z = np.ascontiguousarray(np.nan_to_num(np.asarray(z, dtype=float)), dtype=dt).reshape(M, m)
        gamma = np.ascontiguousarray(gamma, dtype=np.int32)
        late_node = np.array([e[0] for e in late], dtype=np.int32)
        late_lag = np.array([e[1] for e in late], dtype=np.int32)
        late_z = np.array([e[2] for e in late], dtype=dt).reshape(-1, m)
        applied = np.zeros(len(late), dtype=np.int32)
        sources = np.ascontiguousarray(sources, dtype=np.int32)
        ref = np.ascontiguousarray(ref, dtype=dt)
        nx, nP = np.zeros((M, n), dt), np.zeros((M, n, n), dt)
        x, P, u, v = np.zeros(n, dt), np.zeros((n, n), dt), np.zeros(m, dt), np.zeros(m, dt)
        err = ctypes.c_int(0)
        call = getattr(lib.lib, f"{lib.p}_harness_step")(
            self.state, _ptr(z), _ptr(gamma), len(late), _ptr(late_node), _ptr(late_lag), _ptr(late_z),
            _ptr(applied), _ptr(sources), _ptr(ref), None, _ptr(nx), _ptr(nP), 1, _ptr(x), _ptr(P), _ptr(u),
            _ptr(v), ctypes.byref(err))
        if call:
            raise MismatchError(failure({"failed_step": -1, "failed_call": call, "status": err.value}))
        c = self.rec.n    # the canonical part, as FilterBank.step returns it
        return list(applied.astype(bool)), list(nx[:, :c]), list(nP[:, :c, :c]), x[:c], P[:c, :c], u, v


def filter_bank(library: Library):
    """A drop-in for `experiment.closed_loop.FilterBank` that runs the compiled C: the closed loop
    (plant, cameras, network) stays in Python, the filters and the controller are the C's."""

    class _Node:
        def __init__(self, harness: Harness, i: int):
            self.harness, self.i = harness, i

        @property
        def counters(self) -> dict:
            return self.harness.counters(self.i)

    class CFilterBank:
        def __init__(self, flat, ts, q, R, node_x0, node_P0, master_x0, master_P0, gains, max_lag, oosm, fusion,
                     dtype=None, predictor=None, disturbance=None, gate=None):
            del dtype, predictor   # the library's build fixed both (it predicts with <P>_PREDICTS_WITH_U's input)
            opts = library.model.options
            for key, want in (("oosm", oosm), ("fusion", fusion), ("max_lag", max_lag), ("nodes", len(R)),
                              ("disturbance", None if disturbance is None else disturbance.kind), ("gate", gate)):
                if key in opts and opts[key] != want:
                    raise SetupError(f"the C was built with {key} = {opts[key]}, the run needs {want}")
            init = SimpleNamespace(nodes=len(R), n=flat.n, m=flat.m, ref=np.zeros((0, flat.n + flat.m)),
                                   pkt_step=[], pkt_node=[], pkt_src=[], z=np.zeros((len(R), 0, flat.m)),
                                   gamma=np.zeros((len(R), 0)), late_step=[], late_node=[], late_lag=[],
                                   late_z=np.zeros((0, flat.m)), v=np.zeros((0, flat.m)), node_x0=node_x0, node_P0=node_P0, R=R, q=q,
                                   master_x0=master_x0, master_P0=master_P0, gains=gains,
                                   params=flat.param_vector,
                                   disturbance="" if disturbance is None else disturbance.to_json())
            self.harness = Harness(library, init)
            self.nodes = [_Node(self.harness, i) for i in range(len(R))]

        def step(self, k, z, gamma, late, sources, ref):
            return self.harness.step(z, gamma, late, sources, ref)

    return CFilterBank


def program(model: ModelDir, work: Path, sanitize: bool = False) -> Path:
    """Compile the driver as a stand-alone host program (scenario.bin in, results.bin out),
    optionally with AddressSanitizer and UBSan."""
    work = Path(work)
    driver = render_driver(model, work)
    return compile_program([*model.sources(), driver], work / f"{model.name}_harness", [model.path],
                           ["-DHARNESS_MAIN"], sanitize=sanitize)


def run_compiled_program(exe: Path, model: ModelDir, rec, work: Path, timeout: float = 600.0,
                         wrapper: Sequence[str] = (), inputs: str = "recorded") -> tuple[dict, dict]:
    """Replay the recording through a program from `program`, or under a `wrapper` such as valgrind."""
    work = Path(work)
    write_scenario(rec, model, work / "scenario.bin", inputs)
    (work / "results.bin").unlink(missing_ok=True)
    env = dict(os.environ, ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:exitcode=86",
               UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:exitcode=87")
    proc = subprocess.run([*wrapper, str(exe)], cwd=work, capture_output=True, text=True, env=env,
                          timeout=timeout)
    if proc.returncode not in (0, 4) or not (work / "results.bin").is_file():
        raise MismatchError(f"{exe.name} exited with {proc.returncode}:\n{(proc.stdout + proc.stderr)[-4000:]}")
    status, out = read_results(rec, model, work / "results.bin")
    if status["status"] != 0:
        raise MismatchError(failure(status))
    out["late_applied"] = out["late_applied"].astype(bool)
    return status, out


def run_program(model: ModelDir, rec, work: Path, sanitize: bool = False, timeout: float = 600.0,
                wrapper: Sequence[str] = (), inputs: str = "recorded") -> tuple[dict, dict]:
    """`program` then `run_compiled_program`."""
    return run_compiled_program(program(model, work, sanitize), model, rec, work, timeout, wrapper, inputs)
