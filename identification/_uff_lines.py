"""Trace lines of a universal file (dataset 82): the test wireframe drawn between nodes."""

from __future__ import annotations

import numpy as np

from ._csv import MAX_ID


def trace_lines(records: list[tuple[int, dict]], path: str) -> list[tuple[int, int]]:
    """The lines of dataset-82 records ``[(dataset number, pyuff record), ...]`` as node-id pairs.

    A record lists node ids to visit in order; a line is drawn from each node to the
    next, and a 0 means "move, do not draw" (UFF dataset 82: a 0 between two ids breaks
    the line). Each undirected pair is returned once, in the order first drawn, with the
    smaller id first; a node joined to itself is left out. Raises ``ValueError`` naming
    the dataset when its node list is not whole numbers in 0..2³¹−1.
    """
    lines: dict[tuple[int, int], None] = {}
    for number, record in records:
        nodes = np.asarray(record.get("nodes", ()), dtype=np.float64).reshape(-1)
        if not np.all(np.isfinite(nodes) & (nodes == np.round(nodes)) & (nodes >= 0) & (nodes <= MAX_ID)):
            raise ValueError(f"{path}: dataset #{number} (type 82, trace {record.get('trace_num')}): "
                             f"node ids are not whole numbers in 0..{MAX_ID}")
        ids = nodes.astype(np.int64).tolist()
        for a, b in zip(ids[:-1], ids[1:]):
            if a != 0 and b != 0 and a != b:
                lines.setdefault((min(a, b), max(a, b)), None)
    return list(lines)
