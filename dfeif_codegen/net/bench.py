"""`codegen network --bench`: the wire's figures for BENCHMARKS.md, measured on this machine.

- wire sizes per built-in model and precision (from the format: header + reals + tag + CRC);
- master throughput: a Python sender streams pre-encoded packets of M nodes and the tick of each
  step straight to the master program over loopback (at most `window` steps ahead of the commands
  it gets back); datagrams and packets per second over the whole stream. The sender is Python, so
  this is a lower bound of what the master sustains; its CPU time (wait4) per datagram gives the
  rate one core could take (syscalls included);
- tick -> command round trip at the master (window 1): the master's share of the latency;
- a `codegen network` run (5 s simulated): latency from the step's last camera frame sent to the
  command received, through the relay (median and 99th percentile; the emulated delays are whole
  steps, not wall time, so none is included), CPU seconds per process, the C's busy time per step.
"""

from __future__ import annotations

import os
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from dfeif_codegen.check import harness
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.net import launch, programs, run, wire

MODELS = ("dc_motor_link", "two_link_arm")
MARK = "<!-- codegen network --bench -->"


def wire_sizes() -> list[tuple]:
    rows = []
    for model in MODELS:
        flat = ex._flat(model)
        for precision in ("double", "float"):
            lay = wire.Layout(flat.n, flat.m, precision, "0" * 64)
            rows.append((model, precision, lay.size(lay.packet_reals), lay.size(lay.command_reals),
                         lay.size(lay.m), lay.size(lay.tick_reals)))
    return rows


