"""Containers of measured data: sensors, modal data, FRFs, and the sensor observation matrix.

Everything is SI: lengths in m, frequencies in Hz, shapes in the units of displacement
(m, or rad for rotations). Arrays are NumPy float64/complex128, so the containers do not
depend on the JAX configuration; values may also be JAX arrays, including tracers, in
which case only the shape checks run (the value checks need concrete numbers).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence

import equinox as eqx
import jax
import numpy as np
from jaxtyping import Bool, Float, Int, Shaped

import jaxfem
from jaxfem import Model

from ._csv import MAX_ID, integer, table_rows

FRF_KINDS = ("receptance", "mobility", "accelerance")  # displacement, velocity, acceleration / force
_AXES = "XYZ"
_UNIT_TOL = 1e-9  # |‖d‖ − 1| allowed for a direction given as unit vector
_PARALLEL_TOL = 1e-9  # 1 − |d₁·d₂| below which two directions measure the same DoF


def _concrete(x) -> np.ndarray | None:
    """The values of ``x`` as NumPy, or None for a JAX tracer (no values to check)."""
    return None if isinstance(x, jax.core.Tracer) else np.asarray(x)


def _first(mask: np.ndarray) -> int | None:
    """Index of the first True entry, or None."""
    hits = np.flatnonzero(mask)
    return int(hits[0]) if len(hits) else None


def _as_float(x, name: str, ndim: int) -> np.ndarray | jax.Array:
    arr = x if isinstance(x, jax.Array) else np.asarray(x, dtype=np.float64)
    if arr.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimension(s), got shape {arr.shape}")
    return arr


def _as_numeric(x, name: str, ndim: int) -> np.ndarray | jax.Array:
    """Real (float64) or complex (complex128) array; integers become float64."""
    if isinstance(x, jax.Array):
        arr = x
    else:
        arr = np.asarray(x)
        arr = arr.astype(np.complex128 if np.iscomplexobj(arr) else np.float64)
    if arr.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimension(s), got shape {arr.shape}")
    return arr


def _direction_label(node: int, d: np.ndarray, rotational: bool) -> str:
    axis = np.flatnonzero(np.abs(d) > 1.0 - _UNIT_TOL)
    r = "R" if rotational else ""
    if len(axis) == 1:
        return f"{node}{'+' if d[axis[0]] > 0 else '-'}{r}{_AXES[axis[0]]}"
    return f"{node}:{r}({d[0]:.2f},{d[1]:.2f},{d[2]:.2f})"


class Sensors(eqx.Module):
    """Measured degrees of freedom: a grid id and a direction each.

    A translational sensor measures ``d · u`` (m) at its grid, a rotational one ``d · θ``
    (rad), with ``d`` a unit vector in basic (global) axes. Labels read ``101+Z``,
    ``101-RX`` (rotation about −X) or ``101:(0.00,0.71,0.71)`` for a skew direction.
    Two sensors on the same grid along parallel or opposite directions of the same kind
    measure the same DoF and are refused.

    Build with :meth:`from_components` (Nastran/UFF direction codes) or
    :meth:`from_vectors` (any directions); ``Sensors(nodes, directions, rotational)``
    requires unit vectors.
    """

    nodes: Int[np.ndarray, " n"]
    directions: Float[np.ndarray, "n 3"]
    rotational: Bool[np.ndarray, " n"]
    labels: list[str]

    def __init__(self, nodes, directions, rotational=None):
        self.nodes = np.asarray(nodes, dtype=np.int64).reshape(-1)
        self.directions = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        n = len(self.nodes)
        if self.directions.shape != (n, 3):
            raise ValueError(f"{n} sensor nodes but directions of shape {self.directions.shape}")
        self.rotational = (
            np.zeros(n, dtype=bool) if rotational is None else np.asarray(rotational, dtype=bool).reshape(-1)
        )
        if self.rotational.shape != (n,):
            raise ValueError(f"{n} sensor nodes but rotational of shape {self.rotational.shape}")
        self.labels = [
            _direction_label(int(g), d, bool(r)) for g, d, r in zip(self.nodes, self.directions, self.rotational)
        ]

    def __check_init__(self):
        norms = np.linalg.norm(self.directions, axis=1)
        i = _first(~(np.abs(norms - 1.0) <= _UNIT_TOL))
        if i is not None:
            raise ValueError(
                f"sensor {i} at grid {self.nodes[i]}: direction {self.directions[i].tolist()} is not a unit "
                "vector (use Sensors.from_vectors to normalise)"
            )
        for node in np.unique(self.nodes):
            rows = np.flatnonzero(self.nodes == node)
            cos = np.abs(self.directions[rows] @ self.directions[rows].T)
            same = (cos >= 1.0 - _PARALLEL_TOL) & (self.rotational[rows, None] == self.rotational[None, rows])
            i, j = np.nonzero(np.triu(same, k=1))
            if len(i):
                a, b = rows[i[0]], rows[j[0]]
                raise ValueError(
                    f"sensors {a} ({self.labels[a]}) and {b} ({self.labels[b]}) measure the same DoF"
                )

    def __len__(self) -> int:
        return len(self.nodes)

    @classmethod
    def from_components(cls, nodes: Sequence[int], components: Sequence[int]) -> Sensors:
        """Sensors from direction codes ±1..6 (Nastran components, UFF direction codes).

        1, 2, 3 are translations along X, Y, Z; 4, 5, 6 rotations about X, Y, Z; a negative
        code measures along the negative axis (its values have the opposite sign).
        """
        codes = np.asarray(components, dtype=np.int64).reshape(-1)
        nodes = np.asarray(nodes, dtype=np.int64).reshape(-1)
        if codes.shape != nodes.shape:
            raise ValueError(f"{len(nodes)} sensor nodes but {len(codes)} components")
        i = _first((np.abs(codes) < 1) | (np.abs(codes) > 6))
        if i is not None:
            raise ValueError(f"sensor {i} at grid {nodes[i]}: direction code {codes[i]} is not ±1..6")
        directions = np.zeros((len(codes), 3))
        directions[np.arange(len(codes)), (np.abs(codes) - 1) % 3] = np.sign(codes)
        return cls(nodes, directions, np.abs(codes) > 3)

    @classmethod
    def read_csv(cls, path) -> Sensors:
        """Sensors from a CSV file with the columns ``label,node,component`` (node an id
        1..2³¹−1, component a direction code ±1..6 as in :meth:`from_components`); a bad
        row, or a DoF listed twice, names file and line (:func:`identification._csv.table_rows`)."""
        nodes, codes, first = [], [], {}
        for line, row in table_rows(path, ("node", "component"), "sensor list"):
            where = f"{os.fspath(path)}, line {line}"
            node = integer(row["node"], f"{where}: field 'node'", 1, what="a node id (integer)")
            code = integer(row["component"], f"{where}: field 'component'", -MAX_ID, MAX_ID)
            if not 1 <= abs(code) <= 6:
                raise ValueError(f"{where}: field 'component': {code} is not a direction code ±1..6")
            if (node, code) in first or (node, -code) in first:
                raise ValueError(f"{where}: node {node} component {abs(code)} repeats line "
                                 f"{first.get((node, code), first.get((node, -code)))}")
            first[node, code] = line
            nodes.append(node)
            codes.append(code)
        return cls.from_components(nodes, codes)

    @classmethod
    def from_vectors(cls, nodes: Sequence[int], directions, rotational=None) -> Sensors:
        """Sensors along arbitrary directions (basic axes), normalised to unit length."""
        nodes = np.asarray(nodes, dtype=np.int64).reshape(-1)
        directions = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        if len(directions) != len(nodes):
            raise ValueError(f"{len(nodes)} sensor nodes but {len(directions)} directions")
        norms = np.linalg.norm(directions, axis=1)
        i = _first(~(norms > 0.0) | ~np.isfinite(norms))
        if i is not None:
            raise ValueError(f"sensor {i} at grid {nodes[i]}: direction {directions[i].tolist()} has no length")
        return cls(nodes, directions / norms[:, None], rotational)

    @property
    def codes(self) -> Int[np.ndarray, " n"]:
        """Direction codes ±1..6 of axis-aligned sensors; 0 for a skew direction."""
        axis = np.argmax(np.abs(self.directions), axis=1)
        value = self.directions[np.arange(len(self)), axis]
        aligned = np.abs(value) > 1.0 - _UNIT_TOL
        code = np.sign(value).astype(np.int64) * (axis + 1 + 3 * self.rotational)
        return np.where(aligned, code, 0)


class ModalData(eqx.Module):
    """Identified modes at the sensors.

    **Fields:**

    - ``frequencies_hz`` (m,): undamped natural frequencies f = ω/2π, Hz.
    - ``damping_ratios`` (m,): viscous damping ratios ζ (0 where unknown).
    - ``shapes`` (n_sensors, m): mode shapes at the sensors, real or complex (m, rad).
    - ``sensors``: the measured DoFs, one per row of ``shapes``.
    - ``generalised_masses`` (m,) in kg, or None: φᵀMφ of the shapes as scaled.
    - ``mode_ids`` (m,): mode numbers as in the source, for reporting.
    """

    frequencies_hz: Float[np.ndarray, " m"]
    damping_ratios: Float[np.ndarray, " m"]
    shapes: Shaped[np.ndarray, "n m"]
    sensors: Sensors
    generalised_masses: Float[np.ndarray, " m"] | None
    mode_ids: Int[np.ndarray, " m"]

    def __init__(
        self,
        frequencies_hz,
        shapes,
        sensors: Sensors,
        *,
        damping_ratios=None,
        generalised_masses=None,
        mode_ids=None,
    ):
        self.frequencies_hz = _as_float(frequencies_hz, "frequencies_hz", 1)
        m = self.frequencies_hz.shape[0]
        self.shapes = _as_numeric(shapes, "shapes", 2)
        self.sensors = sensors
        self.damping_ratios = _as_float(np.zeros(m) if damping_ratios is None else damping_ratios, "damping_ratios", 1)
        self.generalised_masses = (
            None if generalised_masses is None else _as_float(generalised_masses, "generalised_masses", 1)
        )
        self.mode_ids = np.arange(1, m + 1) if mode_ids is None else np.asarray(mode_ids, dtype=np.int64).reshape(-1)

    def __check_init__(self):
        m = self.frequencies_hz.shape[0]
        expected = {
            "damping_ratios": (self.damping_ratios.shape, (m,)),
            "shapes": (self.shapes.shape, (len(self.sensors), m)),
            "mode_ids": (self.mode_ids.shape, (m,)),
        }
        if self.generalised_masses is not None:
            expected["generalised_masses"] = (self.generalised_masses.shape, (m,))
        for name, (got, want) in expected.items():
            if got != want:
                raise ValueError(f"{name} has shape {got}, expected {want} ({m} modes, {len(self.sensors)} sensors)")
        ids, counts = np.unique(self.mode_ids, return_counts=True)
        if np.any(counts > 1):
            raise ValueError(f"mode ids {ids[counts > 1].tolist()} appear more than once")
        ids = self.mode_ids
        checks = (
            (self.frequencies_hz, lambda f: np.isfinite(f) & (f > 0), "frequency {} Hz is not finite and positive"),
            (self.damping_ratios, lambda z: (z >= 0) & (z < 1), "damping ratio {} is not in [0, 1)"),
            (
                self.generalised_masses,
                lambda g: np.isfinite(g) & (g > 0),
                "generalised mass {} kg is not finite and positive",
            ),
        )
        for values, ok, message in checks:
            a = None if values is None else _concrete(values)
            k = None if a is None else _first(~ok(a))
            if k is not None:
                raise ValueError(f"mode {ids[k]}: " + message.format(a[k]))
        phi = _concrete(self.shapes)
        if phi is not None:
            bad = np.argwhere(~np.isfinite(phi))
            if len(bad):
                i, k = bad[0]
                raise ValueError(f"mode {ids[k]}: shape value {phi[i, k]} at sensor {self.sensors.labels[i]}")
            k = _first(~np.any(phi != 0, axis=0))
            if k is not None:
                raise ValueError(f"mode {ids[k]}: the shape is zero at every sensor")

    @property
    def n_modes(self) -> int:
        return self.frequencies_hz.shape[0]

    def real(self) -> ModalData:
        """Real normal modes from complex ones (thesis §2.3.1: compare real with real).

        Each complex mode ψ is rotated by the phase θ that maximises ‖Re(e^{iθ}ψ)‖², i.e.
        θ = −½ arg Σ_k ψ_k², and its real part is kept: the least-squares best real
        approximation of ψ up to a complex scale. The sign is then fixed so that the
        largest-magnitude component is positive (the project convention). A mode in
        perfect circular motion (Σψ_k² = 0) has no preferred phase and keeps θ = 0.
        Frequencies, damping and ids are unchanged; real data is returned as is.
        """
        if not np.iscomplexobj(self.shapes):
            return self
        psi = np.asarray(self.shapes)
        theta = -0.5 * np.angle(np.sum(psi**2, axis=0))
        phi = np.real(psi * np.exp(1j * theta)[None, :])
        peak = phi[np.argmax(np.abs(phi), axis=0), np.arange(phi.shape[1])]
        phi = phi * np.where(peak < 0, -1.0, 1.0)[None, :]
        return eqx.tree_at(lambda d: d.shapes, self, phi)

    def select(self, mode_indices: Sequence[int]) -> ModalData:
        """The modes at the given positions (0-based, in the given order)."""
        k = np.asarray(mode_indices, dtype=np.int64).reshape(-1)
        if np.any((k < -self.n_modes) | (k >= self.n_modes)):
            raise ValueError(f"mode indices {k.tolist()} out of range for {self.n_modes} modes")
        return ModalData(
            self.frequencies_hz[k],
            self.shapes[:, k],
            self.sensors,
            damping_ratios=self.damping_ratios[k],
            generalised_masses=None if self.generalised_masses is None else self.generalised_masses[k],
            mode_ids=self.mode_ids[k],
        )


class FRFData(eqx.Module):
    """Measured frequency response functions H[f, output, input].

    **Fields:**

    - ``frequencies_hz`` (nf,): strictly increasing, Hz.
    - ``values`` (nf, n_out, n_in) complex: response per unit input, SI: m/N
      (receptance), m/(s·N) (mobility) or m/(s²·N) (accelerance); rad instead of m for
      rotational outputs and N·m instead of N for rotational inputs.
    - ``outputs``, ``inputs``: response and excitation DoFs.
    - ``kind``: "receptance", "mobility" or "accelerance".
    - ``coherence`` (nf, n_out, n_in) in [0, 1], or None.
    """

    frequencies_hz: Float[np.ndarray, " nf"]
    values: Shaped[np.ndarray, "nf nout nin"]
    outputs: Sensors
    inputs: Sensors
    kind: str = eqx.field(static=True)
    coherence: Float[np.ndarray, "nf nout nin"] | None

    def __init__(self, frequencies_hz, values, outputs: Sensors, inputs: Sensors, kind: str, coherence=None):
        self.frequencies_hz = _as_float(frequencies_hz, "frequencies_hz", 1)
        values = _as_numeric(values, "values", 3)
        self.values = values if isinstance(values, jax.Array) else values.astype(np.complex128)
        self.outputs = outputs
        self.inputs = inputs
        self.kind = kind
        self.coherence = None if coherence is None else _as_float(coherence, "coherence", 3)

    def __check_init__(self):
        if self.kind not in FRF_KINDS:
            raise ValueError(f"FRF kind {self.kind!r} is not one of {FRF_KINDS}")
        shape = (self.frequencies_hz.shape[0], len(self.outputs), len(self.inputs))
        if self.values.shape != shape:
            raise ValueError(
                f"values has shape {self.values.shape}, expected {shape} (frequencies, outputs, inputs)"
            )
        if self.coherence is not None and self.coherence.shape != shape:
            raise ValueError(f"coherence has shape {self.coherence.shape}, expected {shape}")
        f = _concrete(self.frequencies_hz)
        if f is not None:
            k = _first(~(np.isfinite(f) & (f >= 0)))
            if k is not None:
                raise ValueError(f"frequency line {k}: {f[k]} Hz is not finite and non-negative")
            k = _first(np.diff(f) <= 0)
            if k is not None:
                raise ValueError(
                    f"frequency axis not strictly increasing: line {k + 1} ({f[k + 1]} Hz) after {f[k]} Hz"
                )
        for name, arr, ok in (
            ("value", self.values, np.isfinite),
            ("coherence", self.coherence, lambda c: np.isfinite(c) & (c >= 0) & (c <= 1)),
        ):
            a = None if arr is None else _concrete(arr)
            if a is None:
                continue
            bad = np.argwhere(~ok(a))
            if len(bad):
                k, o, i = bad[0]
                where = f"{self.frequencies_hz[k]} Hz" if f is not None else f"line {k}"
                raise ValueError(
                    f"FRF {self.outputs.labels[o]} / {self.inputs.labels[i]}: {name} {a[k, o, i]} at {where}"
                )


def observation_matrix(
    model: Model,
    sensors: Sensors,
    *,
    nearest: bool = False,
    sensor_xyz=None,
    tol: float = 1e-6,
) -> tuple[Float[np.ndarray, "n_sensors n_dof"], list[dict]]:
    """Matrix C with φ_sensors = C φ_model, φ_model over the model's solved DoFs.

    A translational sensor along d at grid g reads ``Σ_c d_c u_c(g)`` with
    ``u_c(g) = coef[g, c] · u_solved[index[g]]`` (c = T1..T3; R1..R3 for a rotational
    sensor), so constrained components contribute nothing and an RBE2-dependent grid
    reads the rigid-body combination of its independent grid's DoFs.

    **Arguments:**

    - ``model``: the FE model (its grids in m).
    - ``sensors``: the measured DoFs.
    - ``nearest``: map each sensor to the model grid closest to ``sensor_xyz`` (m,
      shape (n_sensors, 3)) instead of by grid id; a ``UserWarning`` names the sensors
      farther than ``tol`` (m) from their grid.

    **Returns:** ``(C, report)``: C as NumPy float64 (n_sensors, n_dof), and one dict per
    sensor ``{"sensor": label, "grid": model grid id, "distance": m}`` (distance 0 when
    mapped by id).

    Raises ``ValueError`` listing sensor grids that are not in the model (without
    ``nearest``), and naming a sensor whose DoF is fully constrained (zero row).
    """
    n = len(sensors)
    if nearest:
        if sensor_xyz is None:
            raise ValueError("nearest=True needs sensor_xyz, the (n_sensors, 3) sensor coordinates in m")
        xyz = np.asarray(sensor_xyz, dtype=np.float64)
        if xyz.shape != (n, 3):
            raise ValueError(f"sensor_xyz has shape {xyz.shape}, expected ({n}, 3)")
        located = jaxfem.locate_sensors(model, xyz, sensors.directions, "nearest", rotational=sensors.rotational,
                                         labels=sensors.labels)
        far = np.flatnonzero(located.distance > tol)
        if len(far):
            listing = ", ".join(
                f"{sensors.labels[i]} → grid {located.grids[i, 0]} ({located.distance[i]:.3g} m)" for i in far
            )
            warnings.warn(f"sensors farther than {tol:g} m from their nearest model grid: {listing}", stacklevel=2)
    else:
        if sensor_xyz is not None:
            raise ValueError("sensor_xyz is only used with nearest=True")
        known = set(np.asarray(model.node_ids).tolist())
        missing = sorted({int(g) for g in sensors.nodes if int(g) not in known})
        if missing:
            raise ValueError(
                f"sensor grid(s) {missing} not in the model (pass nearest=True with sensor_xyz to map them)"
            )
        located = jaxfem.sensors_at_grids(model, sensors.nodes, sensors.directions, rotational=sensors.rotational,
                                          labels=sensors.labels)
    C, distance, grids = located.matrix, located.distance, located.grids[:, 0]
    i = _first(~np.any(C != 0.0, axis=1))
    if i is not None:
        raise ValueError(
            f"sensor {sensors.labels[i]} reads grid {grids[i]} where every measured component is constrained "
            "(SPC or auto-SPC): it can never be compared"
        )
    report = [
        {"sensor": label, "grid": int(g), "distance": float(d)} for label, g, d in zip(sensors.labels, grids, distance)
    ]
    return C, report
