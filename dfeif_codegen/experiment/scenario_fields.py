"""Typed reads of a scenario file's fields (experiment/scenario.py parses with them): each
read fails in one line that names the field and its line in the file."""

from __future__ import annotations

from typing import TYPE_CHECKING

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.experiment.network import Link
from dfeif_codegen.symbolic import disturbance as disturbances

if TYPE_CHECKING:
    from dfeif_codegen.experiment.scenario import Scenario

STD_SPAN = (1e-100, 1e100)   # a scenario's standard deviations (Reader.stds)


class Reader:
    """Typed reads of a scenario's fields, each failing in one line that names the field's line."""

    def __init__(self, sc: Scenario):
        self.sc = sc

    def fail(self, key: str, message: str):
        raise ScenarioError(f"{self.sc.where(key)}: {message}")

    def number(self, table, section, key, default, positive=False, allow_zero=True, integer=False):
        value = table.get(key, default)
        ok = disturbances.finite_number(value) and (not integer or float(value).is_integer())
        if ok and positive and (value < 0 or (value == 0 and not allow_zero)):
            ok = False
        if not ok:
            kind = "an integer" if integer else "a finite number"
            sign = " > 0" if positive and not allow_zero else (" >= 0" if positive else "")
            self.fail(f"{section}.{key}", f"must be {kind}{sign}, got {value!r}")
        return int(value) if integer else float(value)

    def numbers(self, table, section, key, default, positive=True):
        value = table.get(key, default)
        items = value if isinstance(value, list) else [value]
        if not items or not all(disturbances.finite_number(v) for v in items) \
                or (positive and not all(v > 0 for v in items)):
            self.fail(f"{section}.{key}", f"must be {'a positive' if positive else 'a'} finite number or a non-empty "
                                          f"list of them, got {value!r}")
        return [float(v) for v in items]

    def std(self, table, section, key, default) -> float:
        """One standard deviation (or scale of them), as `stds`."""
        value = self.number(table, section, key, default, positive=True, allow_zero=False)
        return self._in_span([value], section, key, table)[0]

    def stds(self, table, section, key, default) -> list[float]:
        """Standard deviations (and their scales): positive, and within STD_SPAN, so that their
        squares, the covariances' inverses and the two multiplied stay normal doubles (a std of
        1e-300 made a singular covariance, 1e300 beside 1 a condition number of 1e600)."""
        return self._in_span(self.numbers(table, section, key, default), section, key, table)

    def _in_span(self, values: list[float], section, key, table) -> list[float]:
        lo, hi = STD_SPAN
        if not all(lo <= v <= hi for v in values):
            self.fail(f"{section}.{key}", f"standard deviations must be within [{lo:g}, {hi:g}], got {table.get(key)!r}")
        return values

    def names(self, table, section, key, default, allowed):
        value = table.get(key, default)
        if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
            self.fail(f"{section}.{key}", f"must be a non-empty list of names from {', '.join(allowed)}")
        for v in value:
            if v not in allowed:
                self.fail(f"{section}.{key}", f"'{v}' is not one of {', '.join(allowed)}")
        return list(value)

    def link(self, table, section) -> Link:
        p = self.number(table, section, "p", 0.0, positive=True)
        d = self.number(table, section, "d", 0, positive=True, integer=True)
        lk = Link(p, d, self.number(table, section, "p_drop", 0.0, positive=True))
        if lk.problem():
            self.fail(section, lk.problem())
        return lk