def master_throughput(model: str, work: Path, steps: int = 20000, window: int = 32, key: str | None = None,
                      nodes: int = 2) -> dict:
    md = harness.build_model(model, work / "gen", nodes=nodes)
    progs = programs.build_programs(md, work / "programs")
    lay = wire.Layout.of_folder(md.path)
    n, m = lay.n, lay.m
    kb = bytes.fromhex(key) if key else None
    pkt = np.concatenate([np.zeros(m), np.zeros(n), (0.005 * np.eye(n)).ravel(), np.zeros(n), (0.01 * np.eye(n)).ravel()])
    gains = np.ones(n)
    conf = work / "master.cfg"
    conf.write_text(" ".join(repr(float(v)) for v in np.r_[np.zeros(n), np.eye(n).ravel() * 0.01, np.ones(m), gains]))
    mport, bport = launch.free_ports(2)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    sock.bind((launch.HOST, bport))
    proc = subprocess.Popen([str(progs.master), "-l", f"{launch.HOST}:{mport}", "-p", f"{launch.HOST}:{bport}", "-c", str(conf),
                             "-o", str(work / "master.log"), "-t", "5000", *(["-k", key] if key else [])],
                            stderr=subprocess.DEVNULL)
    try:
        frames = [[wire.encode(lay, wire.KIND_PACKET, i, k, k, pkt, kb) for i in range(nodes)] +
                  [wire.encode(lay, wire.KIND_TICK, wire.MASTER_ID, k, k, np.zeros(lay.tick_reals), kb)]
                  for k in range(steps)]
        time.sleep(0.3)
        to = (launch.HOST, mport)

        def stream(first: int, count: int, win: int) -> tuple[float, list[float]]:
            sock.settimeout(5.0)
            got, sent_at, rtt = first, {}, []
            start = time.perf_counter()
            for k in range(first, first + count):
                while k - got >= win:
                    buf = sock.recv(4096)
                    got = wire.peek(buf).step + 1
                    if got - 1 in sent_at:
                        rtt.append(time.perf_counter() - sent_at[got - 1])
                for f in frames[k][:-1]:
                    sock.sendto(f, to)
                sent_at[k] = time.perf_counter()
                sock.sendto(frames[k][-1], to)
            while got < first + count:
                got = wire.peek(sock.recv(4096)).step + 1
                if got - 1 in sent_at:
                    rtt.append(time.perf_counter() - sent_at[got - 1])
            return time.perf_counter() - start, rtt

        lat_steps = min(2000, steps // 4)
        _, rtt = stream(0, lat_steps, 1)
        elapsed, _ = stream(lat_steps, steps - lat_steps, window)
        sock.sendto(wire.encode(lay, wire.KIND_TICK, wire.MASTER_ID, steps, steps, np.r_[1.0, np.zeros(lay.tick_reals - 1)], kb), to)
        cpu = None
        deadline = time.monotonic() + 10
        while cpu is None and time.monotonic() < deadline:
            pid, _, ru = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                cpu = ru.ru_utime + ru.ru_stime
                proc.returncode = 0
            else:
                time.sleep(0.01)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        sock.close()
    counters = {}
    for line in (work / "master.log").read_text().splitlines():
        f = line.split()
        if f and f[0] == "R":
            counters = {f[i]: int(f[i + 1]) for i in range(1, len(f) - 1, 2)}
    count = steps - lat_steps
    return {"model": model, "keyed": bool(key), "steps": count, "seconds": elapsed,
            "datagrams_per_s": count * (nodes + 1) / elapsed, "packets_per_s": count * nodes / elapsed,
            "accepted": counters.get("accepted", 0), "expected": steps * nodes,
            "master_cpu_us_per_datagram": (cpu or float("nan")) * 1e6 / (steps * (nodes + 1) + 1),
            "tick_rtt_median_us": float(np.median(rtt) * 1e6), "tick_rtt_p99_us": float(np.percentile(rtt, 99) * 1e6)}


def measure(work: Path) -> dict:
    out = {"sizes": wire_sizes(), "throughput": [], "network": None, "cpus": os.cpu_count(),
           "load": os.getloadavg()[0]}
    for model in MODELS:
        for key in (None, "00112233445566778899aabbccddeeff"):
            out["throughput"].append(master_throughput(model, work / f"tp-{model}-{bool(key)}", key=key))
    from dfeif_codegen.net import fuzz

    md = harness.build_model("dc_motor_link", work / "fuzz-gen")
    corpus = Path(__file__).resolve().parents[2] / "tests" / "fuzz_corpus"
    seeds = work / "fuzz-seeds"
    seeds.mkdir()
    for name, data in fuzz.seed_corpus(wire.Layout.of_folder(md.path), 32).items():
        (seeds / name).write_bytes(data)
    res = fuzz.run(fuzz.build(md, work / "fuzz"), corpus if corpus.is_dir() else seeds, work / "fuzz-work", 60)
    out["fuzz"] = {"executions": res.executions, "seconds": res.seconds, "findings": len(res.findings)}
    res = launch.launch(launch.Options(duration=5.0), work / "net")
    errors, _ = run.compare(res)
    out["network"] = {**run.figures(res), "equal": all(e.ok for e in errors)}
    return out


def markdown(fig: dict) -> str:
    lines = [MARK, "## Network (`codegen network --bench`)", "",
             f"Measured on this machine ({machine(fig)}; loopback UDP, 127.0.0.1 only).", "",
             f"### Wire sizes (bytes per frame: {wire.HEADER.size}-byte header, reals, 8-byte tag field, CRC-32)", "",
             "| model | precision | packet | command | camera | tick |", "|---|---|---:|---:|---:|---:|"]
    lines += [f"| {r[0]} | {r[1]} | {r[2]} | {r[3]} | {r[4]} | {r[5]} |" for r in fig["sizes"]]
    lines += ["", "### Master throughput (Python sender, so a lower bound; target >= 20,000 packets/s)", "",
              "| model | tag | packets/s | datagrams/s | accepted | master CPU per datagram | capacity (1 core) "
              "| tick -> command median | p99 |",
              "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for t in fig["throughput"]:
        lines.append(f"| {t['model']} | {'SipHash-2-4' if t['keyed'] else 'CRC only'} | {t['packets_per_s']:,.0f} | "
                     f"{t['datagrams_per_s']:,.0f} | {t['accepted']}/{t['expected']} | {t['master_cpu_us_per_datagram']:.1f} us | "
                     f"{1e6 / t['master_cpu_us_per_datagram']:,.0f} datagrams/s | {t['tick_rtt_median_us']:.0f} us | "
                     f"{t['tick_rtt_p99_us']:.0f} us |")
    nw = fig["network"]
    cpu = ", ".join(f"{k} {v:.3f} s" for k, v in nw["cpu_s"].items())
    lines += ["", f"### `codegen network` (dc_motor_link, double, paper row 2, {nw['steps']} steps, "
              f"{nw['wall_s']:.1f} s wall; equal to the reference: {'yes' if nw['equal'] else 'NO'})", "",
              f"- frame -> command latency (the step's last camera frame sent by the plant to the command "
              f"received, through the relay: three relay traversals on the path): median {nw['latency_median_us']:.0f} us, 99th percentile "
              f"{nw['latency_p99_us']:.0f} us (targets 200 us and 2 ms)",
              f"- C busy time per step: master {nw['master_busy_us_per_step']:.1f} us, nodes "
              + ", ".join(f"{b:.1f} us" for b in nw["node_busy_us_per_step"]),
              f"- CPU per process over the run: {cpu}", f"- datagrams through the relay: {nw['datagrams']}", ""]
    lines += missed(fig)
    fz = fig.get("fuzz")
    if fz:
        lines += ["### Fuzzing (libFuzzer, ASan + UBSan, dc_motor_link double)", "",
                  f"{fz['executions']:,} executions in {fz['seconds']:.0f} s over decode, master receive/fuse and "
                  f"the node API; {fz['findings']} findings.", ""]
    return "\n".join(lines)


def machine(fig: dict) -> str:
    """What was seen of the machine at the start of the measurement, nothing assumed."""
    if fig.get("cpus") is None:
        return "processor count not recorded"
    load = f", 1-minute load average {fig['load']:.2f} at the start" if fig.get("load") is not None else ""
    return f"{fig['cpus']} processors seen by the OS{load}"


def missed(fig: dict) -> list[str]:
    """Where the latency targets (200 us median, 2 ms p99) are missed, split by what was measured:
    the master's own round trip and the C's busy time against the rest of the path."""
    nw = fig["network"]
    med, p99 = nw["latency_median_us"], nw["latency_p99_us"]
    if not (med > 200 or p99 > 2000):
        return ["Both latency targets are met.", ""]
    own = [t["tick_rtt_median_us"] for t in fig["throughput"] if t["model"] == "dc_motor_link" and not t["keyed"]]
    busy = nw["master_busy_us_per_step"] + sum(nw["node_busy_us_per_step"])
    text = f"Targets missed: median {med:.0f} us (target 200 us), 99th percentile {p99:.0f} us (target 2 ms). "
    if own:
        text += (f"Of the median, the master's own tick -> command round trip is {own[0]:.0f} us (table above) and "
                 f"the C busy time of all programs {busy:.1f} us per step; the remaining {max(med - own[0] - busy, 0.0):.0f} us "
                 "is spent on the other loopback hops of the path (plant, relay, node, relay, master, relay, plant). ")
    text += f"The 99th percentile is {p99 / med:.1f} times the median." if med > 0 else ""
    return [text, ""]


def write(path: Path, fig: dict) -> None:
    """Replace the network section of BENCHMARKS.md (everything from MARK on), keep the rest."""
    old = path.read_text() if path.exists() else "# Benchmarks\n"
    head = old.split(MARK)[0].rstrip() + "\n\n"
    path.write_text(head + markdown(fig))


def run_bench(out: Path) -> dict:
    """Measure, then write the network section into `out`: a new file or a report of ours
    (checked before measuring, as `codegen bench --out`)."""
    from dfeif_codegen.check.bench import check_out

    check_out(str(out), flag="--bench", command="bench or codegen network --bench")
    with tempfile.TemporaryDirectory(prefix="codegen-network-bench-") as tmp:
        fig = measure(Path(tmp))
    write(out, fig)
    return fig
