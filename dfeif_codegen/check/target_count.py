"""Instructions executed on the emulated Cortex-M4F, a cycle estimate, and stack with library calls.

QEMU's mps2-an386 runs the program one instruction per translation block (`-singlestep`, from
QEMU 8.1 `-accel tcg,one-insn-per-tb=on`) and logs every block it executes (`-d exec,nochain`):
the log is the sequence of executed program counters, the same for the same ELF (no interrupts
are enabled, semihosting calls are synchronous). The benchmark programs of templates/harness/
mark what to count with calls of `harness_toggle` and `harness_dump` (target_mark.h): between two
toggles every instruction outside the measuring function counts (the call's own work, callees and
newlib included, the harness's argument set-up not).

Cycles are an estimate: each executed instruction costed by CYCLES below, from the Cortex-M4
Technical Reference Manual (r0p1, table 3-1 "Cortex-M4 instruction set summary" and, for the
FPU, table 7-1 "FPU instruction set"), assuming zero-wait-state memory (no flash accelerator
misses, no bus contention). The low figure takes the best case the TRM allows (a branch refill P
of 1 cycle, neighbouring loads and stores pipelined, IT folded), the high one the worst (P = 3, no
pipelining, IT 1 cycle). Divisions (SDIV/UDIV 2-12) are taken at 2 and 12.
"""

from __future__ import annotations

import os
import re
import subprocess
import tempfile
import threading
from array import array
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dfeif_codegen.check import target
from dfeif_codegen.errors import SetupError

MARKS = ("harness_toggle", "harness_dump")

# base cycles (low, high) per mnemonic, condition codes and .w/.n/.f32 suffixes stripped
_ONE = ("mov mvn add adc sub sbc rsb and orr eor bic orn lsl lsr asr ror rrx cmp cmn tst teq mul "
        "uxtb uxth sxtb sxth uxtab uxtah sxtab sxtah ubfx sbfx bfi bfc clz rbit rev rev16 revsh movw "
        "movt adr addw subw nop umull smull umlal smlal ssat usat sel cpsie cpsid dmb dsb isb "
        "vadd vsub vmul vnmul vabs vneg vcmp vcmpe vcvt vcvtr vmov vmrs vmsr").split()
CYCLES = {**{m: (1, 1) for m in _ONE},
          "mla": (2, 2), "mls": (2, 2), "sdiv": (2, 12), "udiv": (2, 12), "it": (0, 1),
          "ldr": (2, 2), "ldrb": (2, 2), "ldrh": (2, 2), "ldrsb": (2, 2), "ldrsh": (2, 2),
          "str": (2, 2), "strb": (2, 2), "strh": (2, 2), "ldrd": (3, 3), "strd": (3, 3),
          "vldr": (2, 2), "vstr": (2, 2),
          "vmla": (3, 3), "vmls": (3, 3), "vnmla": (3, 3), "vnmls": (3, 3),
          "vfma": (3, 3), "vfms": (3, 3), "vfnma": (3, 3), "vfnms": (3, 3),
          "vdiv": (14, 14), "vsqrt": (14, 14),
          "b": (1, 1), "bl": (1, 1), "bx": (1, 1), "blx": (1, 1), "cbz": (1, 1), "cbnz": (1, 1),
          "tbb": (2, 2), "tbh": (2, 2), "bkpt": (1, 1), "svc": (1, 1), "wfi": (1, 1)}
_MULTI = ("push", "pop", "ldm", "ldmia", "ldmfd", "ldmdb", "stm", "stmia", "stmea", "stmdb", "stmfd",
          "vpush", "vpop", "vldmia", "vldmdb", "vstmia", "vstmdb", "vldm", "vstm")
