"""The one progress protocol of long runs: update, add_effect, diagnose, diagnose_damping and
the Monte-Carlo studies each call ``progress(Progress(...))``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Progress:
    """One report: ``message``, a line for a person (also ``str(p)``); ``done`` of ``total``
    units where they are counted (an update's iterations, a study's samples); ``detail``,
    the typed state behind it (an update's :class:`updating.Iteration`, a study's chunk
    record: a dict with ``chunk``, ``done``, ``rate``, ``seconds_left``, ``retries``, ...)."""

    message: str
    done: int | None = None
    total: int | None = None
    detail: object = None

    def __str__(self) -> str:
        return self.message


ProgressFn = Callable[[Progress], None]


def lines(progress: ProgressFn | None) -> Callable[[str], None]:
    """A one-line reporter that sends each line as a :class:`Progress` (nothing without one)."""
    return (lambda line: None) if progress is None else (lambda line: progress(Progress(line)))
