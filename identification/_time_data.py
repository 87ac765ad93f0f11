"""Measured time histories, FRFs estimated from them, and the channel → DoF map of exports.

A test system exports what its channels recorded: force and response time histories
(UFF dataset 58, function type 1, read by :func:`identification.read_uff` into
:class:`TimeHistories`). :func:`frf_from_histories` takes the force channels the user
names, the other channels as responses, and estimates H1 or H2 with the coherence by
:func:`identification.frf_from_time` (Welch: Bendat & Piersol, *Random Data*, §§9.1–9.2);
:class:`FRFEstimate` holds the FRFs with the averaging they came from.

Channel-only exports (records with node 0, direction 0 and a channel name) get their DoFs
from a map {channel: (node, direction code)}, read from CSV by :func:`read_dof_map`.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import equinox as eqx
import numpy as np
from jaxtyping import Float, Int

from ._csv import integer, table_rows
from ._data import FRFData, Sensors
from ._frf import ESTIMATORS, WINDOWS, frf_from_time

QUANTITIES = ("force", "displacement", "velocity", "acceleration")
_FRF_KIND = {"displacement": "receptance", "velocity": "mobility", "acceleration": "accelerance"}
_OVERLAP = {"hann": 0.5, "rect": 0.0}  # random excitation: half-overlapping Hann blocks; rect: whole blocks
_SI_UNIT = {  # (translational, rotational) DoF
    "force": ("N", "N·m"),
    "displacement": ("m", "rad"),
    "velocity": ("m/s", "rad/s"),
    "acceleration": ("m/s²", "rad/s²"),
}
_AXES = {"X": 1, "Y": 2, "Z": 3, "RX": 4, "RY": 5, "RZ": 6}
_NODE_DIR = re.compile(r"^\s*([0-9]+)\s*:\s*([+-]?)\s*([1-6])\s*$")
_DIRECTION = re.compile(r"^\s*([+-]?)\s*(?:([1-6])|(R?[XYZ]))\s*$", re.IGNORECASE)


def _dof_label(node: int, code: int) -> str:
    return Sensors.from_components([node], [code]).labels[0]


def parse_direction(text: str) -> int:
    """Direction code ±1..6 from ``3``, ``+3``, ``-3``, ``Z``, ``+Z``, ``-RX`` (case-insensitive);
    raises ``ValueError`` otherwise."""
    m = _DIRECTION.match(str(text))
    if m is None:
        raise ValueError(f"{text!r} is not a direction code ±1..6 or an axis (+X, -Z, RY, ...)")
    code = int(m.group(2)) if m.group(2) else _AXES[m.group(3).upper()]
    return -code if m.group(1) == "-" else code


class TimeHistories(eqx.Module):
    """Simultaneously sampled channels: a name, a DoF and a quantity each, values in SI.

    **Fields:**

    - ``values`` (n_samples, n_channels): N (N·m for a moment) for forces; m, m/s, m/s²
      (rad, rad/s, rad/s² on rotational DoFs) for displacement, velocity, acceleration.
    - ``fs``: sampling rate, Hz; ``start_s``: time of the first sample, s.
    - ``names``: channel names as exported ("" when the record has none).
    - ``nodes``, ``codes``: DoF of each channel, node id and direction code ±1..6.
    - ``quantities``: one of ``QUANTITIES`` per channel.

    A force and a response may share a DoF (driving point); two channels of one quantity
    on one DoF are refused.
    """

    values: Float[np.ndarray, "n_samples n_channels"]
    fs: float
    nodes: Int[np.ndarray, " n_channels"]
    codes: Int[np.ndarray, " n_channels"]
    names: tuple[str, ...] = eqx.field(static=True)
    quantities: tuple[str, ...] = eqx.field(static=True)
    start_s: float = 0.0

    def __init__(self, values, fs: float, nodes, codes, names: Sequence[str], quantities: Sequence[str],
                 start_s: float = 0.0):
        self.values = np.asarray(values, dtype=np.float64)
        self.fs = float(fs)
        self.nodes = np.asarray(nodes, dtype=np.int64).reshape(-1)
        self.codes = np.asarray(codes, dtype=np.int64).reshape(-1)
        self.names = tuple(str(n) for n in names)
        self.quantities = tuple(str(q) for q in quantities)
        self.start_s = float(start_s)

    def __check_init__(self):
        if self.values.ndim != 2:
            raise ValueError(f"values must have shape (n_samples, n_channels), got {self.values.shape}")
        n = self.values.shape[1]
        for name, count in (("nodes", len(self.nodes)), ("codes", len(self.codes)), ("names", len(self.names)),
                            ("quantities", len(self.quantities))):
            if count != n:
                raise ValueError(f"{count} {name} for {n} channels")
        if self.values.shape[0] < 2:
            raise ValueError(f"a time history needs at least 2 samples, got {self.values.shape[0]}")
        if not (math.isfinite(self.fs) and self.fs > 0):
            raise ValueError(f"sampling rate {self.fs} Hz is not finite and positive")
        for c in range(n):
            if self.quantities[c] not in QUANTITIES:
                raise ValueError(f"channel {c} ({self.names[c]}): quantity {self.quantities[c]!r} is not one of "
                                 f"{QUANTITIES}")
            if not 1 <= abs(int(self.codes[c])) <= 6:
                raise ValueError(f"channel {c} ({self.names[c]}): direction code {self.codes[c]} is not ±1..6")
        bad = np.argwhere(~np.isfinite(self.values))
        if len(bad):
            k, c = bad[0]
            raise ValueError(f"channel {c} ({self.labels[c]}): value {self.values[k, c]} at sample {k}")
        seen: dict[tuple[int, int, str], int] = {}
        for c, key in enumerate(zip(self.nodes.tolist(), self.codes.tolist(), self.quantities)):
            if key in seen:
                raise ValueError(f"channels {seen[key]} ({self.labels[seen[key]]}) and {c} ({self.labels[c]}) "
                                 f"both measure {key[2]} at {_dof_label(key[0], key[1])}")
            seen[key] = c

    @property
    def n_samples(self) -> int:
        return self.values.shape[0]

    @property
    def n_channels(self) -> int:
        return self.values.shape[1]

    @property
    def dof_labels(self) -> list[str]:
        """``101+Z`` per channel."""
        return [_dof_label(g, c) for g, c in zip(self.nodes.tolist(), self.codes.tolist())]

    @property
    def labels(self) -> list[str]:
        """``name (101+Z, acceleration)`` per channel (without the name when there is none)."""
        return [f"{name} ({dof}, {q})" if name else f"{dof} ({q})"
                for name, dof, q in zip(self.names, self.dof_labels, self.quantities)]

    def units(self, channel: int) -> str:
        """SI unit of a channel's values: ``N``, ``m/s²``, ``rad/s`` ..."""
        return _SI_UNIT[self.quantities[channel]][abs(int(self.codes[channel])) > 3]

    def find(self, spec: str) -> list[int]:
        """Channels matching ``spec``: a channel name (exact), a DoF label (``101+Z``,
        case-insensitive), or ``NODE:DIR`` with a direction code (``101:+3`` and
        ``101:-3`` one sign, ``101:3`` either)."""
        spec = str(spec).strip()
        m = _NODE_DIR.match(spec)
        hits = []
        for c, (name, dof) in enumerate(zip(self.names, self.dof_labels)):
            node, code = int(self.nodes[c]), int(self.codes[c])
            if name == spec or dof.upper() == spec.upper():
                hits.append(c)
            elif m is not None and node == int(m.group(1)) and abs(code) == int(m.group(3)) and (
                    not m.group(2) or (code > 0) == (m.group(2) == "+")):
                hits.append(c)
        return hits


