"""A bounded libFuzzer run over the generated wire decoder, master receive/fuse and node API
(`templates/harness/fuzz.c.j2`), and the seed corpus it starts from (`tests/fuzz_corpus/`)."""

from __future__ import annotations

import re
import struct
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dfeif_codegen.check import harness
from dfeif_codegen.errors import SetupError
from dfeif_codegen.net import wire

FLAGS = ["-g", "-O1", "-fsanitize=fuzzer,address,undefined", "-fno-sanitize-recover=all", "-std=c99"]


@dataclass
class FuzzResult:
    returncode: int
    executions: int
    seconds: float
    findings: list[Path]
    log: str


def build(model: harness.ModelDir, out: Path, clang: str = "clang") -> Path:
    from dfeif_codegen import __version__
    from dfeif_codegen.codegen import render

    out.mkdir(parents=True, exist_ok=True)
    src = out / "fuzz.c"
    src.write_text(render.environment(model.precision).get_template("harness/fuzz.c.j2").render(
        p=model.name, P=model.name.upper(), banner=render.banner("harness/fuzz.c.j2", model.name, __version__),
        wrap=f"{model.name}_wrap(" in (model.path / f"{model.name}_internal.h").read_text()))
    exe = out / "fuzz"
    cmd = [clang, *FLAGS, f"-I{model.path}", str(src), *map(str, model.sources()), "-lm", "-o", str(exe)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        raise SetupError(f"building the fuzzer failed (needs clang and libclang-rt-14-dev):\n{proc.stderr[-2000:]}")
    return exe


def run(exe: Path, corpus: Path, work: Path, seconds: int) -> FuzzResult:
    """Fuzz for `seconds`, new inputs into work/new (the committed corpus is only read)."""
    new = work / "new"
    new.mkdir(parents=True, exist_ok=True)
    cmd = [str(exe), str(new.resolve()), str(Path(corpus).resolve()), f"-max_total_time={seconds}", "-print_final_stats=1",
           "-rss_limit_mb=1024", "-timeout=10", f"-artifact_prefix={work}/"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=seconds + 120, cwd=work)
    m = re.search(r"stat::number_of_executed_units:\s*(\d+)", proc.stderr)
    t = re.search(r"stat::average_exec_per_sec:\s*(\d+)", proc.stderr)
    execs = int(m.group(1)) if m else 0
    findings = sorted(p for p in work.iterdir() if p.name.startswith(("crash-", "leak-", "timeout-", "oom-")))
    return FuzzResult(proc.returncode, execs, execs / int(t.group(1)) if t and int(t.group(1)) else 0.0,
                      findings, proc.stderr[-3000:])


def seed_corpus(layout: wire.Layout, max_lag: int) -> dict[str, bytes]:
    """A few valid starting points: good frames for the master (plain, keyed, CRC-fixed mode),
    frames whose covariances the master cannot take (not positive definite, asymmetric, above the
    prediction, information that overflows), node operation sequences (updates, late
    measurements, predictions, packets, commands; huge angles) and huge values for the wrap."""
    n, m = layout.n, layout.m
    key = bytes(range(1, 17))
    pkt = np.concatenate([np.zeros(m), np.zeros(n), (0.005 * np.eye(n)).ravel(), np.zeros(n), (0.01 * np.eye(n)).ravel()])
    real = "<f" if layout.precision == "float" else "<d"
    reals = lambda vals: b"".join(struct.pack(real, v) for v in vals)  # noqa: E731
    frame = lambda op, buf: bytes([op]) + struct.pack("<H", len(buf)) + buf  # noqa: E731
    plain = wire.encode(layout, wire.KIND_PACKET, 0, 0, 1, pkt)
    keyed = wire.encode(layout, wire.KIND_PACKET, 1, 0, 5, pkt, key)
    out = {
        "master-plain": bytes([0]) + frame(2, plain) + bytes([1]) + frame(2, plain),
        "master-keyed": bytes([1]) + frame(2, keyed) + bytes([1, 0]) + reals([0.1] * m) + frame(3, keyed),
        "master-predict": bytes([0]) + b"".join(bytes([0]) + reals([0.5] * m) for _ in range(3)) + frame(2, plain),
        # a keyed packet of another boot (epoch 1; the master's is 0), then one of its own
        "master-epoch": bytes([1]) + frame(2, wire.encode(layout, wire.KIND_PACKET, 1, 0, 5, pkt, key, 1)) +
        frame(2, keyed),
    }
    ops = bytearray([2])
    for k in range(4):
        ops += bytes([0]) + reals([0.01 * k] * m) + bytes([3])
        if k >= 2:
            ops += bytes([1]) + reals([0.02] * m) + struct.pack("<i", 1)
        ops += bytes([4]) + reals([0.1] * m) + struct.pack("<I", k + 1) + bytes([2]) + reals([0.1] * m)
    out["node-steps"] = bytes(ops)
    huge = [1e17, -3e18, 2.0 ** 60, 3.0e38, -3.0e38, 1e9 + 0.5, 3.141592653589793, -3.141592653589793]
    if layout.precision == "double":
        huge += [1e300, -1.7e308, 1e16 + 2]
    ops = bytearray([2])
    for k, value in enumerate(huge):
        ops += bytes([0]) + reals([value] * m) + bytes([1]) + reals([-value] * m) + struct.pack("<i", 1)
        ops += bytes([2]) + reals([0.0] * m) + bytes([3])
    out["node-huge-angles"] = bytes(ops)
    out["angles-huge"] = bytes([3]) + reals(huge)
    bad = {"indefinite": (m + n, -0.005), "asymmetric": (m + n + 1, 1e-4), "above": None,
           "unfusable": None}
    for name, patch in bad.items():
        vals = pkt.copy()
        if patch is not None:
            vals[patch[0]] = patch[1]
        elif name == "above":
            vals[m + n:m + n + n * n] *= 3.0
        else:
            vals[m + n:m + n + n * n] *= (1e-320 if layout.precision == "double" else 1e-44) / 0.005
        good_1 = wire.encode(layout, wire.KIND_PACKET, 1, 0, 1, pkt)
        out[f"master-{name}"] = bytes([0]) + frame(2, wire.encode(layout, wire.KIND_PACKET, 0, 0, 1, vals)) + \
            frame(2, good_1) + bytes([1])
    out["node-late-limits"] = bytes([2, 0]) + reals([0.0] * m) + bytes([1]) + reals([0.0] * m) + \
        struct.pack("<i", max_lag + 1) + bytes([1]) + reals([float("nan")] * m) + struct.pack("<i", 1)
    return out
