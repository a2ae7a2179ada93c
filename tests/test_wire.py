"""The wire: the generated C codec equals the Python one byte for byte (both precisions, both
models), SipHash-2-4 meets its published vectors in C and in Python, CRC-32 equals zlib, and the
master's receive path rejects and counts every cause while fusion goes on with the rest."""

from __future__ import annotations

import ctypes
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from dfeif_codegen.check import harness
from dfeif_codegen.net import wire
from dfeif_codegen.net.clib import WireLib
from dfeif_codegen.net.siphash import siphash24

VECTORS = [line.strip() for line in (Path(__file__).parent / "data" / "siphash24_vectors.txt").read_text().splitlines()
           if line and not line.startswith("#")]
KEY = bytes(range(16))
DEPLOY = bytes.fromhex("8f1e2d3c4b5a69788796a5b4c3d2e1f0")


@pytest.fixture(scope="module")
def libs(tmp_path_factory, host_cc):
    root = tmp_path_factory.mktemp("wire")
    cache = {}

    def get(model: str, precision: str) -> WireLib:
        if (model, precision) not in cache:
            md = harness.build_model(model, root / f"{model}-{precision}" / "gen", precision)
            cache[model, precision] = WireLib(md, root / f"{model}-{precision}" / "lib", wire.Layout.of_folder(md.path))
        return cache[model, precision]
    return get


def random_reals(rng, count: int, dtype) -> np.ndarray:
    """Finite values of every kind the codec must carry: signed zeros, subnormals, extremes, random bits."""
    info = np.finfo(dtype)
    special = np.array([0.0, -0.0, info.tiny, -info.tiny, info.tiny / 4, info.max, -info.max, 1.0, -1 / 3], dtype=dtype)
    bits = rng.integers(0, 2 ** (8 * np.dtype(dtype).itemsize), size=4 * count, dtype=np.uint64 if dtype == np.float64 else np.uint32)
    vals = bits.view(dtype)
    vals = vals[np.isfinite(vals)]
    return np.concatenate([special, vals])[:count] if count > special.size else special[:count]


def test_siphash_published_vectors_python():
    for i, expected in enumerate(VECTORS):
        assert siphash24(KEY, bytes(range(i))).to_bytes(8, "little").hex() == expected, i
    assert len(VECTORS) == 64


@pytest.mark.parametrize("precision", ["double", "float"])
def test_siphash_published_vectors_c(libs, precision):
    lib = libs("dc_motor_link", precision)
    f = lib.fn("siphash24", ctypes.c_uint64)
    key = ctypes.create_string_buffer(KEY, 16)
    for i, expected in enumerate(VECTORS):
        msg = ctypes.create_string_buffer(bytes(range(i)), max(i, 1))
        assert f(key, msg, ctypes.c_size_t(i)).to_bytes(8, "little").hex() == expected, i


def test_crc32_equals_zlib(libs):
    lib = libs("dc_motor_link", "double")
    rng = np.random.default_rng(1)
    for n in (0, 1, 3, 64, 241, 1000):
        data = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        assert lib.fn("crc32", ctypes.c_uint32)(ctypes.create_string_buffer(data, max(n, 1)), ctypes.c_size_t(n)) == zlib.crc32(data)
    assert zlib.crc32(b"123456789") == 0xCBF43926   # the CRC-32/IEEE check value


