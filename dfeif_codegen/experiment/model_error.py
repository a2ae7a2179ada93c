"""Model error: the true plant's parameters differ from the model's, so a user can measure how a
filter copes with a model that is wrong.

Only the plant (its dynamics `f`, `g` and the truth's canonical coordinates `Phi`, i.e. the true
flat outputs and their derivatives) takes the perturbed values; the filters (derivative-free,
EKF, UKF), the controller and the cameras' `recover` keep the model's nominal ones. Per
parameter p with nominal value p0:

    p = p0 (1 + r + delta) + a

r: a fixed relative offset, a: a fixed absolute one, delta: drawn per run, uniform on
[-s, s] or Gaussian with std s (truncated at 3 s by redrawing), s the parameter's spread. The
draw comes from the run's seed through its own stream (spawn key 3 of the seed, beside the
network, noise and initial-state streams): every filter, method and delay row of one seed sees
the same plant, so their results stay paired, and a run is reproducible from its seed. A
relative change of 100% or more (|r| + s >= 1, or 3 s for a Gaussian) could flip a parameter's
sign and is refused, and so is an absolute offset that could make a parameter 0 or flip it.

Scenario TOML:

    [model_error]
    relative = { R = 0.2 }       # the plant's R is 1.2 times the model's
    absolute = { k_d = 0.01 }    # added to the model's value
    draw = "uniform"             # per run: "uniform" (+-spread), "normal" (std spread), "none"
    spread = 0.05                # relative; a number for every parameter (or those in `params`),
    params = ["J", "R"]          #   or a table per parameter: spread = { J = 0.05, R = 0.2 }
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dfeif_codegen.errors import ScenarioError
from dfeif_codegen.symbolic.disturbance import finite_number

DRAWS = ("none", "uniform", "normal")
KEYS = {"relative", "absolute", "draw", "spread", "params"}
STREAM = 3          # spawn key of the run's seed that draws the parameters
ALL = "*"           # `spread` entry meaning every parameter not named


@dataclass(frozen=True)
class ParamError:
    """What the plant's parameters are, relative to the model's: plain, hashable, picklable."""

    relative: tuple = ()      # ((name, r), ...)
    absolute: tuple = ()      # ((name, a), ...)
    draw: str = "none"
    spread: tuple = ()        # ((name or ALL, s), ...)

    @property
    def active(self) -> bool:
        return bool(self.relative or self.absolute or (self.draw != "none" and any(s for _, s in self.spread)))

    def check(self, model, where) -> None:
        """Against the model: every name a parameter, no sign flip. `where(key)` names the line."""
        known = [q.name for q in model.parameters]
        for key, items in (("relative", self.relative), ("absolute", self.absolute), ("spread", self.spread)):
            for name, _ in items:
                if name != ALL and name not in known:
                    raise ScenarioError(f"{where(f'{key}.{name}')}: '{name}' is not a parameter of model {model.name} "
                                        f"(its parameters: {', '.join(known) or 'none'})")
        if self.active and not known:
            raise ScenarioError(f"{where('model_error')}: model {model.name} has no parameters to perturb")
        rel, ab, spread = self._vectors(model)
        reach = np.abs(rel) + (TRUNCATION if self.draw == "normal" else 1.0) * spread * (self.draw != "none")
        if np.any(reach >= 1.0):
            i = int(np.argmax(reach))
            raise ScenarioError(f"{where('relative' if rel[i] else 'spread')}: parameter {known[i]} could change "
                                f"by {100 * reach[i]:.0f}% of its value (sign flip): keep |relative| + "
                                f"{'3 x ' if self.draw == 'normal' else ''}spread below 1")
        self._check_absolute(model, ab, reach, where)

    def _check_absolute(self, model, ab, reach, where) -> None:
        """An absolute offset may not make a parameter 0 or flip its sign, even at the draw's
        edge: the plant would divide by 0 or run another system (as a relative one >= 100%)."""
        for i, q in enumerate(model.parameters):
            p0 = float(q.value)
            if not ab[i] or p0 == 0:      # a parameter the model leaves at 0 may take any value
                continue
            edges = (p0 * (1.0 - reach[i]) + ab[i], p0 * (1.0 + reach[i]) + ab[i])
            bad = [v for v in edges if v == 0 or (v > 0) != (p0 > 0)]
            if bad:
                raise ScenarioError(f"{where(f'absolute.{q.name}')}: the model's {q.name} = {p0:g} plus {ab[i]:g} "
                                    f"reaches {bad[0]:g} (zero or sign flip): keep |absolute| below "
                                    f"{abs(p0) * (1.0 - reach[i]):g}")

    def stds(self, model) -> np.ndarray:
        """Each parameter's relative error, as a standard deviation (model order): the draw's when
        drawn (spread/sqrt(3) uniform, the truncated normal's), else the size of its fixed offset
        relative to its value; 0 for a parameter left alone."""
        rel, ab, spread = self._vectors(model)
        p0 = np.array([abs(q.value) for q in model.parameters], dtype=float)
        fixed = np.abs(rel) + np.abs(ab) / np.where(p0 == 0, 1.0, p0)
        level = math.sqrt(TRUNCATED_VARIANCE) if self.draw == "normal" else 1.0 / math.sqrt(3.0)
        return np.where((spread > 0) & (self.draw != "none"), spread * level, fixed)

    def _vectors(self, model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        index = {q.name: i for i, q in enumerate(model.parameters)}
        rel, ab, spread = (np.zeros(len(index)) for _ in range(3))
        for name, s in self.spread:
            if name == ALL:
                spread[:] = s
        for vec, items in ((rel, self.relative), (ab, self.absolute), (spread, self.spread)):
            for name, value in items:
                if name != ALL:
                    vec[index[name]] = value
        return rel, ab, spread

    def values(self, model, seed: int) -> np.ndarray | None:
        """The plant's parameter vector (model order) for the run of `seed`; None: the model's own."""
        if not self.active:
            return None
        p0 = np.array([q.value for q in model.parameters], dtype=float)
        rel, ab, spread = self._vectors(model)
        return p0 * (1.0 + rel + spread * self._delta(len(p0), seed)) + ab

    def _delta(self, count: int, seed: int) -> np.ndarray:
        """One draw per parameter of the model (drawn for all, whichever are perturbed, so adding
        a parameter to the list leaves the others' draws unchanged)."""
        if self.draw == "none":
            return np.zeros(count)
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(STREAM,)))
        if self.draw == "uniform":
            return rng.uniform(-1.0, 1.0, count)
        z = rng.standard_normal(count)
        while np.any(np.abs(z) > TRUNCATION):
            bad = np.abs(z) > TRUNCATION
            z[bad] = rng.standard_normal(int(bad.sum()))
        return z

    def design(self, model, at_least: int = 8) -> list["ParamError"]:
        """Fixed errors standing in for the draw when a mean over runs is wanted from few of them
        (`codegen scenario`'s calibration): the rows of a two-level orthogonal array (a
        Sylvester-Hadamard matrix's columns 1..d, d the perturbed parameters) at the draw's
        standard deviation, +-1/sqrt(3) (uniform) or +-0.987 (normal truncated at 3), times the
        spread. Balanced columns, orthogonal pairs
        and the draw's second moment: the average over the rows of any function quadratic in the
        draw is its expectation. Why: a run's NEES under a drawn error is close to quadratic in
        the draw and spans decades (motor, +-5%: 1.1 to 12.6 between the 5% and 95% points), so
        8 random draws put the mean anywhere in 2.0-6.8 where the 100-run band is 2.5-3.5."""
        level = np.sqrt(TRUNCATED_VARIANCE) if self.draw == "normal" else 1.0 / np.sqrt(3.0)
        return self._array(model, at_least, level, fold=False)

    def corners(self, model) -> list["ParamError"]:
        """Fixed errors at the draw's edges, where a loop is likeliest lost (`codegen scenario`'s
        pole check, experiment/pole_margin.py): the rows of `design`'s array at the full spread
        (uniform; a normal draw at twice its spread, its 95% points) and their negatives, so
        that every parameter sits at each edge, every pair at each of its four sign pairs, and
        the all-low and all-high plants are among them."""
        return self._array(model, 8, 2.0 if self.draw == "normal" else 1.0, fold=True)

    def _array(self, model, at_least: int, level: float, fold: bool) -> list["ParamError"]:
        rel, ab, spread = self._vectors(model)
        names = [q.name for q in model.parameters]
        moved = [i for i, s in enumerate(spread) if s and self.draw != "none"]
        if not moved:
            return [self]
        size = max(at_least, 1 << len(moved).bit_length())       # a power of two above d
        signs = _hadamard(size)[:, 1:len(moved) + 1]
        signs = np.vstack([signs, -signs]) if fold else signs
        out = []
        for row in signs:
            r = rel.copy()
            r[moved] += spread[moved] * level * row
            out.append(ParamError(tuple((names[i], float(r[i])) for i in range(len(names)) if r[i]),
                                  self.absolute))
        return out

    def describe(self) -> str:
        parts = [f"{n} {100 * r:+.3g}%" for n, r in self.relative] + [f"{n} {a:+.4g}" for n, a in self.absolute]
        text = ("fixed: " + ", ".join(parts)) if parts else ""
        if self.draw != "none" and any(s for _, s in self.spread):
            how = "uniform +-" if self.draw == "uniform" else "Gaussian, std "
            drawn = ", ".join(("every parameter" if n == ALL else n) + f" {how}{100 * s:.3g}%"
                              for n, s in self.spread if s)
            text = (text + "; " if text else "") + f"drawn per run: {drawn}"
        return text or "none"