_SINGLE_MEM = {"ldr", "ldrb", "ldrh", "ldrsb", "ldrsh", "str", "strb", "strh", "vldr", "vstr"}
_CONDS = ("eq", "ne", "cs", "cc", "hs", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le", "al")
REFILL = (1, 3)   # P: pipeline refill after a taken branch, TRM: 1 to 3


def base_mnemonic(mnem: str) -> str:
    """'ble.n' -> 'b', 'vadd.f32' -> 'vadd', 'addeq' -> 'add', 'movs' -> 'mov', 'ldmia.w' -> 'ldmia'."""
    m = mnem.split(".")[0].lower()
    for cand in (m, m[:-2] if m[-2:] in _CONDS else None):
        if not cand:
            continue
        if cand in CYCLES or cand in _MULTI:
            return cand
        if cand.endswith("s") and (cand[:-1] in CYCLES):
            return cand[:-1]
    if m[-2:] in _CONDS and m[:-2].endswith("s") and m[:-3] in CYCLES:
        return m[:-3]
    if m.startswith("it"):
        return "it"
    return m


def _registers(ops: str) -> int:
    """Words moved by a register list '{r4, r5, lr}', '{s16-s19}', '{d8-d9}'."""
    body = ops[ops.find("{") + 1:ops.find("}")]
    words = 0
    for part in (p.strip() for p in body.split(",") if p.strip()):
        lo, _, hi = part.partition("-")
        count = int(hi[1:]) - int(lo[1:]) + 1 if hi else 1
        words += count * (2 if lo.startswith("d") else 1)
    return words


@dataclass(frozen=True)
class Insn:
    size: int
    base: str
    cost: tuple        # (low, high) cycles when it does not branch
    branch: bool       # can change the flow (its taken cost adds the refill P)
    conditional: bool  # a branch that may fall through
    memory: bool       # a single load or store (pipelines with a neighbouring one)
    function: str
    callee: str        # the function a direct branch or call goes to ('' if none)


_LINE = re.compile(r"^\s*([0-9a-f]+):\t([0-9a-f]{4}(?: [0-9a-f]{4})?)\s*\t(\S+)(?:\s+(.*))?$")
_FUNC = re.compile(r"^([0-9a-f]+) <([^>]+)>:$")


def disassemble(elf: Path) -> dict[int, Insn]:
    """Every instruction of the ELF's code by address (literal pools come out as instructions
    too; they are never executed, so never costed)."""
    out = subprocess.run([_objdump(), "-d", str(elf)], capture_output=True, text=True, check=True).stdout
    table, func = {}, ""
    for line in out.splitlines():
        f = _FUNC.match(line)
        if f:
            func = f.group(2)
            continue
        m = _LINE.match(line)
        if not m:
            continue
        addr, raw, mnem, ops = int(m.group(1), 16), m.group(2), m.group(3), _strip(m.group(4))
        base = base_mnemonic(mnem)
        writes_pc = bool(re.match(r"pc\b", ops)) or ("pc" in ops and base in ("pop", "ldm", "ldmia", "ldmfd"))
        if base in _MULTI:
            cost = (1 + _registers(ops),) * 2
        else:
            cost = CYCLES.get(base, (1, 1))
        branch = base in ("b", "bl", "bx", "blx", "cbz", "cbnz", "tbb", "tbh") or writes_pc
        cond = base in ("cbz", "cbnz") or (base == "b" and mnem.split(".")[0].lower() not in ("b", "bl"))
        dest = re.search(r"<([^>+]+)(?:\+0x[0-9a-f]+)?>", ops) if branch else None
        table[addr] = Insn(len(raw.replace(" ", "")) // 2, base, cost, branch, cond, base in _SINGLE_MEM, func,
                           dest.group(1) if dest else "")
    return table


def _strip(ops: str | None) -> str:
    """Operands without objdump's comments ('@ 0x29c', '; 0x1a4 <x>')."""
    return re.split(r"\s*[@;]", ops or "", maxsplit=1)[0].strip()


def _objdump() -> str:
    return target.require("arm-none-eabi-gcc").replace("-gcc", "-objdump")


def symbols(elf: Path) -> dict[str, tuple[int, int]]:
    """Function name -> (start, end) addresses (Thumb bit cleared)."""
    out = subprocess.run([target.require("arm-none-eabi-nm"), "-S", "--defined-only", str(elf)],
                         capture_output=True, text=True, check=True).stdout
    res = {}
    for parts in (line.split() for line in out.splitlines()):
        if len(parts) == 4 and parts[2] in "tTW":
            start = int(parts[0], 16) & ~1
            res[parts[3]] = (start, start + int(parts[1], 16))
    return res


def qemu_trace_args() -> list[str]:
    """One instruction per block, every executed block logged."""
    out = subprocess.run([target.require("qemu-system-arm"), "--version"], capture_output=True, text=True).stdout
    ver = tuple(int(v) for v in re.search(r"version (\d+)\.(\d+)", out).groups())
    one = ["-accel", "tcg,one-insn-per-tb=on"] if ver >= (8, 1) else ["-singlestep"]
    return [*one, "-d", "exec,nochain"]


_PC = re.compile(rb"\[[0-9a-f]+/([0-9a-f]+)/")


def trace(elf: Path, cwd: Path, timeout: float = 1200.0) -> tuple[np.ndarray, str]:
    """The executed program counters of a whole run, and the program's stdout. The log goes
    through a pipe (a run logs some hundred bytes per instruction)."""
    pcs = array("I")
    with tempfile.TemporaryDirectory(prefix="qemu-trace-") as tmp:
        fifo = Path(tmp) / "trace"
        os.mkfifo(fifo)
        cmd = [target.require("qemu-system-arm"), *target.QEMU_ARGS, *qemu_trace_args(), "-D", str(fifo),
               "-kernel", str(elf)]
        proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)

        def read():
            tail = b""
            with open(fifo, "rb") as f:
                while chunk := f.read(1 << 22):
                    data = tail + chunk
                    cut = data.rfind(b"\n") + 1
                    pcs.extend(int(h, 16) for h in _PC.findall(data, 0, cut))
                    tail = data[cut:]

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        try:
            out, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired as exc:
            proc.kill()
            raise SetupError(f"qemu-system-arm did not finish {elf.name} within {timeout:.0f} s") from exc
        reader.join()
    if proc.returncode != 0:
        raise SetupError(f"{elf.name} under QEMU exited with {proc.returncode}: {(out + err).decode()[-2000:]}")
    return np.frombuffer(pcs, dtype=np.uint32).copy(), out.decode(errors="replace")


