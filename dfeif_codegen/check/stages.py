"""`verify`'s three steps, each called once and in this order: compile the generated C (for the
host: one shared library loaded with ctypes, or a stand-alone program under ASan+UBSan; for the
Cortex-M4F: an ELF for QEMU), run the recording through it, compare its outputs with the
reference's. Each step takes what the previous one returned and nothing else of its kind, so
compiling never runs and running never compiles."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from dfeif_codegen.check import driver_io, harness
from dfeif_codegen.check import target as targets
from dfeif_codegen.errors import MismatchError


@dataclass
class Compiled:
    """What `compile` made: `kind` "library", "program" (sanitized) or "cortex-m4f"."""

    kind: str
    model: harness.ModelDir
    work: Path
    artifact: object        # harness.Library, the program's path, or target.App


@dataclass
class Ran:
    """The C's outputs (shaped as replay_recording's) and, on the target, its sizes and stack."""

    outputs: dict
    target_report: str = ""


def compile(model: harness.ModelDir, target: str, sanitize: bool, work: Path) -> Compiled:
    """Step 1: the generated C and the scenario driver, compiled for `target`."""
    if target == "cortex-m4f":
        return Compiled("cortex-m4f", model, work / "target", targets.build_app(model, work / "target"))
    if sanitize:
        (work / "host").mkdir(parents=True, exist_ok=True)
        return Compiled("program", model, work / "host", harness.program(model, work / "host", sanitize=True))
    return Compiled("library", model, work / "host", harness.Library(model, work / "host"))


def run(compiled: Compiled, rec, inputs: str) -> Ran:
    """Step 2: the recording replayed through what step 1 compiled."""
    if compiled.kind == "cortex-m4f":
        result = targets.run_app(compiled.artifact, rec, inputs=inputs)   # type: ignore[arg-type]
        if result.status["status"] != 0:
            raise MismatchError(driver_io.failure(result.status))
        return Ran(result.outputs, targets.report(result))
    if compiled.kind == "program":
        return Ran(harness.run_compiled_program(compiled.artifact, compiled.model, rec, compiled.work,  # type: ignore[arg-type]
                                                inputs=inputs)[1])
    return Ran(compiled.artifact.run(rec, inputs))   # type: ignore[attr-defined]