@pytest.mark.parametrize("model", ["dc_motor_link", "two_link_arm"])
@pytest.mark.parametrize("precision", ["double", "float"])
@pytest.mark.parametrize("key", [None, DEPLOY], ids=["crc", "keyed"])
def test_codec_c_equals_python(libs, model, precision, key):
    lib = libs(model, precision)
    lay = lib.layout
    rng = np.random.default_rng(7)
    for trial in range(20):
        values = random_reals(rng, lay.packet_reals, lay.dtype.newbyteorder("="))
        rng.shuffle(values)
        step, node, seq = int(rng.integers(0, 2 ** 32)), int(rng.integers(0, 2)), int(rng.integers(0, 2 ** 32))
        epoch = int(rng.integers(0, 2 ** 32))
        rc, c_bytes = lib.packet_encode(values, step, node, seq, key, epoch)
        py_bytes = wire.encode(lay, wire.KIND_PACKET, node, step, seq, values, key, epoch)
        assert rc == 0 and c_bytes == py_bytes and len(py_bytes) == lay.size(lay.packet_reals)
        rc, h, back = lib.packet_decode(py_bytes, key)
        assert rc == 0 and (h.step, h.node, h.seq, h.epoch) == (step, node, seq, epoch)
        assert back.tobytes() == values.tobytes()          # bit for bit, -0.0 and subnormals included
        hd, vals = wire.decode(lay, c_bytes, wire.KIND_PACKET, key)
        assert vals.tobytes() == values.tobytes() and (hd.step, hd.node, hd.seq, hd.epoch) == (step, node, seq, epoch)
        v, u = values[:lay.m], values[lay.m:2 * lay.m]
        rc, c_cmd = lib.command_encode(step, v, u, seq, key, epoch)
        assert rc == 0 and c_cmd == wire.encode(lay, wire.KIND_COMMAND, wire.MASTER_ID, step, seq, np.r_[v, u], key, epoch)
        rc, c_hello = lib.announce_encode(step, seq, epoch, key)
        assert rc == 0 and c_hello == wire.encode(lay, wire.KIND_ANNOUNCE, wire.MASTER_ID, step, seq, [], key, epoch)
        assert wire.decode(lay, c_hello, wire.KIND_ANNOUNCE, key)[0].epoch == epoch
    # the layout is the documented one: the epoch at byte 28, little-endian reals after the 32-byte header
    assert struct.unpack_from("<I", py_bytes, 28)[0] == epoch and len(c_hello) == 44
    assert struct.unpack_from("<d" if precision == "double" else "<f", py_bytes, 32)[0] == values[0] or np.isnan(values[0])
    assert py_bytes[:4] == b"DFEW" and py_bytes[7] == lay.dtype.itemsize


# --- the master's receive path ------------------------------------------------------------------

class Master:
    """A C master and inbox at step `k` (predicted with v = 0), fed frames."""

    def __init__(self, lib: WireLib, k: int, key: bytes | None = None, nodes: int = 2, epoch: int = 0, base: int = 0):
        self.lib, self.key, lay = lib, key, lib.layout
        n = lay.n
        self.P0 = np.eye(n) * 0.01
        self.m = lib.buffer("master")
        self.inbox = lib.buffer("inbox")
        assert lib.fn("master_init")(self.m, lib.reals(np.zeros(n)), lib.reals(self.P0), lib.reals(np.ones(lay.m))) == 0
        for _ in range(k):
            assert lib.fn("master_predict")(self.m, lib.reals(np.zeros(lay.m))) == 0
        assert lib.fn("inbox_init")(self.inbox, lib.key(key), ctypes.c_uint32(base), ctypes.c_uint32(epoch)) == 0

    def receive(self, frame: bytes) -> int:
        return self.lib.fn("master_receive")(self.m, self.inbox, frame, ctypes.c_size_t(len(frame)))

    def estimate(self):
        lay = self.lib.layout
        x, P = self.lib.reals(np.zeros(lay.n)), self.lib.reals(np.zeros(lay.n ** 2))
        assert self.lib.fn("master_estimate")(self.m, x, P) == 0
        return np.array(x[:]), np.array(P[:])


def good_packet(lay, step: int, scale: float = 1.0) -> np.ndarray:
    """A consistent packet: x near 0, P = scale * 0.005 I, prediction 0.01 I (in wire order)."""
    n, m = lay.n, lay.m
    return np.concatenate([np.zeros(m), 0.01 * np.arange(1, n + 1), (0.005 * scale * np.eye(n)).ravel(),
                           np.zeros(n), (0.01 * np.eye(n)).ravel()]).astype(lay.dtype.newbyteorder("="))


def frame(lay, step, node=0, seq=1, key=None, values=None, epoch=0, **patch):
    buf = bytearray(wire.encode(lay, wire.KIND_PACKET, node, step, seq, good_packet(lay, step) if values is None else values,
                                key, epoch))
    for offset, value in patch.get("set", []):
        buf[offset] = value
    if patch.get("fix_crc", True):
        buf[-4:] = struct.pack("<I", zlib.crc32(bytes(buf[:-4])))
    return bytes(buf)


