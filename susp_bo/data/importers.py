"""Importers (and matching exporters) of measured runs from CSV and MATLAB ``.mat`` files.

CSV layout (comma separated, one header row, lines starting with ``#`` ignored,
empty cells read as NaN):

* accelerations file: first column ``time_s`` (s, uniformly sampled — the
  sampling rate is derived from it), then one column per sensor named
  ``<channel>`` or ``<channel> [<unit>]`` (unit default ``m/s^2``; ``g``,
  ``mm/s^2``, ``cm/s^2`` are recognised, see :meth:`MeasuredRun.to_si`).
  An optional column ``speed_m_s`` holds the speed record at the same times.
* geometry file: column ``s_m`` (uniformly spaced), the irregularities
  ``vertical_m, alignment_m, cross_level_rad, gauge_m`` — all four or none: without
  them the track under the run was not measured (:attr:`MeasuredRun.geometry` None) —
  and optionally the line's design on the same rows: ``curvature_1_m`` (1/m,
  + left-hand curve), ``cant_m`` (m, signed cross-level, + left rail higher) and
  ``gradient`` (rise/run) — all three or none (see :mod:`susp_bo.rig.design`); any
  order. The first row is the track origin (s = 0); its original chainage is kept in
  the metadata as ``geometry_start_m``. From Python, ``geometry_csv=None`` reads a run
  without geometry or design (``susp-bo import csv`` asks for the file, which may then
  hold ``s_m`` alone).
* speed: a constant in m/s, or a CSV with columns ``time_s, speed_m_s``, or
  (``speed=None``) the ``speed_m_s`` column of the accelerations file.

The clock starts at the first row of the speed CSV (or at the first
acceleration sample otherwise); the accelerations' ``time_offset_s`` is their
first time on that clock.

MATLAB layout (``scipy.io.loadmat``; v4–v7 files; v7.3 files are HDF5 and are
refused with a hint): variables ``accelerations`` (n_t x C, or C x n_t when
unambiguous), ``channels`` (cell array of char), ``units`` (optional cell
array, default m/s^2), ``sample_rate_hz``, ``time_offset_s`` (optional),
the geometry ``spacing_m``, ``vertical_m``, ``alignment_m``, ``cross_level_rad``,
``gauge_m`` (all five, or none when the track was not measured), ``speed_m_s``
(scalar = constant, or vector with ``speed_time_s``), ``metadata_json`` (optional
char), and optionally the design: ``design_chainage_m`` (on the track's s axis),
``design_curvature_1_m``, ``design_cant_m``, ``design_gradient`` (all four or none).

Every problem raises :class:`~susp_bo.data.measured.MeasuredDataError` naming
the file, the column or variable and the expectation.

The CSV importer and exporter are here; the MATLAB ones are :mod:`susp_bo.data.mat_files`
(``read_mat_run`` and ``write_mat_run`` are still importable from here), and the checks
both share, :mod:`susp_bo.data.importer_checks`.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np

from susp_bo.data.importer_checks import PathLike, _build, _check_nan, _design, _geometry, _speed

# ``name as name``: re-exported, importable from susp_bo.data.importers as before the split.
from susp_bo.data.mat_files import read_mat_run as read_mat_run
from susp_bo.data.mat_files import write_mat_run as write_mat_run
from susp_bo.data.measured import (
    SI_ACCELERATION,
    MeasuredDataError,
    MeasuredRun,
)
from susp_bo.rig.design import DESIGN_COMPONENTS, TrackDesign
from susp_bo.rig.track import GEOMETRY_COMPONENTS, TrackGeometry

_GEOMETRY_COLUMNS = ("s_m", *GEOMETRY_COMPONENTS)
EXPORT_SPACING_M = 0.25
"""Row spacing (m), at most, of the ``s_m`` column :func:`write_csv_run` writes for a run
without geometry (its design sampled on those rows)."""


def csv_columns(path: PathLike) -> list[str]:
    """The column names of a CSV file (its first row that is not a comment), data unread.

    Raises:
        MeasuredDataError: the file cannot be read as CSV text.
    """
    try:
        with open(path, newline="", encoding="utf-8-sig") as handle:
            rows = (r for r in csv.reader(handle) if r and not r[0].lstrip().startswith("#"))
            return [name.strip() for name in next(rows, [])]
    except (OSError, UnicodeError, csv.Error) as error:
        raise MeasuredDataError(f"{path}: cannot read CSV ({error})") from None


def _read_table(path: Path) -> tuple[list[str], np.ndarray]:
    """Header names and a float64 (rows x columns) table; empty cells are NaN."""
    try:
        # utf-8-sig: a spreadsheet's byte-order mark is not part of the first column's name
        with open(path, newline="", encoding="utf-8-sig") as handle:
            rows = [r for r in csv.reader(handle) if r and not r[0].lstrip().startswith("#")]
    except (OSError, UnicodeError, csv.Error) as error:
        raise MeasuredDataError(f"{path}: cannot read CSV ({error})") from None
    if len(rows) < 3:
        raise MeasuredDataError(f"{path}: needs a header row and at least 2 data rows")
    header = [name.strip() for name in rows[0]]
    if len(set(header)) != len(header) or not all(header):
        raise MeasuredDataError(f"{path}: column names must be unique and non-empty: {header}")
    table = np.empty((len(rows) - 1, len(header)))
    for i, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise MeasuredDataError(
                f"{path}: line {i + 2} has {len(row)} cells; the header has {len(header)}"
            )
        for j, cell in enumerate(row):
            try:
                table[i, j] = float(cell) if cell.strip() else np.nan
            except ValueError:
                raise MeasuredDataError(
                    f"{path}: line {i + 2}, column {header[j]!r}: {cell!r} is not a number"
                ) from None
    return header, table


def _uniform_step(path: Path, name: str, values: np.ndarray) -> float:
    """The step of a uniformly spaced, finite, increasing column, or MeasuredDataError."""
    if not np.all(np.isfinite(values)):
        raise MeasuredDataError(f"{path}: column {name!r} has empty or non-finite cells")
    steps = np.diff(values)
    step = (values[-1] - values[0]) / (values.size - 1)
    if step <= 0 or np.max(np.abs(steps - step)) > 1e-3 * step:
        raise MeasuredDataError(
            f"{path}: column {name!r} must increase in equal steps (found steps "
            f"{steps.min():g} … {steps.max():g})"
        )
    return float(step)


def _check_increasing(path: Path, name: str, values: np.ndarray, unit: str) -> None:
    """MeasuredDataError unless column ``name`` is finite and strictly increasing, naming
    the first offending data row and its value as written in the file (not shifted)."""
    bad = ~np.isfinite(values)
    if np.any(bad):
        row = int(np.argmax(bad))
        raise MeasuredDataError(
            f"{path}: column {name!r}: data row {row + 1} is empty or not finite "
            f"({values[row]:g}); expected finite times"
        )
    steps = np.diff(values)
    if np.any(steps <= 0):
        row = int(np.argmax(steps <= 0)) + 1
        raise MeasuredDataError(
            f"{path}: column {name!r} must be strictly increasing; data row {row + 1} has "
            f"{name} = {values[row]:g} {unit}, not after data row {row} ({values[row - 1]:g} "
            f"{unit})"
        )


def _split_unit(column: str) -> tuple[str, str]:
    if column.endswith("]") and "[" in column:
        name, unit = column[:-1].rsplit("[", 1)
        return name.strip(), unit.strip()
    return column, SI_ACCELERATION


def _track(
    path: Path,
) -> tuple[TrackGeometry | None, TrackDesign | None, float]:
    """The geometry file's irregularities (None without their columns), design (None
    without its columns) and the chainage of its first row (m).

    Raises:
        MeasuredDataError: columns other than ``s_m`` + all or none of the irregularities +
            all or none of the design columns, naming the missing and unknown ones; bad
            values, naming the file.
    """
    header, table = _read_table(path)
    irregularities = set(header) & set(GEOMETRY_COMPONENTS)
    designed = set(header) & set(DESIGN_COMPONENTS)
    expected = (
        ("s_m",)
        + (GEOMETRY_COMPONENTS if irregularities else ())
        + (DESIGN_COMPONENTS if designed else ())
    )
    if sorted(header) != sorted(expected):
        raise MeasuredDataError(
            f"{path}: columns must be 's_m', all of {list(GEOMETRY_COMPONENTS)} (or none of "
            f"them: the track not measured) and optionally all of {list(DESIGN_COMPONENTS)}; "
            f"missing {sorted(set(expected) - set(header))}, unknown "
            f"{sorted(set(header) - set(expected))}"
        )
    s = table[:, header.index("s_m")]
    spacing = _uniform_step(path, "s_m", s)
    geometry = None
    if irregularities:
        geometry = _geometry(
            path,
            spacing_m=spacing,
            **{name: table[:, header.index(name)] for name in GEOMETRY_COMPONENTS},
        )
    design = None
    if designed:
        design = _design(
            path,
            chainage_m=s - s[0],
            **{name: table[:, header.index(name)] for name in DESIGN_COMPONENTS},
        )
    return geometry, design, float(s[0])


def read_csv_run(
    accelerations_csv: PathLike,
    geometry_csv: PathLike | None,
    speed: float | PathLike | None = None,
    *,
    metadata: dict[str, Any] | None = None,
    allow_nan: bool = False,
) -> MeasuredRun:
    """Import one run from CSV files (layout in the module docstring).

    Args:
        accelerations_csv: ``time_s`` + channel columns (+ optional ``speed_m_s``).
        geometry_csv: ``s_m`` + the four geometry columns (or none of them: the track not
            measured) + optionally the three design columns; None: a run without geometry
            or design.
        speed: constant speed (m/s), a speed CSV, or None for the ``speed_m_s`` column.
        metadata: stored with the run (``geometry_start_m`` and ``source`` are added).
        allow_nan: keep empty / NaN acceleration cells instead of refusing the file.

    Raises:
        MeasuredDataError: naming the file, line or column.
    """
    acc_path = Path(accelerations_csv)
    geo_path = None if geometry_csv is None else Path(geometry_csv)
    header, table = _read_table(acc_path)
    if header[0] != "time_s":
        raise MeasuredDataError(f"{acc_path}: the first column must be 'time_s'; got {header[0]!r}")
    time = table[:, 0]
    rate = 1.0 / _uniform_step(acc_path, "time_s", time)
    channel_columns = [j for j, name in enumerate(header) if j > 0 and name != "speed_m_s"]
    if not channel_columns:
        raise MeasuredDataError(f"{acc_path}: no acceleration channel columns after 'time_s'")
    names, units = zip(*(_split_unit(header[j]) for j in channel_columns))

    if speed is None:
        if "speed_m_s" not in header:
            raise MeasuredDataError(
                f"{acc_path}: no speed: give speed= (m/s or a CSV) or a 'speed_m_s' column"
            )
        clock = time[0]
        profile = _speed(acc_path, time - clock, table[:, header.index("speed_m_s")])
    elif isinstance(speed, (int, float)) and not isinstance(speed, bool):
        clock = time[0]
        duration = time[-1] - clock
        profile = _speed(acc_path, np.array([0.0, duration]), np.array([speed, speed], float))
    else:
        speed_path = Path(speed)
        speed_header, speed_table = _read_table(speed_path)
        if sorted(speed_header) != ["speed_m_s", "time_s"]:
            raise MeasuredDataError(
                f"{speed_path}: columns must be 'time_s', 'speed_m_s'; got {speed_header}"
            )
        speed_time = speed_table[:, speed_header.index("time_s")]
        _check_increasing(speed_path, "time_s", speed_time, "s")  # the file's own times
        clock = speed_time[0] if speed_time.size else 0.0
        profile = _speed(
            speed_path, speed_time - clock, speed_table[:, speed_header.index("speed_m_s")]
        )
    offset = float(time[0] - clock)
    if offset < 0:
        raise MeasuredDataError(
            f"{acc_path}: accelerations start at t = {time[0]:g} s, before the speed record "
            f"({clock:g} s)"
        )

    geometry, design, start_m = (None, None, None) if geo_path is None else _track(geo_path)
    info = {"source": f"csv:{acc_path.name}", **(metadata or {})}
    if start_m is not None:
        info["geometry_start_m"] = start_m
    run = _build(
        acc_path,
        geometry=geometry,
        speed=profile,
        channels=tuple(names),
        accelerations_m_s2=table[:, channel_columns].T,
        sample_rate_hz=rate,
        units=tuple(units),
        metadata=info,
        time_offset_s=offset,
        design=design,
    )
    return _check_nan(acc_path, run, allow_nan)


def write_csv_run(
    run: MeasuredRun, accelerations_csv: PathLike, geometry_csv: PathLike, speed_csv: PathLike
) -> None:
    """Export ``run`` to the CSV layout (times on the speed clock; full float precision).

    A design is written as its values at the geometry's samples (its knots in between
    are not kept: a design record sampled like the geometry). A run without geometry
    gets a geometry file without the irregularity columns: ``s_m`` in equal steps of at
    most :data:`EXPORT_SPACING_M` over its design (or, without one, over the distance of
    its speed record), with the design's values on those rows.
    """
    header = ["time_s", *(f"{c} [{u}]" for c, u in zip(run.channels, run.units))]
    columns = [run.time_s, *run.accelerations_m_s2]
    _write_table(Path(accelerations_csv), header, np.column_stack(columns))
    if run.geometry is not None:
        names = list(_GEOMETRY_COLUMNS)
        table = [run.geometry.position_m, *run.geometry.stacked()]
    else:
        end = (
            run.design.end_m
            if run.design is not None
            else run.speed.distance_m(run.speed.duration_s)
        )
        rows = max(2, math.ceil(float(end) / EXPORT_SPACING_M - 1e-9) + 1)
        names, table = ["s_m"], [np.linspace(0.0, float(end), rows)]
    if run.design is not None:
        s = table[0]
        names += list(DESIGN_COMPONENTS)
        table += [run.design.curvature(s), run.design.cant(s), run.design.grade(s)[0]]
    _write_table(Path(geometry_csv), names, np.column_stack(table))
    _write_table(
        Path(speed_csv),
        ["time_s", "speed_m_s"],
        np.column_stack([run.speed.time_s, run.speed.speed_m_s]),
    )


def _write_table(path: Path, header: list[str], table: np.ndarray) -> None:
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows([["" if np.isnan(v) else repr(float(v)) for v in row] for row in table])
