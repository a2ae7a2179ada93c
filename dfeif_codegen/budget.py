"""A time and memory budget for the symbolic work.

Why a child process: a 63-character expression can make sympy expand for hours or allocate
tens of GB before any Python-level check sees it. The work runs in a forked child with an
address-space limit (RLIMIT_AS: what it maps already plus the budget, so a machine whose BLAS
reserves much address space is not refused for it) while the parent watches the child's CPU time
(not the wall clock: the outcome must not depend on how loaded the machine is; RLIMIT_CPU is the
backstop where /proc is missing); the child reports each stage it enters, so a refusal names what
it was working on. Without fork (not Linux/macOS) the work
runs inline, unbounded; DFEIF_NO_BUDGET=1 does the same (for a debugger).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import pickle
import signal
import time

from dfeif_codegen.errors import CodegenError

MAX_SECONDS = 60.0
MAX_MEMORY = 2.0  # GB, the unit of --max-memory
WALL_FACTOR = 10  # wall-clock backstop: a child that gets no CPU is stopped after 10x the budget + 60 s


class BudgetError(CodegenError):
    """The derivation ran out of its time or memory budget."""


# This process's budget when a call gives none: what the running command's --max-seconds and
# --max-memory asked for (configure), so a derivation it starts deep inside (the build `verify`
# or `simulate` makes) keeps to the same budget.
LIMITS = {"max_seconds": MAX_SECONDS, "max_memory": MAX_MEMORY}


def _check(max_seconds, max_memory) -> None:
    for flag, value in (("--max-seconds", max_seconds), ("--max-memory", max_memory)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < float("inf"):
            raise BudgetError(f"{flag} must be a positive finite number, got {value!r}")


def configure(max_seconds: float | None = None, max_memory: float | None = None) -> None:
    """Set this process's default budget (CPU seconds, GB); None keeps the current one."""
    seconds = LIMITS["max_seconds"] if max_seconds is None else max_seconds
    memory = LIMITS["max_memory"] if max_memory is None else max_memory
    _check(seconds, memory)
    LIMITS.update(max_seconds=seconds, max_memory=memory)


def _mapped() -> int:
    """Bytes of address space this process maps now (Linux /proc; 0 where unknown)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


def _cpu_seconds(pid: int) -> float | None:
    """User + system CPU seconds of a process (Linux /proc; None where unknown)."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


def _die_with(parent_pid: int) -> None:
    """Linux: the kernel kills this child with SIGKILL when its parent dies (a parent killed by
    SIGTERM or SIGKILL runs no cleanup), so no derivation outlives the build that started it."""
    try:
        import ctypes
        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))   # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent_pid:     # the parent died before the line above
        os._exit(1)


def _out_of_memory(exc: BaseException) -> bool:
    """A failed allocation under RLIMIT_AS, however it surfaced: a MemoryError anywhere in the
    chain, or a C extension (sympy's or CasADi's) returning NULL without setting an exception,
    which Python reports as SystemError "error return without exception set", possibly wrapped."""
    seen: BaseException | None = exc
    while seen is not None:
        if isinstance(seen, MemoryError) or "error return without exception set" in str(seen):
            return True
        seen = seen.__cause__ or seen.__context__
    return False


def _child(conn, theirs, parent_pid: int, fn, args, max_bytes: float, max_seconds: float) -> None:
    theirs.close()      # the parent's read end: held here, it would keep the pipe open
    _die_with(parent_pid)
    try:
        import math
        import resource
        limit = int(_mapped() + max_bytes)  # on top of what is mapped already (libraries, BLAS)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        cpu = int(math.ceil(max_seconds)) + 2  # the backstop; the parent stops the child first
        resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 5))
    except (ImportError, ValueError, OSError):
        pass

    def progress(text: str) -> None:
        conn.send(("stage", text))
    try:
        result = fn(*args, progress=progress)
        conn.send(("ok", pickle.dumps(result)))
    except CodegenError as exc:
        try:
            conn.send(("error", pickle.dumps(exc)))
        except (pickle.PicklingError, TypeError, AttributeError):
            conn.send(("error", pickle.dumps(CodegenError(str(exc)))))
    except MemoryError:
        conn.send(("memory", None))
    except (ImportError, OSError) as exc:  # a library that cannot be mapped under the limit
        conn.send(("memory", None) if "map" in str(exc) or "memory" in str(exc) else ("bug", f"{exc!r}"))
    except RecursionError:
        conn.send(("recursion", None))
    except BaseException as exc:  # a bug: the parent reports it as an internal error
        conn.send(("memory", None) if _out_of_memory(exc) else ("bug", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def bounded(fn, args: tuple, max_seconds: float | None, max_memory: float | None, what: str):
    """`fn(*args, progress=...)` within max_seconds of CPU time and max_memory GB; BudgetError
    (exit 2) naming the stage when either runs out (None: this process's LIMITS). CodegenErrors
    raised inside come out unchanged.
    A child that gets no CPU at all is still stopped after WALL_FACTOR times the budget of wall time."""
    max_seconds = LIMITS["max_seconds"] if max_seconds is None else max_seconds
    max_memory = LIMITS["max_memory"] if max_memory is None else max_memory
    _check(max_seconds, max_memory)
    if "fork" not in mp.get_all_start_methods() or os.environ.get("DFEIF_NO_BUDGET"):
        return fn(*args, progress=None)
    ctx = mp.get_context("fork")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child, parent, os.getpid(), fn, args, max_memory * 1e9, max_seconds),
                       daemon=True)
    proc.start()
    child.close()
    pid = proc.pid
    assert pid is not None  # set by start()
    stage, wall_deadline = "starting the derivation", time.monotonic() + WALL_FACTOR * max_seconds + 60
    try:
        while True:
            used = _cpu_seconds(pid)
            if (used is not None and used >= max_seconds) or time.monotonic() >= wall_deadline \
                    or proc.exitcode == -getattr(signal, "SIGXCPU", -1):
                raise BudgetError(f"{what}: stopped after {max_seconds:g} CPU-s while {stage} (the expression "
                              "grows too large; simplify it or raise --max-seconds)")
            step = 0.5 if used is None else min(0.5, max(0.01, max_seconds - used))
            if not parent.poll(step):
                if not proc.is_alive() and not parent.poll(0):
                    if proc.exitcode == -getattr(signal, "SIGXCPU", -1):
                        continue
                    raise BudgetError(f"{what}: the derivation died while {stage} (exit {proc.exitcode}; "
                                      "out of memory? raise --max-memory)")
                continue
            try:
                kind, payload = parent.recv()
            except EOFError:
                proc.join(1)
                if proc.exitcode == -getattr(signal, "SIGXCPU", -1):
                    continue
                raise BudgetError(f"{what}: the derivation died while {stage} (exit {proc.exitcode}; out of "
                                  "memory? raise --max-memory)") from None
            if kind == "stage":
                stage = payload
            elif kind == "ok":
                return pickle.loads(payload)
            elif kind == "error":
                raise pickle.loads(payload)
            elif kind == "memory":
                raise BudgetError(f"{what}: out of the {max_memory:g} GB memory budget while {stage} "
                                  "(simplify the expression or raise --max-memory)")
            elif kind == "recursion":
                raise BudgetError(f"{what}: expression nested too deeply while {stage}")
            else:
                raise RuntimeError(f"while {stage}: {payload}")
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join(5)
        parent.close()
