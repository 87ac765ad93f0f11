"""Grids, coordinate systems and element axes of bulk data, in basic coordinates.

Coordinate systems (:mod:`jaxfem._coordinates`) place each GRID in basic and give the
axes of its CD system; an element axis runs A→B, with a located error at zero length; an
orientation vector (X1, X2, X3 or the grid G0) must not be parallel to it (MSC QRG,
GRID, CBAR). Coordinates, offsets and
orientation components lie within ±1e100 m, element lengths above 1e-100 m, so that no
length, area or volume overflows. Also the small converters
the builders share: cards sorted by id, int64 and float64 arrays. Errors are
:class:`jaxfem.io.BulkDataError` naming the card and field.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ._coordinates import _resolve
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


class _Grids:
    """Grid and scalar-point ids (ascending), positions in basic [deck length unit], the
    displacement axes of each grid's CD system (``cd``: None when all are basic), and row
    lookup with located errors. A scalar point (SPOINT, or ``implicit``: an id that scalar
    elements name and no GRID defines) is a point with one DoF: it sits at the basic
    origin, its component 0 is stored as component 1 (``scalar_rows``: their rows)."""

    def __init__(self, cards: list[Card], cords: list[Card], spoints: list[Card] = (),
                 implicit: set[int] = frozenset()):
        cards = _by_id(cards)
        self.frames, placed = _resolve(_by_id(cords), cards, _check_lengths)
        scalar = sorted({int(s) for card in spoints for s in card["ID"]} | (set(implicit) - set(placed)))
        clash = set(scalar) & set(placed)
        if clash:
            card = next(c for c in spoints if clash & set(c["ID"]))
            raise card.error("ID", f"scalar point {min(clash)} is also a GRID")
        ids = sorted(list(placed) + scalar)
        self.cards = cards
        self.ids = _ints(ids)
        self.xyz = np.array([placed.get(g, np.zeros(3)) for g in ids], dtype=np.float64).reshape(-1, 3)
        self.row = {int(g): i for i, g in enumerate(self.ids)}
        self.scalar_rows = frozenset(self.row[s] for s in scalar)
        self.cd = self._cd_axes(cards) if any(c["CD"] for c in cards) else None

    def _cd_axes(self, cards: list[Card]) -> np.ndarray:
        """(n, 3, 3): the displacement axes of every point's CD system at its position."""
        axes = np.tile(np.eye(3), (len(self.ids), 1, 1))
        for card in cards:
            if card["CD"] not in self.frames:
                raise card.error("CD", f"coordinate system {card['CD']} is not defined")
            row = self.row[card.id]
            axes[row] = self.frames[card["CD"]].axes_at(self.xyz[row])
        return axes

    def axes(self, row: int) -> np.ndarray:
        """Displacement axes (columns in basic) of the point in ``row``."""
        return np.eye(3) if self.cd is None else self.cd[row]

    def frame(self, card: Card, key: str):
        """The coordinate system ``card[key]`` names, or a located error."""
        if card[key] not in self.frames:
            raise card.error(key, f"coordinate system {card[key]} is not defined")
        return self.frames[card[key]]

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