class FRFEstimate(eqx.Module):
    """FRFs estimated from time histories, with the averaging they came from.

    **Fields:** ``frfs`` (:class:`FRFData`, with coherence unless there was one block);
    ``fs`` (Hz), ``n_samples``, ``block_length`` (samples), ``n_averages`` (blocks
    averaged), ``window``, ``overlap`` (fraction of a block), ``estimator`` ("H1", "H2");
    ``input_channels``, ``output_channels``: channel labels of forces and responses.
    """

    frfs: FRFData
    fs: float
    n_samples: int = eqx.field(static=True)
    block_length: int = eqx.field(static=True)
    n_averages: int = eqx.field(static=True)
    window: str = eqx.field(static=True)
    overlap: float = eqx.field(static=True)
    estimator: str = eqx.field(static=True)
    input_channels: tuple[str, ...] = eqx.field(static=True)
    output_channels: tuple[str, ...] = eqx.field(static=True)

    @property
    def resolution_hz(self) -> float:
        """Line spacing fs / block length, Hz."""
        return self.fs / self.block_length

    def coherence_table(self) -> list[dict]:
        """Per FRF: ``output``, ``input`` (DoF labels) and the ``min`` and ``mean`` coherence
        over the lines estimated (None without coherence)."""
        frfs = self.frfs
        coherence = None if frfs.coherence is None else np.asarray(frfs.coherence)
        rows = []
        for o, out in enumerate(frfs.outputs.labels):
            for i, inp in enumerate(frfs.inputs.labels):
                c = None if coherence is None else coherence[:, o, i]
                rows.append({"output": out, "input": inp,
                             "min": None if c is None else float(np.min(c)),
                             "mean": None if c is None else float(np.mean(c))})
        return rows

    def to_json(self) -> dict:
        f = np.asarray(self.frfs.frequencies_hz)
        return {
            "fs_hz": self.fs,
            "n_samples": self.n_samples,
            "duration_s": self.n_samples / self.fs,
            "block_length": self.block_length,
            "resolution_hz": self.resolution_hz,
            "n_averages": self.n_averages,
            "window": self.window,
            "overlap": self.overlap,
            "estimator": self.estimator,
            "kind": self.frfs.kind,
            "band_hz": [float(f[0]), float(f[-1])],
            "inputs": [{"channel": c, "dof": d} for c, d in zip(self.input_channels, self.frfs.inputs.labels)],
            "outputs": [{"channel": c, "dof": d} for c, d in zip(self.output_channels, self.frfs.outputs.labels)],
            "coherence": self.coherence_table(),
        }


