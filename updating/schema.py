"""The schema checks of the TOML inputs (parameter files, Monte-Carlo studies): one set of
validators, each naming what a key should hold, so that every file and every Python
caller is refused alike, by key, before any computation.

A validator takes the parsed value and returns it normalised (a tuple, an int, a float)
or raises :class:`Expected` with what was expected; :func:`checked` turns that into a
:class:`FieldError` naming the key and the value given.
"""

from __future__ import annotations

import difflib

import numpy as np


class FieldError(ValueError):
    """A schema error on one key: ``key`` (as written in the file, e.g. ``pids``,
    ``max_iterations``, ``study.samples``) and the message ``text`` (what was expected,
    what was given); ``owner`` (``parameter 'cols'``, ``options``) starts the message. A
    file's parser rewrites it with the file and the table (``parameter[2]``)."""

    def __init__(self, key: str, text: str, owner: str = ""):
        super().__init__(f"{owner}: {key}: {text}" if owner else f"{key}: {text}")
        self.key, self.text = key, text


class Expected(Exception):
    """Raised by a validator: ``str(self)`` is what the value should have been."""


def show(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def is_int(v) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def finite(v) -> float | None:
    """``v`` as a finite float, or None (not a number, a bool, NaN, ±inf, an int too big)."""
    if not isinstance(v, (int, float, np.integer, np.floating)) or isinstance(v, (bool, np.bool_)):
        return None
    try:
        f = float(v)
    except OverflowError:
        return None
    return f if np.isfinite(f) else None


def integer(low: int, high: int | None = None):
    what = f"an integer ≥ {low}" + (f" and ≤ {high}" if high is not None else "")

    def check(v):
        if not is_int(v) or v < low or (high is not None and v > high):
            raise Expected(what)
        return int(v)
    return check


def number(low: float, *, strict: bool, high: float | None = None):
    what = f"a finite number {'>' if strict else '≥'} {low:g}" + (f" and ≤ {high:g}" if high is not None else "")

    def check(v):
        f = finite(v)
        if f is None or (f <= low if strict else f < low) or (high is not None and f > high):
            raise Expected(what)
        return f
    return check


def choice(*options: str):
    what = " | ".join(repr(o) for o in options)

    def check(v):
        if not isinstance(v, str) or v not in options:
            raise Expected(f"one of {what}")
        return v
    return check


def integers(what: str, *, nonempty: bool):
    """An array of integers ≥ 1 (ids, mode numbers): bools and 1.7 refused, not truncated."""
    what = f"{'a non-empty' if nonempty else 'an'} array of {what} (integers ≥ 1)"

    def check(v):
        if not isinstance(v, (list, tuple, np.ndarray)) or (nonempty and not len(v)) \
                or not all(is_int(x) and x >= 1 for x in v):
            raise Expected(what)
        return tuple(int(x) for x in v)
    return check


def name(v):
    if not isinstance(v, str) or not v.strip():
        raise Expected("a non-empty string")
    return v


def bounds(v, floor: str = "≥"):
    """Two finite numbers, ``floor``: ``≥`` −1 ≤ lower, ``>`` −1 < lower (α ≤ −1 would be a
    zero or negative value), lower < upper."""
    if not isinstance(v, (list, tuple, np.ndarray)) or len(v) != 2:
        raise Expected("[lower, upper]: two numbers")
    lower, upper = finite(v[0]), finite(v[1])
    if lower is None or upper is None:
        raise Expected("[lower, upper]: two finite numbers")
    if lower >= upper:
        raise Expected("[lower, upper] with lower < upper" + (" (reversed?)" if lower > upper else ""))
    if lower < -1.0 or (floor == ">" and lower == -1.0):
        raise Expected(f"lower {floor} -1 (α = -1 is a value of 0, below it a negative one)")
    return (lower, upper)


def checked(key: str, check, value):
    """``check(value)``, or a :class:`FieldError` naming ``key``, the expectation and the value."""
    try:
        return check(value)
    except Expected as err:
        raise FieldError(key, f"expected {err}, got {show(value)}") from None


def refuse_unknown(table: dict, known, where: str, prefix: str) -> None:
    """Unknown keys are errors (a typo such as ``bound`` would otherwise be ignored)."""
    for key in table:
        if key not in known:
            near = difflib.get_close_matches(str(key), list(known), n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            raise ValueError(f"{where}: {prefix}{key}: unknown key{hint}; known keys: {', '.join(known)}")
