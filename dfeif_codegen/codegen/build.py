"""`codegen build`: model -> flat system -> CasADi kernels -> rendered C module in <out>/<model>.

Why atomic: a firmware tree that includes generated/<model> must never see half a module. Files
are rendered in memory and only then handed to codegen/output.py, which swaps them in by rename;
any failure (bad model, bad option, template error) leaves the previous output as it was.
Why deterministic: no timestamps or paths, stable ordering, so a rebuild is byte-identical and the
committed generated/ can be checked against a fresh build.
"""

from __future__ import annotations

import functools
import json
import math
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

import jinja2
import numpy as np

from dfeif_codegen import __version__, budget
from dfeif_codegen.errors import CodegenError
from dfeif_codegen.symbolic import flatness, model
from dfeif_codegen.symbolic.sampling import nominal_point
from dfeif_codegen.codegen import centring, kernels, layout, provenance, render
from dfeif_codegen.codegen.kernels import csource
from dfeif_codegen.constants import CHANNEL_RESTART_RATIO, CI_REGULARISER, CI_TOLERANCE, ci_iterations
from dfeif_codegen.codegen.options import BuildError, Options
from dfeif_codegen.codegen.output import check_target, write_atomic

GROUP_DOCS = {
    "filter": "Node filter kernels (the master reuses predict)",
    "fusion": "Master fusion kernels",
    "control": "Flatness-based controller kernel: u and v = F + G u from the estimate, flags and gains",
}


@dataclass(frozen=True)
class GeneratedModule:
    """A folder written by `build`: where it is, the model's C prefix and the options baked in."""

    path: Path
    name: str
    options: Options
    files: tuple[str, ...]
    n: int = 0          # the filters' state dimension (NX), as the header defines it


def _comment(text: str) -> str:
    """Safe inside a C block comment and on one line."""
    return " ".join(str(text).replace("*/", "* /").replace("/*", "/ *").split())


def context(flat, opts: Options, model_arg: str | None = None) -> dict:
    """Everything the templates need, computed once. `model_arg`: the model as the banners'
    regenerate command names it (model_argument; default the model's name, a built-in's)."""
    m = flat.model
    p = m.name
    ks = kernels.build(flat, opts, p)
    real_c = "float" if opts.precision == "float" else "double"
    dist = opts.disturbance_states()
    nd = 0 if dist is None else dist.order * flat.m
    disturbances = [f"d_{flat.zeta[h]}" for h in flat.heads] if nd else []
    kernel_code: dict[str, tuple[str, str]] = {}
    kernel_list: list[dict] = []
    for group, functions in ks.groups.items():
        code, infos = csource.c_source(functions, f"{p}_real", opts.precision, f"{p}_{group}",
                                       local_work=group in ks.local_work, wrappers=ks.wrappers,
                                       loops=ks.loops, own_work=ks.own_work)
        looped = [k.name[len(p) + 6:] for k in infos if k.name in ks.loops]
        kernel_code[group] = (code.rstrip("\n"), f"{GROUP_DOCS[group]}: "
                                    + ", ".join(k.name[len(p) + 6:] for k in infos) + "."
                                    + (f" Printed as C loops (over static parts, if any): {', '.join(looped)}." if looped else ""))
        kernel_list += [{"name": k.name, "macro": k.name.upper(), "sz_w": k.sz_w, "local_work": k.local_work,
                         "signature": csource.wrap_comment(_comment(k.signature)),
                         "prototype": layout.pack(f"int {k.name}(", k.parameters(f"{p}_real", k.name.upper() + "_SZ_W"),
                                                 ");")}
                        for k in infos]
    names = render.file_names(p, list(ks.groups))
    steps = centring.centre_steps(m)
    return {
        "p": p, "P": p.upper(), "real": f"{p}_real", "real_c": real_c, "model_arg": model_arg or p,
        "description": _comment(m.description or p),
        "zeta_names": [_comment(z) for z in flat.zeta] + disturbances + [f"rate of {d}" for d in disturbances[:nd - flat.m]],
        # n: the filters' state (the canonical one, nz, then nd disturbance states); nq densities
        # (the chains', then one per chain for the disturbances)
        "n": flat.n + nd, "nz": flat.n, "nd": nd, "nq": flat.m + (flat.m if nd else 0), "m": flat.m, "np": len(flat.params),
        "degrees": flat.degrees, "heads": flat.heads, "angles": [int(c.angle) for c in flat.chains],
        "params": [{"name": q.name, "value": q.value, "unit": _comment(q.unit),
                    "description": _comment(q.description)} for q in m.parameters],
        "opts": opts, "options": asdict(opts), "det_nominal": flat.nominal_det(), "model_ts": m.ts,
        # the held predictor's linearization input (benchmarks drive the filters with it), and
        # the scheduled one's nominal flat outputs after it (where Φ(σ) = Φ₀)
        "input_nominal": nominal_input(flat, opts),
        "example_start": example_start(flat),
        # each flat output's centre moves in exact steps (module centring): the C literals of
        # the step, half of it and its inverse; the list for the comments
        "centre_steps": [{"step": st, "half": st / 2, "per": 1 / st} for st in steps],
        "centre_steps_text": ", ".join(f"1/{round(1 / st)}" for st in steps),
        "ci_iterations": ci_iterations(opts.nodes), "ci_tolerance": CI_TOLERANCE[opts.precision],
        # the CI Hessian's data: H (M x M), or its factor G (M x n^2) when that step is cheaper
        "ci_factor": next((f.numel_out(1) for f in ks.all() if f.name() == f"{p}_kern_ci_grad"), 0),
        "ci_pivots": next((f.numel_out(1) for f in ks.all() if f.name() == f"{p}_kern_ci_dir"), 0),
        "ci_regulariser": CI_REGULARISER, "channel_restart_ratio": CHANNEL_RESTART_RATIO,
        "model_hash": provenance.model_hash(m), "versions": provenance.versions(),
        "cmake_version": provenance.cmake_version(__version__),
        "kernel_code": kernel_code, "kernel_list": kernel_list,
        # the node stores P priors every `check_every` steps (replay recomputes the ones between
        # with the P recursion), `ncheck` of them (Options.checkpoints)
        "check_every": opts.check_every, "ncheck": opts.checkpoints,
        "sz_w": {k["name"][len(p) + 6:]: k["sz_w"] for k in kernel_list},
        "library_sources": [f for f in names if f.endswith(".c") and f != "example_main.c"],
        "extension": extension_context(flat, opts.ts),
    }


