"""The generated wire functions through ctypes: the tests' and the benchmark's way to call the C
codec and the master's receive path from Python (compiled with the harness's host compiler)."""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

from dfeif_codegen.check import harness
from dfeif_codegen.net import wire


class WireLib:
    """One generated model folder compiled into a shared library, with typed helpers."""

    def __init__(self, model: harness.ModelDir, work: Path, layout: wire.Layout):
        work.mkdir(parents=True, exist_ok=True)
        self.model, self.layout, self.p = model, layout, model.name
        self.lib = harness.load(harness.compile_shared(model.sources(), work / f"lib{model.name}_wire.so",
                                                       [model.path]))
        self.real = ctypes.c_float if layout.precision == "float" else ctypes.c_double
        n, m = layout.n, layout.m

        class Packet(ctypes.Structure):
            _fields_ = [("step", ctypes.c_uint32), ("centre", self.real * m), ("x", self.real * n),
                        ("P", self.real * (n * n)), ("x_pred", self.real * n), ("P_pred", self.real * (n * n))]

        class Header(ctypes.Structure):
            _fields_ = [("kind", ctypes.c_uint8), ("node", ctypes.c_uint16), ("step", ctypes.c_uint32),
                        ("seq", ctypes.c_uint32), ("epoch", ctypes.c_uint32)]

        self.Packet, self.Header = Packet, Header
        assert ctypes.sizeof(Packet) == self.fn("packet_size", ctypes.c_size_t)()
        for name in ("crc32",):
            self.fn(name, ctypes.c_uint32)
        self.fn("siphash24", ctypes.c_uint64)
        self.fn("master_size", ctypes.c_size_t)
        self.fn("node_size", ctypes.c_size_t)
        self.fn("inbox_size", ctypes.c_size_t)
        self.fn("command_rx_size", ctypes.c_size_t)

    def fn(self, name: str, restype=ctypes.c_int):
        f = getattr(self.lib, f"{self.p}_{name}")
        f.restype = restype
        return f

    def buffer(self, what: str):
        return ctypes.create_string_buffer(self.fn(f"{what}_size", ctypes.c_size_t)())

    def reals(self, values) -> ctypes.Array:
        a = np.ascontiguousarray(values, dtype=self.layout.dtype.newbyteorder("=")).ravel()
        return (self.real * a.size)(*a.tolist())

    @staticmethod
    def key(key: bytes | None):
        return None if key is None else ctypes.create_string_buffer(key, 16)

    def packet(self, values: np.ndarray, step: int):
        d = wire.split_packet(self.layout, np.asarray(values))
        pk = self.Packet()
        pk.step = step
        for name, arr in d.items():
            getattr(pk, name)[:] = np.ravel(arr).tolist()
        return pk

    def packet_values(self, pk) -> np.ndarray:
        return np.concatenate([np.array(getattr(pk, f)[:], dtype=self.layout.dtype.newbyteorder("="))
                               for f in ("centre", "x", "P", "x_pred", "P_pred")])

    def packet_encode(self, values, step: int, node: int, seq: int, key: bytes | None = None,
                      epoch: int = 0) -> tuple[int, bytes]:
        size = self.layout.size(self.layout.packet_reals)
        buf = ctypes.create_string_buffer(size)
        pk = self.packet(values, step)
        rc = self.fn("packet_encode")(ctypes.byref(pk), ctypes.c_uint16(node), ctypes.c_uint32(seq),
                                      ctypes.c_uint32(epoch), self.key(key), buf)
        return rc, buf.raw

    def packet_decode(self, frame: bytes, key: bytes | None = None):
        pk, h = self.Packet(), self.Header()
        rc = self.fn("packet_decode")(frame, ctypes.c_size_t(len(frame)), self.key(key), ctypes.byref(pk),
                                      ctypes.byref(h))
        return rc, h, self.packet_values(pk)

    def command_encode(self, step: int, v, u, seq: int, key: bytes | None = None,
                       epoch: int = 0) -> tuple[int, bytes]:
        buf = ctypes.create_string_buffer(self.layout.size(self.layout.command_reals))
        rc = self.fn("command_encode")(ctypes.c_uint32(step), self.reals(v), self.reals(u), ctypes.c_uint32(seq),
                                       ctypes.c_uint32(epoch), self.key(key), buf)
        return rc, buf.raw

    def announce_encode(self, step: int, seq: int, epoch: int, key: bytes | None = None) -> tuple[int, bytes]:
        buf = ctypes.create_string_buffer(self.layout.size(0))
        rc = self.fn("announce_encode")(ctypes.c_uint32(step), ctypes.c_uint32(seq), ctypes.c_uint32(epoch),
                                        self.key(key), buf)
        return rc, buf.raw

    def rejected(self, inbox=None, rx=None) -> dict:
        out = (ctypes.c_uint32 * len(wire.COUNTERS))()
        assert self.fn("wire_rejected")(inbox, rx, out) == 0
        return dict(zip(wire.COUNTERS, out[:]))
