"""`codegen build`: model -> flat system -> CasADi kernels -> rendered C module in <out>/<model>.

Why atomic: a firmware tree that includes generated/<model> must never see half a module. Files
are rendered in memory, written into a temporary folder beside the target and swapped in by
rename; any failure (bad model, bad option, template error) leaves the previous output as it was.
Why deterministic: no timestamps or paths, stable ordering, so a rebuild is byte-identical and the
committed generated/ can be checked against a fresh build.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import asdict, dataclass
from importlib import metadata
from pathlib import Path

import jinja2
import sympy as sp

from dfeif_codegen import __version__
from dfeif_codegen.symbolic import flatness, model
from dfeif_codegen.codegen import kernels, layout, render
from dfeif_codegen.constants import CI_ITERATIONS
from dfeif_codegen.codegen.options import BuildError, Options

GROUP_DOCS = {
    "filter": "Node filter kernels (the master reuses predict and info)",
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


def model_hash(m: model.Model) -> str:
    """SHA-256 of a canonical description of the model (sympy srepr is stable)."""
    doc = {
        "name": m.name, "ts": m.ts,
        "states": [s.name for s in m.states], "inputs": [u.name for u in m.inputs],
        "parameters": [[q.name, q.value] for q in m.parameters],
        "f": [sp.srepr(e) for e in m.f], "g": [sp.srepr(e) for e in m.g],
        "outputs": [[o.name, sp.srepr(o.expr), o.angle] for o in m.outputs],
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def versions() -> dict[str, str]:
    """This tool's version and its code-generating dependencies' (recorded in the manifest)."""
    out = {"dfeif-codegen": __version__}
    for dist in ("casadi", "jinja2", "numpy", "sympy"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "unknown"
    return out


def cmake_version(version: str) -> str:
    """The numeric part CMake accepts for project(VERSION) (`0.2.0.dev1` -> `0.2.0`)."""
    mt = re.match(r"\d+(?:\.\d+){0,3}", version)
    return mt.group(0) if mt else "0"


def _comment(text: str) -> str:
    """Safe inside a C block comment and on one line."""
    return " ".join(str(text).replace("*/", "* /").replace("/*", "/ *").split())


def context(flat, opts: Options) -> dict:
    """Everything the templates need, computed once."""
    m = flat.model
    p = m.name
    ks = kernels.build(flat, opts, p)
    real_c = "float" if opts.precision == "float" else "double"
    kernel_code, kernel_list = {}, []
    for group, functions in ks.groups.items():
        code, infos = kernels.c_source(functions, f"{p}_real", opts.precision, f"{p}_{group}")
        kernel_code[group] = (code.rstrip("\n"), f"{GROUP_DOCS[group]}: "
                                    + ", ".join(k.name[len(p) + 6:] for k in infos) + ".")
        kernel_list += [{"name": k.name, "macro": k.name.upper(), "sz_w": k.sz_w,
                         "signature": kernels.wrap_comment(_comment(k.signature)),
                         "prototype": layout.pack(f"int {k.name}(", k.parameters(f"{p}_real"), ");")}
                        for k in infos]
    names = render.file_names(p, list(ks.groups))
    return {
        "p": p, "P": p.upper(), "real": f"{p}_real", "real_c": real_c,
        "description": _comment(m.description or p),
        "zeta_names": [str(z) for z in flat.zeta], "n": flat.n, "m": flat.m, "np": len(flat.params),
        "degrees": flat.degrees, "heads": flat.heads, "angles": [int(c.angle) for c in flat.chains],
        "params": [{"name": q.name, "value": q.value, "unit": _comment(q.unit),
                    "description": _comment(q.description)} for q in m.parameters],
        "opts": opts, "options": asdict(opts), "ci_iterations": CI_ITERATIONS,
        "model_hash": model_hash(m), "versions": versions(), "cmake_version": cmake_version(__version__),
        "dependencies": {k: v for k, v in versions().items() if k != "dfeif-codegen"},
        "kernel_code": kernel_code, "kernel_list": kernel_list,
        "sz_w": {k["name"][len(p) + 6:]: k["sz_w"] for k in kernel_list},
        "library_sources": [f for f in names if f.endswith(".c") and f != "example_main.c"],
    }


def generate(m: model.Model, opts: Options) -> dict[str, str]:
    """Model and options -> {file: text}; nothing is written."""
    flat = flatness.derive(m)
    try:
        return render.render(context(flat, opts))
    except jinja2.TemplateError as exc:
        raise BuildError(f"template error: {type(exc).__name__}: {exc}") from None


def build(spec: str | Path | model.Model, out: str | Path = "generated", *, precision: str = "double",
          max_lag: int = 32, nodes: int = 2, oosm: str = "replay", fusion: str = "difference",
          ts: float | None = None) -> GeneratedModule:
    """Generate the C module of a model (a built-in name, a .toml path or a Model) into out/<model>.

    Options are checked before the derivation starts; the folder is replaced atomically."""
    m = spec if isinstance(spec, model.Model) else model.load(str(spec))
    opts = Options(ts=m.ts if ts is None else ts, max_lag=max_lag, nodes=nodes, oosm=oosm, fusion=fusion,
                   precision=precision)
    files = generate(m, opts)
    target = write_atomic(Path(out), m.name, files)
    return GeneratedModule(target, m.name, opts, tuple(files))


def write_atomic(out_root: Path, name: str, files: dict[str, str]) -> Path:
    """Write files into out_root/name by rendering into a sibling temp folder and renaming."""
    try:
        out_root.mkdir(parents=True, exist_ok=True)
        target = out_root / name
        tmp = Path(tempfile.mkdtemp(prefix=f".{name}.", suffix=".new", dir=out_root))
    except OSError as exc:
        raise BuildError(f"{out_root}: cannot write output ({exc.strerror})") from None
    old = None
    try:
        for fname, text in files.items():
            (tmp / fname).write_bytes(text.encode("utf-8"))
        os.chmod(tmp, 0o755)
        if target.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{name}.", suffix=".old", dir=out_root))
            os.rmdir(old)
            os.rename(target, old)
        os.rename(tmp, target)
    except OSError as exc:
        if old is not None and old.exists() and not target.exists():
            os.rename(old, target)
        shutil.rmtree(tmp, ignore_errors=True)
        raise BuildError(f"{out_root / name}: cannot write output ({exc.strerror})") from None
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return target


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