def nominal_input(flat, opts) -> list[float]:
    """The input a benchmark predicts with (node_predict's, NW reals): u₀ for the held
    predictor, u₀ and the nominal flat outputs for the scheduled one, none for Brunovsky."""
    if not opts.holds_u:
        return []
    zeta0, u0 = nominal_point(flat)
    sigma0 = [float(zeta0[h]) for h in flat.heads] if opts.scheduled else []
    return [float(u) for u in u0] + sigma0


def extension_context(flat, ts: float) -> dict | None:
    """The controller's integrator chains of a dynamically extended model, for
    <model>_extension_step: per input its chain's indices into xi and the exact step's
    coefficients Ts^k / k!; None for a model that needed no extension."""
    ext = flat.extension
    if ext is None or not ext.steps:
        return None
    names, chains, offset = ext.states, [], 0
    for j, (u, states) in enumerate(ext.chains.items()):
        r = len(states)
        chains.append({"input": j, "name": _comment(u), "offset": offset, "degree": r,
                       "states": [_comment(s) for s in states],
                       "coef": [ts ** k / math.factorial(k) for k in range(r + 1)]})
        offset += r
    return {"nxi": len(names), "names": [_comment(s) for s in names], "chains": chains,
            "inputs": [_comment(u) for u in ext.inputs]}


def example_start(flat) -> list[float]:
    """Where the example program starts its plant and filters, and its reference's drift: the
    model's nominal state in canonical coordinates with each chain's derivatives above the first
    set to 0 (a unicycle moves at its nominal speed: at rest its extension is singular; an arm
    whose nominal torque is 0 would start falling), where the model is defined and G regular;
    else the nominal state itself; else the origin."""
    with np.errstate(all="ignore"):
        zeta = np.asarray(flat.phi_num(flatness.nominal_state(flat.model)), dtype=float)
        moving = zeta.copy()
        for head, r in zip(flat.heads, flat.degrees):
            moving[head + 2:head + r] = 0.0
        for cand in (moving, zeta):
            if np.all(np.isfinite(cand)) and np.all(np.isfinite(flat.F_num(cand))):
                G = np.asarray(flat.G_num(cand), dtype=float)
                if np.all(np.isfinite(G)) and abs(np.linalg.det(G)) > 0:
                    return [float(v) for v in cand]
    return [0.0] * flat.n


def model_argument(spec: str | Path | model.Model, m: model.Model) -> str:
    """How `codegen build` is told the model, for the command a generated file says regenerates
    it: a built-in's name; a model file's base name (`twoin.toml`: machine-independent, so the
    output stays deterministic); a Python Model's name (it has no file)."""
    if isinstance(spec, model.Model) or str(spec) in model.builtin_names():
        return m.name
    return Path(spec).name


