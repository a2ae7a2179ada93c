"""The wire format in Python, byte for byte the generated C's (`templates/wire.c.j2`, docs/wire.md).

Used by the plant-and-camera process and the relay of `codegen network`, and by the tests that
check the C against it. A frame: 32-byte header, `count` little-endian IEEE-754 reals, an 8-byte
SipHash-2-4 tag (zero without a key), a CRC-32 trailer equal to `zlib.crc32` of the bytes before it.
"""

from __future__ import annotations

import json
import re
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dfeif_codegen.net.siphash import siphash24

MAGIC = b"DFEW"
VERSION = 3
HEADER = struct.Struct("<4sBBBB8sHHIII")   # magic version kind flags real_size model node count step seq epoch
KIND_PACKET, KIND_COMMAND, KIND_CAMERA, KIND_TICK, KIND_ANNOUNCE = 1, 2, 3, 4, 5
MASTER_ID = 0xFFFF

# decode failures, named as the C's return codes (P_ERR_WIRE_* and P_ERR_NONFINITE)
ERRORS = {"length": -10, "crc": -11, "format": -12, "version": -13, "model": -14, "tag": -15,
          "node": -16, "duplicate": -17, "old": -18, "future": -19, "replay": -20, "outdated": -21,
          "nonfinite": -3, "covariance": -22, "gain": -23, "epoch": -24}


# the C's wire_counters fields, in order
COUNTERS = ("length", "crc", "format", "version", "model", "tag", "node", "duplicate", "old", "future", "replay",
            "outdated", "nonfinite", "covariance", "gain", "epoch", "unfused", "other")


class WireError(ValueError):
    """A frame rejected by `decode`; `cause` is a key of ERRORS."""

    def __init__(self, cause: str):
        super().__init__(cause)
        self.cause = cause


@dataclass(frozen=True)
class Layout:
    """What fixes a model's frames: dimensions, precision and the model hash (hex)."""

    n: int
    m: int
    precision: str
    model_hash: str
    scheduled: bool = False     # commands carry σ after u (`--predictor scheduled`)
    flags: int | None = None    # the reference's flags per tick (n + m of the canonical state);
                                # None: n + m, n the filters' (without disturbance states)

    @classmethod
    def of_folder(cls, folder) -> "Layout":
        """The layout of a folder written by `codegen build` (its manifest and header)."""
        folder = Path(folder)
        manifest = json.loads((folder / "manifest.json").read_text())
        name = manifest["model"]
        header = (folder / f"{name}.h").read_text()
        dims = {k: int(v) for k, v in re.findall(rf"#define {name.upper()}_(NX|NY|NFLAGS) (\d+)", header)}
        options = manifest["options"]
        return cls(dims["NX"], dims["NY"], options["precision"], manifest["model_hash"],
                   options.get("predictor") == "scheduled", dims["NFLAGS"])

    @property
    def dtype(self):
        return np.dtype("<f4") if self.precision == "float" else np.dtype("<f8")

    @property
    def packet_reals(self) -> int:
        return self.m + 2 * self.n + 2 * self.n * self.n

    @property
    def command_reals(self) -> int:
        return (3 if self.scheduled else 2) * self.m       # v, u, and σ

    @property
    def tick_reals(self) -> int:
        return 1 + (self.n + self.m if self.flags is None else self.flags)   # end flag, then the reference's

    def size(self, count: int) -> int:
        return HEADER.size + self.dtype.itemsize * count + 12

    def reals(self, kind: int) -> int:
        return {KIND_PACKET: self.packet_reals, KIND_COMMAND: self.command_reals, KIND_CAMERA: self.m,
                KIND_TICK: self.tick_reals, KIND_ANNOUNCE: 0}[kind]


@dataclass(frozen=True)
class Header:
    kind: int
    node: int
    step: int
    seq: int
    keyed: bool = False
    epoch: int = 0


