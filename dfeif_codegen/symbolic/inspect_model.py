"""`codegen inspect`: what the toolkit derived from a model, for a person or (`--json`) a program."""

from __future__ import annotations

import json

import numpy as np
import sympy as sp

from dfeif_codegen.symbolic import flatness, model
from dfeif_codegen.symbolic.inverse import near_singular, singular_sets
from dfeif_codegen.errors import ModelError


def describe(flat: flatness.FlatSystem, ts: float) -> dict:
    """Everything `inspect` shows, as plain data (expressions as strings, matrices as lists)."""
    mdl = flat.model
    ext = flat.extension
    a_d, b_d, c_d = flat.discrete(ts)
    text = lambda e: str(sp.sympify(e))  # noqa: E731
    return {
        "model": mdl.name,
        "description": mdl.description,
        "source": mdl.source,
        "states": [{"name": s.name, "unit": s.unit, "description": s.description} for s in mdl.states],
        "inputs": [{"name": s.name, "unit": s.unit, "description": s.description} for s in mdl.inputs],
        "parameters": [{"name": q.name, "value": q.value, "unit": q.unit, "description": q.description}
                       for q in mdl.parameters],
        "flat_outputs": [{"name": o.name, "expr": text(o.expr), "angle": o.angle, "relative_degree": c.degree}
                         for o, c in zip(mdl.outputs, flat.chains)],
        "dynamic_extension": None if ext is None or not ext.steps else {
            "controller_states": ext.states, "inputs": list(ext.inputs),
            "chains": {u: list(c) for u, c in ext.chains.items()}, "steps": ext.describe()},
        "singular_sets": singular_sets(flat),
        "warnings": near_singular(flat),
        "canonical_state": [str(z) for z in flat.zeta],
        "phi": {str(z): text(e) for z, e in zip(flat.zeta, flat.phi)},
        "phi_inv": {s.name: text(e) for s, e in zip(mdl.states, flat.phi_inv)},
        "f_bar": {c.output: text(e) for c, e in zip(flat.chains, flat.F)},
        "g_bar": [[text(e) for e in flat.G.row(i)] for i in range(flat.m)],
        "ts": ts,
        "mean_substeps": mdl.mean_substeps,
        "A_d": a_d.tolist(),
        "B_d": b_d.tolist(),
        "C_d": c_d.tolist(),
    }


def _matrix(rows: list[list[float]]) -> str:
    return "\n".join("    [" + "  ".join(f"{v:12.6g}" for v in row) + " ]" for row in rows)


def _variable(s: dict) -> str:
    unit = f"[{s['unit']}]" if s["unit"] else ""
    return f"  {s['name']:<10} {unit:<12} {s['description']}".rstrip()


def render_text(info: dict) -> str:
    title = f"model {info['model']}" + (f": {info['description']}" if info["description"] else "")
    lines = [title, f"  from {info['source']}", "", "states:"]
    lines += [_variable(s) for s in info["states"]]
    lines += ["inputs:"] + [_variable(s) for s in info["inputs"]]
    lines += ["flat outputs:"] + [
        f"  {o['name']:<10} = {o['expr']}   relative degree {o['relative_degree']}" + ("   (angle)" if o["angle"] else "")
        for o in info["flat_outputs"]]
    ext = info.get("dynamic_extension")
    if ext:
        lines += ["", "dynamic extension (the decoupling matrix of the model as written is singular):"]
        lines += [f"  {s}" for s in ext["steps"]]
        lines += [f"  controller states {', '.join(ext['controller_states'])} (the controller integrates them; "
                  f"the first of each chain is the plant's input), extended inputs {', '.join(ext['inputs'])}"]
    if info.get("singular_sets"):
        lines += ["", "singular sets (a reference must stay away from them):"]
        lines += [f"  {s}" for s in info["singular_sets"]]
    lines += [f"warning: {w}" for w in info.get("warnings", [])]
    lines += ["", "zeta = Phi(x):"] + [f"  {k} = {v}" for k, v in info["phi"].items()]
    lines += ["x = Phi^-1(zeta):"] + [f"  {k} = {v}" for k, v in info["phi_inv"].items()]
    lines += ["", "canonical form  y^(r) = f_bar(zeta) + g_bar(zeta) u:"]
    lines += [f"  f_bar[{k}] = {v}" for k, v in info["f_bar"].items()]
    lines += [f"  g_bar[{i}] = [{', '.join(row)}]" for i, row in enumerate(info["g_bar"])]
    lines += ["", f"held predictor's mean: {info['mean_substeps']} ETD2RK step(s) per period of Ts = {info['ts']:g} s"]
    lines += ["", f"exact discretization at Ts = {info['ts']:g} s:", "  A_d =", _matrix(info["A_d"]),
              "  B_d =", _matrix(info["B_d"]), "  C_d =", _matrix(info["C_d"])]
    return "\n".join(lines)


def inspect(spec, ts: float | None = None, max_seconds: float | None = None,
            max_memory: float | None = None) -> dict:
    """What `codegen inspect` shows for a model (a built-in name, a .toml path or a Model), at
    the sampling period `ts` (default the model's), as plain data. The derivation runs under the
    budget of `build` (CPU seconds, GB; None: the process's default)."""
    mdl = spec if isinstance(spec, model.Model) else model.load(str(spec))
    ts = mdl.ts if ts is None else ts
    if isinstance(ts, bool) or not isinstance(ts, (int, float)) or not (np.isfinite(ts) and 1e-9 <= ts <= 1e3):
        raise ModelError(f"--ts {ts!r}: the sampling period must be a number of seconds in [1e-9, 1e3]"
                         + (f", not a {type(ts).__name__}" if not isinstance(ts, (int, float)) else ""))
    from dfeif_codegen import budget  # the same time/memory budget as `build`
    flat = budget.bounded(flatness.derive, (mdl,), max_seconds, max_memory, f"deriving {mdl.source}")
    return describe(flat, float(ts))


def render_json(info: dict) -> str:
    return json.dumps(info, indent=2)
