"""Coordinate systems (datasets 18 and 2420) and nodes (15 and 2411) of a universal file,
in global coordinates [m], and sensor directions turned from local displacement systems
into global axes."""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np

from ._data import Sensors

_SYSTEM_TYPES = {0: "rectangular", 1: "cylindrical", 2: "spherical"}
_ORTHO_TOL = 1e-6  # axes written with 7 digits are still orthonormal


class _System(NamedTuple):
    kind: int  # 0 rectangular, 1 cylindrical, 2 spherical
    axes: np.ndarray  # (3, 3): rows are the local x, y, z axes in global coordinates
    origin: np.ndarray  # (3,) m, global
    where: str


_GLOBAL = _System(0, np.eye(3), np.zeros(3), "global")


def _systems(records18: list, records2420: list, length: float, path: str) -> dict[int, _System]:
    """Coordinate systems of datasets 2420 (matrix) and 18 (three points in a reference
    system, resolved in order of reference), in global coordinates; 0 is global."""
    systems = {0: _GLOBAL}

    def add(label: int, system: _System) -> None:
        if system.kind not in _SYSTEM_TYPES:
            raise ValueError(f"{path}: {system.where}: coordinate system {label} has type {system.kind} (expected "
                             "0 rectangular, 1 cylindrical or 2 spherical)")
        old = systems.get(label)
        if old is not None and not (old.kind == system.kind and np.allclose(old.axes, system.axes, atol=_ORTHO_TOL)
                                    and np.allclose(old.origin, system.origin, rtol=1e-9, atol=1e-12)):
            raise ValueError(f"{path}: coordinate system {label} of {system.where} differs from {old.where}")
        systems[label] = system

    for number, r in records2420:
        for label, kind, matrix in zip(r["CS_sys_labels"], r["CS_types"], r["CS_matrices"]):
            m = np.asarray(matrix, dtype=np.float64)
            where = f"dataset #{number}"
            if m.shape != (4, 3) or not np.all(np.isfinite(m)):
                raise ValueError(f"{path}: {where}: coordinate system {int(label)}: matrix {m.tolist()} is not 4 "
                                 "finite rows of 3")
            if not np.allclose(m[:3] @ m[:3].T, np.eye(3), atol=_ORTHO_TOL):
                raise ValueError(f"{path}: {where}: coordinate system {int(label)}: rows 1-3 of the matrix "
                                 f"{m[:3].tolist()} are not orthonormal axes")
            add(int(label), _System(int(kind), m[:3], m[3] / length, where))
    pending = {}
    for number, r in records18:
        for i, label in enumerate(np.asarray(r["cs_num"]).astype(int).tolist()):
            pending[label] = (number, i, r)
    while pending:
        ready = [label for label, (_, i, r) in pending.items() if int(r["ref_cs_num"][i]) in systems]
        if not ready:
            raise ValueError(f"{path}: coordinate systems {sorted(pending)} (dataset 18) refer to systems "
                             f"{sorted({int(r['ref_cs_num'][i]) for _, i, r in pending.values()})} that are not "
                             "defined (or refer to each other in a circle)")
        for label in ready:
            number, i, r = pending.pop(label)
            where = f"dataset #{number}"
            if int(r["method"][i]) != 1:
                raise ValueError(f"{path}: {where}: coordinate system {label}: method of definition "
                                 f"{int(r['method'][i])} (only 1: origin, +x axis, +xz plane)")
            ref = systems[int(r["ref_cs_num"][i])]
            o, xp, zp = (_to_global(ref, np.asarray(r[k][i], dtype=np.float64).reshape(1, 3), length)[0]
                         for k in ("ref_o", "x_point", "xz_point"))
            x, y = xp - o, np.cross(zp - o, xp - o)  # y is normal to the xz plane
            if not (np.linalg.norm(x) > 0 and np.linalg.norm(y) > 1e-9 * np.linalg.norm(x) * np.linalg.norm(zp - o)):
                raise ValueError(f"{path}: {where}: coordinate system {label}: origin, +x point and +xz point "
                                 f"{[o.tolist(), xp.tolist(), zp.tolist()]} m do not define axes")
            x, y = x / np.linalg.norm(x), y / np.linalg.norm(y)
            add(label, _System(int(r["cs_type"][i]), np.stack([x, y, np.cross(x, y)]), o, where))
    return systems


