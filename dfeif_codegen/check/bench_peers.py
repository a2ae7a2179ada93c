"""`codegen bench`'s comparisons: peers side by side and scaling with fitted growth, what each
compiles (the run step measures it, check/bench_measure.py) and how its figures are checked and
shaped (the compare step).

Peers of one node step (update with an on-time frame, then predict), each as a ratio to the
generated code: the numpy reference (`reference.node.NodeFilter`), FilterPy's `KalmanFilter`
(extra `bench`), a dense-loop C filter in the style of small embedded libraries and, for a
3-state chain with one output, the same filter written out by hand (templates/harness/peers.c.j2).
The C peers are checked against the generated filter's estimate before their numbers are used.

Scaling: synthetic flat chains (one output, relative degree n), nodes M and window N_max; growth
is the least-squares slope of log(cost) against log(size).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from dfeif_codegen import __version__
from dfeif_codegen.check import bench_programs, harness, target
from dfeif_codegen.check.bench_measure import Measure
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
        model_c, work_size, n_trig = _model_function(flat, md.precision)
        step = H.sub or H   # the mean's ETD2RK step (one of the model's mean_substeps)
        consts = {"Q": arr(H.Q(np.ones(flat.m))), "E": arr(H.E), "Psi": arr(step.Psi), "Ac": arr(Ac), "Bc": arr(Bc),
                  "G2": arr(step.G2), "L0": arr(H.L0), "model_c": model_c, "model_work": work_size, "n_trig": n_trig,
                  "steps": H.steps}
    else:
        A, B, _ = flat.discrete(ts)
        consts = {"A": arr(A), "B": arr(B), "Q": arr(flat.process_noise(ts, np.ones(flat.m))), "steps": 1}
    env = render.environment(md.precision)
    work.mkdir(parents=True, exist_ok=True)
    src = work / "peers.c"
    src.write_text(env.get_template("harness/peers.c.j2").render(
        p=md.name, P=md.name.upper(), straight=flat.n == 3 and flat.m == 1, precision=md.precision, held=held,
        heads=flat.heads, angles=[int(c.angle) for c in flat.chains], input_nominal=md.input_nominal, **consts,
        banner=render.banner("harness/peers.c.j2", md.name, __version__)))
    return src


def _model_function(flat, precision: str) -> tuple[str, int, int]:
    """The model's top derivatives v = F(z) + G(z) u at the default parameters as C: what a user
    of a filter library writes for it, in the two forms the ETD2RK step calls, the second
    stage's sines and cosines carried from the first's as the generated filter carries them
    (sampling.TrigCarry), so the peers run the same arithmetic: `peer_v(z, u, v, T, w)` also
    returns T (sin and cos of each argument at z), `peer_v2(z, a, u, T, v, w)` is v at a. Also
    the work size and T's length."""
    import casadi as ca

    from dfeif_codegen.codegen.kernels import csource
    from dfeif_codegen.symbolic import sampling

    z, a, u, p = ca.SX.sym("z", flat.n), ca.SX.sym("a", flat.n), ca.SX.sym("u", flat.m), ca.DM(flat.param_vector)
    first = sampling.TrigCarry(flat.zeta)
    v0 = sampling.remainder_sx(flat, z, u, p, first.first)
    T = ca.SX.sym("T", max(1, 2 * len(first.at_start)))     # one unused entry without sines: no T[0] in C
    v1 = sampling.remainder_sx(flat, a, u, p, first.starting_from(T).second)
    trig = first.values() if first.at_start else ca.SX.zeros(1)
    text, _ = csource.c_source([ca.Function("peer_v", [z, u], [v0, trig], ["z", "u"], ["v", "T"]),
                                ca.Function("peer_v2", [z, a, u, T], [v1], ["z", "a", "u", "T"], ["v"])],
                               "real", precision)
    text = text.replace("int peer_v(", "static int peer_v(").replace("int peer_v2(", "static int peer_v2(")
    work = max(int(n) for n in re.findall(r"real w\[(\d+)\]", text))
    return text, work, T.numel()


def peers(spec: str, md: harness.ModelDir, work: Path) -> Measure:
    """The peers program (the generated filter and the C peers) compiled for the host."""
    return Measure("c-peers", (bench_programs.host(md, render_peers(spec, md, work), work),), work)


