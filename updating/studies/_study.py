"""A Monte-Carlo study of thesis §4.3 (procedure of Fig. 4.23): its definition and its results.

:class:`Study` says what is sampled (model, sensors, the modelling error of Table 4.6,
the parameters, the numbers of modes, the measurement errors of Table 4.7, samples,
seed, chunking); :class:`MonteCarloResult` holds the samples and their statistics:
Δα = α(δ)/α(0) − 1 (eq. 4.4), Δf_n (eq. 4.5) and ΔMAC_n (eq. 4.6) per category,
magnitude and number of modes. :mod:`updating.studies._montecarlo` runs a study.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from importlib import resources
from pathlib import Path

import numpy as np
import tomllib

from .. import STUDY_EIGENSOLVERS, Options, Parameter, ParameterSet, schema

CATEGORIES = ("relative", "absolute", "frequency")
TABLE_4_7 = {"relative": (0.01, 0.02, 0.05, 0.10, 0.20),
             "absolute": (0.001, 0.002, 0.005, 0.01, 0.02),
             "frequency": (0.01, 0.02, 0.05)}
# Thesis Table 4.6 on the embedded tree (property ids of tree.bdf).
TABLE_4_6 = {1: ((2, 4), -0.17), 2: ((2, 4), -0.07), 3: ((12,), 0.10)}
STATUS = ("ok", "not converged", "unpaired mode", "non-finite")
# Δα is the ratio α(δ)/α(0) − 1 (eq. 4.4) where |α(0)| exceeds this, else α(δ) − α(0):
# parameters without modelling error have α(0) at the level of the stopping tolerance.
RATIO_FLOOR = 1e-4


@dataclasses.dataclass(frozen=True)
class Study:
    """A Monte-Carlo study (TOML, see :meth:`from_toml`).

    ``model``/``sensors``: BDF file and sensor CSV (``label,node,component``);
    ``error_pids``/``error_alpha``: the modelling error K̃ = α K_group on those property ids
    (Table 4.6); ``parameters``: the updating parameters and options; ``n_modes``: numbers
    of modes used in the update; ``errors``: magnitudes per category (fractions,
    Table 4.7); ``samples`` per category and magnitude; ``seed``; ``chunk_size``: samples
    per batch (the unit of incremental results and of Ray tasks); ``eigensolver``:
    ``subspace`` or ``dense`` (every mode, refined: :class:`updating.Refined`), or ``sparse`` (:func:`jaxfem.eigsh` in every
    evaluation: models beyond the dense solver's reach); ``lockstep``: samples updated together under ``vmap`` on
    each device — 1 (in sequence) on CPUs, where a batch waits for its slowest sample
    (measured: 24 samples with 1/5/20 % errors in lockstep 1.9× slower per sample than in
    sequence; 4 with uniform errors as fast); larger batches are meant for accelerators
    (not measured: no GPU was available).
    """

    model: Path
    sensors: Path
    error_pids: tuple[int, ...]
    error_alpha: float
    parameters: ParameterSet
    n_modes: tuple[int, ...] = (2, 5, 10, 20)
    errors: tuple[tuple[str, tuple[float, ...]], ...] = tuple(TABLE_4_7.items())
    samples: int = 100
    seed: int = 0
    chunk_size: int = 64
    eigensolver: str = "subspace"
    lockstep: int = 1

    def __post_init__(self):
        """The one check of the TOML file and of Python callers: each value against
        ``_STUDY_SCHEMA`` (a :class:`schema.FieldError` naming ``study.KEY`` or ``errors.CATEGORY``)."""
        for key, check in _STUDY_SCHEMA.items():
            object.__setattr__(self, key, schema.checked(f"study.{key}", check, getattr(self, key)))
        if not isinstance(self.errors, (tuple, list)) or not self.errors:
            raise schema.FieldError("errors", f"expected at least one category of {', '.join(CATEGORIES)}, "
                                              f"got {schema.show(self.errors)}")
        errors = []
        for category, magnitudes in self.errors:
            if category not in CATEGORIES:
                raise schema.FieldError(f"errors.{category}", f"unknown error category; known: {', '.join(CATEGORIES)}")
            errors.append((category, schema.checked(f"errors.{category}", _fractions, magnitudes)))
        object.__setattr__(self, "errors", tuple(errors))

    @property
    def cells(self) -> list[tuple[str, float]]:
        """(category, magnitude) of every cell, in sample order."""
        return [(c, float(m)) for c, mags in self.errors for m in mags]

    def chunks(self) -> list[tuple[int, int, int]]:
        """Units of work ``(n_modes, first sample, end)``; samples of one n are numbered
        cell-major (cell index × samples + draw)."""
        total = len(self.cells) * self.samples
        return [(n, a, min(a + self.chunk_size, total)) for n in self.n_modes
                for a in range(0, total, self.chunk_size)]

    def to_dict(self) -> dict:
        return {"model": str(self.model), "sensors": str(self.sensors), "error_pids": list(self.error_pids),
                "error_alpha": self.error_alpha, "n_modes": list(self.n_modes),
                "errors": {c: list(m) for c, m in self.errors}, "samples": self.samples, "seed": self.seed,
                "chunk_size": self.chunk_size, "eigensolver": self.eigensolver, "lockstep": self.lockstep,
                "parameters": [dataclasses.asdict(p) for p in self.parameters.parameters],
                "options": dataclasses.asdict(self.parameters.options)}

    def digest(self) -> str:
        """A hash of everything that determines the samples (guards resumed runs)."""
        return hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True, default=str).encode()).hexdigest()[:16]

    @classmethod
    def from_toml(cls, path: str | Path) -> Study:
        """Read a study::

            [study]
            model = "tree"             # the embedded tree (thesis Table 4.5) or a .bdf path
            sensors = "tree"           # its 49 measured DoFs, or a CSV label,node,component
            modelling_error = 1        # Table 4.6 model 1-3 on the tree, or
            # error_pids = [2, 4]; error_alpha = -0.17
            n_modes = [2, 5, 10, 20]
            samples = 100              # per category and magnitude
            seed = 0
            chunk_size = 64
            lockstep = 1               # samples per vmap batch on each device
            [errors]                   # fractions; default Table 4.7
            relative = [0.01, 0.02, 0.05, 0.10, 0.20]
            [[parameter]]              # as for `jaxfem update`; default: the tree's substructures
            ...
            [options]

        Relative paths are relative to the file.
        """
        path = Path(path)
        try:
            data = tomllib.loads(path.read_text())
        except tomllib.TOMLDecodeError as err:
            raise ValueError(f"{path}: {err}") from None
        return cls.from_dict(data, str(path), path.parent)

    @classmethod
    def from_dict(cls, data: dict, where: str = "study", base: Path = Path(".")) -> Study:
        """From the parsed TOML; every key checked before anything is read or run,
        errors naming ``where`` and the key (``study.samples``, ``errors.relative``)."""
        schema.refuse_unknown(data, ("study", "errors", "parameter", "options"), where, "")
        for table in ("study", "errors"):
            if not isinstance(data.get(table, {}), dict):
                raise ValueError(f"{where}: {table}: expected a table [{table}], got {schema.show(data[table])}")
        s = dict(data.get("study", {}))
        schema.refuse_unknown(s, ("model", "sensors", "modelling_error", *_STUDY_SCHEMA), where, "study.")
        try:
            files = {key: schema.checked(f"study.{key}", schema.name, s.pop(key, "tree"))
                     for key in ("model", "sensors")}
            if "modelling_error" in s:
                if {"error_pids", "error_alpha"} & set(s):
                    raise schema.FieldError("study.modelling_error",
                                            "give modelling_error or error_pids/error_alpha, not both")
                number = schema.checked("study.modelling_error", _table_4_6, s.pop("modelling_error"))
                s["error_pids"], s["error_alpha"] = TABLE_4_6[number]
            if "parameter" in data:
                parameters = ParameterSet.from_dict(data, where)
            else:
                parameters = tree_parameters(Options.from_dict(data["options"], where) if "options" in data else None)
            data_dir = resources.files("updating") / "data"
            return cls(model=Path(str(data_dir / "tree.bdf")) if files["model"] == "tree" else base / files["model"],
                       sensors=(Path(str(data_dir / "tree_sensors.csv")) if files["sensors"] == "tree"
                                else base / files["sensors"]),
                       error_pids=s.pop("error_pids", TABLE_4_6[1][0]),
                       error_alpha=s.pop("error_alpha", TABLE_4_6[1][1]),
                       parameters=parameters, errors=tuple(data.get("errors", TABLE_4_7).items()), **s)
        except schema.FieldError as err:
            raise ValueError(f"{where}: {err}") from None


def _table_4_6(v):
    if not (schema.is_int(v) and v in TABLE_4_6):
        raise schema.Expected(f"a model of Table 4.6: {', '.join(map(str, TABLE_4_6))}")
    return v


def _fractions(v):
    if not isinstance(v, (list, tuple, np.ndarray)) or not len(v) \
            or not all(f is not None and 0 <= f < 1 for f in map(schema.finite, v)):
        raise schema.Expected("a non-empty array of fractions in [0, 1), e.g. 0.05 for 5 %")
    return tuple(float(m) for m in v)


_STUDY_SCHEMA = {
    "error_pids": schema.integers("property ids", nonempty=True), "error_alpha": schema.number(-1.0, strict=True),
    "n_modes": schema.integers("numbers of modes", nonempty=True), "samples": schema.integer(1),
    "seed": schema.integer(0), "chunk_size": schema.integer(1),
    "eigensolver": schema.choice(*STUDY_EIGENSOLVERS), "lockstep": schema.integer(1),
}


def tree_parameters(options: Options | None = None) -> ParameterSet:
    """The tree's substructure stiffness factors: compound blades 2 & 4, homogeneous
    blades 1 & 3, upper pylon (Table 4.5 components); at most 16 iterations (§4.3.3.3).
    Gauss–Newton, the thesis' iteration (eq. 3.11 without regularisation), converges in
    5–6 steps to an α change of 1e-8 (the floor set by the modes' accuracy, ~1e-9 at the
    sensors); Levenberg–Marquardt's damping made the first steps small (13 to reach 1e-6)."""
    options = options or Options(tolerance=1e-8, max_iterations=16, solver="gauss-newton")
    return ParameterSet((Parameter("blades_2_4", "stiffness", pids=(2, 4)),
                         Parameter("blades_1_3", "stiffness", pids=(1, 3)),
                         Parameter("pylon_upper", "stiffness", pids=(12,))), options)


def default_study(modelling_error: int = 1, **changes) -> Study:
    """The tree-structure study of §4.3 (Table 4.5 structure, 49 measured DoFs, Table 4.6
    model 1–3, Table 4.7 errors)."""
    return dataclasses.replace(Study.from_dict({"study": {"modelling_error": modelling_error}}), **changes)


@dataclasses.dataclass
class MonteCarloResult:
    """Samples and statistics of a study. ``samples[n]``: arrays over the samples of the
    n-mode group (cell-major: ``cells[i]`` owns rows i·samples … (i+1)·samples − 1):
    ``alpha`` (N, p), ``f_e``/``f_a``/``mac`` (N, n), ``iterations``, ``status`` (index in
    ``STATUS``), ``fallback`` (redone with full solves), ``refreshes`` (evaluations that
    needed a fresh preconditioner); ``reference[n]``: the same for the error-free update."""

    study: Study
    names: list[str]
    samples: dict[int, dict]
    reference: dict[int, dict]
    seconds: float

    @property
    def failures(self) -> dict[str, int]:
        counts = {s: 0 for s in STATUS[1:]}
        for d in self.samples.values():
            for code in d["status"][d["status"] > 0]:
                counts[STATUS[code]] += 1
        return counts

    @property
    def fallbacks(self) -> int:
        return int(sum(d["fallback"].sum() for d in self.samples.values()))

    @property
    def refreshes(self) -> int:
        """Residual evaluations whose subspace solve needed a fresh preconditioner."""
        return int(sum(d["refreshes"].sum() for d in self.samples.values()))

    def statistics(self) -> list[dict]:
        """Per n, category and magnitude over the successful samples: mean, standard
        deviation and RMS of Δα (eq. 4.4, as α(δ)/α(0) − 1; where |α(0)| ≤ ``RATIO_FLOOR``
        the difference α(δ) − α(0)), of Δf_n (eq. 4.5) and ΔMAC_n (eq. 4.6) per mode; failure counts."""
        out = []
        s = self.study
        for n, d in self.samples.items():
            ref = self.reference[n]
            a0 = ref["alpha"][0]
            ratio = np.abs(a0) > RATIO_FLOOR
            dev0 = (ref["f_a"][0] - ref["f_e"][0]) / ref["f_e"][0]
            for i, (cat, mag) in enumerate(s.cells):
                rows_ = slice(i * s.samples, (i + 1) * s.samples)
                ok = d["status"][rows_] == 0
                alpha = d["alpha"][rows_][ok]
                dalpha = np.where(ratio, alpha / np.where(ratio, a0, 1.0) - 1.0, alpha - a0)
                df = (d["f_a"][rows_][ok] - d["f_e"][rows_][ok]) / d["f_e"][rows_][ok] - dev0  # eq. 4.5
                dmac = d["mac"][rows_][ok] - ref["mac"][0]  # eq. 4.6
                stats = lambda x: {"mean": _nan_stat(np.mean, x), "std": _nan_stat(np.std, x),
                                   "rms": _nan_stat(lambda v, axis: np.sqrt(np.mean(v**2, axis=axis)), x)}
                out.append({"n_modes": n, "category": cat, "magnitude": mag, "samples": len(ok),
                            "succeeded": int(ok.sum()),
                            "failed": {STATUS[k]: int(np.sum(d["status"][rows_] == k)) for k in range(1, len(STATUS))},
                            "fallback": int(d["fallback"][rows_].sum()),
                            "refreshes": int(d["refreshes"][rows_].sum()),
                            "delta_alpha": dict(zip(self.names, _per_column(stats(dalpha)))),
                            "delta_alpha_is_ratio": dict(zip(self.names, ratio.tolist())),
                            "delta_f": stats(df), "delta_mac": stats(dmac)})
        return out

    def to_json(self) -> dict:
        return {"study": self.study.to_dict(), "parameters": self.names, "seconds": self.seconds,
                "samples": int(sum(len(d["status"]) for d in self.samples.values())),
                "failures": self.failures, "fallbacks": self.fallbacks, "refreshes": self.refreshes,
                "reference": {str(n): {"alpha": r["alpha"][0].tolist(), "f_a": r["f_a"][0].tolist(),
                                       "f_e": r["f_e"][0].tolist(), "mac": r["mac"][0].tolist()}
                              for n, r in self.reference.items()},
                "statistics": self.statistics()}


def _nan_stat(fn, x):
    if x.shape[0] == 0:
        return np.full(x.shape[1:], np.nan).tolist()
    return np.asarray(fn(x, axis=0)).tolist()


def _per_column(stats: dict) -> list[dict]:
    return [{k: v[j] for k, v in stats.items()} for j in range(len(stats["mean"]))]