@dataclass(frozen=True)
class Window:
    instructions: int
    cycles: tuple      # (low, high)


def costs(pcs: np.ndarray, table: dict[int, Insn]) -> tuple[np.ndarray, np.ndarray]:
    """Cycles (low, high) of each executed instruction: its base cost, plus the refill P when it
    branched (the next PC is not the following instruction), minus one for a load or store whose
    predecessor was one too (pipelined: the low figure only)."""
    uniq, inv = np.unique(pcs, return_inverse=True)
    info = [table.get(int(a)) for a in uniq]
    if any(i is None for i in info):
        missing = [hex(int(a)) for a, i in zip(uniq, info) if i is None][:5]
        raise SetupError(f"executed addresses outside the disassembly: {missing}")
    size = np.array([i.size for i in info])[inv]
    lo = np.array([i.cost[0] for i in info])[inv]
    hi = np.array([i.cost[1] for i in info])[inv]
    branch = np.array([i.branch for i in info])[inv]
    mem = np.array([i.memory for i in info])[inv]
    nxt = np.append(pcs[1:].astype(np.int64), -1)
    taken = branch & (nxt != pcs.astype(np.int64) + size)
    lo = lo + taken * REFILL[0]
    hi = hi + taken * REFILL[1]
    lo[1:] -= (mem[1:] & mem[:-1]).astype(lo.dtype)
    return lo, hi


def sections(pcs: np.ndarray, stdout: str, elf: Path, table: dict[int, Insn] | None = None) -> dict[str, list]:
    """Per dump name (in order of the program's "dump NAME:CALLS" lines), the windows counted
    since the previous dump and the number of calls they stand for."""
    syms = symbols(elf)
    table = table or disassemble(elf)
    lo, hi = costs(pcs, table)
    toggle, dump = (syms[m][0] for m in MARKS)
    callers = {i.function for i in table.values() if i.callee == "harness_toggle"}
    ranges = [syms[f] for f in callers | set(MARKS) if f in syms]
    counted = np.ones(len(pcs), bool)
    for a, b in ranges:
        counted &= ~((pcs >= a) & (pcs < b))
    names = [line.split(" ", 1)[1] for line in stdout.splitlines() if line.startswith("dump ")]
    toggles = np.flatnonzero(pcs == toggle)
    dumps = np.flatnonzero(pcs == dump)
    if len(dumps) != len(names) or len(toggles) % 2:
        raise SetupError(f"the trace has {len(dumps)} dumps and {len(toggles)} toggles for {len(names)} names")
    cum = [np.concatenate(([0], np.cumsum(a))) for a in (counted, lo * counted, hi * counted)]
    out: dict[str, list] = {}
    pairs = toggles.reshape(-1, 2)
    for name, at in zip(names, dumps):
        label, calls = name.rsplit(":", 1)
        mine = pairs[(pairs[:, 1] < at)]
        pairs = pairs[(pairs[:, 1] > at)]
        wins = [Window(int(cum[0][b] - cum[0][a]), (int(cum[1][b] - cum[1][a]), int(cum[2][b] - cum[2][a])))
                for a, b in mine]
        out.setdefault(label, []).append((int(calls), wins))
    return out


