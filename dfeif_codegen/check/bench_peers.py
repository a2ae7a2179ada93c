"""`codegen bench`'s comparisons: peers side by side, scaling with fitted growth, closed-loop
Monte Carlo throughput.

Peers of one node step (update with an on-time frame, then predict), each as a ratio to the
generated code: the numpy reference (`reference.node.NodeFilter`), FilterPy's `KalmanFilter`
(extra `bench`), a dense-loop C filter in the style of small embedded libraries and, for a
3-state chain with one output, the same filter written out by hand (templates/harness/peers.c.j2).
The C peers are checked against the generated filter's estimate before their numbers are used.

Scaling: synthetic flat chains (one output, relative degree n), nodes M and window N_max; growth
is the least-squares slope of log(cost) against log(size).
"""

from __future__ import annotations

import json
import re
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from dfeif_codegen import __version__
from dfeif_codegen.check import harness, target
from dfeif_codegen.codegen import render
from dfeif_codegen.errors import SetupError

CHAINS = tuple(range(2, 13))

def _predictors() -> tuple:
    """The predictors the C peers are measured with, the default first (builds from before the
    held predictor know only the Brunovsky one: None)."""
    from dfeif_codegen.codegen.options import Options

    return ("held", "brunovsky") if "predictor" in Options.__dataclass_fields__ else (None,)


PREDICTORS = _predictors()


def with_predictor(predictor) -> dict:
    """build_model's keyword for a predictor of PREDICTORS."""
    return {} if predictor is None else {"predictor": predictor}
NODES = (1, 2, 4, 8, 16)
WINDOWS = (8, 16, 32, 64, 128)


def growth(sizes, costs) -> float:
    """Exponent b of cost ~ a size^b (least squares in log-log)."""
    return float(np.polyfit(np.log(np.asarray(sizes, float)), np.log(np.asarray(costs, float)), 1)[0])


def chain_rows(ch: dict, cells) -> list[str]:
    """The scaling tables' rows, one per chain length n: n, the node step's instructions, their
    ratio to the previous n, then the cells `cells(ch[n])` of the table at hand."""
    ns = sorted(ch)
    rows = []
    for a, n in enumerate(ns):
        prev = f"{ch[n]['step'] / ch[ns[a - 1]]['step']:.2f}" if a else "-"
        rows.append(f"| {n} | {ch[n]['step']:,.0f} | {prev} | " + " | ".join(str(c) for c in cells(ch[n])) + " |")
    return rows


def chain_model(n: int) -> str:
    """A flat chain of n integrators with one measured output, as a model file."""
    states = "".join(f'[[states]]\nname = "x{i}"\n' for i in range(1, n + 1))
    f = "".join(f'x{i} = "x{i + 1}"\n' for i in range(1, n)) + f'x{n} = "0"\n'
    return (f'[model]\nname = "chain{n}"\nts = 0.01\n{states}[[inputs]]\nname = "u"\n[dynamics.f]\n{f}'
            f'[dynamics.g.u]\nx{n} = "1"\n[[outputs]]\nname = "y"\nexpr = "x1"\n[measurement.noise]\ny = 0.01\n')


# --- peers of one node step ------------------------------------------------------------------------

def render_peers(spec: str, md: harness.ModelDir, work: Path) -> Path:
    """templates/harness/peers.c.j2 for this model, in the build's precision."""
    from dfeif_codegen.symbolic import flatness, model as model_mod

    flat = flatness.derive(model_mod.load(spec))
    ts = float(md.options.get("ts") or flat.model.ts)
    lit = render.literal(md.precision)
    arr = lambda a: [lit(v) for v in np.ravel(a)]  # noqa: E731
    held = md.options.get("predictor") == "held"
    if held:
        from dfeif_codegen.symbolic import sampling

        H = sampling.held_sampling(flat, ts)
        Ac, Bc, _ = flat.canonical()
        model_c, work_size = _model_function(flat, md.precision)
        consts = {"Q": arr(H.Q(np.ones(flat.m))), "E": arr(H.E), "Psi": arr(H.Psi), "Ac": arr(Ac), "Bc": arr(Bc),
                  "G2": arr(H.G2), "L0": arr(H.L0), "model_c": model_c, "model_work": work_size}
    else:
        A, B, _ = flat.discrete(ts)
        consts = {"A": arr(A), "B": arr(B), "Q": arr(flat.process_noise(ts, np.ones(flat.m)))}
    env = render.environment(md.precision)
    work.mkdir(parents=True, exist_ok=True)
    src = work / "peers.c"
    src.write_text(env.get_template("harness/peers.c.j2").render(
        p=md.name, P=md.name.upper(), straight=flat.n == 3 and flat.m == 1, precision=md.precision, held=held,
        heads=flat.heads, angles=[int(c.angle) for c in flat.chains], **consts,
        banner=render.banner("harness/peers.c.j2", md.name, __version__)))
    return src


