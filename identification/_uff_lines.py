"""Trace lines of a universal file (dataset 82): the test wireframe drawn between nodes."""

from __future__ import annotations

import os

import numpy as np
import pyuff


def read_trace_lines(path: str | os.PathLike) -> list[tuple[int, int]]:
    """The lines of every dataset-82 record of a universal file, as node-id pairs.

    A record lists node ids to visit in order; a line is drawn from each node to the
    next, and a 0 means "move, do not draw" (UFF dataset 82: a 0 between two ids breaks
    the line). Each undirected pair is returned once, in the order first drawn, with the
    smaller id first; a node joined to itself is left out.

    **Returns:** ``[(a, b), ...]``, empty when the file has no dataset 82.

    Raises ``ValueError`` naming the record for a dataset 82 that cannot be parsed or
    whose node list is not whole numbers.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"no universal file {path}")
    uff = pyuff.UFF(path)
    lines: dict[tuple[int, int], None] = {}
    for i, kind in enumerate(uff.get_set_types()):
        if int(kind) != 82:
            continue
        try:
            record = uff.read_sets(i)
        except Exception as err:  # pyuff raises bare Exception for any parse failure
            raise ValueError(f"{path}: dataset #{i + 1} (type 82) cannot be parsed: {err}") from err
        nodes = np.asarray(record.get("nodes", ()), dtype=np.float64).reshape(-1)
        if not np.all(np.isfinite(nodes) & (nodes == np.round(nodes))):
            raise ValueError(f"{path}: dataset #{i + 1} (type 82, trace {record.get('trace_num')}): "
                             "node ids are not whole numbers")
        ids = nodes.astype(np.int64).tolist()
        for a, b in zip(ids[:-1], ids[1:]):
            if a != 0 and b != 0 and a != b:
                lines.setdefault((min(a, b), max(a, b)), None)
    return list(lines)
