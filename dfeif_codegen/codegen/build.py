"""`codegen build`: model -> flat system -> CasADi kernels -> rendered C module in <out>/<model>.

Why atomic: a firmware tree that includes generated/<model> must never see half a module. Files
are rendered in memory, written into a temporary folder beside the target and swapped in by
rename; any failure (bad model, bad option, template error) leaves the previous output as it was.
Why deterministic: no timestamps or paths, stable ordering, so a rebuild is byte-identical and the
committed generated/ can be checked against a fresh build.
"""

from __future__ import annotations

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

from dfeif_codegen import __version__, budget
from dfeif_codegen.symbolic import flatness, model
from dfeif_codegen.symbolic.sampling import nominal_point
from dfeif_codegen.codegen import kernels, layout, provenance, render
from dfeif_codegen.codegen.kernels import csource
from dfeif_codegen.constants import CI_REGULARISER, CI_TOLERANCE, ci_iterations
from dfeif_codegen.codegen.options import BuildError, Options

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


def context(flat, opts: Options) -> dict:
    """Everything the templates need, computed once."""
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
    return {
        "p": p, "P": p.upper(), "real": f"{p}_real", "real_c": real_c,
        "description": _comment(m.description or p),
        "zeta_names": [_comment(z) for z in flat.zeta] + disturbances + [f"rate of {d}" for d in disturbances[:nd - flat.m]],
        # n: the filters' state (the canonical one, nz, then nd disturbance states); nq densities
        # (the chains', then one per chain for the disturbances)
        "n": flat.n + nd, "nz": flat.n, "nd": nd, "nq": flat.m + (flat.m if nd else 0), "m": flat.m, "np": len(flat.params),
        "degrees": flat.degrees, "heads": flat.heads, "angles": [int(c.angle) for c in flat.chains],
        "params": [{"name": q.name, "value": q.value, "unit": _comment(q.unit),
                    "description": _comment(q.description)} for q in m.parameters],
        "opts": opts, "options": asdict(opts), "det_nominal": flat.nominal_det(), "model_ts": m.ts,
        # the held predictor's linearization input (benchmarks drive the filters with it)
        "input_nominal": [float(u) for u in nominal_point(flat)[1]] if opts.predictor == "held" else [],
        "ci_iterations": ci_iterations(opts.nodes), "ci_tolerance": CI_TOLERANCE[opts.precision],
        # the CI Hessian's data: H (M x M), or its factor G (M x n^2) when that step is cheaper
        "ci_factor": next((f.numel_out(1) for f in ks.all() if f.name() == f"{p}_kern_ci_grad"), 0),
        "ci_pivots": next((f.numel_out(1) for f in ks.all() if f.name() == f"{p}_kern_ci_dir"), 0),
        "ci_regulariser": CI_REGULARISER,
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


def generate(m: model.Model, opts: Options, progress=None) -> dict[str, str]:
    """Model and options -> {file: text}; nothing is written. `progress(text)` hears each stage."""
    flat = flatness.derive(m, progress=progress)
    if progress:
        progress("CasADi kernels and C rendering")
    try:
        return render.render(context(flat, opts))
    except jinja2.TemplateError as exc:
        raise BuildError(f"template error: {type(exc).__name__}: {exc}") from None


def _model_and_options(spec, precision, max_lag, nodes, oosm, fusion, ts,
                       singular_rtol, predictor, disturbance=None, tau=None) -> tuple[model.Model, Options]:
    m = spec if isinstance(spec, model.Model) else model.load(str(spec))
    return m, Options(ts=m.ts if ts is None else ts, max_lag=max_lag, nodes=nodes, oosm=oosm, fusion=fusion,
                      precision=precision, singular_rtol=singular_rtol, predictor=predictor,
                      disturbance=disturbance, tau=tau)


def check(spec: str | Path | model.Model, out: str | Path = "generated", *, precision: str = "double",
          max_lag: int = 32, nodes: int = 2, oosm: str = "replay", fusion: str = "difference",
          ts: float | None = None, singular_rtol: float = 1e-6, max_seconds: float | None = None,
          max_memory: float | None = None, predictor: str | None = None, disturbance: str | None = None,
          tau: float | None = None) -> list[str]:
    """What `build` with these arguments would change in out/<model>, rendered in memory and
    compared byte for byte: the differing, missing ("missing: f") and extra ("extra: f") files;
    empty if the folder is up to date. A folder that does not exist is a BuildError (exit 2),
    raised before the derivation. Nothing is written."""
    m, opts = _model_and_options(spec, precision, max_lag, nodes, oosm, fusion, ts, singular_rtol, predictor,
                                 disturbance, tau)
    target = Path(out) / m.name
    if not target.is_dir():
        raise BuildError(f"{target}: missing (run `codegen build {spec if isinstance(spec, (str, Path)) else m.name}"
                         f"{'' if str(out) == 'generated' else f' --out {out}'}`)")
    files = budget.bounded(generate, (m, opts), max_seconds, max_memory, f"deriving {m.source}")
    on_disk = {p.name for p in target.iterdir()}
    stale = [f for f in files if f in on_disk and (target / f).read_bytes() != files[f].encode("utf-8")]
    stale += [f"missing: {f}" for f in files if f not in on_disk]
    return stale + [f"extra: {f}" for f in sorted(on_disk - set(files))]


def build(spec: str | Path | model.Model, out: str | Path = "generated", *, precision: str = "double",
          max_lag: int = 32, nodes: int = 2, oosm: str = "replay", fusion: str = "difference",
          ts: float | None = None, singular_rtol: float = 1e-6, force: bool = False,
          max_seconds: float | None = None, max_memory: float | None = None,
          compile_check: bool = True, predictor: str | None = None, disturbance: str | None = None,
          tau: float | None = None) -> GeneratedModule:
    """Generate the C module of a model (a built-in name, a .toml path or a Model) into out/<model>.

    Options and the output folder are checked before the derivation starts; the derivation runs
    under a time and memory budget (`max_seconds` in seconds, `max_memory` in GB, as the
    command's --max-seconds and --max-memory); what was written is compiled (host compiler, when
    there is one) before it replaces the folder, atomically. `force` allows replacing files the
    toolkit did not write there. `predictor`: "held" (u held) or "brunovsky"; None: brunovsky, and
    brunovsky with retrodict (the only one it can use). `disturbance` ("random_walk",
    "gauss_markov" with its time constant `tau`, or "integrated_random_walk"): disturbance
    states per chain (symbolic/disturbance.py)."""
    if isinstance(out, str) and not out.strip():
        raise BuildError(f"--out {out!r}: an empty path (give a folder; . for the current one)")
    from dfeif_codegen.paths import writable_dir
    writable_dir(out, "--out")
    m, opts = _model_and_options(spec, precision, max_lag, nodes, oosm, fusion, ts, singular_rtol, predictor,
                                 disturbance, tau)
    check_target(Path(out), m.name, force)
    files = budget.bounded(generate, (m, opts), max_seconds, max_memory, f"deriving {m.source}")
    compiles = (lambda folder: compile_check_folder(folder, m.name)) if compile_check else None
    target = write_atomic(Path(out), m.name, files, force=force, check=compiles)
    nx = re.search(rf"^#define {m.name.upper()}_NX (\d+)$", files[f"{m.name}.h"], re.M)  # derived in a child
    return GeneratedModule(target, m.name, opts, tuple(files), int(nx.group(1)) if nx else 0)


def _written_before(target: Path) -> set[str]:
    """Files a previous build wrote into target: its manifest and what the manifest lists."""
    try:
        doc = json.loads((target / "manifest.json").read_text(encoding="utf-8"))
        listed = doc.get("files", {}) if isinstance(doc, dict) else {}
        return {"manifest.json", *(str(f) for f in listed)} if isinstance(listed, dict) else set()
    except (OSError, ValueError):
        return set()


def check_target(out_root: Path, name: str, force: bool = False) -> None:
    """Refuse (unless force) to replace anything in out_root/name the toolkit did not write."""
    target = out_root / name
    if out_root.exists() and not out_root.is_dir():
        raise BuildError(f"--out {out_root}: exists and is not a folder")
    if force or not (target.exists() or target.is_symlink()):
        return
    if target.is_symlink() or not target.is_dir():
        raise BuildError(f"{target}: a file the toolkit did not write is in the way (use --force to replace it)")
    ours = _written_before(target)
    theirs = sorted(p.name for p in target.iterdir() if p.name not in ours or not p.is_file())
    if theirs:
        more = f" and {len(theirs) - 1} more" if len(theirs) > 1 else ""
        raise BuildError(f"{target / theirs[0]}{more}: not written by codegen build (not in manifest.json); "
                         "move it away or use --force")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def clean_stale(out_root: Path, name: str) -> None:
    """Temp folders `.NAME.PID.*.new|old` of builds whose process is gone (killed mid-write):
    an old output whose replacement never arrived is put back, the rest removed."""
    if not out_root.is_dir():
        return
    target = out_root / name
    for p in sorted(out_root.glob(f".{name}.*.*")):
        parts = p.name[len(name) + 2:].split(".")
        if len(parts) != 3 or parts[2] not in ("new", "old") or not parts[0].isdigit() or _alive(int(parts[0])):
            continue
        if parts[2] == "old" and not (target.exists() or target.is_symlink()):
            os.rename(p, target)
        elif p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)


