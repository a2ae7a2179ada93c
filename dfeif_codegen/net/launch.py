"""`codegen network`'s processes: the model, the node/master programs and the relay (the seeded
network emulator, C) built, then the relay, the master, one process per node and the
plant-and-camera process started, all bound to 127.0.0.1, and their logs collected. The plant's
ticks step everyone in lock-step, so the run is deterministic and bounded; every process has an
idle timeout and the launcher a deadline. Faults (a node or the master killed and restarted at
given steps, bit errors on the uplink, forged datagrams) are options of `launch`, used by the tests.
net/run.py compares the logs with the reference.
"""

from __future__ import annotations

import dataclasses
import json
import os
import queue
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dfeif_codegen.check import harness
from dfeif_codegen.errors import ScenarioError, SetupError
from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.net import programs, session, wire

HOST = "127.0.0.1"


@dataclass(frozen=True)
class Fault:
    """Kill `who` ("master" or a node index) before step `at`, start it again before step `back`."""

    who: object
    at: int
    back: int


@dataclass
class Options:
    model: str = "dc_motor_link"
    scenario: str = "paper"
    row: int = 2
    seed: int = 0
    precision: str = "double"
    oosm: str = "replay"
    fusion: str = "difference"
    nodes: int = 2
    max_lag: int = 32
    reference: str | None = None      # None: the scenario's first (as verify runs it)
    duration: float | None = 5.0
    key: str | None = None            # 32 hex digits: keyed tags on every frame
    flip_rate: float = 0.0            # bit error rate on node -> master packets
    predictor: str | None = None      # None: held, brunovsky with retrodict (ex.Config)
    faults: tuple = ()
    step_timeout: float = 1.0         # relay: how long a master tick waits for missing packets
    command_timeout: float = 2.0      # plant: how long it waits for the master's command
    # tests: datagrams sent straight to a program at the start of a step (forged, replayed), after
    # that step's faults: inject(k) -> [("master" | node index, bytes)], called at each step of inject_at
    inject_at: tuple = ()
    inject: object = None


@dataclass
class Outcome:
    opts: Options
    setup: session.Setup
    layout: wire.Layout
    steps: int
    nodes: list[dict]
    master: dict
    relay: list[dict]
    plant: dict
    cpu: dict = field(default_factory=dict)        # process -> CPU seconds (user + system)
    returncodes: dict = field(default_factory=dict)
    stderr: dict = field(default_factory=dict)
    wall: float = 0.0


def make_config(o: Options) -> ex.Config:
    from dfeif_codegen.experiment import plan, scenario

    sc = scenario.load(o.scenario)
    sc.check_predictor(o.predictor, o.oosm)
    sc.check_model(ex._flat(o.model))
    if not 0 <= o.row < len(sc.grid):
        raise ScenarioError(f"--row {o.row}: the scenario '{sc.name}' has rows 0..{len(sc.grid) - 1}")
    scenario.check_window(sc, o.max_lag, o.nodes, rows=[o.row])
    cfg = plan.make_config(sc, o.model, o.nodes, o.max_lag, o.reference or sc.references[0], sc.grid[o.row],
                           o.oosm, o.fusion, o.seed, o.predictor)
    if o.duration is not None:
        cfg = dataclasses.replace(cfg, duration=o.duration, metrics_from=min(cfg.metrics_from, o.duration / 2))
    return cfg


def free_ports(count: int) -> list[int]:
    """Ports the kernel hands out on 127.0.0.1 (held open together so they differ)."""
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(count)]
    for s in socks:
        s.bind((HOST, 0))
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return ports


def _reals(path: Path, *arrays) -> Path:
    path.write_text(" ".join(repr(float(v)) for a in arrays for v in np.ravel(a)) + "\n")
    return path


class _Proc:
    """A child process whose CPU time is collected with wait4 (resource usage of that child only)."""

    def __init__(self, name: str, cmd: list, work: Path, **kw):
        self.name = name
        self.err = open(work / f"{name}.err", "w")
        self.p = subprocess.Popen([str(c) for c in cmd], stderr=self.err, **kw)
        self.cpu: float | None = None

    def ended(self) -> int | None:
        """The exit code if the process has ended (not reaped, so reap still collects its CPU)."""
        try:
            info = os.waitid(os.P_PID, self.p.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT)
        except ChildProcessError:
            return self.p.returncode
        if info is None:
            return None
        return -info.si_status if info.si_code in (os.CLD_KILLED, os.CLD_DUMPED) else info.si_status

    def reap(self, timeout: float) -> int | None:
        deadline = time.monotonic() + timeout
        while self.cpu is None and self.p.returncode is None:
            try:
                pid, status, ru = os.wait4(self.p.pid, os.WNOHANG)
            except ChildProcessError:      # already reaped by Popen
                break
            if pid:
                self.p.returncode = os.waitstatus_to_exitcode(status)
                self.cpu = ru.ru_utime + ru.ru_stime
            elif time.monotonic() > deadline:
                os.kill(self.p.pid, signal.SIGKILL)
                deadline = time.monotonic() + 5
            else:
                time.sleep(0.01)
        self.err.close()
        return self.p.returncode