NONE = ParamError()
TRUNCATION = 3.0   # a normal draw is redrawn beyond this many standard deviations (_delta)
# its variance once truncated: 1 - 2c phi(c) / (2 Phi(c) - 1) at c = TRUNCATION
TRUNCATED_VARIANCE = 1.0 - (2.0 * TRUNCATION * math.exp(-TRUNCATION ** 2 / 2) / math.sqrt(2.0 * math.pi)
                            / math.erf(TRUNCATION / math.sqrt(2.0)))


def _hadamard(size: int) -> np.ndarray:
    """Sylvester's Hadamard matrix of order `size` (a power of two): +-1, orthogonal rows and
    columns, the first column all ones."""
    h = np.ones((1, 1))
    while h.shape[0] < size:
        h = np.block([[h, h], [h, -h]])
    return h


# --- reading it ---------------------------------------------------------------------------------

def from_table(table: dict, fail) -> ParamError:
    """A [model_error] table; `fail(key, message)` raises with the line."""
    for key in table:
        if key not in KEYS:
            fail(f"model_error.{key}", f"unknown field (expected one of {', '.join(sorted(KEYS))})")

    def named(key) -> tuple:
        value = table.get(key, {})
        if not isinstance(value, dict) or not all(finite_number(v) for v in value.values()):
            fail(f"model_error.{key}", f"must be a table of parameter = number, got {value!r}")
        return tuple(sorted((str(k), float(v)) for k, v in value.items()))

    draw = table.get("draw", "uniform" if "spread" in table else "none")
    if draw not in DRAWS:
        fail("model_error.draw", f"must be one of {', '.join(DRAWS)}, got {draw!r}")
    spread_value = table.get("spread", 0.0)
    if isinstance(spread_value, dict):
        spread = named("spread")
        if "params" in table:
            fail("model_error.params", "give either spread per parameter (a table) or params, not both")
    elif finite_number(spread_value):
        params = table.get("params", [ALL])
        if not isinstance(params, list) or not params or not all(isinstance(p, str) for p in params):
            fail("model_error.params", f"must be a non-empty list of parameter names, got {params!r}")
        spread = tuple((p, float(spread_value)) for p in dict.fromkeys(params))
    else:
        fail("model_error.spread", f"must be a number or a table of parameter = number, got {spread_value!r}")
    if any(s < 0 for _, s in spread):
        fail("model_error.spread", "must be >= 0")
    if draw != "none" and not any(s for _, s in spread):
        fail("model_error.spread", f"draw = \"{draw}\" needs a spread > 0")
    return ParamError(named("relative"), named("absolute"), draw, spread if draw != "none" else ())