def _swap(target: Path, tmp: Path, old: Path | None) -> None:
    """target -> old, tmp -> target with SIGINT and SIGTERM held off between the two renames (a
    signal there would leave no output folder, only the hidden old one); delivered after. Also
    recorded by a Python handler: a process-directed signal goes to any thread not blocking it."""
    import signal
    import threading
    held = (signal.SIGINT, signal.SIGTERM)
    pending: list[int] = []
    saved = {}
    if threading.current_thread() is threading.main_thread():
        saved = {s: signal.signal(s, lambda signum, _frame: pending.append(signum)) for s in held}
    masked = hasattr(signal, "pthread_sigmask")
    if masked:
        before = signal.pthread_sigmask(signal.SIG_BLOCK, set(held))
    try:
        if old is not None:
            os.rename(target, old)
        try:
            os.rename(tmp, target)
        except OSError:
            if old is not None and not (target.exists() or target.is_symlink()):
                os.rename(old, target)
            raise
    finally:
        if masked:
            signal.pthread_sigmask(signal.SIG_SETMASK, before)   # a blocked one is recorded now
        for s, handler in saved.items():
            signal.signal(s, handler)
        for signum in dict.fromkeys(pending):
            handler = saved[signal.Signals(signum)]
            if callable(handler):
                handler(signum, None)              # Python's: KeyboardInterrupt for SIGINT
            elif handler == signal.SIG_DFL:
                signal.raise_signal(signum)        # the default action (SIGTERM ends the process)


