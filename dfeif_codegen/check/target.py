"""The Cortex-M4F bare-metal route: cross-compile with arm-none-eabi-gcc, run on QEMU's mps2-an386.

The program links newlib with semihosting (`--specs=rdimon.specs`), so `printf` and `fopen` reach
the host and `main`'s return value becomes QEMU's exit code: the scenario goes in and the results
come out as binary files in the run folder, with no UART driver or hex parsing. Memory map, startup
and the FPU switch-on are in `templates/harness/`.

Sizes are measured on the library's own objects (not newlib), stack use from `-fstack-usage`
combined with `-fcallgraph-info=su` into a worst case per entry point.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Iterable, Sequence

from dfeif_codegen.errors import SetupError

CPU_FLAGS = ["-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16"]
# -fno-math-errno lets sqrtf be the VSQRT instruction instead of a libm call.
CFLAGS = ["-Wall", "-Wextra", "-ffunction-sections", "-fdata-sections",
          "-fno-math-errno", "-fstack-usage", "-fcallgraph-info=su"]
QEMU_ARGS = ["-M", "mps2-an386", "-nographic", "-semihosting-config", "enable=on,target=native"]
# what the driver may allocate: the board's 4 MiB of RAM (mps2_an386.ld) less 512 KiB for the
# program's statics, newlib's buffers and the stack (the stack paint alone takes 64 KiB)
HEAP_BUDGET = 4 * 1024 * 1024 - 512 * 1024

# tool -> Debian package that provides it
PACKAGES = {
    "arm-none-eabi-gcc": "gcc-arm-none-eabi",
    "arm-none-eabi-size": "binutils-arm-none-eabi",
    "arm-none-eabi-nm": "binutils-arm-none-eabi",
    "qemu-system-arm": "qemu-system-arm",
    "rdimon.specs": "libnewlib-arm-none-eabi",
}


def require(tool: str) -> str:
    """Path of `tool`, or a SetupError naming the Debian package to install."""
    path = shutil.which(tool)
    if path is None:
        pkg = PACKAGES[tool]
        raise SetupError(f"{tool} not found: install the Debian package {pkg} (apt-get install {pkg})")
    return path


def require_newlib() -> None:
    """newlib ships no program; gcc finds its semihosting specs file only when it is installed."""
    out = subprocess.run([require("arm-none-eabi-gcc"), "-print-file-name=rdimon.specs"],
                         capture_output=True, text=True).stdout.strip()
    if not Path(out).is_absolute():
        pkg = PACKAGES["rdimon.specs"]
        raise SetupError(f"newlib for arm-none-eabi not found: install the Debian package {pkg} "
                         f"(apt-get install {pkg})")


def harness_file(name: str) -> Path:
    return Path(str(resources.files("dfeif_codegen.templates") / "harness" / name))


def _run(cmd: Sequence[str], **kw) -> subprocess.CompletedProcess:
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **kw)
    if proc.returncode != 0:
        raise SetupError(f"command failed ({proc.returncode}): {' '.join(map(str, cmd))}\n"
                         f"{proc.stderr.strip()[-4000:]}")
    return proc


def compile_objects(sources: Iterable[Path], out_dir: Path, include_dirs: Iterable[Path] = (),
                    opt: str = "-O2", extra: Sequence[str] = ()) -> list[Path]:
    """One object per source (so each can be sized), with .su and .ci files beside it."""
    gcc = require("arm-none-eabi-gcc")
    out_dir.mkdir(parents=True, exist_ok=True)
    incs = [f"-I{d}" for d in include_dirs]
    objects = []
    for src in sources:
        obj = out_dir / (Path(src).stem + ".o")
        _run([gcc, *CPU_FLAGS, opt, *CFLAGS, *incs, *extra, "-c", src, "-o", obj], cwd=out_dir)
        objects.append(obj)
    return objects


def link(objects: Iterable[Path], elf: Path) -> Path:
    """Link with the startup code, the mps2-an386 linker script and newlib + semihosting."""
    gcc = require("arm-none-eabi-gcc")
    require_newlib()
    startup = compile_objects([harness_file("startup_cm4.c")], elf.parent / "startup", opt="-O2")
    _run([gcc, *CPU_FLAGS, "--specs=rdimon.specs", "-T", harness_file("mps2_an386.ld"),
          "-Wl,--gc-sections", *startup, *objects, "-lm", "-o", elf])
    return elf


def run(elf: Path, cwd: Path, timeout: float = 300.0) -> subprocess.CompletedProcess:
    """Run the ELF under QEMU in `cwd` (semihosting file names are relative to it)."""
    qemu = require("qemu-system-arm")
    try:
        return subprocess.run([qemu, *QEMU_ARGS, "-kernel", str(elf)], cwd=cwd, capture_output=True,
                              text=True, timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        raise SetupError(f"qemu-system-arm did not finish {elf.name} within {timeout:.0f} s") from exc


STRUCTS = ("node", "master", "packet")


def sizeof_probe(model, work: Path) -> Path:
    """The assembly of a probe holding sizeof the state structs of a built model (check/harness.py
    ModelDir) as arm-none-eabi-gcc lays them out (`read_struct_sizes` reads it)."""
    work.mkdir(parents=True, exist_ok=True)
    src = work / "sizeof.c"
    src.write_text(f'#include "{model.name}.h"\nconst unsigned sizes[] = {{'
                   + ", ".join(f"sizeof({model.name}_{k})" for k in STRUCTS) + "};\n")
    gcc = require("arm-none-eabi-gcc")
    proc = subprocess.run([gcc, *CPU_FLAGS, "-O2", f"-I{model.path}", "-S", "-o", str(work / "sizeof.s"), str(src)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise SetupError(f"sizeof probe failed:\n{proc.stderr[-2000:]}")
    return work / "sizeof.s"


def read_struct_sizes(asm: Path) -> dict[str, int]:
    words = [int(w) for w in re.findall(r"\.word\s+(\d+)", asm.read_text())]
    return dict(zip(STRUCTS, words))


def struct_sizes(model, work: Path) -> dict[str, int]:
    """sizeof the state structs of a built model on the Cortex-M4F."""
    return read_struct_sizes(sizeof_probe(model, work))


@dataclass(frozen=True)
class Size:
    text: int
    data: int
    bss: int


def sizes(objects: Iterable[Path]) -> dict[str, Size]:
    """Berkeley sizes per object (`arm-none-eabi-size`): .text includes read-only data."""
    out = _run([require("arm-none-eabi-size"), "-B", *objects]).stdout.splitlines()
    result = {}
    for line in out[1:]:
        text, data, bss, _dec, _hex, name = line.split(None, 5)
        result[Path(name).name] = Size(int(text), int(data), int(bss))
    return result


def undefined_symbols(obj: Path) -> set[str]:
    """Symbols an object imports: a clean float build has no __aeabi_d* nor double sin/cos."""
    out = _run([require("arm-none-eabi-nm"), "-u", obj]).stdout.split()
    return {w for w in out if w != "U"}


_NODE = re.compile(r'node: \{ title: "([^"]+)" label: "[^"]*?\\n[^"]*?(?:\\n(\d+) bytes \((\w[^)]*)\))?"')
_EDGE = re.compile(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')


def _short(title: str) -> str:
    """GCC titles a static function 'path/file.c:name.isra.0'; keep 'name.isra.0'."""
    return title.rsplit(":", 1)[-1]


@dataclass(frozen=True)
class StackUse:
    bytes: int          # worst case over every call path from the function
    path: tuple         # the function names on that path
    bounded: bool       # False if a frame is dynamic, a call is recursive or goes to unknown code
    unknown: tuple      # callees with no stack information (external code: newlib, libgcc)


def stack_usage(ci_files: Iterable[Path]) -> dict[str, StackUse]:
    """Worst-case stack per function from GCC's call graph with frame sizes (-fcallgraph-info=su)."""
    frame: dict[str, int] = {}
    qualifier: dict[str, str] = {}
    calls: dict[str, set[str]] = {}
    for ci in ci_files:
        text = Path(ci).read_text()
        for name, size, qual in _NODE.findall(text):
            if size:
                frame[name] = int(size)
                qualifier[name] = qual
        for src, dst in _EDGE.findall(text):
            calls.setdefault(src, set()).add(dst)

    memo: dict[str, StackUse] = {}

    def walk(fn: str, active: tuple) -> StackUse:
        if fn in active:
            return StackUse(0, (_short(fn),), False, ())
        if fn in memo:
            return memo[fn]
        if fn not in frame:
            return StackUse(0, (_short(fn),), False, (_short(fn),))
        best, path, bounded, unknown = 0, (), qualifier[fn] == "static", set()
        for callee in sorted(calls.get(fn, ())):
            sub = walk(callee, active + (fn,))
            bounded &= sub.bounded
            unknown |= set(sub.unknown)
            if sub.bytes >= best:
                best, path = sub.bytes, sub.path
        use = StackUse(frame[fn] + best, (_short(fn),) + path, bounded, tuple(sorted(unknown)))
        memo[fn] = use
        return use

    return {_short(fn): walk(fn, ()) for fn in frame}


