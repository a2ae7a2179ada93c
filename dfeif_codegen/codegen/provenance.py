"""What a generated module records of where it came from: the model's hash (the wire format
carries its first bytes, so a node and a master of different models refuse each other), the
tools' versions that print the code, and the CMake project version."""

from __future__ import annotations

import hashlib
import json
import re
from importlib import metadata

import sympy as sp

from dfeif_codegen import __version__
from dfeif_codegen.symbolic import model


def model_hash(m: model.Model) -> str:
    """SHA-256 of a canonical description of the model (sympy srepr is stable)."""
    doc = {
        "name": m.name, "ts": m.ts,
        "states": [s.name for s in m.states], "inputs": [u.name for u in m.inputs],
        "parameters": [[q.name, q.value] for q in m.parameters],
        "f": [sp.srepr(e) for e in m.f], "g": [sp.srepr(e) for e in m.g],
        "outputs": [[o.name, sp.srepr(o.expr), o.angle] for o in m.outputs],
    }
    if m.inverse:   # only when given: the hashes of models without one stay as they were
        doc["inverse"] = sorted(m.inverse.items())
    if m.mean_substeps != 1:   # the nodes' and the master's means must be the same map
        doc["mean_substeps"] = m.mean_substeps
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def versions() -> dict[str, str]:
    """What the generated files may record of the tools that wrote them: this tool's version
    and CasADi's release series (major.minor), which prints the kernels. Nothing that changes
    without the generated code changing (no patch releases, no numpy or sympy versions), so the
    committed output and `build --check` do not go stale on a dependency's patch release."""
    try:
        casadi = ".".join(metadata.version("casadi").split(".")[:2])
    except metadata.PackageNotFoundError:
        casadi = "unknown"
    return {"dfeif-codegen": __version__, "casadi": casadi}


def cmake_version(version: str) -> str:
    """The numeric part CMake accepts for project(VERSION) (`0.2.0.dev1` -> `0.2.0`)."""
    mt = re.match(r"\d+(?:\.\d+){0,3}", version)
    return mt.group(0) if mt else "0"
