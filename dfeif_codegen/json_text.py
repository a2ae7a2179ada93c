"""JSON as any reader takes it: a number that is not finite (the 95% interval of a single run, the
NEES of a filter that failed) is written as null. Python's json module writes NaN and Infinity,
which are not JSON: JavaScript's JSON.parse and strict parsers refuse the whole document."""

from __future__ import annotations

import json
import math
from typing import Any


def dumps(value: Any, **options) -> str:
    """json.dumps with every non-finite float written as null."""
    return json.dumps(_finite(value), allow_nan=False, **options)


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value
