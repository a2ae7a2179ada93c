"""The scenario driver's inputs and outputs (templates/harness/driver.c.j2): a Recording as the
arrays the driver reads in one call (`scenario_arrays`, `output_arrays`), as the scenario.bin its
stand-alone program reads, and results.bin read back (`read_results`), with the driver's status
codes. check/harness.py compiles and runs the driver with these.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dfeif_codegen.errors import SetupError
from dfeif_codegen.reference.predictor import with_flat_outputs
from dfeif_codegen.symbolic.disturbance import Disturbance, augment

if TYPE_CHECKING:
    from dfeif_codegen.check.harness import ModelDir

CHUNK = 128     # steps of outputs the stand-alone driver holds at once (driver.c.j2)


INPUTS = ("recorded", "own")


def scenario_arrays(rec, dtype) -> dict[str, np.ndarray]:
    """The driver's inputs, C-contiguous, reals in the build's precision, integers int32;
    `v_in` is the reference's broadcast input (`broadcast`: u, (u, σ) or v),
    for runs that predict with the recorded inputs. With disturbance states the initial states and
    q are the filters' (`filter_start`)."""
    K = rec.ref.shape[0]
    source = np.full((K, rec.nodes), -1, dtype=np.int32)
    source[np.asarray(rec.pkt_step, int), np.asarray(rec.pkt_node, int)] = rec.pkt_src
    real = lambda a: np.ascontiguousarray(a, dtype=dtype)  # noqa: E731
    int32 = lambda a: np.ascontiguousarray(a, dtype=np.int32)  # noqa: E731
    start = filter_start(rec)
    return {
        "node_x0": real(start["node_x0"]), "node_P0": real(start["node_P0"]), "R": real(rec.R), "q": real(start["q"]),
        "master_x0": real(start["master_x0"]), "master_P0": real(start["master_P0"]), "gains": real(rec.gains),
        "params": real(rec.params),
        "z": real(rec.z), "gamma": int32(rec.gamma), "ref": real(rec.ref),
        "late_step": int32(rec.late_step), "late_node": int32(rec.late_node),
        "late_lag": int32(rec.late_lag), "late_z": real(np.reshape(rec.late_z, (-1, rec.m))),
        "source": source, "v_in": real(broadcast(rec)),
    }


def broadcast(rec) -> np.ndarray:
    """(K, NW): the input the filters predicted with at each step, as the master broadcast it:
    u (held), u then the fused flat outputs σ = x[heads] (scheduled), v (Brunovsky; a recording
    from before the held predictor)."""
    predictor = getattr(rec, "predictor", "brunovsky")
    if predictor == "scheduled":
        return with_flat_outputs(rec.u, rec.x, rec.heads)
    return rec.u if predictor == "held" else rec.v


def output_arrays(rec, dtype) -> dict[str, np.ndarray]:
    """The driver's output buffers, sized for the filters' state (`canonical` cuts them to n)."""
    K, M, n, m = rec.ref.shape[0], rec.nodes, filter_size(rec), rec.m
    shapes = {"node_x": (M, K, n), "node_P": (M, K, n, n), "x": (K, n), "P": (K, n, n),
              "u": (K, m), "v": (K, m)}
    out = {k: np.zeros(s, dtype=dtype) for k, s in shapes.items()}
    out["late_applied"] = np.zeros(len(rec.late_step), dtype=np.int32)
    return out


def filter_size(rec) -> int:
    """The C filters' state dimension for a recording (disturbance states after the canonical)."""
    dist = Disturbance.from_json(getattr(rec, "disturbance", ""))
    return rec.n + (0 if dist is None else dist.order * rec.m)


def filter_start(rec) -> dict[str, np.ndarray]:
    """node_x0, node_P0, q, master_x0, master_P0 of a recording as the filters take them: with
    disturbance states (`rec.disturbance`, Disturbance.to_json) the states extended as the
    reference's FilterBank extends them (symbolic/disturbance.py `augment`) and q followed by the
    disturbances' densities."""
    dist = Disturbance.from_json(getattr(rec, "disturbance", ""))
    nodes = [augment(x, P, dist, rec.m) for x, P in zip(rec.node_x0, rec.node_P0)]
    x0, P0 = augment(rec.master_x0, rec.master_P0, dist, rec.m)
    q = np.broadcast_to(np.asarray(rec.q, dtype=float), (rec.m,))
    return {"node_x0": np.array([x for x, _ in nodes]), "node_P0": np.array([P for _, P in nodes]),
            "q": q if dist is None else np.concatenate([q, dist.densities(rec.m)]), "master_x0": x0, "master_P0": P0}