def _write_configs(o: Options, s: session.Setup, lay: wire.Layout, work: Path, ports: list[int]) -> int:
    """The relay's and the plant's configuration files; returns the programs' idle timeout (ms)."""
    K, M = s.K, s.nodes
    relay_port, master_port, plant_port, *node_ports = ports
    rank = np.zeros((M, K), dtype=int)     # the drawn arrival order of late frames
    for i, late in enumerate(s.net.late):
        for a, lags in late.items():
            for r, lag in enumerate(lags):
                rank[i, a - lag] = r
    idle_ms = int(1000 * max(10.0, 4 * o.command_timeout, 4 * o.step_timeout))
    head = [M, K, int(1000 * o.step_timeout), 2 * idle_ms, repr(float(o.flip_rate)), o.seed + 1,
            relay_port, master_port, plant_port, *node_ports]
    (work / "relay.cfg").write_text(" ".join(map(str, head)) + "\n" + "\n".join(
        " ".join(map(str, a.ravel())) for a in (s.net.lag[:, :K], rank, s.net.up_lag[:, :K])) + "\n")
    fields = {f.name: getattr(o, f.name) for f in dataclasses.fields(o) if f.name not in ("faults", "inject")}
    plant_cfg = {"options": fields, "layout": dataclasses.asdict(lay), "key": o.key, "steps": K,
                 "plant_port": plant_port, "relay_port": relay_port, "out": str(work / "plant.npz"),
                 "command_timeout": o.command_timeout,
                 "pause_at": sorted({f.at for f in o.faults} | {f.back for f in o.faults} | set(o.inject_at))}
    session.write_json(work / "plant.json", plant_cfg)
    return idle_ms


@dataclass
class _Commands:
    """The command lines of the node and master programs (a restart gets its own log). The
    master's epoch is its boot count (`-e`); a node is started knowing the current one, as a
    firmware would keep the last epoch it heard."""

    o: Options
    s: session.Setup
    progs: programs.Programs
    work: Path
    ports: list[int]
    idle_ms: int
    epoch: int = 0

    def _tail(self, restart: int) -> list:
        key = ["-k", self.o.key] if self.o.key else []
        return ["-s", restart << 24, "-e", self.epoch, *key, "-t", str(self.idle_ms)]

    def node(self, i: int, restart: int = 0) -> list:
        s, work = self.s, self.work
        f = s.filter_start()
        conf = _reals(work / f"node{i}.cfg", f["node_x0"][0], f["node_P0"][0], s.R[i], f["q"])
        return [self.progs.node, "-i", i, "-l", f"{HOST}:{self.ports[3 + i]}", "-p", f"{HOST}:{self.ports[0]}",
                "-c", conf, "-o", work / f"node{i}.{restart}.log", *self._tail(restart)]

    def master(self, restart: int = 0) -> list:
        s, work = self.s, self.work
        f = s.filter_start()
        conf = _reals(work / "master.cfg", f["master_x0"], f["master_P0"], f["q"], s.gains)
        return [self.progs.master, "-l", f"{HOST}:{self.ports[1]}", "-p", f"{HOST}:{self.ports[0]}", "-c", conf,
                "-o", work / f"master.{restart}.log", *self._tail(restart), *(["-r"] if restart else [])]


def _lines_of(stream) -> queue.Queue:
    """The lines of a child's stdout, read by a thread ("" at its end)."""
    lines: queue.Queue = queue.Queue()

    def read() -> None:
        for x in stream:
            lines.put(x)
        lines.put("")

    threading.Thread(target=read, daemon=True).start()
    return lines