def _model_function(flat, precision: str) -> tuple[str, int]:
    """The model's top derivatives v = F(z) + G(z) u at the default parameters as C
    (`peer_v(z, u, v, w)`, w its work array): what a user of a filter library writes for it."""
    import casadi as ca

    from dfeif_codegen.codegen.kernels import csource
    from dfeif_codegen.symbolic import sampling

    z, u = ca.SX.sym("z", flat.n), ca.SX.sym("u", flat.m)
    top = sampling.remainder_function(flat)(z, u, ca.DM(flat.param_vector))[0]
    text, _ = csource.c_source([ca.Function("peer_v", [z, u], [top], ["z", "u"], ["v"])], "real", precision)
    text = text.replace("int peer_v(", "static int peer_v(")
    return text, int(re.search(r"real w\[(\d+)\]", text).group(1))


def _peers_program(spec: str, md: harness.ModelDir, work: Path) -> Path:
    src = render_peers(spec, md, work)
    return harness.compile_program([*md.sources(), src], work / "peers", [md.path], [harness.BIND_NOW])


def c_peers(spec: str, md: harness.ModelDir, work: Path) -> dict:
    """Instructions and wall ns per step of the generated filter and the C peers."""
    work.mkdir(parents=True, exist_ok=True)
    exe = _peers_program(spec, md, work)
    counts, finals = _callgrind(exe, work)
    ref = np.array(finals["generated"])
    for name, x in finals.items():
        if not np.allclose(x, ref, rtol=1e-9, atol=1e-12):
            raise SetupError(f"bench peer '{name}' disagrees with the generated filter: {x} vs {ref}")
    proc = subprocess.run([str(exe), "time"], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SetupError(f"peers timing failed:\n{proc.stderr[-2000:]}")
    ns = {line.split()[0]: float(line.split()[1]) for line in proc.stdout.splitlines() if line.strip()}
    return {"instructions": counts, "ns": ns}


def _callgrind(exe: Path, work: Path) -> tuple[dict, dict]:
    counts, stdout = harness.callgrind(exe, work)
    return counts, finals(stdout)


def finals(stdout: str) -> dict[str, list[float]]:
    """Each peer's final estimate, as the peers program prints it."""
    return {m.group(1): [float(v) for v in m.group(2).split()]
            for m in re.finditer(r"^final (\w+) (.*)$", stdout, re.M)}


def python_peers(model: str, steps: int = 2000, repeat: int = 5) -> dict:
    """Wall ns per step (median of `repeat`) of the numpy reference and FilterPy's KalmanFilter."""
    from dfeif_codegen.reference.node import NodeFilter
    from dfeif_codegen.symbolic import flatness, model as model_mod

    flat = flatness.derive(model_mod.load(model))
    ts, n, m = flat.model.ts, flat.n, flat.m
    A, B, C = flat.discrete(ts)
    Q, R = flat.process_noise(ts, np.ones(m)), 1e-4 * np.eye(m)
    x0, P0, v = 0.1 * np.arange(1, n + 1), 0.01 * np.eye(n), 0.5 * np.ones(m)
    zs = [0.1 + 1e-3 * (k & 7) * np.ones(m) for k in range(steps)]
    out = {}

    def timed(make, step) -> float:
        runs = []
        for _ in range(repeat):
            f = make()
            t0 = time.perf_counter()
            for z in zs:
                step(f, z)
            runs.append((time.perf_counter() - t0) / steps * 1e9)
        return statistics.median(runs)

    def ref_step(f, z):
        f.update(z, True)
        f.predict(v)

    out["numpy reference"] = timed(lambda: NodeFilter(flat, ts, np.ones(m), R, x0, P0), ref_step)
    try:
        from filterpy.kalman import KalmanFilter
    except ImportError:
        out["FilterPy KalmanFilter"] = None
    else:
        def make():
            kf = KalmanFilter(dim_x=n, dim_z=m, dim_u=m)
            kf.x, kf.P, kf.F, kf.B, kf.H, kf.Q, kf.R = x0.copy(), P0.copy(), A, B, C, Q, R
            return kf

        def fp_step(kf, z):
            kf.update(z)
            kf.predict(v)

        out["FilterPy KalmanFilter"] = timed(make, fp_step)
    return out


# --- scaling ------------------------------------------------------------------------------------------

def scaling(work: Path, callgrind) -> dict:
    """Instruction counts and code size over chains n, nodes M and windows N_max."""
    out: dict = {"chains": {}, "nodes": {}, "windows": {}}
    for n in CHAINS:
        spec = work / f"chain{n}.toml"
        spec.parent.mkdir(parents=True, exist_ok=True)
        spec.write_text(chain_model(n))
        md = harness.build_model(str(spec), work / f"chain{n}-double")
        c = callgrind(md, work / f"cg-chain{n}")
        mf = harness.build_model(str(spec), work / f"chain{n}-float", "float")
        objs = target.compile_objects(mf.sources(), work / f"obj-chain{n}", [mf.path], opt="-Os")
        text = {name: z.text for name, z in target.sizes(objs).items()}
        out["chains"][n] = {"step": c["node_update"] + c["node_predict"],
                            "kernel_text": text[f"chain{n}_kernels_filter.o"],
                            "filter_text": text[f"chain{n}_kernels_filter.o"] + text[f"chain{n}_node.o"],
                            "fusion_text": text[f"chain{n}_kernels_fusion.o"]}
    for M in NODES:
        row = {}
        for fusion in ("difference", "ci"):
            md = harness.build_model("dc_motor_link", work / f"nodes{M}-{fusion}", "double", "replay", fusion, M)
            counts = callgrind(md, work / f"cg-nodes{M}-{fusion}")
            row[fusion] = counts["master_fuse"]
            row[f"{fusion}_distinct"] = counts["master_fuse_distinct"]
        every = callgrind(md, work / f"cg-nodes{M}-ci-all", (f"{md.name.upper()}_CI_TOL=-1",))
        row["ci_every_step"] = every["master_fuse_distinct"]
        out["nodes"][M] = row
    for N in WINDOWS:
        row = {}
        for oosm in ("replay", "retrodict"):
            md = harness.build_model("dc_motor_link", work / f"win{N}-{oosm}", "double", oosm, "difference", 2, N)
            row[oosm] = callgrind(md, work / f"cg-win{N}-{oosm}")[f"node_update_delayed_lag{N}"]
        mf = harness.build_model("dc_motor_link", work / f"win{N}-sizeof", "double", "replay", "difference", 2, N)
        row["node_bytes"] = target.struct_sizes(mf, work / f"win{N}-probe")["node"]
        out["windows"][N] = row
    return out


# --- closed-loop Monte Carlo -----------------------------------------------------------------------

def monte_carlo(work: Path, seeds_c: int = 2, seeds_ref: int = 1) -> dict:
    """Runs per second of `codegen simulate` (compilation and start-up excluded: the command's own
    elapsed time of the runs) for each engine and way of running, and the 100-seed paper table's
    wall time as a user runs it (start-up and compilation included)."""
    work.mkdir(parents=True, exist_ok=True)
    cases = [("c", "1 process", seeds_c, ["--workers", "1"]), ("c", "2 processes", seeds_c, ["--workers", "2"]),
             ("reference", "1 process", seeds_ref, ["--workers", "1"]),
             ("reference", "2 processes", seeds_ref, ["--workers", "2"])]
    results = []
    cluster = None
    try:
        from dask.distributed import LocalCluster
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
        cases.append(("c", "LocalCluster, 2 workers", seeds_c, ["--scheduler", cluster.scheduler_address]))
    except ImportError:
        pass
    try:
        for engine, how, seeds, extra in cases:
            doc = _simulate(work, ["--engine", engine, "--runs", str(seeds), *extra])
            s = doc["settings"]
            results.append({"engine": engine, "how": how, "runs": s["distinct_runs"], "seconds": s["elapsed_s"],
                            "per_s": s["distinct_runs"] / s["elapsed_s"]})
    finally:
        if cluster is not None:
            cluster.close()
    t0, cpu0 = time.perf_counter(), _children_cpu()
    doc = _simulate(work, ["--runs", "100"])
    table = {"wall_s": time.perf_counter() - t0, "cpu_s": _children_cpu() - cpu0, "runs": doc["settings"]["distinct_runs"],
             "loop_s": doc["settings"]["elapsed_s"], "workers": doc["settings"]["workers"],
             "longest_task_s": doc["settings"]["longest_bound_cpu_s"]}
    return {"rates": results, "paper100": table}


def _children_cpu() -> float:
    """User + system CPU seconds of every finished child process (and theirs): the command's
    CPU time, which other load on the machine does not inflate the way it inflates wall time."""
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def _simulate(work: Path, extra: list[str]) -> dict:
    out = work / "mc.json"
    cmd = [sys.executable, "-m", "dfeif_codegen.cli", "simulate", "--quiet", "--json", str(out), *extra]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=work)
    if proc.returncode != 0:
        raise SetupError(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    return json.loads(out.read_text())
