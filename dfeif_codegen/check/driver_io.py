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

if TYPE_CHECKING:
    from dfeif_codegen.check.harness import ModelDir

OUTPUTS = ("node_x", "node_P", "x", "P", "u", "v", "late_applied")


INPUTS = ("recorded", "own")


def scenario_arrays(rec, dtype) -> dict[str, np.ndarray]:
    """The driver's inputs, C-contiguous, reals in the build's precision, integers int32;
    `v_in` is the reference's broadcast input (u for the held predictor, v for the Brunovsky one),
    for runs that predict with the recorded inputs."""
    K = rec.ref.shape[0]
    source = np.full((K, rec.nodes), -1, dtype=np.int32)
    source[np.asarray(rec.pkt_step, int), np.asarray(rec.pkt_node, int)] = rec.pkt_src
    real = lambda a: np.ascontiguousarray(a, dtype=dtype)  # noqa: E731
    int32 = lambda a: np.ascontiguousarray(a, dtype=np.int32)  # noqa: E731
    return {
        "node_x0": real(rec.node_x0), "node_P0": real(rec.node_P0), "R": real(rec.R), "q": real(rec.q),
        "master_x0": real(rec.master_x0), "master_P0": real(rec.master_P0), "gains": real(rec.gains),
        "params": real(rec.params),
        "z": real(rec.z), "gamma": int32(rec.gamma), "ref": real(rec.ref),
        "late_step": int32(rec.late_step), "late_node": int32(rec.late_node),
        "late_lag": int32(rec.late_lag), "late_z": real(np.reshape(rec.late_z, (-1, rec.m))),
        "source": source, "v_in": real(rec.u if getattr(rec, "predictor", "brunovsky") == "held" else rec.v),
    }


def output_arrays(rec, dtype) -> dict[str, np.ndarray]:
    K, M, n, m = rec.ref.shape[0], rec.nodes, rec.n, rec.m
    shapes = {"node_x": (M, K, n), "node_P": (M, K, n, n), "x": (K, n), "P": (K, n, n),
              "u": (K, m), "v": (K, m)}
    out = {k: np.zeros(s, dtype=dtype) for k, s in shapes.items()}
    out["late_applied"] = np.zeros(len(rec.late_step), dtype=np.int32)
    return out


_FILE_ORDER = ("node_x0", "node_P0", "R", "q", "master_x0", "master_P0", "gains", "params", "z", "gamma",
               "ref", "late_step", "late_node", "late_lag", "late_z", "source")


def write_scenario(rec, model: ModelDir, path: Path, inputs: str = "recorded") -> Path:
    """scenario.bin for the driver's stand-alone program (format in driver.c.j2)."""
    arrays = scenario_arrays(rec, model.dtype)
    head = np.array([0x43534644, 2, np.dtype(model.dtype).itemsize, rec.n, rec.m, rec.nodes,
                     len(rec.params), rec.ref.shape[0], len(rec.late_step)], dtype="<i4")
    with open(path, "wb") as f:
        f.write(head.tobytes())
        for name in _FILE_ORDER:
            f.write(arrays[name].astype(arrays[name].dtype.newbyteorder("<")).tobytes())
        f.write(np.array([recorded_inputs(inputs)], dtype="<i4").tobytes())
        if recorded_inputs(inputs):
            f.write(arrays["v_in"].astype(arrays["v_in"].dtype.newbyteorder("<")).tobytes())
    return path


def recorded_inputs(inputs: str) -> bool:
    """Whether the filters predict with the recorded inputs ("recorded": the input the plant
    received, which the recorded measurements reflect) or with the v the C controller computes
    ("own": the loop through the controller closed in C, so a rounding difference in v acts on
    the filters as an input the recorded plant never received)."""
    if inputs not in INPUTS:
        raise ValueError(f"inputs must be one of {INPUTS}, not {inputs!r}")
    return inputs == "recorded"


def read_results(rec, model: ModelDir, path: Path) -> tuple[dict, dict]:
    """results.bin -> ({status, failed_step, failed_call, stack_bytes}, outputs)."""
    data = Path(path).read_bytes()
    head = np.frombuffer(data[:16], dtype="<i4")
    status = dict(zip(("status", "failed_step", "failed_call", "stack_bytes"), map(int, head)))
    out, at = output_arrays(rec, model.dtype), 16
    for name in OUTPUTS:
        nbytes = out[name].nbytes
        out[name] = np.frombuffer(data[at:at + nbytes], dtype=out[name].dtype.newbyteorder("<")) \
            .reshape(out[name].shape).copy()
        at += nbytes
    if at != len(data):
        raise SetupError(f"{path}: {len(data)} bytes, expected {at}")
    return status, out


CALLS = {1: "node update", 2: "node update_delayed", 3: "node packet", 4: "master fuse", 5: "control",
         6: "predict"}


def failure(status: dict, err: int | None = None) -> str:
    code = status["status"] if err is None else err
    return (f"the C failed at step {status['failed_step']} in "
            f"{CALLS.get(status['failed_call'], 'init')} with error {code}")
