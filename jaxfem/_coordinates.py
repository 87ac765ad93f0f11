"""Coordinate systems of bulk data: CORD1R/C/S, CORD2R/C/S, resolved to basic.

A :class:`Frame` is an origin and axes (columns of ``t``) in basic and a kind: ``R``
rectangular (x, y, z), ``C`` cylindrical (R, θ [deg], z), ``S`` spherical (R, θ [deg],
φ [deg]) (MSC QRG, CORD2R, CORD2C, CORD2S). :meth:`Frame.position` places a point given
in the system; :meth:`Frame.axes_at` gives the displacement axes of the system at a
point, as Nastran uses them for a GRID's CD: rectangular axes anywhere; cylindrical
(e_R, e_θ, e_z) and spherical (e_R, e_θ, e_φ) rotate with the point (at R = 0 the
angle is taken as 0). CORD2x systems are defined by points A (origin), B (on z) and C
(in the x–z plane) given in their reference system RID; CORD1x systems by three grids
G1, G2, G3 playing those roles. :func:`_resolve` places systems and grids together, as
a CORD1 needs the grids it names and a grid needs its CP system; chains of any length,
loops and undefined ids are located errors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .io import Card

CORD2 = ("CORD2R", "CORD2C", "CORD2S")
CORD1 = ("CORD1R", "CORD1C", "CORD1S")
CORDS = CORD2 + CORD1


@dataclass(frozen=True)
class Frame:
    """A coordinate system in basic: ``x_basic = origin + t @ x_rect`` with ``x_rect`` the
    point's rectangular coordinates in the system (from R, θ, z or R, θ, φ for C and S)."""

    origin: np.ndarray
    t: np.ndarray
    kind: str = "R"

    def rectangular(self, x) -> np.ndarray:
        """Local rectangular coordinates of a point given in the system's own coordinates."""
        x = np.asarray(x, dtype=float)
        if self.kind == "C":
            th = np.radians(x[1])
            return np.array([x[0] * np.cos(th), x[0] * np.sin(th), x[2]])
        if self.kind == "S":
            th, ph = np.radians(x[1]), np.radians(x[2])
            return x[0] * np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
        return x

    def position(self, x) -> np.ndarray:
        """Basic position of a point given in the system's coordinates."""
        return self.origin + self.t @ self.rectangular(x)

    def axes_at(self, point) -> np.ndarray:
        """Displacement axes (3 × 3, columns in basic) of the system at basic ``point``."""
        if self.kind == "R":
            return self.t
        x, y, z = self.t.T @ (np.asarray(point, dtype=float) - self.origin)
        ph = np.arctan2(y, x) if np.hypot(x, y) > 0.0 else 0.0
        c, s = np.cos(ph), np.sin(ph)
        if self.kind == "C":
            local = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        else:
            th = np.arctan2(np.hypot(x, y), z) if np.hypot(np.hypot(x, y), z) > 0.0 else 0.0
            ct, st = np.cos(th), np.sin(th)
            local = np.array([[st * c, ct * c, -s], [st * s, ct * s, c], [ct, -st, 0.0]])
        return self.t @ local


BASIC = Frame(np.zeros(3), np.eye(3))


def _frame(card: Card, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> Frame:
    """The frame with origin A, z towards B and C in the x–z plane (all in basic)."""
    z, xz = b - a, c - a
    y = np.cross(z, xz)
    if np.linalg.norm(z) == 0.0 or np.linalg.norm(y) <= 1e-12 * np.linalg.norm(z) * np.linalg.norm(xz):
        key = "A1" if card.name in CORD2 else "G1"
        raise card.error(key, "points A, B, C do not define axes (coincident or collinear)")
    z, y = z / np.linalg.norm(z), y / np.linalg.norm(y)
    return Frame(a, np.column_stack([np.cross(y, z), y, z]), card.name[-1])


def _place_cord2(card: Card, frames: dict[int, Frame]) -> Frame:
    ref = frames[card["RID"]]
    a, b, c = (ref.position([card[f"{p}{k}"] for k in (1, 2, 3)]) for p in "ABC")
    return _frame(card, a, b, c)


def _resolve(cords: list[Card], grids: list[Card], check_lengths) -> tuple[dict[int, Frame], dict[int, np.ndarray]]:
    """Frames by id (0 = basic) and grid positions in basic by grid id.

    Systems and grids are placed in rounds: a CORD2 once its RID is placed, a grid once
    its CP is, a CORD1 once its three grids are; what is left when a round places
    nothing refers to an undefined id or to itself in a loop (a located error).
    """
    frames: dict[int, Frame] = {0: BASIC}
    xyz: dict[int, np.ndarray] = {}
    todo_cords, todo_grids = list(cords), list(grids)
    for card in cords:
        if card.name in CORD2:
            check_lengths(card, tuple(f"{p}{k}" for p in "ABC" for k in (1, 2, 3)))
    for card in grids:
        check_lengths(card, ("X1", "X2", "X3"))
    while todo_cords or todo_grids:
        waiting = [card for card in todo_grids if card["CP"] not in frames]
        basic = [card for card in todo_grids if card["CP"] == 0]
        if basic:  # most grids: one vectorised placement
            points = np.array([[c["X1"], c["X2"], c["X3"]] for c in basic], dtype=float).reshape(-1, 3)
            xyz.update(zip((c.id for c in basic), points))
        for card in todo_grids:
            if card["CP"] != 0 and card["CP"] in frames:
                xyz[card.id] = frames[card["CP"]].position([card["X1"], card["X2"], card["X3"]])
        placed = len(waiting) < len(todo_grids)
        todo_grids, left = waiting, []
        for card in todo_cords:
            if card.name in CORD2 and card["RID"] in frames:
                frames[card.id] = _place_cord2(card, frames)
            elif card.name in CORD1 and all(card[g] in xyz for g in ("G1", "G2", "G3")):
                frames[card.id] = _frame(card, *(xyz[card[g]] for g in ("G1", "G2", "G3")))
            else:
                left.append(card)
        placed = placed or len(left) < len(todo_cords)
        todo_cords = left
        if not placed:
            raise _unresolved(todo_cords, todo_grids, {c.id for c in cords}, {c.id for c in grids})
    return frames, xyz


def _unresolved(cords: list[Card], grids: list[Card], cord_ids: set, grid_ids: set):
    """The located error for what could not be placed: an undefined id, else a loop."""
    for card in grids:
        if card["CP"] not in cord_ids:
            return card.error("CP", f"coordinate system {card['CP']} is not defined")
    for card in cords:
        if card.name in CORD2 and card["RID"] not in cord_ids:
            return card.error("RID", f"reference system {card['RID']} is not defined")
        for key in ("G1", "G2", "G3") if card.name in CORD1 else ():
            if card[key] not in grid_ids:
                return card.error(key, f"grid {card[key]} is not defined")
    card = (cords or grids)[0]
    ids = sorted({c.id for c in cords})
    return card.error("RID" if card.name in CORD2 else ("G1" if card.name in CORD1 else "CP"),
                      f"coordinate systems refer to each other in a loop (systems {ids} and the grids "
                      "that define them)")
