"""Entries of Phi^-1 the user gives in the model's [inverse] table.

Sympy's solver does not finish every coupled subsystem (a 3-D quadrotor's roll, pitch and thrust
from its accelerations and yaw), while the user often knows a closed form. A given entry is
taken as solved before the solver starts; it is trusted no more than a branch the solver found:
it must round-trip at the same sampled states of the declared domain, in double precision and
then in float32, or the model is refused at the entry's line.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import sympy as sp

from dfeif_codegen.errors import ModelError
from dfeif_codegen.symbolic.expr_parser import parse_expression
from dfeif_codegen.symbolic.model import Model

Check = Callable[[dict], np.ndarray]   # a candidate {state: expression of zeta} -> per test point ok


def given_entries(model: Model, zeta: list[sp.Symbol], rows: np.ndarray, zeta_rows: np.ndarray,
                  round_trips: Check, float32_trips: Check) -> dict[sp.Symbol, sp.Expr]:
    """The [inverse] entries as {state: expression of zeta and parameters}, each checked by the
    solver's own round-trip tests (`rows` are the test states, `zeta_rows` Phi of them). Keys are
    matched against the states of the model as derived, so a dynamic extension's T and T_d1
    are keys too."""
    names = {str(z): z for z in zeta} | {q.name: sp.Symbol(q.name) for q in model.parameters}
    states = {s.name: sp.Symbol(s.name) for s in model.states}
    out: dict[sp.Symbol, sp.Expr] = {}
    for key, text in model.inverse.items():
        at = model.where(f"inverse.{key}")
        if key not in states:
            raise ModelError(f"{at}: '{key}' is not a state of the model as derived "
                             f"(states: {', '.join(states)})")
        expr = parse_expression(text, names, at)
        var = states[key]
        ok = round_trips({var: expr})
        if not ok.all():
            raise ModelError(f"{at}: does not invert Phi at {_state(model, rows, zeta_rows, zeta, ~ok, expr)}")
        ok = float32_trips({var: expr})
        if not ok.all():
            raise ModelError(f"{at}: loses its digits in float32 at "
                             f"{_state(model, rows, zeta_rows, zeta, ~ok, expr)}: write a form that does not cancel")
        out[var] = expr
    return out


def _state(model: Model, rows: np.ndarray, zeta_rows: np.ndarray, zeta: list, bad: np.ndarray,
           expr: sp.Expr) -> str:
    """The first failing test state, and what the entry gives there against the state's value,
    so that the user sees which branch or sign is wrong."""
    k = int(np.argmax(bad))
    state = ", ".join(f"{s.name} = {v:.4g}" for s, v in zip(model.states, rows[k]))
    point = {z: float(v) for z, v in zip(zeta, zeta_rows[k])} | model.param_values
    value = sp.sympify(expr).subs(point).evalf()
    shown = f"{float(value):.6g}" if value.is_real else str(value)
    return f"{state}: it gives {shown}"