def frf_from_histories(
    histories: TimeHistories,
    forces: Sequence[str],
    *,
    estimator: str = "H1",
    window: str = "hann",
    blocks: int = 8,
) -> FRFEstimate:
    """FRFs from time histories: the named force channels are the inputs, every other
    channel a response.

    **Arguments:**

    - ``forces``: specs as :meth:`TimeHistories.find` reads them (channel name,
      ``101+Z``, ``101:+3``, ``101:3``); the force channels each matches are inputs (a
      driving-point response on the same DoF is not), and a spec matching no force
      channel is refused.
    - ``estimator``: "H1" (G_yx G_xx⁻¹) or "H2" (G_yy / G_xy, one input).
    - ``window``: "hann" (random excitation; blocks overlap by half) or "rect" (periodic
      excitation whose period is the block, or transients; blocks do not overlap).
    - ``blocks``: the record is cut into this many blocks of n_samples // blocks
      samples (the resolution is fs / that length); with Hann and half overlap,
      2·blocks − 1 blocks are averaged.

    **Returns:** :class:`FRFEstimate`. The FRF kind follows the responses' quantity
    (displacement: receptance, velocity: mobility, acceleration: accelerance).

    Raises ``ValueError`` naming the channels for: a spec matching no channel (the
    channels are listed) or no force channel, a force channel left among the responses
    (every acting force must be an input), no response, responses of mixed quantities,
    and bad settings.
    """
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator {estimator!r} is not one of {ESTIMATORS}")
    if window not in WINDOWS:
        raise ValueError(f"window {window!r} is not one of {WINDOWS}")
    if not forces:
        raise ValueError("no force channel named")
    labels = histories.labels
    listing = "; ".join(labels)
    inputs: list[int] = []
    for spec in forces:
        hits = histories.find(spec)
        if not hits:
            raise ValueError(f"no channel matches force {spec!r}; the channels are: {listing}")
        found = [c for c in hits if histories.quantities[c] == "force"]
        if not found:
            raise ValueError(f"force {spec!r} matches {', '.join(labels[c] for c in hits)}, not a force channel; "
                             f"the force channels are: "
                             f"{'; '.join(l for l, q in zip(labels, histories.quantities) if q == 'force') or 'none'}")
        inputs += [c for c in found if c not in inputs]
    outputs = [c for c in range(histories.n_channels) if c not in inputs]
    left = [labels[c] for c in outputs if histories.quantities[c] == "force"]
    if left:
        raise ValueError(f"force channel(s) {'; '.join(left)} not named as inputs: every force acting on the "
                         "structure must be an input of the estimate")
    if not outputs:
        raise ValueError(f"no response channel: every channel is a named force ({listing})")
    kinds = {histories.quantities[c] for c in outputs}
    if len(kinds) > 1:
        by = {q: [labels[c] for c in outputs if histories.quantities[c] == q] for q in sorted(kinds)}
        raise ValueError("responses of mixed quantities (one FRF kind per set): "
                         + "; ".join(f"{q}: {', '.join(v)}" for q, v in by.items()))
    kind = _FRF_KIND[kinds.pop()]
    blocks = int(blocks)
    n = histories.n_samples
    if not 1 <= blocks <= n // 2:
        raise ValueError(f"blocks = {blocks} must be in 1..{n // 2} (n_samples // 2, {n} samples)")
    nperseg = n // blocks
    overlap = _OVERLAP[window]
    try:
        sensors = [Sensors.from_components(histories.nodes[idx], histories.codes[idx])
                   for idx in (np.asarray(inputs), np.asarray(outputs))]
    except ValueError as err:
        raise ValueError(f"channels: {err}") from err
    values = histories.values
    frfs = frf_from_time(values[:, inputs], values[:, outputs], histories.fs, inputs=sensors[0], outputs=sensors[1],
                         kind=kind, estimator=estimator, window=window, nperseg=nperseg, overlap=overlap)
    step = max(1, round(nperseg * (1 - overlap)))  # as frf_from_time cuts the blocks
    return FRFEstimate(
        frfs=frfs,
        fs=histories.fs,
        n_samples=n,
        block_length=nperseg,
        n_averages=1 + (n - nperseg) // step,
        window=window,
        overlap=overlap,
        estimator=estimator,
        input_channels=tuple(labels[c] for c in inputs),
        output_channels=tuple(labels[c] for c in outputs),
    )