def per_call(secs: dict[str, list]) -> dict[str, dict]:
    """Instructions and cycles per call of each section (a section's windows over its calls),
    and its costliest single window."""
    res = {}
    for label, dumps in secs.items():
        calls = sum(c for c, _ in dumps)
        wins = [w for _, ws in dumps for w in ws]
        res[label] = {"instructions": sum(w.instructions for w in wins) / calls,
                      "cycles": (sum(w.cycles[0] for w in wins) / calls, sum(w.cycles[1] for w in wins) / calls),
                      "max": max((w.instructions for w in wins), default=0),
                      "max_cycles": max((w.cycles for w in wins), default=(0, 0), key=lambda c: c[1]),
                      "median": float(np.median([w.instructions for w in wins])) if wins else 0.0}
    return res


def program(lib_sources, harness_src: Path, include_dirs, work: Path, defines=(), opt: str = "-Os") -> Path:
    """The benchmark program for the Cortex-M4F: the library at `opt`, the harness with
    HARNESS_TARGET (callgrind's requests become the marks), linked with newlib + semihosting."""
    work.mkdir(parents=True, exist_ok=True)
    incs = [*include_dirs, target.harness_file("target_mark.h").parent]
    lib = target.compile_objects(lib_sources, work / "lib", include_dirs, opt=opt)
    drv = target.compile_objects([harness_src, target.harness_file("target_mark.c")], work / "harness", incs,
                                 opt=opt, extra=["-DHARNESS_TARGET", *(f"-D{d}" for d in defines)])
    return target.link([*lib, *drv], work / "bench.elf")


def count(elf: Path, work: Path) -> tuple[dict[str, dict], str]:
    """Per section of the program's marks, instructions and cycles per call (`per_call`), and
    the program's stdout."""
    pcs, stdout = trace(elf, work)
    return per_call(sections(pcs, stdout, elf)), stdout


# --- stack with library calls -------------------------------------------------------------------

_SP_SUB = re.compile(r"^sp, (?:sp, )?#(\d+)$")
_PRE_INDEX = re.compile(r"\[sp, #-(\d+)\]!$")


def frames(table: dict[int, Insn], ops: dict[int, str]) -> tuple[dict[str, int], dict[str, set]]:
    """Bytes each linked function takes off the stack (every push, vpush, stmdb sp! and sub sp
    it contains, so an upper bound where a function adjusts the stack on several paths), and the
    functions it calls or branches to."""
    frame: dict[str, int] = {}
    calls: dict[str, set] = {}
    for addr, insn in table.items():
        f = insn.function
        frame.setdefault(f, 0)
        o = ops[addr]
        if insn.base in ("push", "vpush") or (insn.base in ("stmdb", "stmfd", "vstmdb") and o.startswith("sp!")):
            frame[f] += 4 * _registers(o)
        elif insn.base == "sub" and _SP_SUB.match(o):
            frame[f] += int(_SP_SUB.match(o).group(1))
        elif insn.base in ("str", "vstr") and _PRE_INDEX.search(o):
            frame[f] += int(_PRE_INDEX.search(o).group(1))
        if insn.callee and insn.callee != f:
            calls.setdefault(f, set()).add(insn.callee)
    return frame, calls


def operands(elf: Path) -> dict[int, str]:
    out = subprocess.run([_objdump(), "-d", str(elf)], capture_output=True, text=True, check=True).stdout
    return {int(m.group(1), 16): _strip(m.group(4)).strip()
            for m in map(_LINE.match, out.splitlines()) if m}


def stack_with_library(elf: Path, roots, table: dict[int, Insn] | None = None) -> dict[str, tuple[int, tuple]]:
    """Worst-case stack bytes of each root function over its calls in the linked program (newlib
    and libgcc included, their frames read from their code), and the path that takes it.
    A recursive call is cut (newlib's entry points the library calls are not recursive)."""
    table = table or disassemble(elf)
    frame, calls = frames(table, operands(elf))
    memo: dict[str, tuple[int, tuple]] = {}

    def walk(fn: str, active: tuple) -> tuple[int, tuple]:
        if fn in memo:
            return memo[fn]
        best: tuple = (-1, ())
        for callee in sorted(calls.get(fn, ())):
            if callee not in active and callee in frame:
                best = max(best, walk(callee, active + (fn,)), key=lambda b: b[0])
        best = (max(best[0], 0), best[1])
        memo[fn] = (frame.get(fn, 0) + best[0], (fn,) + best[1])
        return memo[fn]

    return {r: walk(r, ()) for r in roots if r in frame}
