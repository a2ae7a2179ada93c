"""A user-given reference: a CSV of the flat outputs, with their derivatives or without.

The file has a header row and one row per sample: `t` (seconds from the run's start, strictly
increasing, the first at or before 0 and the last at or after the run's last step), then per flat
output `<name>` and, optionally, its derivatives `<name>_d1`, `<name>_d2`, ... The controller
needs every output's derivatives up to its relative degree r (its flags y, y', ..., y^(r)):

- **derivatives given** (`<name>_d1` ... `<name>_dr` all present): each order j is interpolated
  between samples by the cubic Hermite polynomial whose slopes are the next order's samples
  (error at most h^4/384 max|y^(j+4)| for sample spacing h); the top order r, without a slope
  unless `<name>_d(r+1)` is given, linearly (error at most h^2/8 max|y^(r+2)|). At the sample
  times the given values come back exactly.
- **outputs only** (no derivative column): a local polynomial least-squares fit, Savitzky-Golay's
  filter for any spacing: at each time the polynomial of degree r + 2 fitted to the nearest
  samples (at least 2(r + 2) + 1 of them, or every sample within `smoothing` seconds when that is
  wider) gives y and its derivatives as the polynomial's. It reproduces any polynomial of degree
  r + 2 exactly; on smooth data its error on y^(j) is the fit applied to the Taylor remainder,
  O(w^(r+3-j)) for a window w; white noise sigma on the samples reaches y^(j) as about
  sigma / (w^j sqrt(samples)): noisy recordings need a wider `smoothing` window. Numpy only.

Every problem with the file is one line naming the file and the row (line of the file) or column.
"""

from __future__ import annotations

import csv
import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.paths import MAX_TABLE_BYTES, read_bytes

MIN_ROWS = 2
KIND = "trajectory"   # the reference name a scenario lists for its file


@dataclass(frozen=True)
class Trajectory:
    """The file's samples. Compared and hashed by path, content digest and smoothing, so a changed
    file is another reference (another run id); the samples travel with it to worker processes."""

    path: str                  # as the scenario names it, joined to the scenario's folder
    digest: str                # sha256 of the file's bytes
    smoothing: float = 0.0     # [s] window of the fit for outputs given without derivatives
    columns: tuple = field(default=(), compare=False, repr=False)
    data: np.ndarray = field(default=None, compare=False, repr=False)   # (rows, columns)

    @property
    def t(self) -> np.ndarray:
        return self.data[:, 0]

    def column(self, name: str) -> np.ndarray | None:
        return self.data[:, self.columns.index(name)] if name in self.columns else None

    def given_orders(self, name: str) -> int:
        """How many consecutive derivative columns `<name>_d1`, ... the file gives."""
        k = 0
        while f"{name}_d{k + 1}" in self.columns:
            k += 1
        return k

    def amplitude(self, names) -> tuple:
        """Per output, half its swing over the file (the default tracking bound is twice it)."""
        return tuple(float(np.ptp(self.column(n))) / 2 for n in names)

    def outputs(self, names, degrees) -> list:
        """Per flat output, an object with `flags(t, r)` as experiment/trajectory.Reference."""
        return [Hermite(self, n) if self.given_orders(n) >= r else LocalFit(self, n, r)
                for n, r in zip(names, degrees)]


def read(path: Path, smoothing: float = 0.0) -> Trajectory:
    """The CSV at `path`, checked for what does not depend on the model (header, numbers, time)."""
    shown = str(path)
    raw = read_bytes(path, shown, ScenarioError, "trajectory", MAX_TABLE_BYTES)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{shown}: cannot read the trajectory: {exc}") from None
    rows = list(csv.reader(text.splitlines()))
    lines = [i + 1 for i, row in enumerate(rows) if row and any(c.strip() for c in row)]
    if not lines:
        raise ScenarioError(f"{shown}: empty: needs a header row (t, then the flat outputs) and samples")
    header = [c.strip() for c in rows[lines[0] - 1]]
    if header[0] != "t":
        raise ScenarioError(f"{shown}:1: column 1 is '{header[0]}': the first column must be t (seconds)")
    for i, name in enumerate(header):
        if not name or header.index(name) != i:
            raise ScenarioError(f"{shown}:1: column {i + 1} '{name}': " + ("empty name" if not name else "repeated"))
    values = np.empty((len(lines) - 1, len(header)))
    for r, line in enumerate(lines[1:]):
        row = rows[line - 1]
        if len(row) != len(header):
            raise ScenarioError(f"{shown}:{line}: {len(row)} fields, the header has {len(header)}")
        for c, cell in enumerate(row):
            try:
                values[r, c] = float(cell)
            except ValueError:
                raise ScenarioError(f"{shown}:{line}: column {header[c]}: '{cell.strip()}' is not a number") from None
            if not math.isfinite(values[r, c]):
                raise ScenarioError(f"{shown}:{line}: column {header[c]}: {cell.strip()} is not a finite number")
    if len(values) < MIN_ROWS:
        raise ScenarioError(f"{shown}: {len(values)} sample row(s): a trajectory needs at least {MIN_ROWS}")
    back = np.flatnonzero(np.diff(values[:, 0]) <= 0)
    if back.size:
        r = int(back[0]) + 1
        raise ScenarioError(f"{shown}:{lines[r + 1]}: t = {values[r, 0]:g} s is not after the previous row's "
                            f"{values[r - 1, 0]:g} s (time must increase)")
    values.flags.writeable = False
    return Trajectory(shown, hashlib.sha256(raw).hexdigest(), float(smoothing), tuple(header), values)