def generate(m: model.Model, opts: Options, progress=None, model_arg: str | None = None) -> dict[str, str]:
    """Model and options -> {file: text}; nothing is written. `progress(text)` hears each stage;
    `model_arg`: the model as the files' regenerate command names it (model_argument)."""
    flat = flatness.derive(m, progress=progress)
    if progress:
        progress("generating the CasADi kernels and rendering the C")
    try:
        return render.render(context(flat, opts, model_arg))
    except jinja2.TemplateError as exc:
        raise BuildError(f"template error: {type(exc).__name__}: {exc}") from None


# the build options' keyword defaults, as check and build take them
OPTION_DEFAULTS = dict(precision="double", max_lag=32, nodes=2, oosm="replay", fusion="difference", ts=None,
                       singular_rtol=1e-6, predictor=None, disturbance=None, tau=None, gate=None)


def _model_and_options(spec, precision, max_lag, nodes, oosm, fusion, ts,
                       singular_rtol, predictor, disturbance=None, tau=None, gate=None) -> tuple[model.Model, Options]:
    m = spec if isinstance(spec, model.Model) else model.load(str(spec))
    return m, Options(ts=m.ts if ts is None else ts, max_lag=max_lag, nodes=nodes, oosm=oosm, fusion=fusion,
                      precision=precision, singular_rtol=singular_rtol, predictor=predictor,
                      disturbance=disturbance, tau=tau, gate=gate)


def out_folder(out: object) -> None:
    """`out` must name a folder: None or a number would otherwise be a TypeError from pathlib,
    and an empty string the current folder by accident; both a BuildError like any bad option."""
    if not isinstance(out, (str, os.PathLike)):
        raise BuildError(f"--out must be a folder path (a str or a pathlib.Path), got {out!r}")
    if isinstance(out, str) and not out.strip():
        raise BuildError(f"--out {out!r}: an empty path (give a folder; . for the current one)")


def check(spec: str | Path | model.Model, out: str | Path = "generated", *, precision: str = "double",
          max_lag: int = 32, nodes: int = 2, oosm: str = "replay", fusion: str = "difference",
          ts: float | None = None, singular_rtol: float = 1e-6, max_seconds: float | None = None,
          max_memory: float | None = None, predictor: str | None = None, disturbance: str | None = None,
          tau: float | None = None, gate: float | None = None) -> list[str]:
    """What `build` with these arguments would change in out/<model>, rendered in memory and
    compared byte for byte (line endings as written: a checkout's CRLF is not a change, as for
    `build`): the differing, missing ("missing: f") and extra ("extra: f") files;
    empty if the folder is up to date. A folder that does not exist is a BuildError (exit 2),
    raised before the derivation. Nothing is written."""
    out_folder(out)
    m, opts = _model_and_options(spec, precision, max_lag, nodes, oosm, fusion, ts, singular_rtol, predictor,
                                 disturbance, tau, gate)
    target = Path(out) / m.name
    if not target.is_dir():
        raise BuildError(f"{target}: missing (run `{opts.command(_as_passed(spec, m), m.ts, str(out))}`)")
    files = budget.bounded(functools.partial(generate, model_arg=model_argument(spec, m)), (m, opts),
                           max_seconds, max_memory, f"deriving {m.source}")
    on_disk = {p.name for p in target.iterdir()}
    stale = [f for f in files if f in on_disk
             and (target / f).read_bytes().replace(b"\r\n", b"\n") != files[f].encode("utf-8")]
    stale += [f"missing: {f}" for f in files if f not in on_disk]
    return stale + [f"extra: {f}" for f in sorted(on_disk - set(files))]


def _as_passed(spec: str | Path | model.Model, m: model.Model) -> str:
    """The model as the user gave it (a path as typed: advice is run where they are)."""
    return str(spec) if isinstance(spec, (str, Path)) else m.name


def built_options(folder: Path) -> Options | None:
    """The options folder/manifest.json says its build was made with; None if it says none."""
    try:
        return Options(**json.loads((folder / "manifest.json").read_text(encoding="utf-8"))["options"])
    except (OSError, ValueError, TypeError, KeyError, CodegenError):
        return None


def rebuild_advice(spec: str | Path | model.Model, out: str | Path = "generated", **options) -> str:
    """What `codegen build --check` tells the user to run on a stale folder (`options`: check's
    keywords): the build with the checked options, which makes the check pass, options and --out
    included; and, when its manifest.json records other ones (a check that left out the build's
    --precision float), the command the folder was built with."""
    m, opts = _model_and_options(spec, **{**OPTION_DEFAULTS, **options})
    text = f"run `{opts.command(_as_passed(spec, m), m.ts, str(out))}`"
    made = built_options(Path(out) / m.name)
    if made is not None and made != opts:
        text += f"; it was built with `{made.command(_as_passed(spec, m), m.ts, str(out))}`"
    return text


