"""Damage candidates on shells: patches of elements around each point of a region.

A delamination (thesis §5.3.2.2) is "a single concentrated damage of fixed size" whose
location is the only unknown; the thesis moves a patch of fixed size in steps of one
element (§5.3.5, Figure 5.27). :func:`shell_patches` builds these candidates: for each
element centre (or each grid) of a region, the region's shell elements whose centres lie
within a radius of it. Pass ``patches.groups`` as the ``candidates`` of
:func:`identification.localise_damage` (with ``part="shear"`` for a delamination) and
``patches`` to :func:`identification.plot_shell_damage_map`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from jaxtyping import Float, Int

from jaxfem import Model

_SHELL_BLOCKS = ("quads", "trias")
_TOL = 1e-9  # relative: a centre at exactly the radius is inside


class ShellPatches(NamedTuple):
    """Result of :func:`shell_patches`, one row per patch.

    - ``groups``: element ids of each patch (the candidates of
      :func:`identification.localise_damage`).
    - ``centres`` (c, 3): the point each patch is centred on [m].
    - ``anchors`` (c,): the element id (``at="elements"``) or grid id (``at="grids"``)
      at that point.
    - ``at``: ``"elements"`` or ``"grids"``.
    - ``radius``: the patch radius [m].
    """

    groups: tuple[tuple[int, ...], ...]
    centres: Float[np.ndarray, "c 3"]
    anchors: Int[np.ndarray, " c"]
    at: str
    radius: float


def shell_centres(model: Model, pids: Sequence[int] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shell elements (CQUAD4, CTRIA3) of the given property ids (all shells by default):
    ``(element ids, centres (n, 3) [m] as the mean of the corner grids, corner grid rows
    (n, 4), −1 padding a triangle)``, sorted by element id."""
    ids, centres, corners = [], [], []
    for name, nn in zip(_SHELL_BLOCKS, (4, 3)):
        block = getattr(model, name)
        keep = np.ones(len(block.ids), bool) if pids is None else np.isin(block.pids, np.asarray(pids, np.int64))
        nodes = np.asarray(block.nodes, dtype=np.int64).reshape(len(block.ids), nn)[keep]
        ids.append(np.asarray(block.ids, dtype=np.int64)[keep])
        centres.append(np.asarray(model.xyz)[nodes].mean(axis=1) if len(nodes) else np.zeros((0, 3)))
        corners.append(np.pad(nodes, ((0, 0), (0, 4 - nodes.shape[1])), constant_values=-1))
    ids, centres, corners = np.concatenate(ids), np.concatenate(centres), np.concatenate(corners)
    order = np.argsort(ids, kind="stable")
    return ids[order], centres[order], corners[order]


def shell_patches(model: Model, radius: float, pids: Sequence[int] | None = None, *,
                  at: str = "elements") -> ShellPatches:
    """Patches of shell elements within ``radius`` of each point of a region (candidates
    for :func:`identification.localise_damage`, module docstring).

    **Arguments:**

    - ``model``: a model with CQUAD4/CTRIA3 elements.
    - ``radius`` [m] > 0: an element belongs to a patch when its centre (the mean of its
      corner grids) lies within ``radius`` of the patch's point.
    - ``pids``: property ids of the region (e.g. the base plate's); default all shells.
      Patches hold elements of the region only.
    - ``at``: ``"elements"`` (default): one patch per element of the region, centred on
      its centre (the element itself always in it); ``"grids"``: one per grid of the
      region's elements, leaving out grids with no element centre within the radius.

    **Returns:** a :class:`ShellPatches`, patches in the order of element (or grid) ids.
    """
    r = np.asarray(radius)
    if r.ndim or not np.isfinite(r) or r <= 0:
        raise ValueError(f"radius must be a positive finite number of metres, got {radius!r}")
    r = float(r)
    if at not in ("elements", "grids"):
        raise ValueError(f"at must be 'elements' or 'grids', got {at!r}")
    ids, centres, corners = shell_centres(model, pids)
    if not len(ids):
        known = sorted({int(p) for b in _SHELL_BLOCKS for p in np.asarray(getattr(model, b).pids)})
        raise ValueError(f"no shell elements with property ids {list(pids) if pids is not None else 'any'}; "
                         f"the model's shells have property ids {known}")
    if at == "elements":
        anchors, points = ids, centres
    else:
        rows = np.unique(corners[corners >= 0])
        anchors, points = np.asarray(model.node_ids, dtype=np.int64)[rows], np.asarray(model.xyz)[rows]
    distance = np.linalg.norm(points[:, None, :] - centres[None, :, :], axis=2)  # (anchors, elements)
    inside = distance <= r * (1.0 + _TOL)
    keep = inside.any(axis=1)
    if not keep.any():
        raise ValueError(f"radius {r} m holds no element centre around any grid: take a larger radius")
    groups = tuple(tuple(int(e) for e in ids[row]) for row in inside[keep])
    return ShellPatches(groups=groups, centres=points[keep], anchors=anchors[keep], at=at, radius=r)
