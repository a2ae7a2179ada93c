"""After `codegen verify` finds a mismatch: is the C wrong, or the scenario ill-conditioned at that
precision? The C's distance from the reference is set beside a second implementation's (float: the
reference in float32; double: its covariance products associated the other way), kind of signal by
kind of signal.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:   # verify calls this module: the type only
    from dfeif_codegen.check.verify import SignalError


@dataclass(frozen=True)
class Twin:
    """How `yardstick` speaks of a precision's second implementation, and how far from the C it
    may land for the scenario to be called ill-conditioned (`factor`)."""

    head: str         # the table's first line
    column: str       # the twin's column
    name: str         # the twin in a sentence
    where: str        # the precision, in a sentence
    advice: str       # what to do, or why, when the twin drifts as far
    culprit: str      # what is likely wrong when it does not
    factor: float


# float: the float32 twin rounds in every operation, as the C does, so the two land alike (the C
# 0.96x and 1.16x the twin on the arm's float master): within 3x. double: the twin changes one
# product per step and the C rounds otherwise in every operation, so the C lands a few times
# farther (1.6-2.4x on a stiff hydraulic model, with the twin's perturbation moved to P0 or the
# measurements): within 10x; a wrong C is orders away (the motor's twin: 1.3e-14).
TWINS = {"float": Twin("single-precision yardstick: distance from the float64 reference", "float32 reference",
                       "the float32 reference", "single precision",
                       "use double, replay, or a process noise suited to each chain", "the C's rounding", 3.0),
         "double": Twin("double-precision yardstick: distance from the reference", "other roundings",
                        "the reference with its covariance products associated the other way", "double precision",
                        "a stiff model, or a mode fast against Ts, amplifies every rounding", "the C", 10.0)}


def _kind(signal: str) -> str:
    """node0.x and node1.x are one kind (node.x): the nodes run one filter on like data."""
    return "node." + signal.split(".", 1)[1] if signal.startswith("node") else signal


def _drift_sources(kind: str) -> tuple[str, ...]:
    """The kinds whose drift a kind's inherits: the master fuses the nodes' x and P, so a twin
    drifting on the nodes' x drifts on the master's x too (node.x, master.x); a node, its own."""
    return (kind, "node." + kind.split(".")[1]) if kind.startswith("master.") else (kind,)


def yardstick(errors: list[SignalError], twin: list[SignalError], precision: str) -> str:
    """After a mismatch: the C's distance from the reference next to a second implementation's
    (float: float32_reference_errors; double: double_twin_errors). If the second lands as far
    (within TWINS' factor) on each kind of filter signal that failed (the nodes' x, their P, the
    master's x, its P; the master's beside its own and the nodes' of the same quantity, which it
    fuses: a node's x drifting says nothing of the master's P), the scenario is ill-conditioned at that
    precision (typically a process noise far too large for a chain, which makes retrodiction
    cancel; or a stiff model, whose canonical top derivative is a small difference of large
    terms), not the C. u and v are shown, not judged: the float32 twin's controller computes in
    double."""
    t = TWINS[precision]
    mine = {e.signal: e.worst for e in errors if e.signal != "late_applied"}
    other = {e.signal: e.worst for e in twin if e.signal != "late_applied"}
    lines = [t.head, f"signal        C           {t.column}"]
    lines += [f"{s:12s}  {mine[s]:.3e}   {other[s]:.3e}" + ("   (not judged)" if "." not in s else "") for s in mine]
    judged = [s for s in mine if "." in s]
    failed = {_kind(e.signal) for e in errors if e.signal in judged and not e.ok} or {_kind(s) for s in judged}
    ill = all(max(other[s] for s in judged if _kind(s) in _drift_sources(k))
              >= max(mine[s] for s in judged if _kind(s) == k) / t.factor for k in failed)
    lines.append(f"{t.name} drifts as far: the scenario is ill-conditioned in {t.where}, not the C ({t.advice})" if ill
                 else f"{t.name} stays closer: {t.culprit} is the likely cause")
    return "\n".join(lines)