def build(spec: str | Path | model.Model, out: str | Path = "generated", *, precision: str = "double",
          max_lag: int = 32, nodes: int = 2, oosm: str = "replay", fusion: str = "difference",
          ts: float | None = None, singular_rtol: float = 1e-6, force: bool = False,
          max_seconds: float | None = None, max_memory: float | None = None,
          compile_check: bool = True, predictor: str | None = None, disturbance: str | None = None,
          tau: float | None = None, gate: float | None = None) -> GeneratedModule:
    """Generate the C module of a model (a built-in name, a .toml path or a Model) into out/<model>.

    Options and the output folder are checked before the derivation starts; the derivation runs
    under a time and memory budget (`max_seconds` in seconds, `max_memory` in GB, as the
    command's --max-seconds and --max-memory); what was written is compiled (host compiler, when
    there is one) before it replaces the folder, atomically. `force` allows replacing files the
    toolkit did not write there. `predictor`: "held" (u held), "scheduled" (held, Φ(σ) at the
    master's broadcast flat outputs) or "brunovsky"; None: held, and brunovsky with retrodict (the only one it can use). `disturbance` ("random_walk",
    "gauss_markov" with its time constant `tau`, or "integrated_random_walk"): disturbance
    states per chain (symbolic/disturbance.py). `gate`: the nodes refuse a measurement whose
    innovation is more than that many standard deviations out (ERR_OUTLIER); None: no gate."""
    out_folder(out)
    from dfeif_codegen.paths import writable_dir
    writable_dir(out, "--out")
    m, opts = _model_and_options(spec, precision, max_lag, nodes, oosm, fusion, ts, singular_rtol, predictor,
                                 disturbance, tau, gate)
    check_target(Path(out), m.name, force)
    files = budget.bounded(functools.partial(generate, model_arg=model_argument(spec, m)), (m, opts),
                           max_seconds, max_memory, f"deriving {m.source}")
    compiles = (lambda folder: compile_check_folder(folder, m.name)) if compile_check else None
    target = write_atomic(Path(out), m.name, files, force=force, check=compiles)
    nx = re.search(rf"^#define {m.name.upper()}_NX (\d+)$", files[f"{m.name}.h"], re.M)  # derived in a child
    return GeneratedModule(target, m.name, opts, tuple(files), int(nx.group(1)) if nx else 0)


def compile_check_folder(folder: Path, name: str) -> None:
    """Compile every generated .c (syntax and declarations) with the host compiler; a failure
    is the toolkit's or the model's fault and must not reach the user's tree."""
    cc = host_compiler()
    if cc is None:
        return
    sources = sorted(str(p) for p in folder.glob("*.c"))
    try:
        run = subprocess.run([cc, "-std=c99", "-fsyntax-only", "-I", str(folder), *sources],
                             capture_output=True, text=True, timeout=300)
    except (OSError, subprocess.SubprocessError) as exc:
        raise BuildError(f"{name}: the host compiler {cc} could not check the generated C ({exc})") from None
    if run.returncode != 0:
        errors = [ln for ln in run.stderr.splitlines() if "error" in ln] or run.stderr.splitlines() or ["?"]
        first = errors[0].replace(str(folder) + os.sep, "")
        raise BuildError(f"{name}: the generated C does not compile ({cc}): {first.strip()}")


def host_compiler() -> str | None:
    for cc in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if cc and shutil.which(cc):
            return cc
    return None


def measure_sizes(folder: Path, name: str) -> dict[str, int] | None:
    """sizeof the node, master and packet structs, by compiling a probe with the host compiler."""
    cc = host_compiler()
    if cc is None:
        return None
    with tempfile.TemporaryDirectory() as tmp:
        probe = Path(tmp) / "probe.c"
        probe.write_text(f'#include <stdio.h>\n#include "{name}.h"\nint main(void) {{ printf("%lu %lu %lu\\n", '
                         f"(unsigned long)sizeof({name}_node), (unsigned long)sizeof({name}_master), "
                         f"(unsigned long)sizeof({name}_packet)); return 0; }}\n")
        exe = Path(tmp) / "probe"
        try:
            subprocess.run([cc, "-std=c99", "-I", str(folder), str(probe), "-o", str(exe)], check=True,
                           capture_output=True, timeout=60)
            out = subprocess.run([str(exe)], check=True, capture_output=True, text=True, timeout=10).stdout
        except (OSError, subprocess.SubprocessError):
            return None
    node, master, packet = (int(v) for v in out.split())
    return {"node": node, "master": master, "packet": packet}