@pytest.mark.parametrize("precision", ["double", "float"])
def test_every_rejection_cause_counted_and_state_kept(libs, precision):
    lib = libs("dc_motor_link", precision)
    lay = lib.layout
    k = 40
    ms = Master(lib, k)
    nan_values = good_packet(lay, k)
    nan_values[lay.m] = np.nan
    bad = {
        "length": frame(lay, k)[:-1],
        "crc": frame(lay, k, set=[(30, 0x55)], fix_crc=False),
        "format": frame(lay, k, set=[(0, ord("X"))]),
        "version": frame(lay, k, set=[(4, 1)]),   # the format before epochs
        "model": frame(lay, k, set=[(9, 0)]) if frame(lay, k)[9] != 0 else frame(lay, k, set=[(9, 1)]),
        "node": frame(lay, k, node=7),
        "future": frame(lay, k + 1),
        "old": frame(lay, k - lib.model.options["max_lag"] - 1),
        "nonfinite": wire.encode(lay, wire.KIND_PACKET, 0, k, 1, nan_values),
    }
    before = ms.m.raw, ms.inbox.raw
    for cause, buf in bad.items():
        assert ms.receive(buf) == wire.ERRORS[cause], cause
    assert ms.m.raw == before[0]
    counts = lib.rejected(inbox=ms.inbox)
    assert {c: v for c, v in counts.items() if v} == {c: 1 for c in bad}
    # fusion goes on with the rest: one good packet accepted, a duplicate and an older one refused
    assert ms.receive(frame(lay, k, node=1)) == 0
    assert ms.receive(frame(lay, k, node=1, seq=2)) == wire.ERRORS["duplicate"]
    assert ms.receive(frame(lay, k - 1, node=1, seq=3)) == wire.ERRORS["outdated"]
    assert lib.fn("master_fuse_inbox")(ms.m, ms.inbox) == 0
    x, P = ms.estimate()
    # independent expectation: the same packet fused directly through master_fuse with present = {0, 1}
    ref = Master(lib, k)
    pks = (lib.Packet * 2)(lib.packet(good_packet(lay, k), 0), lib.packet(good_packet(lay, k), k))
    assert lib.fn("master_fuse")(ref.m, pks, (ctypes.c_uint8 * 2)(0, 1)) == 0
    xr, Pr = ref.estimate()
    assert np.array_equal(x, xr) and np.array_equal(P, Pr)


def test_every_single_byte_error_rejected(libs):
    """CRC-32 detects every error burst of up to 32 bits, so each changed byte must be refused (the
    issue's probe: 201 of 208 corrupted packets used to be accepted) and the master left as it was."""
    lib = libs("dc_motor_link", "double")
    lay = lib.layout
    ms = Master(lib, 3)
    good = frame(lay, 3)
    before = ms.m.raw
    for i in range(len(good)):
        for flip in (0x01, 0x80, 0xFF):
            buf = bytearray(good)
            buf[i] ^= flip
            assert ms.receive(bytes(buf)) == wire.ERRORS["crc"], i
    assert ms.m.raw == before and lib.rejected(inbox=ms.inbox)["crc"] == 3 * len(good)
    assert ms.receive(good) == 0


def test_keyed_forged_and_replayed_frames_rejected(libs):
    lib = libs("dc_motor_link", "double")
    lay = lib.layout
    ms = Master(lib, 10, key=DEPLOY)
    assert ms.receive(frame(lay, 9, seq=100, key=DEPLOY)) == 0
    # a forger without the key: changes x and recomputes the CRC (valid CRC, stale tag)
    forged = bytearray(frame(lay, 10, seq=101, key=DEPLOY))
    forged[36] ^= 0x10
    forged[-4:] = struct.pack("<I", zlib.crc32(bytes(forged[:-4])))
    assert wire.peek(bytes(forged)) is not None          # the CRC is valid
    assert ms.receive(bytes(forged)) == wire.ERRORS["tag"]
    assert ms.receive(frame(lay, 10, seq=101, key=b"\x00" * 16)) == wire.ERRORS["tag"]   # another key
    assert ms.receive(frame(lay, 10, seq=101)) == wire.ERRORS["tag"]                      # untagged
    assert ms.receive(frame(lay, 10, seq=100, key=DEPLOY)) == wire.ERRORS["replay"]       # old sequence number
    assert ms.receive(frame(lay, 10, seq=101, key=DEPLOY)) == 0
    counts = lib.rejected(inbox=ms.inbox)
    assert (counts["tag"], counts["replay"]) == (3, 1)
    # the Python codec refuses the same forgery for the same reason
    with pytest.raises(wire.WireError, match="tag"):
        wire.decode(lay, bytes(forged), wire.KIND_PACKET, DEPLOY)


