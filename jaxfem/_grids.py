"""Grids, coordinate systems and element axes of bulk data, in basic coordinates.

CORD2R systems (chains of RID resolved) place each GRID in basic; an element axis runs
A→B, with a located error at zero length; an orientation vector (X1, X2, X3 or the grid
G0) must not be parallel to it (MSC QRG, CORD2R, GRID, CBAR). Also the small converters
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


def _f64(values) -> jax.Array:
    return jnp.asarray(np.asarray(values, dtype=np.float64))


def _ints(values, *shape: int) -> np.ndarray:
    return np.asarray(values, dtype=np.int64).reshape(-1, *shape)


def _by_id(cards: list[Card]) -> list[Card]:
    return sorted(cards, key=lambda c: c.id)


def _coordinate_systems(cards: list[Card]) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """CORD2R id -> (origin, T) in basic: ``x_basic = origin + T @ x_local``, T columns = axes.

    Axes from points A (origin), B (on z) and C (in the x–z plane), each given in the
    reference system RID (MSC QRG, CORD2R); chains of RID are resolved.
    """
    by_id = {c.id: c for c in cards}
    frames: dict[int, tuple[np.ndarray, np.ndarray]] = {0: (np.zeros(3), np.eye(3))}

    def resolve(card: Card, chain: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        if card.id in frames:
            return frames[card.id]
        rid = card["RID"]
        if rid in chain:
            raise card.error("RID", f"coordinate systems refer to each other in a loop {chain + (rid,)}")
        if rid not in frames and rid not in by_id:
            raise card.error("RID", f"reference system {rid} is not a CORD2R")
        origin, t = frames[rid] if rid in frames else resolve(by_id[rid], chain + (rid,))
        a, b, c = (origin + t @ np.array([card[f"{p}{k}"] for k in (1, 2, 3)], dtype=float) for p in "ABC")
        z, xz = b - a, c - a
        y = np.cross(z, xz)
        if np.linalg.norm(z) == 0.0 or np.linalg.norm(y) <= 1e-12 * np.linalg.norm(z) * np.linalg.norm(xz):
            raise card.error("A1", "points A, B, C do not define axes (coincident or collinear)")
        z, y = z / np.linalg.norm(z), y / np.linalg.norm(y)
        frames[card.id] = (a, np.column_stack([np.cross(y, z), y, z]))
        return frames[card.id]

    for card in cards:
        resolve(card, (card.id,))
    return frames


class _Grids:
    """Grid ids (ascending), positions in basic [m], and row lookup with located errors."""

    def __init__(self, cards: list[Card], frames: dict[int, tuple[np.ndarray, np.ndarray]]):
        cards = _by_id(cards)
        xyz = []
        for card in cards:
            if card["CP"] not in frames:
                raise card.error("CP", f"coordinate system {card['CP']} is not a CORD2R")
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


def _coincident(xa: np.ndarray, xb: np.ndarray) -> bool:
    return np.linalg.norm(xb - xa) <= _LENGTH_TOL * max(np.linalg.norm(xa), np.linalg.norm(xb))


def _axis(card: Card, xa: np.ndarray, xb: np.ndarray, key: str) -> np.ndarray:
    """Unit vector A→B, or a located error for a zero-length element."""
    if _coincident(xa, xb):
        raise card.error(key, f"zero length: both ends (offsets included) at {xa.tolist()}")
    return (xb - xa) / np.linalg.norm(xb - xa)


def _orientation(card: Card, grids: _Grids, axis: np.ndarray) -> np.ndarray:
    """Orientation vector v in basic (G0: x_G0 − x_GA), not parallel to the element axis."""
    if card["G0"] is not None:
        v = grids.xyz[grids(card, "G0")] - grids.xyz[grids(card, "GA")]
        key = "G0"
    else:
        v = np.array([card["X1"], card["X2"], card["X3"]])
        key = "X1"
    norm = np.linalg.norm(v)
    if norm == 0.0 or np.linalg.norm(np.cross(axis, v)) < _PARALLEL_TOL * norm:
        raise card.error(key, f"orientation vector {v.tolist()} is zero or parallel to the element axis")
    return v