def _keep_theirs(target: Path, tmp: Path, files: dict[str, str]) -> None:
    """--force replaces the files a build writes; the user's other files there come along into
    the new folder (copied, so the old folder stays whole until the swap)."""
    for p in target.iterdir():
        if p.name in files:
            continue
        if p.is_dir() and not p.is_symlink():
            shutil.copytree(p, tmp / p.name, symlinks=True)
        else:
            shutil.copy2(p, tmp / p.name, follow_symlinks=False)


def write_atomic(out_root: Path, name: str, files: dict[str, str], force: bool = False,
                 check=None) -> Path:
    """Write files into out_root/name by rendering into a sibling temp folder and renaming.
    `check(folder)` may refuse the new files (BuildError) before they replace the old ones.
    Temp folders carry this process's id, so a later build removes those of a killed one."""
    check_target(out_root, name, force)
    try:
        out_root.mkdir(parents=True, exist_ok=True)
        target = out_root / name
        clean_stale(out_root, name)
        tmp = Path(tempfile.mkdtemp(prefix=f".{name}.{os.getpid()}.", suffix=".new", dir=out_root))
    except OSError as exc:
        raise BuildError(f"{out_root}: cannot write output ({exc.strerror})") from None
    old = None
    try:
        for fname, text in files.items():
            (tmp / fname).write_bytes(text.encode("utf-8"))
        if force and target.is_dir() and not target.is_symlink():
            _keep_theirs(target, tmp, files)
        os.chmod(tmp, 0o755)
        if check is not None:
            check(tmp)
        if target.exists() or target.is_symlink():
            old = Path(tempfile.mkdtemp(prefix=f".{name}.{os.getpid()}.", suffix=".old", dir=out_root))
            os.rmdir(old)
        _swap(target, tmp, old)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        raise BuildError(f"{out_root / name}: cannot write output ({exc.strerror})") from None
    except BaseException:       # an interrupt: delivered after the swap, or before it
        shutil.rmtree(tmp, ignore_errors=True)
        if old is not None and old.is_dir() and not old.is_symlink() and target.is_dir():
            shutil.rmtree(old, ignore_errors=True)
        raise
    if old is not None:
        if old.is_dir() and not old.is_symlink():
            shutil.rmtree(old, ignore_errors=True)
        else:
            old.unlink()
    return target


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