# --- a recorded scenario on the emulated Cortex-M4F ----------------------------------------------

@dataclass
class TargetRun:
    status: dict                  # status, failed_step, failed_call, stack_bytes (painted high-water)
    outputs: dict                 # as harness.Library.run
    sizes: dict[str, Size]        # per library object (the driver and newlib not included)
    stack: dict[str, StackUse]    # worst case per public function, from the call graph
    seconds: float                # emulation wall time


def public_functions(model_name: str, stack: dict[str, StackUse]) -> dict[str, StackUse]:
    return {f: s for f, s in sorted(stack.items()) if f.startswith(model_name + "_")
            and "_kern_" not in f and "harness" not in f}


@dataclass
class App:
    """The model's library and its scenario driver, compiled and linked for the Cortex-M4F."""

    model: object
    elf: Path
    lib_objs: list
    work: Path


def build_app(model, work: Path, opt: str = "-O2") -> App:
    """Build the model folder (float or double) and the driver for the Cortex-M4F."""
    from dfeif_codegen.check import harness

    work = Path(work)
    work.mkdir(parents=True, exist_ok=True)
    lib_objs = compile_objects(model.sources(), work / "lib", [model.path], opt=opt)
    driver = harness.render_driver(model, work / "driver")
    drv_objs = compile_objects([driver], work / "driver", [model.path], opt=opt,
                               extra=["-DHARNESS_MAIN", "-DHARNESS_STACK_PAINT"])
    return App(model, link([*lib_objs, *drv_objs], work / "app.elf"), lib_objs, work)


