"""Model blocks on single DoFs and direct matrices: scalar masses (CMASS1–4), scalar and
viscous dampers (CDAMP1–4, CVISC), general 6 × 6 masses at a grid (CONM1) and direct
input matrices (DMIG selected by K2GG/M2GG/B2GG).

Scalar elements act on a (point, component) pair in the point's global (CD) system or
on ground (node −1), as springs do (:class:`jaxfem.Springs`); CONM1 matrices are in basic
axes at their grid; direct matrices are on the global components of the points they
name (MSC QRG, per card). Units: those of the deck (consistent), masses after PARAM
WTMASS where Nastran applies it.
"""

from __future__ import annotations

import equinox as eqx
import numpy as np
from jaxtyping import Array, Float, Int


class ScalarMasses(eqx.Module):
    """CMASS1–4: mass m between two (point, component) pairs, ``m [[1, −1], [−1, 1]]``."""

    ids: Int[np.ndarray, " n"]
    pids: Int[np.ndarray, " n"]  # PMASS id, 0 for CMASS2/CMASS4
    nodes: Int[np.ndarray, "n 2"]  # rows in Model.node_ids, -1 for ground
    components: Int[np.ndarray, "n 2"]  # global components 1..6 (0 for ground)
    m: Float[Array, " n"]
    m_scale: Float[Array, " n"]


class Dampers(eqx.Module):
    """Viscous dampers: CDAMP1–4 (b between two (point, component) pairs, as a spring) and
    CVISC (CE along the axis GA→GB, CR about it, as a rod), in one table: ``axial`` rows
    are CVISC (components unused), the others scalar."""

    ids: Int[np.ndarray, " n"]
    nodes: Int[np.ndarray, "n 2"]
    components: Int[np.ndarray, "n 2"]
    axial: np.ndarray  # bool (n,)
    b: Float[Array, " n"]  # CDAMP b or CVISC CE [force·time/length]
    br: Float[Array, " n"]  # CVISC CR [moment·time/rad], 0 for CDAMP


class Conm1(eqx.Module):
    """CONM1: a symmetric 6 × 6 mass matrix at a grid, in basic axes."""

    ids: Int[np.ndarray, " n"]
    nodes: Int[np.ndarray, " n"]
    m: Float[Array, "n 6 6"]
    m_scale: Float[Array, " n"]


class DirectMatrices(eqx.Module):
    """K2GG, M2GG and B2GG of the subcase, summed over the DMIG matrices they name, on the
    union of their (point, global component) DoFs (symmetric d × d)."""

    names: tuple[str, ...] = eqx.field(static=True)
    nodes: Int[np.ndarray, " d"]
    components: Int[np.ndarray, " d"]
    k: Float[Array, "d d"]
    m: Float[Array, "d d"]
    b: Float[Array, "d d"]
