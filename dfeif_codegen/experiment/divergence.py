"""When a closed-loop run has diverged: the step-by-step watch (`DivergenceWatch`, the numpy
engine) and the same test over a whole run's arrays (`check_divergence`, an engine that ran the
loop elsewhere), with the same message."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dfeif_codegen.experiment.metrics import _errors, _nees, tracking_bound, tracking_errors

if TYPE_CHECKING:
    from dfeif_codegen.experiment.closed_loop import Setup


# A run has diverged when the true state leaves its declared domain, or when the master's NEES
# stays above NEES_DIVERGED * n for NEES_STEPS steps in a row. This is not the consistency test
# (the tables do that against the chi-square band); it detects a filter that has lost the state:
# NEES = 1e4 n means errors 100 times the standard deviations P claims. A consistent filter's NEES
# is chi-square with n degrees of freedom (mean n), so P(NEES > 1e4 n) is below 1e-1000, and a
# merely inconsistent baseline (as-current, NEES of a few hundred) is not called diverged.
NEES_DIVERGED = 1e4


NEES_STEPS = 50


class Diverged(FloatingPointError):
    """The closed loop went wrong: the message says when and why."""


class DivergenceWatch:
    """Raises Diverged when the true state leaves its declared domain, a flat output strays from
    its reference by more than its tracking bound (the run stopped tracking), or the master's NEES
    has stayed above NEES_DIVERGED * n for NEES_STEPS steps in a row."""

    def __init__(self, model, nees: bool = True, bound=None):
        self.nees = nees
        self.names = [v.name for v in model.states]
        self.outputs = [o.name for o in model.outputs]
        self.lo = np.array([-np.inf if v.min is None else v.min for v in model.states])
        self.hi = np.array([np.inf if v.max is None else v.max for v in model.states])
        self.bound = np.full(len(self.outputs), np.inf) if bound is None else np.asarray(bound, dtype=float)
        self.high = 0

    def tracking(self, t: float, track) -> None:
        """Raises Diverged when an output strays beyond its bound (the first check of `step`)."""
        if track is not None and np.any(np.abs(track) > self.bound):
            j = int(np.argmax(np.abs(track) > self.bound))
            raise Diverged(f"stopped tracking at t = {t:.2f} s: output {self.outputs[j]} is {track[j]:.4g} from its "
                           f"reference, beyond the tracking bound {self.bound[j]:.4g} (default twice the "
                           "reference's amplitude; [reference] tracking_bound)")

    def step(self, t: float, x, err, P, track=None) -> None:
        self.tracking(t, track)
        if not np.all(np.isfinite(x)):
            raise Diverged(f"diverged at t = {t:.2f} s: the state is not finite")
        outside = np.nonzero((x < self.lo) | (x > self.hi))[0]
        if outside.size:
            i = int(outside[0])
            raise Diverged(f"diverged at t = {t:.2f} s: state {self.names[i]} = {x[i]:.4g} left its domain "
                           f"[{self.lo[i]:g}, {self.hi[i]:g}]")
        if not self.nees:
            return
        n = len(err)
        with np.errstate(all="ignore"):
            nees = float(err @ np.linalg.solve(P, err)) if np.all(np.isfinite(P)) else np.inf
        self.high = self.high + 1 if not nees <= NEES_DIVERGED * n else 0
        if self.high >= NEES_STEPS:
            raise Diverged(f"diverged at t = {t:.2f} s: master NEES above {NEES_DIVERGED:g} n = "
                           f"{NEES_DIVERGED * n:g} for {NEES_STEPS} steps (now {nees:.3g})")


def check_divergence(s: "Setup", x_true, zeta, x, P, steps: int | None = None) -> None:
    """The divergence watch over a run's arrays (an engine that ran the loop elsewhere), over its
    first `steps` steps (default all): the state after step k is the next step's x_true, so the
    last step's successor goes unchecked. Vectorized over the steps to find the first one that
    trips a criterion; the step-by-step watch then runs over the steps leading to it, so the
    message is the one the numpy engine's watch gives."""
    K = min(s.K, s.K if steps is None else steps + 1) - 1
    if K <= 0:
        return
    watch = DivergenceWatch(s.flat.model, s.cfg.watch_nees, tracking_bound(s.cfg, s.flat.m))
    xs = np.asarray(x_true[1:K + 1], dtype=float)
    track = tracking_errors(s.flat, np.asarray(zeta[:K], dtype=float), s.ref[:K])
    with np.errstate(invalid="ignore"):
        bad = ~np.all(np.isfinite(xs), axis=1) | np.any((xs < watch.lo) | (xs > watch.hi), axis=1) \
            | np.any(np.abs(track) > watch.bound, axis=1)
    first = int(np.argmax(bad)) if bad.any() else K
    if watch.nees:
        high = ~(_batch_nees(_errors(s.flat, np.array(x[:K], dtype=float), zeta[:K]), P[:K])
                 <= NEES_DIVERGED * s.flat.n)
        steps_k = np.arange(K)
        run = steps_k - np.maximum.accumulate(np.where(high, -1, steps_k))   # highs in a row up to k
        tripped = run >= NEES_STEPS
        if tripped.any():
            first = min(first, int(np.argmax(tripped)))
    if first == K:
        return
    for k in range(max(0, first - NEES_STEPS + 1), first + 1):   # raises at `first`
        watch.step(s.t[k], x_true[k + 1], _errors(s.flat, x[k], zeta[k]), P[k], track[k])


def check_tracking_at(s: "Setup", zeta, step: int) -> None:
    """The watch's first check at `step` alone, from the plant's canonical state there: an engine
    whose step failed (a non-finite estimate or plant) reports what the numpy engine's watch
    reports first at that step, a lost track, before the non-finite state."""
    watch = DivergenceWatch(s.flat.model, False, tracking_bound(s.cfg, s.flat.m))
    watch.tracking(s.t[step], tracking_errors(s.flat, np.asarray(zeta[step:step + 1], dtype=float),
                                              s.ref[step:step + 1])[0])


def _batch_nees(err, P) -> np.ndarray:
    """NEES per step; inf where P is not finite or singular (the watch's `not nees <= limit`)."""
    out = np.full(len(err), np.inf)
    ok = np.all(np.isfinite(P), axis=(1, 2)) & np.all(np.isfinite(err), axis=1)
    if ok.any():
        with np.errstate(all="ignore"):
            try:
                out[ok] = _nees(err[ok], P[ok])
            except np.linalg.LinAlgError:   # a singular P somewhere: step by step
                for k in np.nonzero(ok)[0]:
                    try:
                        out[k] = float(err[k] @ np.linalg.solve(P[k], err[k]))
                    except np.linalg.LinAlgError:
                        out[k] = np.inf
    return out