def fitting(rec, model, inputs: str = "recorded"):
    """(rec, or its longest beginning whose inputs the driver can hold in the target's RAM with
    one chunk of outputs; the steps kept): the driver streams its outputs (driver.c.j2), but
    reads the whole scenario first, so a very long one (about 48,000 steps of the motor in
    float) would otherwise leave the program without memory and without results."""
    from dfeif_codegen.check import driver_io

    steps = rec.ref.shape[0]
    need = driver_io.driver_bytes(rec, model, inputs)
    if need <= HEAP_BUDGET:
        return rec, steps
    steps = int(steps * HEAP_BUDGET / need)
    while steps > 1 and driver_io.driver_bytes(rec.head(steps), model, inputs) > HEAP_BUDGET:
        steps = int(steps * 0.95)
    return rec.head(steps), steps


def run_app(app: App, rec, timeout: float = 600.0, inputs: str = "recorded") -> TargetRun:
    """Replay the recording under QEMU, read the results back through semihosting files."""
    import time

    from dfeif_codegen.check import driver_io

    model, work = app.model, app.work
    driver_io.write_scenario(rec, model, work / "scenario.bin", inputs)
    results = work / "results.bin"
    results.unlink(missing_ok=True)
    start = time.perf_counter()
    proc = run(app.elf, work, timeout=timeout)
    seconds = time.perf_counter() - start
    if not results.is_file():
        raise SetupError(f"the target program wrote no results (QEMU exit {proc.returncode}): "
                         f"{(proc.stdout + proc.stderr).strip()[-2000:]}")
    status, outputs = driver_io.read_results(rec, model, results)
    stack = stack_usage(o.with_suffix(".ci") for o in app.lib_objs)
    return TargetRun(status, outputs, sizes(app.lib_objs), public_functions(model.name, stack), seconds)


def run_scenario(model, rec, work: Path, opt: str = "-O2", timeout: float = 600.0,
                 inputs: str = "recorded") -> TargetRun:
    """`build_app` then `run_app`."""
    return run_app(build_app(model, work, opt), rec, timeout, inputs)


def report(result: TargetRun) -> str:
    """Sizes of the library's objects and stack use, as printed by `codegen verify`."""
    lines = ["Cortex-M4F library objects (arm-none-eabi-size, bytes):",
             f"  {'object':36} {'.text':>7} {'.data':>6} {'.bss':>6}"]
    for name, s in result.sizes.items():
        lines.append(f"  {name:36} {s.text:7d} {s.data:6d} {s.bss:6d}")
    total = Size(*(sum(getattr(s, f) for s in result.sizes.values()) for f in ("text", "data", "bss")))
    lines.append(f"  {'total':36} {total.text:7d} {total.data:6d} {total.bss:6d}")
    lines.append("worst-case stack per entry point (-fstack-usage + call graph, bytes):")
    for fn, use in result.stack.items():
        if use.bytes:
            note = "" if not use.unknown else f"  + newlib {', '.join(use.unknown)}"
            lines.append(f"  {fn:36} {use.bytes:5d}{note}")
    lines.append(f"measured stack high-water over the whole run (driver included): "
                 f"{result.status['stack_bytes']} bytes; QEMU run {result.seconds:.1f} s")
    return "\n".join(lines)
