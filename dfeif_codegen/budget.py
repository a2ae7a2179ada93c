"""A time and memory budget for the symbolic work.

Why a child process: a 63-character expression can make sympy expand for hours or allocate
tens of GB before any Python-level check sees it. The work runs in a forked child with an
address-space limit (RLIMIT_AS: what it maps already plus the budget, so a machine whose BLAS
reserves much address space is not refused for it) while the parent watches the clock; the child reports each stage
it enters, so a refusal names what it was working on. Without fork (not Linux/macOS) the work
runs inline, unbounded; DFEIF_NO_BUDGET=1 does the same (for a debugger).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import pickle
import time

from dfeif_codegen.errors import CodegenError

MAX_SECONDS = 60.0
MAX_MEMORY = 2.0  # GB, the unit of --max-memory


class BudgetError(CodegenError):
    """The derivation ran out of its time or memory budget."""


def _mapped() -> int:
    """Bytes of address space this process maps now (Linux /proc; 0 where unknown)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


def _child(conn, fn, args, max_bytes: float) -> None:
    try:
        import resource
        limit = int(_mapped() + max_bytes)  # on top of what is mapped already (libraries, BLAS)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
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
        conn.send(("bug", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def bounded(fn, args: tuple, max_seconds: float, max_memory: float, what: str):
    """`fn(*args, progress=...)` within max_seconds seconds and max_memory GB (the units of
    --max-seconds and --max-memory); BudgetError (exit 2) naming the stage when either runs
    out. CodegenErrors raised inside come out unchanged."""
    for flag, value in (("--max-seconds", max_seconds), ("--max-memory", max_memory)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 or value != value:
            raise BudgetError(f"{flag} must be a positive number, got {value!r}")
    if "fork" not in mp.get_all_start_methods() or os.environ.get("DFEIF_NO_BUDGET"):
        return fn(*args, progress=None)
    ctx = mp.get_context("fork")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child, fn, args, max_memory * 1e9), daemon=True)
    proc.start()
    child.close()
    stage, deadline = "starting", time.monotonic() + max_seconds
    try:
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise BudgetError(f"{what}: stopped after {max_seconds:g} s while {stage} (the expression "
                                  "grows too large; simplify it or raise --max-seconds)")
            if not parent.poll(min(left, 0.5)):
                if not proc.is_alive() and not parent.poll(0):
                    raise BudgetError(f"{what}: the derivation died while {stage} (exit {proc.exitcode}; "
                                      "out of memory? raise --max-memory)")
                continue
            try:
                kind, payload = parent.recv()
            except EOFError:
                proc.join(1)
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
