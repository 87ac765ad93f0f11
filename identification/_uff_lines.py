"""Trace lines of a universal file (dataset 82): the test wireframe drawn between nodes."""

from __future__ import annotations

import os

import numpy as np

from ._uff import _MAX_ID, read_records


def read_trace_lines(path: str | os.PathLike) -> list[tuple[int, int]]:
    """The lines of every dataset-82 record of a universal file, as node-id pairs.

    A record lists node ids to visit in order; a line is drawn from each node to the
    next, and a 0 means "move, do not draw" (UFF dataset 82: a 0 between two ids breaks
    the line). Each undirected pair is returned once, in the order first drawn, with the
    smaller id first; a node joined to itself is left out.

    **Returns:** ``[(a, b), ...]``, empty when the file has no dataset 82.

    Raises ``ValueError`` naming the dataset and line when the file is not whole (a -1
    missing, truncated: :func:`read_records`), a dataset 82 cannot be parsed or its node
    list is not whole numbers in 0..2³¹−1.
    """
    path = os.fspath(path)
    lines: dict[tuple[int, int], None] = {}
    for number, record in read_records(path, lambda kind: kind == 82)[0]:
        nodes = np.asarray(record.get("nodes", ()), dtype=np.float64).reshape(-1)
        if not np.all(np.isfinite(nodes) & (nodes == np.round(nodes)) & (nodes >= 0) & (nodes <= _MAX_ID)):
            raise ValueError(f"{path}: dataset #{number} (type 82, trace {record.get('trace_num')}): "
                             f"node ids are not whole numbers in 0..{_MAX_ID}")
        ids = nodes.astype(np.int64).tolist()
        for a, b in zip(ids[:-1], ids[1:]):
            if a != 0 and b != 0 and a != b:
                lines.setdefault((min(a, b), max(a, b)), None)
    return list(lines)