def read_dof_map(path: str | os.PathLike) -> dict[str, tuple[int, int]]:
    """Channel → DoF map from CSV with the header ``channel,node,direction``.

    ``channel`` is the channel name of the UFF 58 records (:func:`read_uff` says which
    field), ``node`` a node id (integer ≥ 0), ``direction`` a code ±1..6 or an axis
    (``+Z``, ``-RX``). **Returns:** {channel: (node, direction code)}.

    Raises ``ValueError`` naming the file, line and field for a missing column, an empty
    channel, a bad node or direction, a channel listed twice, or a file without rows.
    """
    path = os.fspath(path)
    mapping: dict[str, tuple[int, int]] = {}
    where: dict[str, int] = {}
    for line, row in table_rows(path, ("channel", "node", "direction"), "channel map"):
        channel = row["channel"]
        node = integer(row["node"], f"{path}, line {line}: field 'node'", 0, what="a node id (integer)")
        try:
            code = parse_direction(row["direction"])
        except ValueError as err:
            raise ValueError(f"{path}, line {line}: field 'direction': {err}") from None
        if channel in mapping:
            raise ValueError(f"{path}, line {line}: channel {channel!r} repeats line {where[channel]}")
        mapping[channel], where[channel] = (node, code), line
    return mapping


def check_dof_map(dof_map: Mapping[str, tuple[int, int]]) -> dict[str, tuple[int, int]]:
    """``dof_map`` as {str: (int node ≥ 0, int code ±1..6)}; ``ValueError`` naming a bad entry."""
    out = {}
    for channel, dof in dof_map.items():
        try:
            node, code = (int(v) for v in dof)
        except (TypeError, ValueError):
            raise ValueError(f"DoF map: channel {channel!r} maps to {dof!r}, not (node, direction)") from None
        if node < 0 or not 1 <= abs(code) <= 6:
            raise ValueError(f"DoF map: channel {channel!r} maps to node {node}, direction {code}; need a node ≥ 0 "
                             "and a direction ±1..6")
        out[str(channel).strip()] = (node, code)
    return out


def plot_coherence(frfs: FRFData, path: str | Path, title: str | None = None) -> Path:
    """FRF magnitudes (top, SI units of the kind) and coherence γ² (bottom) against frequency,
    one line per FRF, as PNG. Without coherence only the magnitudes are drawn.

    **Returns:** the path written.
    """
    from ._plots import figure

    unit = {"receptance": "m/N", "mobility": "m/(s·N)", "accelerance": "m/(s²·N)"}[frfs.kind]
    f = np.asarray(frfs.frequencies_hz)
    values = np.asarray(frfs.values)
    pairs = [(o, i) for o in range(len(frfs.outputs)) for i in range(len(frfs.inputs))]
    fig = figure(8.0, 6.0 if frfs.coherence is not None else 3.5)
    axes = fig.subplots(2 if frfs.coherence is not None else 1, 1, sharex=True, squeeze=False)[:, 0]
    for o, i in pairs:
        label = f"{frfs.outputs.labels[o]} / {frfs.inputs.labels[i]}"
        axes[0].semilogy(f, np.abs(values[:, o, i]), lw=1.0, label=label)
        if frfs.coherence is not None:
            axes[1].plot(f, np.asarray(frfs.coherence)[:, o, i], lw=1.0, label=label)
    axes[0].set_ylabel(f"|H| [{unit}] ({frfs.kind})")
    axes[0].set_title(title or f"FRFs and coherence ({len(pairs)} FRFs)")
    if frfs.coherence is not None:
        axes[1].set_ylabel("coherence γ² [–]")
        axes[1].set_ylim(0.0, 1.05)
    axes[-1].set_xlabel("frequency [Hz]")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
    if len(pairs) <= 12:
        axes[0].legend(fontsize="small", ncols=2 if len(pairs) > 4 else 1)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, format="png")
    return path