def encode(layout: Layout, kind: int, node: int, step: int, seq: int, values, key: bytes | None = None,
           epoch: int = 0) -> bytes:
    """A frame; `epoch` is the master's boot as the sender knows it (docs/wire.md, "Epochs")."""
    vals = np.asarray(values, dtype=layout.dtype).ravel()
    head = HEADER.pack(MAGIC, VERSION, kind, 1 if key else 0, layout.dtype.itemsize,
                       bytes.fromhex(layout.model_hash[:16]), node, vals.size, step & 0xFFFFFFFF, seq & 0xFFFFFFFF,
                       epoch & 0xFFFFFFFF)
    body = head + vals.tobytes()
    body += struct.pack("<Q", siphash24(key, body) if key else 0)
    return body + struct.pack("<I", zlib.crc32(body))


def peek(buf: bytes) -> Header | None:
    """The header fields of a frame with a valid CRC (the relay routes on them), else None."""
    if len(buf) < HEADER.size + 12 or zlib.crc32(buf[:-4]) != struct.unpack_from("<I", buf, len(buf) - 4)[0]:
        return None
    _, _, kind, flags, _, _, node, _, step, seq, epoch = HEADER.unpack_from(buf)
    return Header(kind, node, step, seq, bool(flags & 1), epoch)


def decode(layout: Layout, buf: bytes, kind: int, key: bytes | None = None) -> tuple[Header, np.ndarray]:
    """The checks of the C's frame_decode, in the same order; raises WireError(cause)."""
    count = layout.reals(kind)
    body = HEADER.size + layout.dtype.itemsize * count
    if len(buf) != layout.size(count):
        raise WireError("length")
    if zlib.crc32(buf[:body + 8]) != struct.unpack_from("<I", buf, body + 8)[0]:
        raise WireError("crc")
    magic, version, k, flags, rs, model, node, cnt, step, seq, epoch = HEADER.unpack_from(buf)
    tag = struct.unpack_from("<Q", buf, body)[0]
    if magic != MAGIC or k != kind or rs != layout.dtype.itemsize or cnt != count or flags & ~1 or (not flags & 1 and tag):
        raise WireError("format")
    if version != VERSION:
        raise WireError("version")
    if model != bytes.fromhex(layout.model_hash[:16]):
        raise WireError("model")
    if key and (not flags & 1 or tag != siphash24(key, buf[:body])):
        raise WireError("tag")
    values = np.frombuffer(buf, dtype=layout.dtype, count=count, offset=HEADER.size).astype(layout.dtype.newbyteorder("="))
    if not np.all(np.isfinite(values)):
        raise WireError("nonfinite")
    return Header(kind, node, step, seq, bool(flags & 1), epoch), values


def packet_values(layout: Layout, step_packet: dict) -> np.ndarray:
    """A packet's reals in wire order (centre, x, P, x_pred, P_pred) from a dict of arrays."""
    return np.concatenate([np.ravel(step_packet[f]) for f in ("centre", "x", "P", "x_pred", "P_pred")])


def split_packet(layout: Layout, values: np.ndarray) -> dict:
    n, m = layout.n, layout.m
    cuts = np.cumsum([m, n, n * n, n])
    centre, x, P, xp, Pp = np.split(values, cuts)
    return {"centre": centre, "x": x, "P": P.reshape(n, n), "x_pred": xp, "P_pred": Pp.reshape(n, n)}


def corrupt(buf: bytes, rng: np.random.Generator, rate: float) -> bytes:
    """Flip each bit independently with probability `rate` (the fault injector's bit errors)."""
    bits = np.unpackbits(np.frombuffer(buf, dtype=np.uint8))
    bits ^= (rng.random(bits.size) < rate).astype(np.uint8)
    return np.packbits(bits).tobytes()


def tick_is_end(buf: bytes) -> bool:
    """A tick's first real is 1 for the end of the run, 0 for a step."""
    rs = buf[7]
    return struct.unpack_from("<f" if rs == 4 else "<d", buf, HEADER.size)[0] > 0