def _to_global(system: _System, coords: np.ndarray, length: float) -> np.ndarray:
    """Global xyz [m] of file coordinates (n, 3) in ``system``: x, y, z; r, θ, z; or
    r, θ, φ (angles in degrees, lengths in file units)."""
    c = np.asarray(coords, dtype=np.float64)
    if system.kind == 1:
        t = np.radians(c[:, 1])
        local = np.column_stack([c[:, 0] * np.cos(t), c[:, 0] * np.sin(t), c[:, 2]]) / length
    elif system.kind == 2:
        t, f = np.radians(c[:, 1]), np.radians(c[:, 2])
        local = c[:, :1] * np.column_stack([np.sin(t) * np.cos(f), np.sin(t) * np.sin(f), np.cos(t)]) / length
    else:
        local = c / length
    return system.origin + local @ system.axes


def _frame(system: _System, x: np.ndarray) -> np.ndarray:
    """Rows: the global directions of the local components 1, 2, 3 at global point ``x``
    (the axes; for curvilinear systems e_r, e_θ, e_z or e_r, e_θ, e_φ there)."""
    if system.kind == 0:
        return system.axes
    p = (x - system.origin) @ system.axes.T
    f = math.atan2(p[1], p[0])
    if system.kind == 1:
        local = np.array([[math.cos(f), math.sin(f), 0.0], [-math.sin(f), math.cos(f), 0.0], [0.0, 0.0, 1.0]])
    else:
        t = math.atan2(math.hypot(p[0], p[1]), p[2])
        local = np.array([[math.sin(t) * math.cos(f), math.sin(t) * math.sin(f), math.cos(t)],
                          [math.cos(t) * math.cos(f), math.cos(t) * math.sin(f), -math.sin(t)],
                          [-math.sin(f), math.cos(f), 0.0]])
    return local @ system.axes


def _nodes(records: list[tuple[int, dict]], length: float, systems: dict[int, _System],
           path: str) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """Global node coordinates [m], and the displacement frames of nodes whose measured
    directions are not the global axes."""
    nodes: dict[int, np.ndarray] = {}
    frames: dict[int, np.ndarray] = {}
    where: dict[int, int] = {}
    undefined: dict[int, list[int]] = {}
    for number, record in records:
        ids = np.asarray(record["node_nums"], dtype=np.float64).astype(np.int64)
        raw = np.column_stack([record["x"], record["y"], record["z"]]).astype(np.float64)
        used = [np.asarray(record[k], dtype=np.float64).astype(np.int64) for k in ("def_cs", "disp_cs")]
        for label in set(used[0].tolist()) | set(used[1].tolist()):
            if label not in systems:
                undefined.setdefault(label, []).extend(ids[(used[0] == label) | (used[1] == label)].tolist())
        for g, c, d, x in zip(ids.tolist(), used[0].tolist(), used[1].tolist(), raw):
            if not np.all(np.isfinite(x)):
                raise ValueError(f"{path}: node dataset #{number}: node {g} has coordinates {x.tolist()}")
            x = _to_global(systems.get(c, _GLOBAL), x.reshape(1, 3), length)[0]
            if g in nodes and not np.allclose(nodes[g], x, rtol=1e-12, atol=0.0):
                raise ValueError(
                    f"{path}: node {g} is at {nodes[g].tolist()} m in dataset #{where[g]} but at {x.tolist()} m "
                    f"in dataset #{number}"
                )
            nodes[g], where[g] = x, number
            frame = _frame(systems.get(d, _GLOBAL), x)
            if not np.allclose(frame, np.eye(3), rtol=0.0, atol=1e-12):
                frames[g] = frame
    if undefined:
        listing = "; ".join(f"system {label}: nodes {sorted(set(g))}" for label, g in sorted(undefined.items()))
        warnings.warn(f"{path}: nodes name coordinate systems that the file does not define (datasets 18/2420), "
                      f"taken as global: {listing}", stacklevel=3)
    return nodes, frames


def _global(sensors: Sensors, frames: dict[int, np.ndarray]) -> Sensors:
    """``sensors`` with each direction, given in its node's displacement frame, in global axes."""
    directions = np.array([d @ frames[int(g)] if int(g) in frames else d
                           for g, d in zip(sensors.nodes, sensors.directions)]).reshape(-1, 3)
    return Sensors.from_vectors(sensors.nodes, directions, sensors.rotational)
