"""The network emulator of `codegen network`: one UDP relay process on 127.0.0.1 between the
plant-and-camera process, the nodes and the master, applying the scenario's seeded delays and
drops per datagram, in whole steps (lock-step: the plant's ticks are the clock).

Camera frame (node i, step s) with drawn lag L: dropped, delivered before node i's tick of step
s + L (late frames in the drawn order), or at once when L = 0. Node packet (i, s) with drawn
uplink lag L: dropped or delivered before the master's tick of step s + L (or of the next step
the relay releases, if it came after that tick), optionally with bit errors at a given rate.
The master's tick of step k is held until every node's packet of step k has arrived, or
`step_timeout` has passed (a dead or slow node). Commands go to every node and the plant at once.
Every datagram's receipt ("send") and forwarding ("arrive", with the step it arrives at) is logged.

Run: python -m dfeif_codegen.net.relay CONFIG.json (written by net/run.py).
"""

from __future__ import annotations

import json
import select
import socket
import sys
import time
from pathlib import Path

import numpy as np

from dfeif_codegen.net import wire

KINDS = {wire.KIND_PACKET: "packet", wire.KIND_COMMAND: "command", wire.KIND_CAMERA: "camera",
         wire.KIND_TICK: "tick"}
HOST = "127.0.0.1"


class Relay:
    def __init__(self, cfg: dict):
        self.cfg = cfg
        self.nodes = cfg["nodes"]
        self.lag = np.array(cfg["lag"], dtype=int)          # (M, K) camera links
        self.order = [{int(a): lags for a, lags in d.items()} for d in cfg["late_order"]]
        self.up_lag = np.array(cfg["up_lag"], dtype=int)    # (M, K) uplinks
        self.K = self.lag.shape[1]
        self.flip_rate = float(cfg.get("flip_rate", 0.0))
        self.rng = np.random.default_rng(cfg.get("flip_seed", 0))
        self.step_timeout = float(cfg.get("step_timeout", 1.0))
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        self.sock.bind((HOST, cfg["relay_port"]))
        self.sock.setblocking(False)
        self.to_node = [(HOST, p) for p in cfg["node_ports"]]
        self.to_master, self.to_plant = (HOST, cfg["master_port"]), (HOST, cfg["plant_port"])
        self.frames: dict[tuple[int, int], list] = {}       # (node, step) -> [(order, src, bytes)]
        self.packets: dict[int, list] = {}                  # master step -> [(node, src, bytes, corrupt)]
        self.got: dict[int, set] = {}                       # step -> nodes whose packet arrived
        self.master_ticks: dict[int, tuple[bytes, float]] = {}
        self.released = -1                                  # last master tick released
        self.log: list[dict] = []
        self.t0 = time.monotonic()

    def note(self, ev: str, h: wire.Header, **kw) -> None:
        self.log.append({"t": round(time.monotonic() - self.t0, 6), "ev": ev, "kind": KINDS.get(h.kind, "?"),
                         "node": h.node, "step": h.step, "seq": h.seq, **kw})

    def send(self, buf: bytes, to, h: wire.Header, at: int | None = None, **kw) -> None:
        self.sock.sendto(buf, to)
        self.note("arrive", h, at=h.step if at is None else at, **kw)

    def release(self, k: int) -> None:
        """Packets due at master step k, then the master's tick k."""
        for node, src, buf, corrupt in self.packets.pop(k, []):
            self.send(buf, self.to_master, wire.Header(wire.KIND_PACKET, node, src, 0), at=k, corrupt=corrupt)
        buf, _ = self.master_ticks.pop(k)
        self.send(buf, self.to_master, wire.peek(buf))
        self.released = k
        self.got.pop(k, None)

    def poll_master(self) -> None:
        while self.master_ticks:
            k = min(self.master_ticks)
            held = self.master_ticks[k][1]
            if len(self.got.get(k, ())) < self.nodes and time.monotonic() - held < self.step_timeout:
                return
            self.release(k)

    def handle(self, buf: bytes) -> bool:
        h = wire.peek(buf)
        if h is None:
            self.log.append({"t": time.monotonic() - self.t0, "ev": "garbage", "bytes": len(buf)})
            return True
        self.note("send", h)
        if h.kind == wire.KIND_CAMERA:
            lag = int(self.lag[h.node, h.step]) if h.step < self.K else 0
            if lag < 0:
                self.note("drop", h)
            elif lag == 0:
                self.send(buf, self.to_node[h.node], h)
            else:
                a = h.step + lag
                rank = self.order[h.node].get(a, []).index(lag) if lag in self.order[h.node].get(a, []) else 0
                self.frames.setdefault((h.node, a), []).append((rank, h.step, buf))
        elif h.kind == wire.KIND_TICK:
            end = wire.tick_is_end(buf)
            if h.node == wire.MASTER_ID:
                if end:
                    for k in sorted(self.master_ticks):
                        self.release(k)
                    self.send(buf, self.to_master, h)
                else:
                    self.master_ticks[h.step] = (buf, time.monotonic())
            else:
                for rank, src, fb in sorted(self.frames.pop((h.node, h.step), []), key=lambda r: r[0]):
                    self.send(fb, self.to_node[h.node], wire.Header(wire.KIND_CAMERA, h.node, src, 0), at=h.step)
                self.send(buf, self.to_node[h.node], h)
            return not (end and h.node == wire.MASTER_ID)
        elif h.kind == wire.KIND_PACKET:
            self.got.setdefault(h.step, set()).add(h.node)
            lag = int(self.up_lag[h.node, h.step]) if h.node < self.nodes and h.step < self.K else 0
            if lag < 0:
                self.note("drop", h)
            else:
                due = max(h.step + lag, self.released + 1)
                corrupt = False
                if self.flip_rate > 0:
                    bad = wire.corrupt(buf, self.rng, self.flip_rate)
                    corrupt, buf = bad != buf, bad
                self.packets.setdefault(due, []).append((h.node, h.step, buf, corrupt))
        elif h.kind == wire.KIND_COMMAND:
            for to in self.to_node:
                self.send(buf, to, h)
            self.send(buf, self.to_plant, h)
        return True

    def run(self) -> int:
        deadline = time.monotonic() + float(self.cfg.get("max_seconds", 600))
        idle = float(self.cfg.get("idle_seconds", 20))
        last = time.monotonic() + 5 * idle     # start-up grace: the plant derives the model first
        running = True
        while running and time.monotonic() < deadline:
            ready, _, _ = select.select([self.sock], [], [], 0.005 if self.master_ticks else 0.2)
            while ready and running:          # drain what is queued before the next select
                try:
                    buf = self.sock.recv(65536)
                except BlockingIOError:
                    break
                last = time.monotonic()
                running = self.handle(buf)
                self.poll_master()
            if not ready and time.monotonic() - last > idle:
                print("relay: nothing received in time, exiting", file=sys.stderr)
                break
            self.poll_master()
        Path(self.cfg["log"]).write_text("\n".join(json.dumps(e) for e in self.log) + "\n")
        return 0 if not running else 3


def main(argv: list[str]) -> int:
    return Relay(json.loads(Path(argv[0]).read_text())).run()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
