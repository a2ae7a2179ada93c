"""`dc.load(module)`: the generated C as Python objects, for users' own simulations and tests.

The module's library sources are compiled with the host compiler into a shared library, cached
by a hash of the sources, the compiler and its flags (a rebuild of unchanged code compiles
nothing), and loaded with ctypes. `Node`, `Master` and `control` wrap the C API of
`<model>.h` one call for one call: arrays in and out are numpy arrays of the build's real type,
their shapes are checked before the call, and a negative return code raises the `CError`
subclass of that code, e.g. `LagError("dc_motor_link_node_update_delayed: ERR_LAG")`.

The dimensions and return codes are read from the generated header, so any model works.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import re
import tempfile
from pathlib import Path

import numpy as np

from dfeif_codegen.check import harness
from dfeif_codegen.errors import SetupError
from dfeif_codegen.reference.node import COUNTERS


class CError(RuntimeError):
    """A generated C function returned an error code; `function`, `name` ("ERR_ARG"), `code`."""

    def __init__(self, function: str, name: str, code: int, detail: str = ""):
        super().__init__(f"{function}: {name}" + (f" ({detail})" if detail else ""))
        self.function, self.name, self.code = function, name, code


class ArgError(CError):
    """ERR_ARG: a NULL pointer, gamma not 0/1, q < 0, R not symmetric."""


class LagError(CError):
    """ERR_LAG: a late measurement outside the window."""


class NonFiniteError(CError):
    """ERR_NONFINITE: NaN or infinity in an input or a result."""


class SingularError(CError):
    """ERR_SINGULAR: a matrix that must be positive definite is not."""


class DuplicateError(CError):
    """ERR_DUPLICATE: that step already has a measurement."""


class SequenceError(CError):
    """ERR_SEQUENCE: calls out of protocol order (update twice, predict before update...)."""


class OutlierError(CError):
    """ERR_OUTLIER: the innovation gate (`--gate`) refused the measurement."""


ERRORS = {"ERR_ARG": ArgError, "ERR_LAG": LagError, "ERR_NONFINITE": NonFiniteError,
          "ERR_SINGULAR": SingularError, "ERR_DUPLICATE": DuplicateError, "ERR_SEQUENCE": SequenceError,
          "ERR_OUTLIER": OutlierError}

DIMENSIONS = ("NX", "NZ", "NY", "NQ", "NU", "NP", "NFLAGS", "NMAX", "NNODES")


def cache_dir() -> Path:
    """$DFEIF_CODEGEN_CACHE, else $XDG_CACHE_HOME/dfeif-codegen, else ~/.cache/dfeif-codegen."""
    if os.environ.get("DFEIF_CODEGEN_CACHE"):
        return Path(os.environ["DFEIF_CODEGEN_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "dfeif-codegen"


def header_facts(text: str, prefix: str) -> tuple[dict[str, int], dict[int, str]]:
    """The dimensions (`#define <P>_NX 3`) and return codes (`#define <P>_ERR_LAG (-2)`)."""
    defines = dict(re.findall(rf"^#define\s+{prefix}_(\w+)\s+\(?(-?\d+)\)?(?=\s|$)", text, re.M))
    missing = [d for d in DIMENSIONS if d not in defines]
    if missing:
        raise SetupError(f"{prefix.lower()}.h: no #define {prefix}_{missing[0]}: not a header "
                                 "written by `codegen build`")
    dims = {d: int(defines[d]) for d in DIMENSIONS}
    codes = {int(v): k for k, v in defines.items() if k == "OK" or k.startswith("ERR_")}
    return dims, codes


def load(module, cache: str | Path | None = None) -> "Library":
    """Compile (or reuse from the cache) and load a module written by `build`: a
    GeneratedModule or its folder."""
    folder = harness.ModelDir.open(Path(getattr(module, "path", module)))
    cc = harness.host_compiler()
    sources = folder.sources()
    digest = hashlib.sha256()
    for part in [cc, *harness.HOST_CFLAGS, *(p.name for p in sources)]:
        digest.update(part.encode() + b"\0")
    for path in sorted([*sources, *folder.path.glob("*.h")]):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    root = Path(cache) if cache is not None else cache_dir()
    lib_path = root / f"lib{folder.name}-{digest.hexdigest()[:20]}.so"
    if not lib_path.is_file():
        root.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{lib_path.name}.", dir=root)
        os.close(fd)
        try:
            harness.compile_shared(sources, Path(tmp), [folder.path])
            os.replace(tmp, lib_path)   # atomic: a concurrent load sees the whole library or none
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    return Library(folder, lib_path)


class Library:
    """One compiled module: `Node`, `Master`, `control`, `gains`, and its dimensions."""

    def __init__(self, folder: harness.ModelDir, path: Path):
        self.name, self.path, self.options = folder.name, path, folder.options
        self.dtype = folder.dtype
        P = folder.name.upper()
        self.dims, self.codes = header_facts((folder.path / f"{folder.name}.h").read_text(), P)
        self.nx, self.ny, self.nu, self.np = (self.dims[k] for k in ("NX", "NY", "NU", "NP"))
        self.nflags, self.nodes = self.dims["NFLAGS"], self.dims["NNODES"]
        # the canonical state (gains) and the densities q: NX and NY unless built with disturbance states
        self.nz, self.nq = self.dims["NZ"], self.dims["NQ"]
        self.saturated = 0   # inputs clamped to their declared limits by `control`, over all calls
        self._lib = ctypes.CDLL(str(path))
        self._real = ctypes.c_float if self.dtype == np.float32 else ctypes.c_double
        self.sizes = {}
        for kind in ("node", "master", "packet"):
            fn = getattr(self._lib, f"{self.name}_{kind}_size")
            fn.restype, fn.argtypes = ctypes.c_size_t, []
            self.sizes[kind] = int(fn())
        self.params_default = np.ctypeslib.as_array(
            (self._real * self.np).in_dll(self._lib, f"{self.name}_params_default")).copy()
        lib = self
        self.Node = type("Node", (Node,), {"_library": lib})
        self.Master = type("Master", (Master,), {"_library": lib})

    # calls ------------------------------------------------------------------------------------
    def call(self, function: str, *args, detail: str = "") -> None:
        """Call `<model>_<function>`; a code other than OK raises its CError subclass, whose
        message carries `detail` (the value refused)."""
        name = f"{self.name}_{function}"
        rc = getattr(self._lib, name)(*args)
        if rc != 0:
            code = self.codes.get(rc, f"code {rc}")
            raise ERRORS.get(code, CError)(name, code, rc, detail)

    def array(self, value, shape: tuple, what: str, allow_none: bool = False):
        """`value` as a C-contiguous array of the build's real type, or a one-line ValueError."""
        if value is None and allow_none:
            return None
        a = np.asarray(value, dtype=float) if not isinstance(value, np.ndarray) else value
        if a.shape != shape:
            raise ValueError(f"{self.name} {what}: expected shape {shape}, got {a.shape}")
        return np.ascontiguousarray(a, dtype=self.dtype)

    def output(self, *shape: int) -> np.ndarray:
        return np.zeros(shape, dtype=self.dtype)

    @staticmethod
    def ptr(a: np.ndarray | None):
        return None if a is None else ctypes.c_void_p(a.ctypes.data)

    def state(self, kind: str):
        """Zeroed storage for a struct, 8-byte aligned (an array of doubles)."""
        return (ctypes.c_double * (-(-self.sizes[kind] // 8)))()

    def control(self, x, flags, gains, params=None) -> tuple[np.ndarray, np.ndarray]:
        """(u, v) of `<model>_control`: u = G^-1 (v - F), v from the tracking law on each chain;
        `params` default to the model's nominal values. Inputs clamped to their declared limits
        are counted in `self.saturated`."""
        x = self.array(x, (self.nx,), "control: x")
        flags = self.array(flags, (self.nflags,), "control: flags")
        gains = self.array(gains, (self.nz,), "control: gains")
        params = self.array(self.params_default if params is None else params, (self.np,), "control: params")
        u, v = self.output(self.nu), self.output(self.ny)
        count = ctypes.c_uint32(0)
        self.call("control", *map(self.ptr, (x, flags, gains, params, u, v)), ctypes.byref(count))
        self.saturated += count.value
        return u, v

    def gains(self, lam) -> np.ndarray:
        """Gains placing every pole of chain j at -lam[j] (`<model>_gains`)."""
        lam = self.array(np.broadcast_to(np.asarray(lam, float), (self.ny,)), (self.ny,), "gains: lambda")
        out = self.output(self.nz)
        self.call("gains", self.ptr(lam), self.ptr(out))
        return out


class Packet:
    """A node's packet for the master (opaque: the C struct's bytes)."""

    def __init__(self, library: Library):
        self.library, self.data = library, library.state("packet")


class _Filter:
    """What a node and the master share: a C struct, its prediction and its estimate."""

    _library: Library
    _kind: str   # the C prefix after the model's: "node" or "master"
    _state: ctypes.Array     # the C struct, owned here

    def predict(self, u) -> None:
        """Predict to the next step with the broadcast input: the applied u (a build with the
        default `held` predictor) or v = F + G u (`predictor="brunovsky"`), as `control` returns them."""
        lib = self._library
        what = f"{type(self).__name__}.predict: input"
        lib.call(f"{self._kind}_predict", self._state, lib.ptr(lib.array(u, (lib.ny,), what)))

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """(x, P) of the current step, in canonical coordinates."""
        lib = self._library
        x, P = lib.output(lib.nx), lib.output(lib.nx, lib.nx)
        lib.call(f"{self._kind}_estimate", self._state, lib.ptr(x), lib.ptr(P))
        return x, P


class Node(_Filter):
    """One camera node's filter (`<model>_node_*`). Per step: `update` once, `update_delayed`
    any number of times, then `predict` with the broadcast v."""

    _kind = "node"

    def __init__(self, x0, P0, R, q, mid_run: bool = False):
        """`mid_run`: the node starts after step 0 with the prior of step 0 (a restart;
        `<model>_node_mid_run`): it takes no late frame of a step before its first measurement."""
        lib = self._library
        n, m = lib.nx, lib.ny
        args = (lib.array(x0, (n,), "Node: x0"), lib.array(P0, (n, n), "Node: P0"),
                lib.array(R, (m, m), "Node: R"), lib.array(q, (lib.nq,), "Node: q"))
        self._state = lib.state("node")
        lib.call("node_init", self._state, *map(lib.ptr, args))
        if mid_run:
            lib.call("node_mid_run", self._state)

    def update(self, z, gamma: int = 1) -> None:
        """The measurement of this step (gamma = 1), or its loss (gamma = 0, z may be None)."""
        lib = self._library
        z = lib.array(z, (lib.ny,), "Node.update: z", allow_none=gamma == 0)
        lib.call("node_update", self._state, lib.ptr(z), ctypes.c_int(int(gamma)))

    def update_delayed(self, z_late, lag: int) -> None:
        """A measurement taken `lag` steps ago, after this step's update."""
        lib = self._library
        z = lib.array(z_late, (lib.ny,), "Node.update_delayed: z_late")
        lib.call("node_update_delayed", self._state, lib.ptr(z), ctypes.c_int32(int(lag)),
                 detail=f"lag {int(lag)}: the window is 1..{lib.dims['NMAX']} steps back, not before the "
                        "node's first step (a node started mid_run: its first measurement), and a step "
                        "without a measurement yet")

    def packet(self) -> Packet:
        lib = self._library
        out = Packet(lib)
        lib.call("node_packet", self._state, out.data)
        return out

    def health(self) -> dict[str, int]:
        """Counters: updates, drops, late_applied, late_rejected, outliers."""
        h = (ctypes.c_uint32 * len(COUNTERS))()   # the reference's counters, the C struct's order
        self._library.call("node_health", self._state, h)
        return dict(zip(COUNTERS, map(int, h)))


class Master(_Filter):
    """The fusion centre (`<model>_master_*`). Per step: `fuse` the packets that arrived, then
    `predict` with the v it broadcasts."""

    _kind = "master"

    def __init__(self, x0, P0, q):
        lib = self._library
        n = lib.nx
        args = (lib.array(x0, (n,), "Master: x0"), lib.array(P0, (n, n), "Master: P0"),
                lib.array(q, (lib.nq,), "Master: q"))
        self._state = lib.state("master")
        lib.call("master_init", self._state, *map(lib.ptr, args))

    def fuse(self, packets) -> None:
        """One entry per node (NNODES), a Packet or None for a missing one."""
        lib = self._library
        packets = list(packets)
        if len(packets) != lib.nodes:
            raise ValueError(f"{lib.name} Master.fuse: expected {lib.nodes} entries (None for a missing "
                             f"packet), got {len(packets)}")
        size = lib.sizes["packet"]
        buf = (ctypes.c_double * (-(-size * lib.nodes // 8)))()
        present = (ctypes.c_uint8 * lib.nodes)()
        for i, p in enumerate(packets):
            if p is None:
                continue
            if not isinstance(p, Packet) or p.library is not lib:
                raise ValueError(f"{lib.name} Master.fuse: entry {i} is not a packet of this library")
            ctypes.memmove(ctypes.addressof(buf) + i * size, p.data, size)
            present[i] = 1
        lib.call("master_fuse", self._state, buf, present)
