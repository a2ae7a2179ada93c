"""The plant-and-camera process of `codegen network`, and the run's clock (lock-step).

Step k: measure the true plant with every camera, send the frames, send each node's tick of
step k and the master's tick (with the reference flags), wait for the master's command of step
k (its u drives the plant; with no command in `command_timeout` the last u is held: the master
is down), integrate over one period. Prints "step k" after each step, and at a fault step named
in the config waits for a line on stdin first, so that the launcher kills and restarts processes
at exact steps. Saves its states, frames, commands and timings to an .npz at the end.

Run: python -m dfeif_codegen.net.plant CONFIG.json (written by net/run.py).
"""

from __future__ import annotations

import json
import socket
import sys
import time
from pathlib import Path

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.net import session, wire

HOST = "127.0.0.1"


def main(argv: list[str]) -> int:
    cfg = json.loads(Path(argv[0]).read_text())
    from dfeif_codegen.net.launch import Options, make_config

    run_cfg = make_config(Options(**cfg["options"]))
    s = session.setup(run_cfg)
    lay = wire.Layout(**cfg["layout"])
    key = bytes.fromhex(cfg["key"]) if cfg.get("key") else None
    K, M, m = cfg["steps"], s.nodes, s.flat.m
    plant = ex._plant(run_cfg.model, s.ts, run_cfg.substeps, s.plant_key)   # the scenario's model error
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((HOST, cfg["plant_port"]))
    relay = (HOST, cfg["relay_port"])
    faults = set(cfg.get("pause_at", []))
    timeout = float(cfg.get("command_timeout", 2.0))
    frames = np.zeros((M, K, m))
    u_log, v_log = np.zeros((K, m)), np.zeros((K, m))
    got = np.zeros(K, dtype=bool)
    zeta = np.zeros((K, s.flat.n))
    x_log = np.zeros((K + 1, len(s.x_phys0)))    # the plant's state before each step, and after the last
    t_send, t_recv = np.zeros(K), np.zeros(K)
    x, u, seq = s.x_phys0, np.zeros(m), 0
    for k in range(K):
        if k in faults:
            print(f"pause {k}", flush=True)
            sys.stdin.readline()
        zeta[k] = s.flat.phi_num(x, s.plant_p)   # the truth: the plant's own flat outputs
        x_log[k] = x
        out = []
        for i in range(M):
            frames[i, k] = s.cams[i].measure(x, s.noise[i][k])
            out.append(wire.encode(lay, wire.KIND_CAMERA, i, k, seq, frames[i, k], key))
            seq += 1
        tick = np.r_[0.0, s.ref[k]]
        for node in [*range(M), wire.MASTER_ID]:
            out.append(wire.encode(lay, wire.KIND_TICK, node, k, seq, tick, key))
            seq += 1
        for i, buf in enumerate(out):
            sock.sendto(buf, relay)
            if i == M - 1:
                t_send[k] = time.perf_counter()   # the step's last camera frame has left its camera
        deadline = time.monotonic() + timeout
        while not got[k]:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            sock.settimeout(left)
            try:
                buf = sock.recv(65536)
            except socket.timeout:
                break
            try:
                h, vals = wire.decode(lay, buf, wire.KIND_COMMAND, key)
            except wire.WireError:
                continue
            if h.step == k:
                t_recv[k] = time.perf_counter()
                v_log[k], u = vals[:m], np.array(vals[m:2 * m], dtype=float)   # (σ after it: scheduled)
                got[k] = True
        u_log[k] = u
        x = plant.step(x, u)
        x_log[k + 1] = x
        if not np.all(np.isfinite(x)):
            print(f"plant: diverged at step {k}", file=sys.stderr)
            K = k + 1
            break
        print(f"step {k}", flush=True)
    end = np.r_[1.0, np.zeros(lay.tick_reals - 1)]
    for node in [*range(M), wire.MASTER_ID]:
        sock.sendto(wire.encode(lay, wire.KIND_TICK, node, K, seq, end, key), relay)
        seq += 1
    np.savez(cfg["out"], x=x_log[:K + 1], frames=frames[:, :K], u=u_log[:K], v=v_log[:K], got=got[:K],
             t_send=t_send[:K], t_recv=t_recv[:K], zeta=zeta[:K])
    print("done", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