def test_command_receive_checks(libs):
    lib = libs("dc_motor_link", "float")
    lay = lib.layout
    rx = lib.buffer("command_rx")
    assert lib.fn("command_rx_init")(rx, lib.key(DEPLOY), ctypes.c_uint32(0)) == 0
    step, v, u = ctypes.c_uint32(), lib.reals([0.0]), lib.reals([0.0])

    def recv(buf):
        return lib.fn("command_receive")(rx, buf, ctypes.c_size_t(len(buf)), ctypes.byref(step), v, u)

    good = wire.encode(lay, wire.KIND_COMMAND, wire.MASTER_ID, 5, 9, [0.25, -2.0], DEPLOY)
    assert recv(good) == 0 and (step.value, v[0], u[0]) == (5, 0.25, -2.0)
    assert recv(good) == wire.ERRORS["replay"]
    assert recv(wire.encode(lay, wire.KIND_COMMAND, 3, 6, 10, [0.25, -2.0], DEPLOY)) == wire.ERRORS["node"]
    assert recv(wire.encode(lay, wire.KIND_COMMAND, wire.MASTER_ID, 6, 10, [0.25, -2.0])) == wire.ERRORS["tag"]
    assert recv(wire.encode(lay, wire.KIND_PACKET, wire.MASTER_ID, 6, 10, np.zeros(lay.packet_reals), DEPLOY)) \
        == wire.ERRORS["length"]
    counts = lib.rejected(rx=rx)
    assert (counts["replay"], counts["node"], counts["tag"], counts["length"]) == (1, 1, 1, 1)


# --- the programs compile cleanly under the strict flags of test_c_compile ------------------------