def finals(stdout: str) -> dict[str, list[float]]:
    """Each peer's final estimate, as the peers program prints it."""
    return {m.group(1): [float(v) for v in m.group(2).split()]
            for m in re.finditer(r"^final (\w+) (.*)$", stdout, re.M)}


def check_finals(stdout: str, rtol: float, atol: float, where: str = "") -> None:
    """Raise unless every peer ends where the generated filter ends."""
    got = finals(stdout)
    ref = np.array(got["generated"])
    for name, x in got.items():
        if not np.allclose(x, ref, rtol=rtol, atol=atol):
            raise SetupError(f"bench peer '{name}'{where} disagrees with the generated filter: {x} vs {ref}")


def checked(ran: dict) -> dict:
    """Host peers' figures once their estimates agree (double: 1e-9 relative, round-off of 200 steps)."""
    check_finals(ran["stdout"], 1e-9, 1e-12)
    return {"instructions": ran["instructions"], "ns": ran["ns"]}


# --- scaling ------------------------------------------------------------------------------------------

def chain_spec(n: int, work: Path) -> str:
    """chain_model(n) written to a file in `work`."""
    spec = work / f"chain{n}.toml"
    spec.parent.mkdir(parents=True, exist_ok=True)
    spec.write_text(chain_model(n))
    return str(spec)


def _callgrind(md: harness.ModelDir, work: Path, defines: tuple[str, ...] = ()) -> Measure:
    return Measure("callgrind", (bench_programs.host_template(md, "bench", work, defines),), work)


def compile_scaling(work: Path) -> dict:
    """The host programs and target objects over chains n, nodes M and windows N_max."""
    out: dict = {"chains": {}, "nodes": {}, "windows": {}}
    for n in CHAINS:
        spec = chain_spec(n, work)
        md = harness.build_model(spec, work / f"chain{n}-double")
        mf = harness.build_model(spec, work / f"chain{n}-float", "float")
        out["chains"][n] = {"counts": _callgrind(md, work / f"cg-chain{n}"),
                            "sizes": Measure("sizes", (bench_programs.objects(mf, work / f"obj-chain{n}"),))}
    for M in NODES:
        row = {}
        for fusion in ("difference", "ci"):
            md = harness.build_model("dc_motor_link", work / f"nodes{M}-{fusion}", "double", "replay", fusion, M)
            row[fusion] = _callgrind(md, work / f"cg-nodes{M}-{fusion}")
        row["ci_every_step"] = _callgrind(md, work / f"cg-nodes{M}-ci-all", (f"{md.name.upper()}_CI_TOL=-1",))
        out["nodes"][M] = row
    for N in WINDOWS:
        row = {}
        for oosm in ("replay", "retrodict"):
            md = harness.build_model("dc_motor_link", work / f"win{N}-{oosm}", "double", oosm, "difference", 2, N)
            row[oosm] = _callgrind(md, work / f"cg-win{N}-{oosm}")
        mf = harness.build_model("dc_motor_link", work / f"win{N}-sizeof", "double", "replay", "difference", 2, N)
        row["node_bytes"] = Measure("sizeof", (target.sizeof_probe(mf, work / f"win{N}-probe"),))
        out["windows"][N] = row
    return out


def scaling_rows(ran: dict) -> dict:
    """The scaling figures the report shows, from what compile_scaling's programs measured."""
    out: dict = {"chains": {}, "nodes": {}, "windows": {}}
    for n, r in ran["chains"].items():
        c, text = r["counts"], {name: z.text for name, z in r["sizes"].items()}
        out["chains"][n] = {"step": c["node_update"] + c["node_predict"],
                            "kernel_text": text[f"chain{n}_kernels_filter.o"],
                            "filter_text": text[f"chain{n}_kernels_filter.o"] + text[f"chain{n}_node.o"],
                            "fusion_text": text[f"chain{n}_kernels_fusion.o"]}
    for M, r in ran["nodes"].items():
        out["nodes"][M] = {"difference": r["difference"]["master_fuse"],
                           "difference_distinct": r["difference"]["master_fuse_distinct"],
                           "ci": r["ci"]["master_fuse"], "ci_distinct": r["ci"]["master_fuse_distinct"],
                           "ci_every_step": r["ci_every_step"]["master_fuse_distinct"]}
    for N, r in ran["windows"].items():
        out["windows"][N] = {oosm: r[oosm][f"node_update_delayed_lag{N}"] for oosm in ("replay", "retrodict")}
        out["windows"][N]["node_bytes"] = r["node_bytes"]["node"]
    return out
