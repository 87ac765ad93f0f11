"""Grids, coordinate systems and element axes of bulk data, in basic coordinates.

CORD2R systems (chains of RID resolved) place each GRID in basic; an element axis runs
A→B, with a located error at zero length; an orientation vector (X1, X2, X3 or the grid
G0) must not be parallel to it (MSC QRG, CORD2R, GRID, CBAR). Coordinates, offsets and
orientation components lie within ±1e100 m, element lengths above 1e-100 m, so that no
length, area or volume overflows. Also the small converters
the builders share: cards sorted by id, int64 and float64 arrays. Errors are
:class:`jaxfem.io.BulkDataError` naming the card and field.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .io import Card

_PARALLEL_TOL = 1e-8  # |x̂ × v| < tol·|v|: orientation vector along the element axis
_LENGTH_TOL = 1e-10  # zero length: L <= tol·(distance of the end points from the origin)
_LENGTH_MIN = 1e-100  # [m] zero length below this, too: L³ (beam stiffness E I / L³) stays a normal float64
_COORD_MAX = 1e100  # [m] largest |coordinate|, offset or orientation component: squares and cubes stay finite


def _check_lengths(card: Card, keys: tuple[str, ...]) -> None:
    """Located error for a length-valued field (coordinate, offset, orientation
    component) beyond ±1e100 m, where lengths, areas and volumes would overflow."""
    for key in keys:
        value = card[key]
        if value is not None and abs(value) > _COORD_MAX:
            raise card.error(key, f"{key} = {value:g} is beyond ±1e100 m: lengths, areas and volumes would overflow")


def _f64(values) -> jax.Array:
    return jnp.asarray(np.asarray(values, dtype=np.float64))


def _ints(values, *shape: int) -> np.ndarray:
    return np.asarray(values, dtype=np.int64).reshape(-1, *shape)


def _by_id(cards: list[Card]) -> list[Card]:
    return sorted(cards, key=lambda c: c.id)


def _coordinate_systems(cards: list[Card]) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """CORD2R id -> (origin, T) in basic: ``x_basic = origin + T @ x_local``, T columns = axes.

    Axes from points A (origin), B (on z) and C (in the x–z plane), each given in the
    reference system RID (MSC QRG, CORD2R); chains of RID are resolved, iteratively (a
    chain may be as long as the file).
    """
    by_id = {c.id: c for c in cards}
    frames: dict[int, tuple[np.ndarray, np.ndarray]] = {0: (np.zeros(3), np.eye(3))}

    def place(card: Card) -> None:
        _check_lengths(card, tuple(f"{p}{k}" for p in "ABC" for k in (1, 2, 3)))
        origin, t = frames[card["RID"]]
        a, b, c = (origin + t @ np.array([card[f"{p}{k}"] for k in (1, 2, 3)], dtype=float) for p in "ABC")
        z, xz = b - a, c - a
        y = np.cross(z, xz)
        if np.linalg.norm(z) == 0.0 or np.linalg.norm(y) <= 1e-12 * np.linalg.norm(z) * np.linalg.norm(xz):
            raise card.error("A1", "points A, B, C do not define axes (coincident or collinear)")
        z, y = z / np.linalg.norm(z), y / np.linalg.norm(y)
        frames[card.id] = (a, np.column_stack([np.cross(y, z), y, z]))

    for card in cards:
        if card.id in frames:
            continue
        chain, seen = [card], {card.id}  # systems to place, each referring to the next one
        while chain[-1]["RID"] not in frames:
            rid = chain[-1]["RID"]
            if rid in seen:
                ids = tuple(c.id for c in chain) + (rid,)
                raise chain[-1].error("RID", f"coordinate systems refer to each other in a loop {ids}")
            if rid not in by_id:
                raise chain[-1].error("RID", f"reference system {rid} is not a CORD2R")
            chain.append(by_id[rid])
            seen.add(rid)
        for c in reversed(chain):
            place(c)
    return frames


class _Grids:
    """Grid ids (ascending), positions in basic [m], and row lookup with located errors."""

    def __init__(self, cards: list[Card], frames: dict[int, tuple[np.ndarray, np.ndarray]]):
        cards = _by_id(cards)
        xyz = []
        for card in cards:
            if card["CP"] not in frames:
                raise card.error("CP", f"coordinate system {card['CP']} is not a CORD2R")
            _check_lengths(card, ("X1", "X2", "X3"))
            origin, t = frames[card["CP"]]
            xyz.append(origin + t @ np.array([card["X1"], card["X2"], card["X3"]]))
        self.cards = cards
        self.ids = _ints([c.id for c in cards])
        self.xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
        self.row = {int(g): i for i, g in enumerate(self.ids)}

    def __call__(self, card: Card, key: str, grid: int | None = None) -> int:
        """Row of grid ``card[key]`` (or ``grid``, listed in field ``key``)."""
        grid = card[key] if grid is None else grid
        if grid not in self.row:
            raise card.error(key, f"grid {grid} is not defined")
        return self.row[grid]

    def listed(self, card: Card, key: str) -> list[int]:
        """The grid ids of ``card[key]`` (an :class:`jaxfem.io.IdRanges`), each of which must
        exist: a range is checked against the sorted ids by bisection, never expanded, so
        ``1 THRU 99999999`` costs what the grids in it cost."""
        out: list[int] = []
        for first, last in card[key].runs:
            lo, hi = np.searchsorted(self.ids, [first, last + 1])
            present = self.ids[lo:hi]
            if len(present) != last - first + 1:  # a gap: the first id that is not a grid
                gap = np.flatnonzero(present != np.arange(first, first + len(present)))
                missing = first + (int(gap[0]) if len(gap) else len(present))
                raise card.error(key, f"grid {missing} is not defined" + (
                    f" ({first} THRU {last} lists it)" if last > first else ""))
            out += present.tolist()
        return out


def _coincident(xa: np.ndarray, xb: np.ndarray) -> bool:
    return np.linalg.norm(xb - xa) <= max(_LENGTH_TOL * max(np.linalg.norm(xa), np.linalg.norm(xb)), _LENGTH_MIN)


def _axis(card: Card, xa: np.ndarray, xb: np.ndarray, key: str) -> np.ndarray:
    """Unit vector A→B, or a located error for a zero-length element."""
    if _coincident(xa, xb):
        raise card.error(key, f"zero length: the ends (offsets included) are {np.linalg.norm(xb - xa):.3g} apart, "
                              f"at {xa.tolist()} and {xb.tolist()} (at most {_LENGTH_TOL:g} × their distance from "
                              "the origin counts as one point)")
    return (xb - xa) / np.linalg.norm(xb - xa)


def _orientation(card: Card, grids: _Grids, axis: np.ndarray) -> np.ndarray:
    """Orientation vector v in basic (G0: x_G0 − x_GA), not parallel to the element axis."""
    if card["G0"] is not None:
        v = grids.xyz[grids(card, "G0")] - grids.xyz[grids(card, "GA")]
        key = "G0"
    else:
        _check_lengths(card, ("X1", "X2", "X3"))
        v = np.array([card["X1"], card["X2"], card["X3"]])
        key = "X1"
    norm = np.linalg.norm(v)
    if norm == 0.0 or np.linalg.norm(np.cross(axis, v)) < _PARALLEL_TOL * norm:
        raise card.error(key, f"orientation vector {v.tolist()} is zero or parallel to the element axis")
    return v
