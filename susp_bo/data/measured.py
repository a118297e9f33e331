"""Measured runs: track geometry, speed and accelerations of one run, and its HDF5 file.

A measured run is what the paper calls one realization ``y_exp,i`` together
with the excitation ``x_exp,i`` recorded with it: the track geometry sampled in
space (when the track under the run was measured; None when it was not), the speed
record, and the accelerations of every sensor channel.

HDF5 format, versions 2 and 3 (one run per file, extension ``.h5`` or ``.hdf5``)
---------------------------------------------------------------------------------

All numbers are float64, SI units. Every numeric dataset carries a ``units`` attribute
(checked on load)::

    /                                   attrs: format = "susp_bo.measured_run"
    │                                          format_version = 2, or 3 without geometry/
    │                                                           (1 is still read)
    │                                          metadata_json = JSON object (str)
    │                                          content_sha256 = hex digest (optional)
    ├── geometry/            (required in versions 1 and 2; optional in version 3:
    │   │                     absent = the track under the run was not measured)
    │   │                               attrs: spacing_m (> 0, m)
    │   ├── vertical_m       (N,)  "m"    mean of the two rails, + up
    │   ├── alignment_m      (N,)  "m"    mean lateral rail position, + left
    │   ├── cross_level_rad  (N,)  "rad"  roll of the rail plane, + left rail higher
    │   └── gauge_m          (N,)  "m"    gauge deviation from nominal, + wider
    │                                     sampled at s = 0, ds, 2 ds, …  (N >= 2)
    ├── design/              (optional, version >= 2; absent on tangent track or unknown)
    │   ├── chainage_m       (K,)  "m"    knots on the track's s axis, non-decreasing
    │   ├── curvature_1_m    (K,)  "1/m"  + left-hand curve, |κ| <= 1/150 m
    │   ├── cant_m           (K,)  "m"    signed cross-level, + left rail higher, <= 0.18 m
    │   └── gradient         (K,)  "1"    rise/run, + uphill, <= 0.040
    │                                     linear between knots (equal chainages: a step)
    ├── speed/
    │   ├── time_s           (n,)  "s"    strictly increasing, time_s[0] = 0
    │   └── speed_m_s        (n,)  "m/s"  > 0, piecewise linear in between
    └── accelerations/                  attrs: sample_rate_hz (> 0, Hz)
        │                                      time_offset_s (>= 0, s; default 0)
        ├── data             (C, n_t)  per-channel units (below)
        ├── channels         (C,)  UTF-8 strings, unique sensor names
        └── units            (C,)  UTF-8 strings, e.g. "m/s^2"

Sample ``j`` of the accelerations is at ``time_offset_s + j / sample_rate_hz``
on the clock of the speed record; the car's rearmost axle is at ``s = 0`` at
``t = 0`` (the convention of :func:`susp_bo.rig.track.axle_excitation`).
``metadata_json`` holds free-form information (rig name, truth parameters and
effects of synthetic runs, seed, noise, line and date of real ones).
``design/`` is the line's design (:class:`susp_bo.rig.design.TrackDesign`):
tangents, transitions and curves with their cant, and the gradient; it must
cover the run (checked by :func:`validate_run`). On a designed line the rig
follows the curves, and the design's quasi-static specific force is removed
from the accelerations before the spectra (see :mod:`susp_bo.rig.curving`).
Version 1 files (no ``design/`` group) load unchanged; a ``design/`` group in a
file labelled version 1 is refused.

Versions: :func:`save_run` writes a run with geometry as version 2, byte for byte as
before version 3 existed, and a run without geometry (:attr:`MeasuredRun.geometry` None:
the track under the run was not measured, e.g. for ``[output_error] model =
"track_statistics"``) as version 3 without ``geometry/``, so that a reader that knows
only versions 1 and 2 refuses it by its version instead of reporting a missing group. A
file labelled version 1 or 2 without ``geometry/`` is refused (missing group /geometry);
a version-3 file may hold ``geometry/``, read as in version 2. A ``geometry/`` group
that is present is checked exactly as in version 2 whatever the version.

``content_sha256`` is the SHA-256 of the run's canonical content (written by
:func:`save_run`; verified on load when present, so files written by other tools
may omit it).

Integrity: :func:`save_run` reserves a 512-byte HDF5 user block (ignored by
every HDF5 reader: h5py, MATLAB, HDFView) holding the line
``susp_bo.measured_run userblock`` and ``sha256=<hex>`` of all bytes after the
block. :func:`load_run` verifies it before HDF5 parses the file, so a
truncated or bit-flipped file is refused with a clear message (a corrupted
HDF5 structure can otherwise make the HDF5 library loop or misread). Files
without the block (written by other tools) are parsed directly; datasets are
also written chunked with Fletcher-32 checksums and HDF5 ≥ 1.10 object headers.

Loading never returns a half-valid run: any problem (not HDF5, truncated,
missing or extra-shaped dataset, wrong dtype, wrong units attribute, NaN or
inf, non-positive sample rate, …) raises :class:`MeasuredDataError`, a
``ValueError`` naming the file, the item and what was expected.

Writing, reading and finding the files (:func:`save_run`, :func:`load_run`,
:func:`load_runs`, :func:`run_paths`) is :mod:`susp_bo.data.run_files`; the names are
still importable from here.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.design import DESIGN_COMPONENTS, TrackDesign
from susp_bo.rig.spectra import Spectra, SpectrumSettings, log_amplitude_spectra
from susp_bo.rig.track import GEOMETRY_COMPONENTS, SpeedProfile, TrackGeometry

if TYPE_CHECKING:  # pragma: no cover - static names for type checkers and IDEs
    from susp_bo.data.run_files import RUN_SUFFIXES as RUN_SUFFIXES
    from susp_bo.data.run_files import load_run as load_run
    from susp_bo.data.run_files import load_runs as load_runs
    from susp_bo.data.run_files import run_paths as run_paths
    from susp_bo.data.run_files import save_run as save_run

FloatArray = NDArray[np.float64]

FORMAT_NAME = "susp_bo.measured_run"
FORMAT_VERSION = 2
"""Version written for a run with geometry (byte-compatible with what version-2 readers read)."""
FORMAT_VERSION_WITHOUT_GEOMETRY = 3
"""Version written for a run without geometry (no ``geometry/`` group)."""
READABLE_VERSIONS = (1, 2, 3)
VERSIONS_REQUIRING_GEOMETRY = (1, 2)
"""Versions whose files must hold ``geometry/``."""
SI_ACCELERATION = "m/s^2"
GEOMETRY_UNITS = {
    "vertical_m": "m",
    "alignment_m": "m",
    "cross_level_rad": "rad",
    "gauge_m": "m",
}
_UNIT_ALIASES = {
    "m/s^2": ("m/s^2", "m/s2", "m/s**2", "m/s²", "m s-2", "m s^-2", "m.s-2", "m·s-2"),
    "g": ("g", "g0", "gn"),
    "mm/s^2": ("mm/s^2", "mm/s2", "mm/s²"),
    "cm/s^2": ("cm/s^2", "cm/s2", "cm/s²", "gal"),
}
_TO_SI = {"m/s^2": 1.0, "g": 9.80665, "mm/s^2": 1e-3, "cm/s^2": 1e-2}


class MeasuredDataError(ValueError):
    """A measured run (in memory or on disk) is malformed; the message says where and why."""


def canonical_unit(unit: str) -> str:
    """The canonical spelling of an acceleration unit (``"m/s^2"``, ``"g"``, …), or ``unit``."""
    cleaned = unit.strip()
    for name, aliases in _UNIT_ALIASES.items():
        if cleaned.lower() in {a.lower() for a in aliases}:
            return name
    return cleaned


def _json_builtin(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (set, frozenset)):
        return sorted(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def nan_runs(values: FloatArray) -> list[tuple[int, int]]:
    """Runs of consecutive NaN in a 1-D array, as (start index, length) pairs."""
    bad = np.isnan(values).astype(np.int8)
    changes = np.flatnonzero(np.diff(np.concatenate([[0], bad, [0]])))
    return [(int(a), int(b - a)) for a, b in zip(changes[::2], changes[1::2])]


@dataclass(frozen=True, eq=False)
class MeasuredRun:
    """One measured (or synthetic) run: geometry, speed and accelerations.

    Args:
        geometry: track geometry under the run, sampled in space (irregularities in m and
            rad on ``s = 0, ds, …``, see :class:`~susp_bo.rig.track.TrackGeometry`); None
            when the track under the run was not measured: such a run can be calibrated
            only with ``[output_error] model = "track_statistics"``, which simulates
            synthetic tracks (every model that simulates the run's own track refuses it).
        speed: speed record (its clock starts at 0 s).
        channels: sensor names (C,), unique.
        accelerations_m_s2: accelerations (C x n_t), in ``units`` (m/s² for a
            calibration); NaN marks dropouts (see :func:`validate_run`), inf is refused.
        sample_rate_hz: sampling rate of the accelerations (Hz), > 0.
        units: unit of each channel (C,), canonical spelling applied (``"m/s^2"``).
        metadata: JSON-compatible information; stored as its JSON round trip.
        time_offset_s: time of the first acceleration sample on the speed clock (s), >= 0.
        design: the line's design on the track's chainage ``s`` (curves, cant, gradient);
            None for tangent track or when unknown. It may be given without a geometry.
    """

    geometry: TrackGeometry | None
    speed: SpeedProfile
    channels: tuple[str, ...]
    accelerations_m_s2: FloatArray
    sample_rate_hz: float
    units: tuple[str, ...] = ()
    metadata: dict[str, Any] = field(default_factory=dict)
    time_offset_s: float = 0.0
    design: TrackDesign | None = None

    def __post_init__(self) -> None:
        if self.design is not None and not isinstance(self.design, TrackDesign):
            raise MeasuredDataError(
                f"MeasuredRun.design: expected a TrackDesign or None, got "
                f"{type(self.design).__name__}"
            )
        if self.geometry is not None and not isinstance(self.geometry, TrackGeometry):
            raise MeasuredDataError(
                "MeasuredRun.geometry: expected a TrackGeometry or None (track not measured), got "
                f"{type(self.geometry).__name__}"
            )
        if not isinstance(self.speed, SpeedProfile):
            raise MeasuredDataError(
                f"MeasuredRun.speed: expected a SpeedProfile, got {type(self.speed).__name__}"
            )
        channels = tuple(self.channels) if not isinstance(self.channels, str) else ()
        if not channels or not all(isinstance(c, str) and c.strip() for c in channels):
            raise MeasuredDataError(
                f"MeasuredRun.channels: need one or more non-empty names; got {self.channels!r}"
            )
        if len(set(channels)) != len(channels):
            duplicates = sorted({c for c in channels if channels.count(c) > 1})
            raise MeasuredDataError(f"MeasuredRun.channels: duplicate names {duplicates}")
        if np.iscomplexobj(self.accelerations_m_s2):  # float64 would drop the imaginary part
            raise MeasuredDataError(
                "MeasuredRun.accelerations_m_s2: complex values; expected real accelerations"
            )
        try:
            data = np.array(self.accelerations_m_s2, dtype=np.float64)
        except (TypeError, ValueError) as error:
            raise MeasuredDataError(
                f"MeasuredRun.accelerations_m_s2: not numeric ({error})"
            ) from None
        if data.ndim != 2 or data.shape[0] != len(channels) or data.shape[1] < 2:
            raise MeasuredDataError(
                f"MeasuredRun.accelerations_m_s2: shape {data.shape}; expected (C, n_t) with "
                f"C = {len(channels)} channels and n_t >= 2 samples"
            )
        if np.any(np.isinf(data)):
            row = int(np.argmax(np.any(np.isinf(data), axis=1)))
            raise MeasuredDataError(
                f"MeasuredRun.accelerations_m_s2: channel {channels[row]!r} contains inf"
            )
        data.setflags(write=False)
        rate = _positive_number("MeasuredRun.sample_rate_hz", self.sample_rate_hz, "Hz")
        offset = real_number("MeasuredRun.time_offset_s", self.time_offset_s, "s")
        if offset < 0:
            raise MeasuredDataError(f"MeasuredRun.time_offset_s: got {offset} s; must be >= 0 s")
        units = tuple(self.units) if self.units else (SI_ACCELERATION,) * len(channels)
        if len(units) != len(channels) or not all(isinstance(u, str) for u in units):
            raise MeasuredDataError(
                f"MeasuredRun.units: need one string per channel ({len(channels)}); got {units!r}"
            )
        try:
            metadata = json.loads(json.dumps(dict(self.metadata), default=_json_builtin))
        except (TypeError, ValueError) as error:
            raise MeasuredDataError(
                f"MeasuredRun.metadata: must be JSON-compatible ({error})"
            ) from None
        object.__setattr__(self, "channels", channels)
        object.__setattr__(self, "accelerations_m_s2", data)
        object.__setattr__(self, "sample_rate_hz", rate)
        object.__setattr__(self, "time_offset_s", offset)
        object.__setattr__(self, "units", tuple(canonical_unit(u) for u in units))
        object.__setattr__(self, "metadata", metadata)

    @property
    def n_samples(self) -> int:
        """Number of acceleration samples n_t."""
        return int(self.accelerations_m_s2.shape[1])

    @property
    def duration_s(self) -> float:
        """Length of the acceleration record, ``n_t / sample_rate_hz`` (s)."""
        return self.n_samples / self.sample_rate_hz

    @property
    def time_s(self) -> FloatArray:
        """Times of the acceleration samples on the speed clock, (n_t,) s."""
        return self.time_offset_s + np.arange(self.n_samples) / self.sample_rate_hz

    def channel(self, name: str) -> FloatArray:
        """Acceleration record of one channel, (n_t,)."""
        if name not in self.channels:
            raise KeyError(f"MeasuredRun: no channel {name!r}; channels are {list(self.channels)}")
        return self.accelerations_m_s2[self.channels.index(name)]

    def select(self, channels: Sequence[str]) -> MeasuredRun:
        """The same run restricted to (and ordered as) ``channels``."""
        channels = _channel_tuple(channels)
        missing = [c for c in channels if c not in self.channels]
        if missing:
            raise MeasuredDataError(
                f"missing channel(s) {missing}; the run has {list(self.channels)}"
            )
        index = [self.channels.index(c) for c in channels]
        return replace(
            self,
            channels=tuple(channels),
            accelerations_m_s2=self.accelerations_m_s2[index],
            units=tuple(self.units[i] for i in index),
        )

    def to_si(self) -> MeasuredRun:
        """The run with every channel converted to m/s² (from g, mm/s², cm/s²)."""
        unknown = [(c, u) for c, u in zip(self.channels, self.units) if u not in _TO_SI]
        if unknown:
            raise MeasuredDataError(
                f"unit mismatch: cannot convert {unknown} to m/s^2; known units {sorted(_TO_SI)}"
            )
        factors = np.array([_TO_SI[u] for u in self.units])[:, None]
        return replace(
            self,
            accelerations_m_s2=self.accelerations_m_s2 * factors,
            units=(SI_ACCELERATION,) * len(self.channels),
        )

    def spectra(
        self, settings: SpectrumSettings | None = None, quasi_static: FloatArray | None = None
    ) -> Spectra:
        """Log-amplitude spectra of all channels (C x F), see :mod:`susp_bo.rig.spectra`.

        Args:
            settings: spectrum settings (default :class:`SpectrumSettings()`).
            quasi_static: on a designed line, the design's quasi-static specific force
                at every channel (C x n_t) m/s², removed before the spectra
                (:func:`susp_bo.rig.curving.reference_specific_force`, which needs the
                rig's geometry); None removes nothing.

        Raises:
            MeasuredDataError: a channel not in m/s², NaN samples, or a record
                that cannot resolve the band.
        """
        settings = SpectrumSettings() if settings is None else settings
        problems = unit_problems(self, self.channels) + nan_problems(self, self.channels)
        if problems:
            raise MeasuredDataError("; ".join(problems))
        signals = self.accelerations_m_s2
        if quasi_static is not None:
            removed = np.asarray(quasi_static, dtype=np.float64)
            if removed.shape != signals.shape:
                raise MeasuredDataError(
                    f"quasi_static: shape {removed.shape}; expected {signals.shape}"
                )
            signals = signals - removed
        try:
            return log_amplitude_spectra(signals, self.sample_rate_hz, self.channels, settings)
        except ValueError as error:
            raise MeasuredDataError(str(error)) from None

    def content_digest(self) -> str:
        """SHA-256 (hex) of the canonical content: arrays, names, units, rates, metadata.

        A run with geometry keeps the digest it has always had (versions 1 and 2); a run
        without one hashes another leading tag, so the same run with and without its
        geometry never share a digest.
        """
        digest = hashlib.sha256()
        if self.geometry is None:
            digest.update(f"{FORMAT_NAME}/{FORMAT_VERSION_WITHOUT_GEOMETRY}:no-geometry".encode())
        else:
            digest.update(f"{FORMAT_NAME}/1".encode())  # version-1 runs keep their digest
            digest.update(np.float64(self.geometry.spacing_m).tobytes())
            for name in GEOMETRY_COMPONENTS:
                digest.update(np.ascontiguousarray(getattr(self.geometry, name)).tobytes())
        for array in (self.speed.time_s, self.speed.speed_m_s, self.accelerations_m_s2):
            digest.update(str(array.shape).encode())
            digest.update(np.ascontiguousarray(array).tobytes())
        text = json.dumps(
            [
                self.channels,
                self.units,
                self.sample_rate_hz.hex(),
                self.time_offset_s.hex(),
                self.metadata,
            ],
            sort_keys=True,
        )
        digest.update(text.encode())
        if self.design is not None:
            digest.update(b"design")
            for array in (
                self.design.chainage_m,
                *(getattr(self.design, n) for n in DESIGN_COMPONENTS),
            ):
                digest.update(str(array.shape).encode())
                digest.update(np.ascontiguousarray(array).tobytes())
        return digest.hexdigest()


def real_number(name: str, value: object, unit: str) -> float:
    """``value`` as a finite float, or :class:`MeasuredDataError` naming ``name`` and ``unit``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
        raise MeasuredDataError(f"{name}: got {value!r}; expected a real number ({unit})")
    number = float(value)
    if not math.isfinite(number):
        raise MeasuredDataError(f"{name}: got {number}; must be finite ({unit})")
    return number


def _positive_number(name: str, value: object, unit: str) -> float:
    number = real_number(name, value, unit)
    if number <= 0:
        raise MeasuredDataError(f"{name}: got {number} {unit}; must be > 0 {unit}")
    return number


def unit_problems(run: MeasuredRun, channels: Sequence[str]) -> list[str]:
    """One problem naming the ``channels`` of ``run`` not in m/s² (none when all are)."""
    wrong = [
        f"{c!r} in {u!r}"
        for c, u in zip(run.channels, run.units)
        if c in channels and u != SI_ACCELERATION
    ]
    return [
        f"unit mismatch: {', '.join(wrong)}; expected m/s^2 (convert the channel to m/s^2 "
        "and import the run again; from Python, MeasuredRun.to_si converts)"
    ] * bool(wrong)


def nan_problems(run: MeasuredRun, channels: Sequence[str]) -> list[str]:
    """One problem per channel of ``channels`` with NaN runs: count, samples, longest."""
    problems = []
    for name in channels:
        if name not in run.channels:
            continue
        runs = nan_runs(run.channel(name))
        if runs:
            start, length = max(runs, key=lambda r: r[1])
            problems.append(
                f"channel {name!r} has NaN runs: {len(runs)} run(s), "
                f"{sum(r[1] for r in runs)} samples; longest {length / run.sample_rate_hz:.4g} s "
                f"at t = {run.time_s[start]:.4g} s"
            )
    return problems


def _channel_tuple(channels: Sequence[str]) -> tuple[str, ...]:
    """``channels`` as a tuple; a str (which would be split into characters) or an empty
    list is refused."""
    if isinstance(channels, str) or not isinstance(channels, Iterable):
        example = [channels] if isinstance(channels, str) else ["carbody_front_vertical"]
        raise MeasuredDataError(
            f"channels: {channels!r} is not allowed; expected a list of channel names, "
            f"e.g. {example!r}"
        )
    names = tuple(channels)
    if not names:
        raise MeasuredDataError(
            f"channels: {channels!r} is not allowed; expected one or more channel names"
        )
    return names


def runs_channels(runs: Sequence[MeasuredRun]) -> tuple[str, ...]:
    """The common channel tuple of runs that share one (as returned by :func:`load_runs`)."""
    if not runs:
        raise MeasuredDataError("no runs given")
    first = runs[0].channels
    for index, run in enumerate(runs):
        if run.channels != first:
            raise MeasuredDataError(f"run {index}: channels {run.channels} differ from {first}")
    return first


_RUN_FILE_NAMES = frozenset({"RUN_SUFFIXES", "load_run", "load_runs", "run_paths", "save_run"})
"""Names that moved to :mod:`susp_bo.data.run_files`, still importable from here."""


def __getattr__(name: str) -> Any:
    """The run-file names, looked up on first use (PEP 562): :mod:`susp_bo.data.run_files`
    imports this module, so importing them here at the top would be a cycle."""
    if name in _RUN_FILE_NAMES:
        return getattr(importlib.import_module("susp_bo.data.run_files"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