def canonical(out: dict[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    """The driver's outputs cut to the canonical state, what the recording holds (the disturbance
    states act on it through the prediction, so a difference in them shows there)."""
    cut = dict(out)
    cut["node_x"], cut["node_P"] = out["node_x"][..., :n], out["node_P"][..., :n, :n]
    cut["x"], cut["P"] = out["x"][..., :n], out["P"][..., :n, :n]
    return cut


_FILE_ORDER = ("node_x0", "node_P0", "R", "q", "master_x0", "master_P0", "gains", "params", "z", "gamma",
               "ref", "late_step", "late_node", "late_lag", "late_z", "source")


def write_scenario(rec, model: ModelDir, path: Path, inputs: str = "recorded") -> Path:
    """scenario.bin for the driver's stand-alone program (format in driver.c.j2)."""
    arrays = scenario_arrays(rec, model.dtype)
    head = np.array([0x43534644, 2, np.dtype(model.dtype).itemsize, filter_size(rec), rec.m, rec.nodes,
                     len(rec.params), rec.ref.shape[0], len(rec.late_step)], dtype="<i4")
    with open(path, "wb") as f:
        f.write(head.tobytes())
        for name in _FILE_ORDER:
            f.write(arrays[name].astype(arrays[name].dtype.newbyteorder("<")).tobytes())
        f.write(np.array([recorded_inputs(inputs)], dtype="<i4").tobytes())
        if recorded_inputs(inputs):
            f.write(arrays["v_in"].astype(arrays["v_in"].dtype.newbyteorder("<")).tobytes())
    return path


def driver_bytes(rec, model: ModelDir, inputs: str = "recorded") -> int:
    """The heap the stand-alone driver allocates for `rec`: every input of the run, and its
    outputs one chunk of CHUNK steps at a time (driver.c.j2), which a target's RAM must hold
    besides the program."""
    arrays = scenario_arrays(rec, model.dtype)
    names = _FILE_ORDER + (("v_in",) if recorded_inputs(inputs) else ())
    one = output_arrays(rec.head(1), model.dtype)     # one step's outputs (and no late frame)
    chunk = CHUNK * sum(a.nbytes for k, a in one.items() if k != "late_applied")
    return sum(arrays[k].nbytes for k in names) + chunk + 4 * len(rec.late_step)


def recorded_inputs(inputs: str) -> bool:
    """Whether the filters predict with the recorded inputs ("recorded": the input the plant
    received, which the recorded measurements reflect) or with the v the C controller computes
    ("own": the loop through the controller closed in C, so a rounding difference in v acts on
    the filters as an input the recorded plant never received)."""
    if inputs not in INPUTS:
        raise ValueError(f"inputs must be one of {INPUTS}, not {inputs!r}")
    return inputs == "recorded"


def read_results(rec, model: ModelDir, path: Path) -> tuple[dict, dict]:
    """results.bin -> ({status, failed_step, failed_call, stack_bytes}, outputs): the outputs
    chunk by chunk (driver.c.j2), put back in the recording's layout; steps a failed run did not
    reach stay 0."""
    data = Path(path).read_bytes()
    tail = np.frombuffer(data[-24:], dtype="<i4") if len(data) >= 24 else np.array([0, 0, 0, 0, 0, -1])
    status = dict(zip(("status", "failed_step", "failed_call", "stack_bytes"), map(int, tail[:4])))
    chunk, written = int(tail[4]), int(tail[5])
    out = output_arrays(rec, model.dtype)
    per_step = sum(a.nbytes for k, a in output_arrays(rec.head(1), model.dtype).items() if k != "late_applied")
    expected = written * per_step + out["late_applied"].nbytes + 24
    if chunk <= 0 or not 0 <= written <= rec.ref.shape[0] or len(data) != expected:
        raise SetupError(f"{path}: {len(data)} bytes, not the results of {rec.ref.shape[0]} steps "
                         f"(chunk {chunk}, {written} written: {expected} bytes)")
    real, at = np.dtype(model.dtype).newbyteorder("<"), 0
    for first in range(0, written, chunk):
        steps = slice(first, min(first + chunk, written))
        for part in (out["node_x"][:, steps], out["node_P"][:, steps], *(out[k][steps] for k in ("x", "P", "u", "v"))):
            part[...] = np.frombuffer(data, dtype=real, count=part.size, offset=at).reshape(part.shape)
            at += part.nbytes
    out["late_applied"][...] = np.frombuffer(data, dtype="<i4", count=len(out["late_applied"]), offset=at)
    return status, canonical(out, rec.n)


CALLS = {1: "node update", 2: "node update_delayed", 3: "node packet", 4: "master fuse", 5: "control",
         6: "predict", 8: "extension_step"}


# the filter calls' return codes, as every generated header defines them (templates/model.h.j2)
FILTER_ERRORS = {-1: "ERR_ARG", -2: "ERR_LAG", -3: "ERR_NONFINITE", -4: "ERR_SINGULAR", -5: "ERR_DUPLICATE",
                 -6: "ERR_SEQUENCE"}


def failure(status: dict, err: int | None = None) -> str:
    code = status["status"] if err is None else err
    name = FILTER_ERRORS.get(code)
    return (f"the C failed at step {status['failed_step']} in "
            f"{CALLS.get(status['failed_call'], 'init')} with error {code}{f' ({name})' if name else ''}")
