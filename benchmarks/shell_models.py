"""Shell meshes as Nastran bulk data, for the shell tests, benchmarks and the CFRP panel.

Every function returns bulk-data text (free field, SI units) that :func:`jaxfem.io.read_bdf_text`
reads; element ids start at 1, grid ids at 1, row by row in x.
"""

from __future__ import annotations

import numpy as np

# Hard simple support of a plate in the x–y plane (Mindlin): w and the rotation whose axis
# is normal to the edge are held (θx on edges x = const, θy on edges y = const).
_SS_X, _SS_Y = "34", "35"


def _grid(gid: int, x: float, y: float, z: float) -> str:
    return f"GRID,{gid},,{float(x)!r},{float(y)!r},{float(z)!r}"


def plate(a: float, b: float, nx: int, ny: int, properties: str, *, bc: str = "ss", distort: float = 0.0,
          seed: int = 0, coupmass: bool = True, pid: int = 1, triangles: bool = False) -> str:
    """A flat a × b plate [m] of nx × ny CQUAD4 (or 2·nx·ny CTRIA3) on property ``pid``.

    ``properties``: the PSHELL/PCOMP and material cards. ``bc``: ``ss`` (hard simple
    support on all edges, in-plane DoFs held everywhere), ``cfff`` (clamped at x = 0),
    ``free``. ``distort``: interior grids moved at random by up to this fraction of an
    element. ``coupmass``: PARAM COUPMASS 1 (consistent mass) or lumped.
    """
    rng = np.random.default_rng(seed)
    xs, ys = np.linspace(0.0, a, nx + 1), np.linspace(0.0, b, ny + 1)
    gid = {}
    lines = [properties.strip()]
    if coupmass:
        lines.append("PARAM,COUPMASS,1")
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            gid[i, j] = j * (nx + 1) + i + 1
            dx = dy = 0.0
            if distort and 0 < i < nx and 0 < j < ny:
                dx, dy = distort * rng.uniform(-1, 1, 2) * (a / nx, b / ny)
            lines.append(_grid(gid[i, j], x + dx, y + dy, 0.0))
    eid = 1
    for j in range(ny):
        for i in range(nx):
            g = (gid[i, j], gid[i + 1, j], gid[i + 1, j + 1], gid[i, j + 1])
            if triangles:
                lines.append(f"CTRIA3,{eid},{pid},{g[0]},{g[1]},{g[2]}")
                lines.append(f"CTRIA3,{eid + 1},{pid},{g[0]},{g[2]},{g[3]}")
                eid += 2
            else:
                lines.append(f"CQUAD4,{eid},{pid},{g[0]},{g[1]},{g[2]},{g[3]}")
                eid += 1
    if bc == "ss":
        for (i, j), g in gid.items():
            held = "126"
            if i in (0, nx):
                held += _SS_X
            if j in (0, ny):
                held += "".join(c for c in _SS_Y if c not in held)
            lines.append(f"SPC1,1,{''.join(sorted(set(held)))},{g}")
    elif bc == "cfff":
        lines += [f"SPC1,1,123456,{g}" for (i, j), g in gid.items() if i == 0]
    elif bc != "free":
        raise ValueError(f"bc {bc!r}: ss | cfff | free")
    return "\n".join(lines) + "\n"


def cylinder(radius: float, length: float, n_around: int, n_along: int, properties: str, *,
             coupmass: bool = True, pid: int = 1) -> str:
    """A closed circular cylinder (axis x) of n_around × n_along CQUAD4, ends held in
    as shear diaphragms: the end grids' y, z and rotation about x held (radial and
    tangential displacement and the hoop slope zero), axial displacement free, so the
    first mode is the axial rigid-body translation."""
    lines = [properties.strip()]
    if coupmass:
        lines.append("PARAM,COUPMASS,1")
    gid = {}
    for j, x in enumerate(np.linspace(0.0, length, n_along + 1)):
        for i in range(n_around):
            phi = 2 * np.pi * i / n_around
            gid[i, j] = j * n_around + i + 1
            lines.append(_grid(gid[i, j], x, radius * np.cos(phi), radius * np.sin(phi)))
    eid = 1
    for j in range(n_along):
        for i in range(n_around):
            k = (i + 1) % n_around
            lines.append(f"CQUAD4,{eid},{pid},{gid[i, j]},{gid[k, j]},{gid[k, j + 1]},{gid[i, j + 1]}")
            eid += 1
    for i in range(n_around):
        for j in (0, n_along):
            lines.append(f"SPC1,1,234,{gid[i, j]}")
    return "\n".join(lines) + "\n"
