"""Measured runs in MATLAB ``.mat`` files: :func:`read_mat_run` and :func:`write_mat_run`.

The variables (``accelerations`` n_t x C, ``channels``, the speed, the geometry — all of
its variables, or none when the track was not measured —, the optional design,
``metadata_json``) are laid out in :mod:`susp_bo.data.importers`,
with the CSV layout; v4–v7 files are read with ``scipy.io.loadmat``, v7.3 (HDF5) files
are refused with a hint. Every problem raises
:class:`~susp_bo.data.measured.MeasuredDataError` naming the file and the variable.
"""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import scipy.io

from susp_bo.data.importer_checks import PathLike, _build, _check_nan, _design, _geometry, _speed
from susp_bo.data.measured import SI_ACCELERATION, MeasuredDataError, MeasuredRun
from susp_bo.rig.design import DESIGN_COMPONENTS
from susp_bo.rig.track import GEOMETRY_COMPONENTS

_GEOMETRY_VARIABLES = ("spacing_m", *GEOMETRY_COMPONENTS)
"""The geometry's variables: all of them, or none when the track was not measured."""
_DESIGN_VARIABLES = tuple(f"design_{name}" for name in ("chainage_m", *DESIGN_COMPONENTS))
_OTHER_VARIABLES = (
    "accelerations",
    "channels",
    "units",
    "sample_rate_hz",
    "time_offset_s",
    "speed_m_s",
    "speed_time_s",
    "metadata_json",
)
"""The layout's other variables (a run without geometry may hold no variable beyond these,
the geometry's and the design's: a misnamed geometry is refused, not read as no track)."""
_MAT_READ_ERRORS: tuple[type[Exception], ...] = (
    scipy.io.matlab.MatReadError,  # e.g. "Mat file appears to be truncated" (empty, short)
    OSError,
    ValueError,
    TypeError,
    EOFError,
    IndexError,  # a file cut inside a variable
    KeyError,
    struct.error,
    zlib.error,
)
"""What ``scipy.io.loadmat`` raises on a file that is not a whole v4–v7 .mat file."""
_MAT_EXPECTED = "expected a MATLAB v4-v7 .mat file (save(..., '-v7'))"


def _mat_strings(path: Path, name: str, value: Any) -> tuple[str, ...]:
    if isinstance(value, str):
        return (value.strip(),)
    array = np.asarray(value, dtype=object).ravel()
    out = []
    for item in array:
        if isinstance(item, np.ndarray):
            item = item.item() if item.size == 1 else "".join(map(str, item.ravel()))
        if not isinstance(item, str):
            raise MeasuredDataError(f"{path}: variable {name!r} must be a cell array of char")
        out.append(item.strip())
    return tuple(out)


def _mat_number(path: Path, variables: dict[str, Any], name: str, default: Any = None) -> float:
    if name not in variables:
        if default is None:
            raise MeasuredDataError(f"{path}: missing variable {name!r}")
        return float(default)
    value = np.asarray(variables[name])
    if value.size != 1 or value.dtype.kind not in "fiu":
        raise MeasuredDataError(f"{path}: variable {name!r} must be a real scalar")
    return float(value.item())


def _mat_vector(path: Path, variables: dict[str, Any], name: str) -> np.ndarray:
    if name not in variables:
        raise MeasuredDataError(f"{path}: missing variable {name!r}")
    value = np.asarray(variables[name])
    if value.dtype.kind not in "fiu" or value.ndim > 1:
        raise MeasuredDataError(
            f"{path}: variable {name!r} must be a real vector; got {value.dtype}, {value.shape}"
        )
    return value.astype(np.float64).ravel()


def _file_size(path: Path) -> int | None:
    """The size of ``path`` in bytes, or None when it cannot be read."""
    try:
        return path.stat().st_size
    except OSError:
        return None


