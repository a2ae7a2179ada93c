"""The wrap of an angle into (-pi, pi], one definition for the numpy reference and the CasADi
kernels (the C's `<model>_wrap` in templates/internal.h.j2 is the same three steps).

`r = fmod(e, 2pi)` is exact for every finite e (IEEE fmod has no rounding: r = e - k*2pi with
the representable 2pi, |r| < 2pi), then one correction: for pi < r < 2pi, `r - 2pi` is exact
(Sterbenz: 2pi/2 <= r <= 2*2pi) and lies in (-pi, 0); for -2pi < r <= -pi, `r + 2pi` is exact and
lies in (0, pi]. So the result lies in (-pi, pi] of the precision's own pi (2pi is 2*pi exactly in
float and double) for any finite input, however large, and the numpy, CasADi and C results are
the same bits. The earlier `e - 2pi*ceil((e - pi)/2pi)` rounded `2pi*ceil(...)` and left (-pi, pi]
for |e| >~ 1e16 in double and 1e9 in float.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

PI = math.pi
TWO_PI = 2 * math.pi


def wrap_np(e: np.ndarray) -> np.ndarray:
    """Every entry of `e` into (-pi, pi]; float32 in, float32 constants and result (NEP 50)."""
    r = np.fmod(e, TWO_PI)
    return np.where(r > PI, r - TWO_PI, np.where(r <= -PI, r + TWO_PI, r))


def wrap_sx(e: ca.SX) -> ca.SX:
    """The same on one CasADi scalar, without a branch: the flags times 2pi are 0 or 2pi exactly,
    so at most one of the two additions changes r and it is the exact one above."""
    r = ca.fmod(e, TWO_PI)
    return r - TWO_PI * (r > PI) + TWO_PI * (r <= -PI)
