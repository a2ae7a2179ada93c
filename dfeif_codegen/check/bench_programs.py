"""The programs `codegen bench` measures, compiled: the benchmark templates of templates/harness/
(bench.c.j2, worst.c.j2, peers.c.j2) for the host (double, -O2, linked for callgrind) or the
Cortex-M4F (float, -Os, linked for QEMU with the counting marks), and the library's objects alone
for its sizes and stack. Compiling only: check/bench_measure.py runs what these return."""

from __future__ import annotations

from pathlib import Path

from dfeif_codegen import __version__
from dfeif_codegen.check import harness, target, target_count
from dfeif_codegen.codegen import render

CALLS = 20    # target calls averaged per section (the host's 200 would take ten times the emulation)
OPT = "-Os"   # the target's optimisation


def render_harness(md: harness.ModelDir, template: str, work: Path) -> Path:
    """templates/harness/`template`.c.j2 for this model, in its precision."""
    work.mkdir(parents=True, exist_ok=True)
    src = work / f"{md.name}_{template}.c"
    src.write_text(render.environment(md.precision).get_template(f"harness/{template}.c.j2").render(
        p=md.name, P=md.name.upper(), banner=render.banner(f"harness/{template}.c.j2", md.name, __version__),
        input_nominal=md.input_nominal))
    return src


def host(md: harness.ModelDir, src: Path, work: Path, defines: tuple[str, ...] = ()) -> Path:
    """The library and a benchmark source as one host program (`defines`: -D options)."""
    work.mkdir(parents=True, exist_ok=True)
    return harness.compile_program([*md.sources(), src], work / src.stem, [md.path],
                                   [harness.BIND_NOW, *(f"-D{d}" for d in defines)])


def host_template(md: harness.ModelDir, template: str, work: Path, defines: tuple[str, ...] = ()) -> Path:
    """bench.c.j2 or worst.c.j2 compiled for the host."""
    return host(md, render_harness(md, template, work), work, defines)


def elf(md: harness.ModelDir, src: Path, work: Path, defines=()) -> Path:
    """The library and a benchmark source linked for the Cortex-M4F (CALLS calls per section;
    a define starting CI_ is the model's, <MODEL>_CI_...)."""
    return target_count.program(md.sources(), src, [md.path], work,
                                [f"CALLS={CALLS}", *(f"{md.name.upper()}_{d}" if d.startswith("CI_") else d
                                                     for d in defines)], OPT)


def elf_template(md: harness.ModelDir, template: str, work: Path, defines=()) -> Path:
    """bench.c.j2 or worst.c.j2 linked for the Cortex-M4F, in `work`/bin (its sources in `work`/src)."""
    return elf(md, render_harness(md, template, work / "src"), work / "bin", defines)


def objects(md: harness.ModelDir, work: Path) -> list[Path]:
    """The library's objects for the Cortex-M4F at -Os, with GCC's stack files beside them."""
    return target.compile_objects(md.sources(), work, [md.path], opt=OPT)