def from_option(text: str) -> ParamError:
    """`--param-error`: `S` draws every parameter uniformly in +-S (relative) per run; `NAME=R,...`
    sets fixed relative offsets; `0` is the exact model (overriding the scenario's)."""
    where = "--param-error"
    text = str(text).strip()
    try:
        spread = float(text)
    except ValueError:
        spread = None
    if spread is not None:
        if not np.isfinite(spread) or spread < 0:
            raise ScenarioError(f"{where}: {text}: needs a spread >= 0 (0.2: every parameter +-20% per run)")
        return ParamError(draw="uniform", spread=((ALL, spread),)) if spread > 0 else NONE
    offsets = {}
    for item in text.split(","):
        name, _, value = item.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = float("nan")
        if not name.strip() or not np.isfinite(number):
            raise ScenarioError(f"{where}: '{item}' is neither a spread (0.2) nor NAME=RELATIVE (R=0.2)")
        if name.strip() in offsets:
            raise ScenarioError(f"{where}: {text}: {name.strip()} is given twice; give distinct parameter names")
        offsets[name.strip()] = number
    return ParamError(relative=tuple(sorted(offsets.items())))


# --- saying it -----------------------------------------------------------------------------------

def summary(spec: ParamError, model, seeds) -> dict:
    """What was asked and every run's parameter vector (the JSON settings; `report` prints it)."""
    out = {"describe": spec.describe(), "relative": dict(spec.relative), "absolute": dict(spec.absolute),
           "draw": spec.draw, "spread": dict(spec.spread), "parameters": [q.name for q in model.parameters],
           "nominal": [float(q.value) for q in model.parameters]}
    if spec.active:
        out["per_seed"] = {int(s): spec.values(model, s).tolist() for s in seeds}
    return out