def _send_forged(datagrams, ports: list[int]) -> None:
    """Datagrams straight to the master's or a node's port, as an attacker on the network would."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        for target, data in datagrams:
            sock.sendto(data, (HOST, ports[1] if target == "master" else ports[3 + int(target)]))
            time.sleep(0.002)
    time.sleep(0.05)


def _drive(o: Options, cmds: _Commands, procs: dict, plant: _Proc, deadline: float) -> tuple[bool, dict, list]:
    """Step the plant until it says done, killing and restarting programs at the faults' steps;
    returns (finished, restarts per program, the killed processes)."""
    restarts: dict = {}
    retired: list[_Proc] = []
    assert plant.p.stdin is not None and plant.p.stdout is not None
    lines = _lines_of(plant.p.stdout)
    finished = False
    while not finished and time.monotonic() < deadline:
        try:
            line = lines.get(timeout=max(0.01, min(1.0, deadline - time.monotonic())))
        except queue.Empty:   # a program that failed (bad start-up values) ends the run now
            if any(p.ended() not in (None, 0) for p in procs.values()):
                break
            continue
        if not line:
            break
        if line.startswith("done"):
            finished = True
        elif line.startswith("pause"):
            k = int(line.split()[1])
            for f in o.faults:
                name = "master" if f.who == "master" else f"node{f.who}"
                if f.at == k:
                    procs[name].reap(0)   # SIGKILL
                    retired.append(procs.pop(name))
                if f.back == k:
                    restarts[name] = restarts.get(name, 0) + 1
                    if f.who == "master":
                        cmds.epoch = restarts[name]    # a new boot: a new epoch
                    cmd = cmds.master(restarts[name]) if f.who == "master" else cmds.node(f.who, restarts[name])
                    procs[name] = _Proc(f"{name}.{restarts[name]}", cmd, cmds.work)
                    time.sleep(0.05)
            if o.inject is not None and k in o.inject_at:     # after a restart: at the new process
                time.sleep(0.3 if any(f.back == k for f in o.faults) else 0)
                _send_forged(o.inject(k), cmds.ports)  # type: ignore[operator]
            plant.p.stdin.write("\n")
            plant.p.stdin.flush()
    plant.p.stdin.close()
    return finished, restarts, retired


def _logs(s: session.Setup, work: Path, restarts: dict) -> tuple[list, dict, list, dict]:
    """The nodes' and master's logs (the last incarnation's, and the first's as "first"), the
    relay's events and the plant's arrays."""
    n, m, M = s.filter_n, s.flat.m, s.nodes
    nodes = [session.parse_node_log(work / f"node{i}.{restarts.get(f'node{i}', 0)}.log", n) for i in range(M)]
    for i in range(M):
        nodes[i]["first"] = session.parse_node_log(work / f"node{i}.0.log", n)
    master = session.parse_master_log(work / f"master.{restarts.get('master', 0)}.log", n, m, M)
    master["first"] = session.parse_master_log(work / "master.0.log", n, m, M)
    relay = [json.loads(line) for line in (work / "relay.jsonl").read_text().splitlines() if line]
    with np.load(work / "plant.npz") as data:
        plant_data = {k: data[k] for k in data.files}
    return nodes, master, relay, plant_data


def _who_ended(early: dict, work: Path, kept: bool) -> str:
    """The processes that ended with an error before the run did, by name with exit code or
    signal and the last line each wrote to stderr (a killed node, a master that gave up)."""
    dead = [(name, rc) for name, rc in early.items() if rc]
    logs = f"see {work}/*.err" if kept else "--keep DIR keeps the logs"
    if not dead:
        return f": no process ended with an error ({logs})"
    parts = []
    for name, rc in dead:
        err = sorted(work.glob(f"{name}*.err"))
        last = (err[-1].read_text().strip().splitlines() or [""])[-1] if err else ""
        how = f"killed by signal {-rc}" if rc < 0 else f"exit {rc}"
        parts.append(f"{name} ended early ({how}{': ' + last if last else ''})")
    return ": " + "; ".join(parts) + f" ({logs})"


def launch(o: Options, work: Path, deadline: float | None = None, kept: bool = True) -> Outcome:
    """Build, start every process, run the scenario's first `duration` seconds, collect the logs
    (`kept`: `work` outlives the call, so an error may point at its logs)."""
    work.mkdir(parents=True, exist_ok=True)
    cfg = make_config(o)
    s = session.setup(cfg)
    md = harness.build_model(o.model, work / "gen", o.precision, o.oosm, o.fusion, o.nodes, o.max_lag, cfg.ts,
                             cfg.predictor, cfg.disturbance, cfg.gate or None)
    progs = programs.build_programs(md, work / "programs")
    lay = wire.Layout.of_folder(md.path)
    ports = free_ports(3 + s.nodes)
    cmds = _Commands(o, s, progs, work, ports, _write_configs(o, s, lay, work, ports))
    t0 = time.monotonic()
    procs = {"relay": _Proc("relay", [progs.relay, work / "relay.cfg", work / "relay.jsonl"], work)}
    time.sleep(0.2)
    procs["master"] = _Proc("master", cmds.master(), work)
    for i in range(s.nodes):
        procs[f"node{i}"] = _Proc(f"node{i}", cmds.node(i), work)
    time.sleep(0.1)
    plant = _Proc("plant", [sys.executable, "-m", "dfeif_codegen.net.plant", work / "plant.json"], work,
                  stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    finished, restarts, retired = _drive(o, cmds, procs, plant, t0 + (deadline or 60 + 0.2 * s.K))
    early = {} if finished else {name: pr.ended() for name, pr in procs.items()}
    rcs = {"plant": plant.reap(5 if finished else 0)}
    for name, pr in procs.items():
        rcs[name] = pr.reap(10 if finished else 0)
    wall = time.monotonic() - t0
    if not finished:
        stop = "stopped early" if any(early.values()) else "did not finish in time"
        raise SetupError(f"the run {stop}" + _who_ended(early, work, kept))
    nodes, master, relay, plant_data = _logs(s, work, restarts)
    cpu = {name: pr.cpu for name, pr in procs.items()}
    errs = {pr.name: Path(pr.err.name).read_text() for pr in [*procs.values(), *retired, plant]}
    return Outcome(o, s, lay, len(plant_data["u"]), nodes, master, relay, plant_data, cpu, rcs, errs, wall)
