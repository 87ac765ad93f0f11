"""The correlation workflow (thesis §4.3.3): model modes observed at the test sensors,
pairing by MAC and Δf (eq. 4.1), AutoMAC, COMAC and signs of spatial aliasing."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

import jaxfem
from identification import (
    GeometryMap,
    ModalData,
    Pairing,
    aliasing,
    automac,
    comac,
    observation_matrix,
    pair_modes,
)
from jaxfem import Model

from ._parameters import Options
from ._solve import n_model_modes


@dataclass(frozen=True)
class CorrelationResult:
    """Outcome of :func:`correlate` (host-side NumPy arrays; modes numbered from 0).

    **Fields:**
    - ``pairing``: the one-to-one :class:`identification.Pairing` of test and model modes.
    - ``model_frequencies_hz`` (n_a,), ``model_shapes`` (n_dof, n_a, mass-normalised) and
      ``model_at_sensors`` (n_s, n_a): the model modes, in full and read at the sensors.
    - ``test_frequencies_hz`` (n_e,), ``test_shapes`` (n_s, n_e): the measured modes.
    - ``sensors``: the sensor labels (``"7001+X"``), one per row of the shapes.
    - ``automac`` (n_e, n_e): MAC of the test shapes with each other (Table 5.2).
    - ``comac`` (n_s,): COMAC per sensor over the pairs, in sensor order (NaN without pairs).
    - ``aliasing``: one line per sign of spatial aliasing (:func:`identification.aliasing`).
    - ``max_automac``: the AutoMAC above which two test modes count as aliased.
    - ``model_name``, ``test_name``, ``geometry``: where the inputs came from (file names,
      the test nodes' :class:`identification.GeometryMap`), for :meth:`to_json`; None: left out.
    """

    pairing: Pairing
    model_frequencies_hz: np.ndarray
    model_shapes: np.ndarray = field(repr=False)
    model_at_sensors: np.ndarray = field(repr=False)
    test_frequencies_hz: np.ndarray
    test_shapes: np.ndarray = field(repr=False)
    sensors: tuple[str, ...]
    automac: np.ndarray = field(repr=False)
    comac: np.ndarray = field(repr=False)
    aliasing: tuple[str, ...]
    max_automac: float
    model_name: str | None = None
    test_name: str | None = None
    geometry: GeometryMap | None = field(default=None, repr=False)

    @property
    def n_model_modes(self) -> int:
        """Model modes computed (:func:`updating.n_model_modes`)."""
        return int(self.model_frequencies_hz.size)

    @property
    def n_paired(self) -> int:
        """Pairs found."""
        return int(self.pairing.test.size)

    @property
    def rms_freq_dev_pct(self) -> float | None:
        """RMS Δf over the pairs, % (None without pairs)."""
        return self.pairing.summary()["rms_freq_dev_pct"]

    @property
    def mean_mac(self) -> float | None:
        """Mean MAC over the pairs (None without pairs)."""
        return self.pairing.summary()["mean_mac"]

    @property
    def warnings(self) -> tuple[str, ...]:
        """One line per unpaired test mode with the reason (the pairing's; see also ``aliasing``)."""
        return tuple(self.pairing.warnings)

    @property
    def comac_ranking(self) -> list[tuple[str, float]]:
        """``(sensor, COMAC)`` lowest first (stable order); empty without pairs."""
        if not self.n_paired:
            return []
        return [(self.sensors[i], float(self.comac[i])) for i in np.argsort(self.comac, kind="stable")]

    def to_json(self) -> dict:
        """JSON-ready, as ``jaxfem correlate --json`` writes it: ``model``, ``test`` (when
        named), ``n_model_modes``, the pairing (:meth:`Pairing.to_json`), ``automac``,
        ``comac`` (sensor and value, lowest first), ``test_geometry`` (with a geometry map)
        and ``aliasing``."""
        named = {key: value for key, value in (("model", self.model_name), ("test", self.test_name))
                 if value is not None}
        out = {**named, "n_model_modes": self.n_model_modes, **self.pairing.to_json(),
               "automac": np.asarray(self.automac).tolist(),
               "comac": [{"sensor": s, "value": v} for s, v in self.comac_ranking]}
        if self.geometry is not None:
            out["test_geometry"] = self.geometry.to_json()
        out["aliasing"] = list(self.aliasing)
        return out


def correlate(
    model: Model,
    test: ModalData,
    *,
    n_modes: int | None = None,
    min_mac: float = Options.min_mac,
    max_freq_dev: float = Options.max_freq_dev,
    max_automac: float = 0.9,
    solver: str = "auto",
    model_name: str | None = None,
    test_name: str | None = None,
    geometry: GeometryMap | None = None,
) -> CorrelationResult:
    """Correlate the modes of ``model`` with the measured modes ``test``.

    The model modes (:func:`jaxfem.modes`; ``n_modes``, default
    :func:`updating.n_model_modes`: twice the test modes, at least six spare) are read at
    the test sensors (:func:`identification.observation_matrix`; the sensors must be
    model grids, e.g. after :func:`identification.map_test_geometry`) and paired one to
    one by MAC ≥ ``min_mac`` and |Δf| ≤ ``max_freq_dev`` (eq. 4.1; defaults those of
    :class:`updating.Options`; :func:`identification.pair_modes`). Then the AutoMAC of
    the test shapes, the COMAC per sensor over the pairs and the signs of spatial
    aliasing (AutoMAC above ``max_automac``, or several model look-alikes).

    **Arguments:** ``solver``: ``"auto"``, ``"dense"`` or ``"sparse"``;
    ``model_name``, ``test_name``, ``geometry``: provenance kept for
    :meth:`CorrelationResult.to_json`.

    **Returns:** a :class:`CorrelationResult`. A ``ValueError`` on thresholds out of range
    (before the eigensolution), sensors the model lacks or a failing eigensolver.
    """
    for name, value, ok, what in (
        ("n_modes", n_modes, n_modes is None or n_modes >= 1, "a positive number of model modes"),
        ("min_mac", min_mac, 0.0 < min_mac <= 1.0, "in (0, 1]"),
        ("max_freq_dev", max_freq_dev, max_freq_dev >= 0.0, "non-negative"),
        ("max_automac", max_automac, 0.0 < max_automac <= 1.0, "in (0, 1]"),
    ):
        if not ok:
            raise ValueError(f"{name} must be {what}, got {value}")
    C = observation_matrix(model, test.sensors)[0]
    lam, phi = jaxfem.modes(model, n_model_modes(model, test.n_modes, n_modes), solver=solver)
    f_a, phi = np.asarray(jaxfem.frequencies_hz(lam)), np.asarray(phi)
    phi_a = C @ phi
    f_e, phi_e = np.asarray(test.frequencies_hz), np.asarray(test.shapes)
    pairing = pair_modes(f_a, phi_a, f_e, phi_e, min_mac=min_mac, max_freq_dev=max_freq_dev)
    lines = aliasing(phi_a, phi_e, f_a, f_e, min_mac=pairing.min_mac, max_automac=max_automac,
                     max_freq_dev=pairing.max_freq_dev)
    co = np.full(phi_e.shape[0], np.nan)
    if pairing.test.size:
        co = np.asarray(comac(phi_a[:, pairing.model], phi_e[:, pairing.test]))
    return CorrelationResult(
        pairing=pairing, model_frequencies_hz=f_a, model_shapes=phi, model_at_sensors=phi_a,
        test_frequencies_hz=f_e, test_shapes=phi_e, sensors=tuple(test.sensors.labels),
        automac=np.asarray(automac(phi_e)), comac=co, aliasing=tuple(lines), max_automac=float(max_automac),
        model_name=model_name, test_name=test_name, geometry=geometry,
    )