def report(out, summary: dict) -> None:
    """The model-error block of `simulate`: what was asked and, per perturbed parameter, its model
    value and the plant's over the runs (min / mean / max; one run: its value)."""
    print(f"Model error (the plant's parameters; the filters and the controller keep the model's): "
          f"{summary['describe']}", file=out)
    if "per_seed" not in summary:
        return
    values = np.array(list(summary["per_seed"].values()))
    p0 = np.array(summary["nominal"])
    single = len(values) == 1
    head = "plant" if single else f"plant over {len(values)} runs: min / mean / max"
    print(f"  {'parameter':12s} {'model':>10s}   {head}", file=out)
    for i in np.nonzero(np.any(values != p0, axis=0))[0]:
        v = values[:, i]
        rel = 100 * (v - p0[i]) / p0[i] if p0[i] else np.full_like(v, np.nan)
        if single:
            cells, rels = f"{v[0]:.5g}", f"{rel[0]:+.2f}%"
        else:
            cells = f"{v.min():.5g} / {v.mean():.5g} / {v.max():.5g}"
            rels = f"{rel.min():+.2f}% / {rel.mean():+.2f}% / {rel.max():+.2f}%"
        print(f"  {summary['parameters'][i]:12s} {p0[i]:10.5g}   {cells}   ({rels})", file=out)
    print(file=out)