def check(traj: Trajectory, names, degrees, end: float, model: str, where: str = "") -> None:
    """What depends on the model and the run: a value column per flat output, its derivative
    columns all or none up to the relative degree, no other column, enough samples for the fit,
    and samples from the run's start (t = 0) to its last step `end`."""
    at = traj.path
    pre = f"{where}: " if where else ""
    known = {"t"} | set(names)
    for n, r in zip(names, degrees):
        if n not in traj.columns:
            raise ScenarioError(f"{pre}{at}: no column '{n}' for flat output {n} of model {model} "
                                f"(columns: {', '.join(traj.columns)})")
        given = traj.given_orders(n)
        extra = [c for c in traj.columns if c.startswith(f"{n}_d") and c[len(n) + 2:].isdigit()]
        known |= set(extra)
        if len(extra) > given:
            missing = f"{n}_d{given + 1}"
            raise ScenarioError(f"{pre}{at}: column {missing} missing: {', '.join(sorted(extra))} given; output {n} "
                                f"needs every derivative up to {n}_d{r} (relative degree {r}), or none, to have "
                                f"them fitted from {n}")
        if 0 < given < r:
            raise ScenarioError(f"{pre}{at}: column {n}_d{given + 1} missing: output {n} needs every derivative up "
                                f"to {n}_d{r} (relative degree {r}), or none, to have them fitted from {n}")
        if given == 0 and len(traj.t) < LocalFit.points(r):
            raise ScenarioError(f"{pre}{at}: {len(traj.t)} rows: fitting {n} up to its derivative of order {r} "
                                f"needs at least {LocalFit.points(r)} samples")
    for c in traj.columns:
        if c not in known:
            raise ScenarioError(f"{pre}{at}:1: column '{c}' is not t, a flat output of model {model} "
                                f"({', '.join(names)}) or one's derivative <name>_d<order>")
    if traj.t[0] > 0:
        raise ScenarioError(f"{pre}{at}:2: starts at t = {traj.t[0]:g} s, after the run's start (t = 0)")
    if traj.t[-1] < end - 1e-9 * max(1.0, abs(end)):
        raise ScenarioError(f"{pre}{at}:{len(traj.t) + 1}: ends at t = {traj.t[-1]:g} s, shorter than the run "
                            f"(its last step is at t = {end:g} s)")


class Hermite:
    """One output whose derivatives the file gives: order j by cubic Hermite with order j + 1 as
    slope, the top given order linearly (see the module docstring)."""

    def __init__(self, traj: Trajectory, name: str):
        self.t = traj.t
        self.d = np.column_stack([traj.column(name)] + [traj.column(f"{name}_d{k}")
                                                        for k in range(1, traj.given_orders(name) + 1)])

    def flags(self, t: float, r: int) -> np.ndarray:
        t = min(max(float(t), self.t[0]), self.t[-1])
        i = int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2))
        h = self.t[i + 1] - self.t[i]
        s = (t - self.t[i]) / h
        out = np.empty(r + 1)
        for j in range(r + 1):
            y0, y1 = self.d[i, j], self.d[i + 1, j]
            if j + 1 < self.d.shape[1]:
                m0, m1 = self.d[i, j + 1] * h, self.d[i + 1, j + 1] * h
                out[j] = ((2 * s**3 - 3 * s**2 + 1) * y0 + (s**3 - 2 * s**2 + s) * m0
                          + (-2 * s**3 + 3 * s**2) * y1 + (s**3 - s**2) * m1)
            else:
                out[j] = (1 - s) * y0 + s * y1
        return out


class LocalFit:
    """One output given without derivatives: the local least-squares polynomial of degree r + 2
    around each time (Savitzky-Golay for any spacing; see the module docstring)."""

    @staticmethod
    def points(r: int) -> int:
        return 2 * (r + 2) + 1

    def __init__(self, traj: Trajectory, name: str, r: int):
        self.t, self.y, self.degree = traj.t, traj.column(name), r + 2
        self.half = traj.smoothing / 2

    def flags(self, t: float, r: int) -> np.ndarray:
        t = min(max(float(t), self.t[0]), self.t[-1])
        N, need = len(self.t), self.points(self.degree - 2)
        lo = int(np.searchsorted(self.t, t - self.half, side="left"))
        hi = int(np.searchsorted(self.t, t + self.half, side="right"))
        if hi - lo < need:   # the nearest `need` samples: centred inside, one-sided at the file's ends
            c = int(np.searchsorted(self.t, t))
            lo = min(max(c - need // 2, 0), N - need)
            hi = lo + need
        scale = max(abs(self.t[lo] - t), abs(self.t[hi - 1] - t))
        tau = (self.t[lo:hi] - t) / scale
        coef = np.linalg.lstsq(np.vander(tau, self.degree + 1, increasing=True), self.y[lo:hi], rcond=None)[0]
        j = np.arange(r + 1)
        return coef[: r + 1] * np.array([math.factorial(k) for k in j]) / scale ** j
