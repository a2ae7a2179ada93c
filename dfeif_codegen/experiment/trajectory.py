"""Reference trajectories with analytic derivatives, as the flatness controller's flags.

`sinusoid`: y_d = c + A sin(k w t + phi), w = 2 pi / T, with a phase phi and a whole number of
cycles k per period for each output: x with phi = pi/2 and y with 0 trace a circle, k = 1 and 2 a
figure eight (the `seesaw` takes the same time shift phi / (k w) and k).

`seesaw`: a triangle wave (the chapter's "see-saw", Fig. 9b) smoothed by keeping the first K odd
harmonics of its Fourier series,

    y_d = c + (8 A / pi^2) * sum_{k = 1, 3, ..., 2K-1} (-1)^((k-1)/2) sin(k w t) / k^2,

so every derivative exists and is analytic: y_d^(j) has the terms k^(j-2) w^j sin(k w t + j pi/2).
Why this smoothing: the control law needs y_d^(r) (jerk for the motor) and the ideal triangle has
a Dirac second derivative; a truncated series is smooth to every order with two lines of code, and
its peak jerk grows only like sum(k) (K = 4: corners rounded over about T/16, peak 0.95 A).
"""

from __future__ import annotations

import numpy as np

KINDS = ("sinusoid", "seesaw")


class Reference:
    """One flat output's reference: `flags(t, r)` = [y_d, y_d', ..., y_d^(r)] at time t."""

    def __init__(self, kind: str, amplitude: float = 1.0, period: float = 5.0, offset: float = 0.0,
                 harmonics: int = 4, phase: float = 0.0, cycles: int = 1):
        if kind not in KINDS:
            raise ValueError(f"unknown reference '{kind}' (one of {', '.join(KINDS)})")
        self.kind, self.offset = kind, float(offset)
        self.w = 2 * np.pi * int(cycles) / float(period)
        self.shift = float(phase) / self.w
        if kind == "sinusoid":
            self.k, self.c = np.array([1.0]), np.array([float(amplitude)])
        else:
            self.k = 2.0 * np.arange(harmonics) + 1.0
            self.c = 8 * float(amplitude) / np.pi ** 2 * (-1.0) ** np.arange(harmonics) / self.k ** 2

    def flags(self, t: float, r: int) -> np.ndarray:
        j = np.arange(r + 1)[:, None]
        kw = self.k[None, :] * self.w
        out = (self.c[None, :] * kw ** j * np.sin(kw * (t + self.shift) + j * np.pi / 2)).sum(axis=1)
        out[0] += self.offset
        return out


def flags(refs: list[Reference], degrees: list[int], t: float) -> np.ndarray:
    """The controller's reference flags: chain by chain [y_d, ..., y_d^(r_j)] (n + m numbers)."""
    return np.concatenate([ref.flags(t, r) for ref, r in zip(refs, degrees)])
