"""HDF5 reading and writing of measured runs (format documented in susp_bo.data.measured).

Every way a file can be malformed ends in :class:`MeasuredDataError` naming the
file and the item; nothing else escapes :func:`read_run_file`.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from susp_bo.data.measured import (
    FORMAT_NAME,
    FORMAT_VERSION,
    FORMAT_VERSION_WITHOUT_GEOMETRY,
    GEOMETRY_UNITS,
    READABLE_VERSIONS,
    VERSIONS_REQUIRING_GEOMETRY,
    MeasuredDataError,
    MeasuredRun,
    nan_problems,
)
from susp_bo.rig.design import DESIGN_COMPONENTS, DESIGN_UNITS, TrackDesign
from susp_bo.rig.track import GEOMETRY_COMPONENTS, SpeedProfile, TrackGeometry

_NUMERIC_KINDS = {"f", "i", "u"}
USERBLOCK_SIZE = 512
USERBLOCK_MAGIC = b"susp_bo.measured_run userblock\n"


def _file_digest(path: Path) -> str:
    """SHA-256 (hex) of the file's bytes after the user block."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        handle.seek(USERBLOCK_SIZE)
        for chunk in iter(lambda: handle.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def _seal(path: Path) -> None:
    """Write the file checksum into the (already reserved) HDF5 user block."""
    text = USERBLOCK_MAGIC + f"sha256={_file_digest(path)}\n".encode()
    with open(path, "r+b") as handle:
        handle.write(text.ljust(USERBLOCK_SIZE, b"\0"))


def _check_seal(path: Path) -> None:
    """Verify the user-block checksum, if the file has one, before HDF5 parses anything."""
    with open(path, "rb") as handle:
        head = handle.read(USERBLOCK_SIZE)
    if not head.startswith(USERBLOCK_MAGIC):
        return
    line = head[len(USERBLOCK_MAGIC) :].split(b"\n", 1)[0]
    expected = line.removeprefix(b"sha256=").decode("ascii", errors="replace")
    if len(head) < USERBLOCK_SIZE or _file_digest(path) != expected:
        raise MeasuredDataError(
            f"{path}: file checksum mismatch: the file is corrupted or truncated "
            f"({path.stat().st_size} bytes); if it was edited on purpose, re-save it with "
            "save_run or zero its first 512 bytes"
        )


def _write_array(group: h5py.Group, name: str, values: np.ndarray, unit: str | None) -> None:
    dataset = group.create_dataset(
        name, data=np.ascontiguousarray(values, dtype=np.float64), chunks=True, fletcher32=True
    )
    if unit is not None:
        dataset.attrs["units"] = unit


def write_run_file(run: MeasuredRun, path: Path) -> None:
    """Write ``run`` to ``path`` (overwritten): format version 2 with its geometry, version 3
    without a ``geometry/`` group when the run has none (module docstring of
    :mod:`susp_bo.data.measured`)."""
    strings = h5py.string_dtype(encoding="utf-8")
    version = FORMAT_VERSION if run.geometry is not None else FORMAT_VERSION_WITHOUT_GEOMETRY
    with h5py.File(path, "w", libver=("v110", "latest"), userblock_size=USERBLOCK_SIZE) as file:
        file.attrs["format"] = FORMAT_NAME
        file.attrs["format_version"] = np.int64(version)
        file.attrs["metadata_json"] = json.dumps(run.metadata, sort_keys=True)
        file.attrs["content_sha256"] = run.content_digest()
        if run.geometry is not None:
            geometry = file.create_group("geometry")
            geometry.attrs["spacing_m"] = np.float64(run.geometry.spacing_m)
            for name in GEOMETRY_COMPONENTS:
                _write_array(geometry, name, getattr(run.geometry, name), GEOMETRY_UNITS[name])
        if run.design is not None:
            design = file.create_group("design")
            for name in ("chainage_m", *DESIGN_COMPONENTS):
                _write_array(design, name, getattr(run.design, name), DESIGN_UNITS[name])
        speed = file.create_group("speed")
        _write_array(speed, "time_s", run.speed.time_s, "s")
        _write_array(speed, "speed_m_s", run.speed.speed_m_s, "m/s")
        accelerations = file.create_group("accelerations")
        accelerations.attrs["sample_rate_hz"] = np.float64(run.sample_rate_hz)
        accelerations.attrs["time_offset_s"] = np.float64(run.time_offset_s)
        _write_array(accelerations, "data", run.accelerations_m_s2, None)
        accelerations.create_dataset(
            "channels", data=np.array(run.channels, dtype=object), dtype=strings
        )
        accelerations.create_dataset("units", data=np.array(run.units, dtype=object), dtype=strings)
    _seal(path)


class _Reader:
    """Reads items of one open file, raising MeasuredDataError that name file and item."""

    def __init__(self, file: h5py.File, where: str) -> None:
        self.file = file
        self.where = where

    def fail(self, message: str) -> MeasuredDataError:
        return MeasuredDataError(f"{self.where}: {message}")

    def group(self, name: str) -> h5py.Group:
        item = self.file.get(name)
        if item is None:
            raise self.fail(f"missing group /{name}")
        if not isinstance(item, h5py.Group):
            raise self.fail(f"/{name} must be a group, found a {type(item).__name__}")
        return item

    def dataset(self, group: h5py.Group, name: str) -> h5py.Dataset:
        item = group.get(name)
        if item is None:
            raise self.fail(f"missing dataset {group.name}/{name}")
        if not isinstance(item, h5py.Dataset):
            raise self.fail(f"{group.name}/{name} must be a dataset")
        return item

    def attribute(self, obj: h5py.HLObject, name: str, default: Any = None) -> Any:
        if name not in obj.attrs:
            if default is None:
                raise self.fail(f"missing attribute {name!r} on {obj.name}")
            return default
        value = obj.attrs[name]
        if isinstance(value, np.ndarray):
            if value.size != 1:
                raise self.fail(
                    f"attribute {obj.name}:{name} must be a scalar, shape {value.shape}"
                )
            value = value.reshape(()).item()
        if isinstance(value, np.generic):
            value = value.item()
        if isinstance(value, bytes):
            value = value.decode("utf-8")
        return value

    def real(self, obj: h5py.HLObject, name: str, unit: str, default: float | None = None) -> float:
        value = self.attribute(obj, name, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(f"attribute {obj.name}:{name} = {value!r}; expected a number ({unit})")
        return float(value)

    def text(self, obj: h5py.HLObject, name: str) -> str:
        value = self.attribute(obj, name)
        if not isinstance(value, str):
            raise self.fail(f"attribute {obj.name}:{name} = {value!r}; expected a string")
        return value

    def numbers(self, group: h5py.Group, name: str, ndim: int, unit: str | None) -> np.ndarray:
        dataset = self.dataset(group, name)
        if dataset.dtype.kind not in _NUMERIC_KINDS:
            raise self.fail(f"{dataset.name} has dtype {dataset.dtype}; expected real numbers")
        if dataset.ndim != ndim:
            raise self.fail(f"{dataset.name} has shape {dataset.shape}; expected {ndim}-D")
        if unit is not None:
            found = self.text(dataset, "units") if "units" in dataset.attrs else None
            if found is None:
                raise self.fail(
                    f"unit mismatch: {dataset.name} has no 'units' attribute; expected {unit!r}"
                )
            if found != unit:
                raise self.fail(f"unit mismatch: {dataset.name} is in {found!r}; expected {unit!r}")
        return np.asarray(dataset[()], dtype=np.float64)

    def strings(self, group: h5py.Group, name: str) -> tuple[str, ...]:
        dataset = self.dataset(group, name)
        if h5py.check_string_dtype(dataset.dtype) is None or dataset.ndim != 1:
            raise self.fail(
                f"{dataset.name} must be a 1-D array of strings; found dtype {dataset.dtype}, "
                f"shape {dataset.shape}"
            )
        return tuple(str(s) for s in dataset.asstr()[()])


def _read_geometry(reader: _Reader, version: int) -> dict[str, Any] | None:
    """The ``geometry/`` group's fields (spacing_m and the components), or None for a
    version-3 file without it (the track not measured).

    Raises:
        MeasuredDataError: ``geometry/`` missing from a version-1 or -2 file, naming the
            versions that may omit it; or present but malformed (as in version 2).
    """
    if "geometry" not in reader.file and version not in VERSIONS_REQUIRING_GEOMETRY:
        return None
    if "geometry" not in reader.file:
        raise reader.fail(
            f"missing group /geometry: format_version {version} requires it (a run whose "
            f"track was not measured is written as format_version "
            f"{FORMAT_VERSION_WITHOUT_GEOMETRY}, without /geometry)"
        )
    group = reader.group("geometry")
    return {
        "spacing_m": reader.real(group, "spacing_m", "m"),
        **{
            name: reader.numbers(group, name, 1, GEOMETRY_UNITS[name])
            for name in GEOMETRY_COMPONENTS
        },
    }


def _read(file: h5py.File, where: str, allow_nan: bool) -> MeasuredRun:
    reader = _Reader(file, where)
    name = reader.text(file, "format") if "format" in file.attrs else None
    if name != FORMAT_NAME:
        raise reader.fail(
            f"not a measured-run file: attribute format = {name!r}, expected {FORMAT_NAME!r}"
        )
    version = reader.attribute(file, "format_version")
    if (
        isinstance(version, bool)
        or not isinstance(version, int)
        or version not in READABLE_VERSIONS
    ):
        raise reader.fail(
            f"format_version = {version!r}; this reader knows "
            f"{', '.join(map(str, READABLE_VERSIONS))}"
        )
    try:
        metadata = json.loads(reader.text(file, "metadata_json"))
    except json.JSONDecodeError as error:
        raise reader.fail(f"metadata_json is not valid JSON ({error})") from None
    if not isinstance(metadata, dict):
        raise reader.fail(f"metadata_json must hold a JSON object, found {type(metadata).__name__}")

    geometry = _read_geometry(reader, version)
    design = None
    if "design" in file:
        if version < 2:
            raise reader.fail(
                f"/design needs format_version >= 2; the file says {version} (a version-1 "
                "file has no design group)"
            )
        design_group = reader.group("design")
        arrays = {
            name: reader.numbers(design_group, name, 1, DESIGN_UNITS[name])
            for name in ("chainage_m", *DESIGN_COMPONENTS)
        }
        try:
            design = TrackDesign(**arrays, source=f"{where}:/design")
        except ValueError as error:
            raise MeasuredDataError(str(error)) from None
    speed_group = reader.group("speed")
    time = reader.numbers(speed_group, "time_s", 1, "s")
    speed_values = reader.numbers(speed_group, "speed_m_s", 1, "m/s")
    group = reader.group("accelerations")
    rate = reader.real(group, "sample_rate_hz", "Hz")
    offset = reader.real(group, "time_offset_s", "s", default=0.0)
    data = reader.numbers(group, "data", 2, None)
    channels = reader.strings(group, "channels")
    units = reader.strings(group, "units")
    if len(units) != len(channels):
        raise reader.fail(
            f"/accelerations/units has {len(units)} entries for {len(channels)} channels"
        )
    try:
        run = MeasuredRun(
            geometry=None if geometry is None else TrackGeometry(**geometry),
            speed=SpeedProfile(time_s=time, speed_m_s=speed_values),
            channels=channels,
            accelerations_m_s2=data,
            sample_rate_hz=rate,
            units=units,
            metadata=metadata,
            time_offset_s=offset,
            design=design,
        )
    except ValueError as error:  # includes MeasuredDataError
        raise reader.fail(str(error)) from None
    problems = [] if allow_nan else nan_problems(run, run.channels)
    if problems:
        raise reader.fail("; ".join(problems))
    if "content_sha256" in file.attrs:
        expected = reader.text(file, "content_sha256")
        if run.content_digest() != expected:
            raise reader.fail(
                "content checksum mismatch: the file is corrupted or was edited "
                "(delete attribute content_sha256 to accept deliberate edits)"
            )
    return run


def read_run_file(path: Path, allow_nan: bool = False) -> MeasuredRun:
    """Read one run; every failure becomes :class:`MeasuredDataError` naming ``path``."""
    if not path.is_file():
        raise MeasuredDataError(f"{path}: no such file")
    try:
        _check_seal(path)
        with h5py.File(path, "r") as file:
            return _read(file, str(path), allow_nan)
    except MeasuredDataError:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError, UnicodeError) as error:
        raise MeasuredDataError(
            f"{path}: not a readable measured-run HDF5 file ({type(error).__name__}: {error})"
        ) from None