def read_mat_run(
    path: PathLike, *, metadata: dict[str, Any] | None = None, allow_nan: bool = False
) -> MeasuredRun:
    """Import one run from a MATLAB ``.mat`` file (layout in :mod:`susp_bo.data.importers`).

    Raises:
        MeasuredDataError: unreadable file, missing or mis-shaped variables, bad values.
    """
    mat_path = Path(path)
    try:
        variables = scipy.io.loadmat(mat_path, squeeze_me=True, chars_as_strings=True)
    except NotImplementedError:
        raise MeasuredDataError(
            f"{mat_path}: MATLAB v7.3 (HDF5) files are not read here; save with "
            "save(..., '-v7') or write the HDF5 measured-run format"
        ) from None
    except _MAT_READ_ERRORS as error:
        size = _file_size(mat_path)
        why = str(error) or type(error).__name__
        if size is not None:
            why = "an empty file" if size == 0 else f"{why}; the file has {size} bytes"
        raise MeasuredDataError(
            f"{mat_path}: not a readable .mat file ({why}); {_MAT_EXPECTED}"
        ) from None
    if "channels" not in variables:
        raise MeasuredDataError(f"{mat_path}: missing variable 'channels'")
    channels = _mat_strings(mat_path, "channels", variables["channels"])
    units = (
        _mat_strings(mat_path, "units", variables["units"])
        if "units" in variables
        else (SI_ACCELERATION,) * len(channels)
    )
    if "accelerations" not in variables:
        raise MeasuredDataError(f"{mat_path}: missing variable 'accelerations'")
    data = np.asarray(variables["accelerations"])
    if data.dtype.kind not in "fiu":
        raise MeasuredDataError(f"{mat_path}: 'accelerations' must be real numbers")
    data = data.astype(np.float64)
    if data.ndim == 1:
        data = data[:, None]
    if data.ndim != 2 or len(channels) not in data.shape:
        raise MeasuredDataError(
            f"{mat_path}: 'accelerations' has shape {data.shape}; expected (n_t, C) with "
            f"C = {len(channels)} channels"
        )
    if data.shape[1] != len(channels):
        data = data.T
    speed = _mat_vector(mat_path, variables, "speed_m_s")
    if speed.size == 1:
        end = _mat_number(mat_path, variables, "time_offset_s", 0.0) + (data.shape[0] - 1) / (
            _mat_number(mat_path, variables, "sample_rate_hz")
        )
        profile = _speed(mat_path, np.array([0.0, max(end, 1e-9)]), np.repeat(speed, 2))
    else:
        profile = _speed(mat_path, _mat_vector(mat_path, variables, "speed_time_s"), speed)
    geometry = None
    given = [name for name in _GEOMETRY_VARIABLES if name in variables]
    if given and len(given) != len(_GEOMETRY_VARIABLES):
        raise MeasuredDataError(
            f"{mat_path}: geometry variables must come together: found {given}, missing "
            f"{[name for name in _GEOMETRY_VARIABLES if name not in variables]}; give all "
            f"of {list(_GEOMETRY_VARIABLES)}, or none of them when the track under the run "
            "was not measured"
        )
    unknown = sorted(
        name
        for name in variables
        if not name.startswith("__")
        and name not in (*_OTHER_VARIABLES, *_GEOMETRY_VARIABLES, *_DESIGN_VARIABLES)
    )
    if not given and unknown:
        raise MeasuredDataError(
            f"{mat_path}: no geometry variables, and variables the layout does not name: "
            f"{unknown}; a measured track is {list(_GEOMETRY_VARIABLES)} (all of them), a "
            "track that was not measured has none of them and no other variables than "
            f"{list(_OTHER_VARIABLES)} and the design's {list(_DESIGN_VARIABLES)}"
        )
    if given:
        geometry = _geometry(
            mat_path,
            spacing_m=_mat_number(mat_path, variables, "spacing_m"),
            **{name: _mat_vector(mat_path, variables, name) for name in GEOMETRY_COMPONENTS},
        )
    stored: dict[str, Any] = {}
    if "metadata_json" in variables:
        try:
            stored = json.loads(str(variables["metadata_json"]))
        except json.JSONDecodeError as error:
            raise MeasuredDataError(f"{mat_path}: 'metadata_json' is not JSON ({error})") from None
        if not isinstance(stored, dict):
            raise MeasuredDataError(f"{mat_path}: 'metadata_json' must hold a JSON object")
    present = [name for name in _DESIGN_VARIABLES if name in variables]
    design = None
    if present and len(present) != len(_DESIGN_VARIABLES):
        raise MeasuredDataError(
            f"{mat_path}: design variables must come together: found {present}, missing "
            f"{sorted(set(_DESIGN_VARIABLES) - set(present))}"
        )
    if present:
        design = _design(
            mat_path,
            **{
                name.removeprefix("design_"): _mat_vector(mat_path, variables, name)
                for name in _DESIGN_VARIABLES
            },
        )
    run = _build(
        mat_path,
        geometry=geometry,
        speed=profile,
        channels=channels,
        accelerations_m_s2=data.T,
        sample_rate_hz=_mat_number(mat_path, variables, "sample_rate_hz"),
        units=units,
        metadata={"source": f"mat:{mat_path.name}", **stored, **(metadata or {})},
        time_offset_s=_mat_number(mat_path, variables, "time_offset_s", 0.0),
        design=design,
    )
    return _check_nan(mat_path, run, allow_nan)


def write_mat_run(run: MeasuredRun, path: PathLike) -> None:
    """Export ``run`` to a MATLAB v5 ``.mat`` file in the documented layout (without the
    geometry's variables when the run has no geometry)."""
    variables: dict[str, Any] = {
        "accelerations": run.accelerations_m_s2.T,
        "channels": np.array(run.channels, dtype=object),
        "units": np.array(run.units, dtype=object),
        "sample_rate_hz": run.sample_rate_hz,
        "time_offset_s": run.time_offset_s,
        "speed_time_s": run.speed.time_s,
        "speed_m_s": run.speed.speed_m_s,
        "metadata_json": json.dumps(run.metadata, sort_keys=True),
    }
    if run.geometry is not None:  # none of the geometry's variables without it
        variables["spacing_m"] = run.geometry.spacing_m
        for name in GEOMETRY_COMPONENTS:
            variables[name] = getattr(run.geometry, name)
    if run.design is not None:
        for name in _DESIGN_VARIABLES:
            variables[name] = getattr(run.design, name.removeprefix("design_"))
    scipy.io.savemat(Path(path), variables, do_compression=False, oned_as="column")
