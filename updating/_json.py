"""JSON at the edge: numbers as JSON has them (NaN and ±inf as null, NumPy scalars as Python)."""

from __future__ import annotations

import math

import numpy as np


def json_number(x) -> float | None:
    """A JSON number: NaN and ±inf become None (null)."""
    x = float(x)
    return x if math.isfinite(x) else None


def json_safe(x):
    """NaN/inf → None, NumPy scalars → Python, recursively through dicts, lists and tuples."""
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [json_safe(v) for v in x]
    if isinstance(x, np.integer | np.bool_):
        return x.item()
    if isinstance(x, float | np.floating):
        return json_number(x)
    return x