@pytest.mark.parametrize("cc", ["gcc", "clang"])
@pytest.mark.parametrize("precision", ["double", "float"])
def test_programs_strict_compile(libs, tmp_path, cc, precision):
    import shutil
    import subprocess

    from dfeif_codegen.net import programs
    from test_c_compile import WARN, tool

    compiler = tool(cc)
    md = libs("dc_motor_link", precision).model
    paths = programs.render_programs(md, tmp_path / "programs")
    for name in ("transport_udp.c", "node_main.c", "master_main.c", "relay.c"):
        out = subprocess.run([compiler, *WARN, "-O2", "-I", str(md.path), "-I", str(tmp_path / "programs"), "-c",
                              str(paths[name]), "-o", str(tmp_path / (name + ".o"))], capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
    assert shutil.which(compiler)


def bad_covariances(lay) -> dict[str, np.ndarray]:
    """Packets whose numbers are finite but whose covariances the master cannot take, by cause."""
    n, m = lay.n, lay.m
    at = {"P": m + n, "P_pred": m + n + n * n + n}
    out = {}
    v = good_packet(lay, 0)
    v[at["P"]] = -0.005                                   # P not positive definite
    out["covariance: P indefinite"] = v
    v = good_packet(lay, 0)
    v[at["P"] + 1] = 1e-4                                 # P(0, 1) without P(1, 0): asymmetric
    out["covariance: P asymmetric"] = v
    v = good_packet(lay, 0)
    v[at["P_pred"] + n * n - 1] = 0.0                     # P_pred singular
    out["covariance: P_pred singular"] = v
    v = good_packet(lay, 0, scale=3.0)                    # P = 0.015 I > P_pred = 0.01 I
    out["gain: P above P_pred"] = v
    return out


@pytest.mark.parametrize("precision", ["double", "float"])
def test_a_bad_packet_costs_only_its_node(libs, precision):
    """Forged packets from node 0 with finite but unusable covariances are each refused at
    receive, counted by cause, and leave node 0's genuine packet for the step acceptable; the
    fuse equals master_fuse of the two genuine packets. A packet that passes those checks but
    still cannot be fused (P = 1e-320 or 1e-44: its information overflows) is dropped at
    fuse_inbox (counted: unfused) and the other node's packet is fused alone. Before: the bad
    packet was staged, every fuse failed with ERR_SINGULAR and node 0's real packet was a
    duplicate."""
    lib = libs("dc_motor_link", precision)
    lay = lib.layout
    k = 40
    ms = Master(lib, k)
    before = ms.m.raw
    bad = bad_covariances(lay)
    for what, values in bad.items():
        assert ms.receive(frame(lay, k, values=values)) == wire.ERRORS[what.split(":")[0]], what
    assert ms.m.raw == before
    counts = {c: v for c, v in lib.rejected(inbox=ms.inbox).items() if v}
    assert counts == {"covariance": 3, "gain": 1}
    assert ms.receive(frame(lay, k, node=0)) == 0 and ms.receive(frame(lay, k, node=1)) == 0
    assert lib.fn("master_fuse_inbox")(ms.m, ms.inbox) == 0
    ref = Master(lib, k)
    pks = (lib.Packet * 2)(lib.packet(good_packet(lay, k), k), lib.packet(good_packet(lay, k), k))
    assert lib.fn("master_fuse")(ref.m, pks, (ctypes.c_uint8 * 2)(1, 1)) == 0
    assert all(np.array_equal(a, b) for a, b in zip(ms.estimate(), ref.estimate()))
    # master_fuse itself refuses each of them, and is left as it was
    for what, values in bad.items():
        one = (lib.Packet * 2)(lib.packet(values, k), lib.packet(good_packet(lay, k), k))
        state = ref.m.raw
        assert lib.fn("master_fuse")(ref.m, one, (ctypes.c_uint8 * 2)(1, 1)) == -4, what   # ERR_SINGULAR
        assert ref.m.raw == state
    # an unfusable packet passes receive, then is dropped at the fuse: node 1 fused alone
    for m_ in (ms, ref):
        assert lib.fn("master_predict")(m_.m, lib.reals(np.zeros(lay.m))) == 0
    tiny = good_packet(lay, 0, scale=(1e-320 if precision == "double" else 1e-44) / 0.005)
    assert ms.receive(frame(lay, k + 1, node=0, values=tiny)) == 0
    assert ms.receive(frame(lay, k + 1, node=1)) == 0
    assert lib.fn("master_fuse_inbox")(ms.m, ms.inbox) == 0
    assert lib.rejected(inbox=ms.inbox)["unfused"] == 1
    pks = (lib.Packet * 2)(lib.packet(good_packet(lay, k), k + 1), lib.packet(good_packet(lay, k), k + 1))
    assert lib.fn("master_fuse")(ref.m, pks, (ctypes.c_uint8 * 2)(0, 1)) == 0
    assert all(np.array_equal(a, b) for a, b in zip(ms.estimate(), ref.estimate()))


def test_gains_refuse_unstable_poles(libs):
    """lambda <= 0 places a pole at 0 or in the right half-plane: ERR_ARG, gains untouched."""
    lib = libs("dc_motor_link", "double")
    lay = lib.layout
    out = lib.reals(np.full(lay.n, 7.0))
    for lam in (-5.0, 0.0, -0.0):
        assert lib.fn("gains")(lib.reals([lam] * lay.m), out) == -1, lam
        assert list(out) == [7.0] * lay.n
    assert lib.fn("gains")(lib.reals([2.0] * lay.m), out) == 0
    assert np.allclose(list(out), [6.0, 12.0, 8.0])      # (s + 2)^3 = s^3 + 6 s^2 + 12 s + 8


def test_null_arguments_and_sequence_wrap(libs):
    """crc32(NULL, 16) and siphash24(NULL key, ...) return 0 instead of reading address 0; a keyed
    sequence number 0xFFFFFFFF is followed by 0 (serial-number arithmetic), and the older one is
    then a replay: before, 0xFFFFFFFF locked the node out for good."""
    lib = libs("dc_motor_link", "double")
    lay = lib.layout
    assert lib.fn("crc32", ctypes.c_uint32)(None, ctypes.c_size_t(16)) == 0
    assert lib.fn("siphash24", ctypes.c_uint64)(None, b"abcdefgh", ctypes.c_size_t(8)) == 0
    assert lib.fn("siphash24", ctypes.c_uint64)(lib.key(KEY), None, ctypes.c_size_t(8)) == 0
    assert lib.fn("siphash24", ctypes.c_uint64)(lib.key(KEY), None, ctypes.c_size_t(0)) == \
        siphash24(KEY, b"")
    ms = Master(lib, 40, key=DEPLOY)
    assert ms.receive(frame(lay, 38, node=0, seq=0xFFFFFFFF, key=DEPLOY)) == 0
    assert ms.receive(frame(lay, 39, node=0, seq=0, key=DEPLOY)) == 0
    assert ms.receive(frame(lay, 40, node=0, seq=0xFFFFFFFF, key=DEPLOY)) == wire.ERRORS["replay"]
    assert ms.receive(frame(lay, 40, node=0, seq=1, key=DEPLOY)) == 0


def test_global_steps_wrap(libs):
    """Global step numbers wrap at 2^32 (a master restarted with base near 2^32, or a long run): a
    master whose step 40 is global step 20 after the wrap takes a fresh frame and one 25 steps old
    from before the wrap, refuses the future, the too old and the outdated (serial-number
    arithmetic, as for sequence numbers), and fuses what it took exactly as a master at base 0
    fed the same frames relabelled; a master at its step 5 refuses a frame from before its step 0
    that lies across the wrap. Before, every frame after the wrap was refused as old."""
    lib = libs("dc_motor_link", "double")
    lay = lib.layout
    base, k = 2 ** 32 - 20, 40
    g = lambda s: (base + s) % 2 ** 32   # noqa: E731 (a master step's global number)
    ms, twin = Master(lib, k, base=base), Master(lib, k)
    took = [(k, 0, 1), (k - 25, 1, 1)]
    for step, node, seq in took:
        assert ms.receive(frame(lay, g(step), node=node, seq=seq)) == 0, step
        assert twin.receive(frame(lay, step, node=node, seq=seq)) == 0, step
    assert ms.receive(frame(lay, g(k + 1), node=0, seq=2)) == wire.ERRORS["future"]
    assert ms.receive(frame(lay, g(k - lib.model.options["max_lag"] - 1), node=0, seq=3)) == wire.ERRORS["old"]
    assert ms.receive(frame(lay, g(k - 26), node=1, seq=4)) == wire.ERRORS["outdated"]
    assert lib.fn("master_fuse_inbox")(ms.m, ms.inbox) == 0 and lib.fn("master_fuse_inbox")(twin.m, twin.inbox) == 0
    (x, P), (xt, Pt) = ms.estimate(), twin.estimate()
    assert np.array_equal(x, xt) and np.array_equal(P, Pt) and not np.array_equal(P, twin.P0)
    young = Master(lib, 5, base=2 ** 32 - 2)
    assert young.receive(frame(lay, 2 ** 32 - 3, node=0)) == wire.ERRORS["old"]    # its step -1
    assert young.receive(frame(lay, 2 ** 32 - 1, node=0)) == 0                     # its step 1


# --- epochs: replay protection across a master's restart (docs/wire.md, "Epochs") ----------------

def test_restarted_master_refuses_frames_of_an_earlier_boot(libs):
    """A keyed master in its epoch 7 (its boot counter) refuses a packet of epoch 6 (recorded
    before it restarted: a genuine tag, a sequence number it has never seen, a step in its
    window) as ERR_WIRE_EPOCH, counted, its state unchanged; inbox_join (a restarted master's
    first packet, what it initialises from) refuses it alike. Before, a restarted master had no
    memory of sequence numbers and took such a frame, or initialised from it."""
    lib = libs("dc_motor_link", "double")
    lay = lib.layout
    ms = Master(lib, 20, key=DEPLOY, epoch=7)
    old = frame(lay, 19, node=0, seq=5, key=DEPLOY, epoch=6)
    before = ms.m.raw
    assert ms.receive(old) == wire.ERRORS["epoch"] and ms.m.raw == before
    assert ms.receive(frame(lay, 19, node=0, seq=5, key=DEPLOY, epoch=8)) == wire.ERRORS["epoch"]
    pk, h = lib.Packet(), lib.Header()
    join = lib.fn("inbox_join")
    assert join(ms.inbox, old, ctypes.c_size_t(len(old)), ctypes.byref(pk), ctypes.byref(h)) == wire.ERRORS["epoch"]
    assert lib.rejected(inbox=ms.inbox)["epoch"] == 3
    new = frame(lay, 20, node=0, seq=2, key=DEPLOY, epoch=7)
    assert join(ms.inbox, new, ctypes.c_size_t(len(new)), ctypes.byref(pk), ctypes.byref(h)) == 0
    assert (h.step, h.epoch, pk.step) == (20, 7, 20)
    assert np.array_equal(lib.packet_values(pk), good_packet(lay, 20))
    assert ms.receive(new) == 0                        # join staged nothing: receive takes it
    assert ms.receive(frame(lay, 20, node=0, seq=2, key=DEPLOY, epoch=7)) == wire.ERRORS["replay"]
    # the Python codec carries the epoch the C reads
    assert wire.decode(lay, old, wire.KIND_PACKET, DEPLOY)[0].epoch == 6
    # without a key nothing is authentic, so nothing is refused for its epoch (as for sequence numbers)
    plain = Master(lib, 20, epoch=7)
    assert plain.receive(frame(lay, 19, node=1, epoch=6)) == 0


def test_node_follows_the_masters_epoch_and_refuses_older_ones(libs):
    """A node that last heard epoch 5 (kept across its own restart) refuses a recorded command of
    epoch 4; takes epoch 5's commands with fresh sequence numbers; takes the restarted master's
    announcement of epoch 6 (its sequence numbers start again) and from then refuses epoch 5's
    frames, whatever their sequence number: a replayed broadcast of an earlier boot changes
    nothing. Epochs are ordered as RFC 1982 serial numbers, so 0 follows 0xFFFFFFFF."""
    lib = libs("dc_motor_link", "float")
    lay = lib.layout
    rx = lib.buffer("command_rx")
    assert lib.fn("command_rx_init")(rx, lib.key(DEPLOY), ctypes.c_uint32(5)) == 0
    step, v, u = ctypes.c_uint32(), lib.reals([0.0]), lib.reals([0.0])

    def cmd(epoch, seq, k=3, value=0.5):
        buf = wire.encode(lay, wire.KIND_COMMAND, wire.MASTER_ID, k, seq, [value, value], DEPLOY, epoch)
        return lib.fn("command_receive")(rx, buf, ctypes.c_size_t(len(buf)), ctypes.byref(step), v, u)

    def hello(epoch, seq):
        buf = wire.encode(lay, wire.KIND_ANNOUNCE, wire.MASTER_ID, 9, seq, [], DEPLOY, epoch)
        return lib.fn("announce_receive")(rx, buf, ctypes.c_size_t(len(buf)))

    def epoch_now():
        return int.from_bytes(rx.raw[:4], "little")     # the first field: the epoch the packets carry

    assert cmd(4, 1000) == wire.ERRORS["epoch"] and epoch_now() == 5
    assert cmd(5, 10, value=0.25) == 0 and v[0] == 0.25
    assert cmd(5, 10, value=9.0) == wire.ERRORS["replay"] and v[0] == 0.25
    assert hello(6, 0) == 0 and epoch_now() == 6
    assert cmd(5, 11, value=9.0) == wire.ERRORS["epoch"] and v[0] == 0.25
    assert hello(5, 99) == wire.ERRORS["epoch"] and epoch_now() == 6
    assert cmd(6, 1, value=-1.0) == 0 and v[0] == -1.0
    assert hello(6, 1) == wire.ERRORS["replay"]
    counts = lib.rejected(rx=rx)
    assert (counts["epoch"], counts["replay"], lib.rejected(rx=rx)["other"]) == (3, 2, 0)
    wrap = lib.buffer("command_rx")
    assert lib.fn("command_rx_init")(wrap, lib.key(DEPLOY), ctypes.c_uint32(0xFFFFFFFF)) == 0
    buf = wire.encode(lay, wire.KIND_ANNOUNCE, wire.MASTER_ID, 0, 0, [], DEPLOY, 0)
    assert lib.fn("announce_receive")(wrap, buf, ctypes.c_size_t(len(buf))) == 0
