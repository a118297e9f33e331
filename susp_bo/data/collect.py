"""Find the runs in a list of CSV or MATLAB files and folders, and read them.

Used by ``susp-bo import``. Naming of the inputs:

- ``mat``: every ``*.mat`` file is one run, named after the file (``run7.mat`` → ``run7``).
- ``csv``: a run is a set of files sharing a prefix: ``<run>_accelerations.csv``
  (required), ``<run>_geometry.csv`` (required; without the irregularity columns when the
  track under the run was not measured: ``s_m`` alone, or with the design columns) and
  ``<run>_speed.csv`` (optional; without it the speed is ``speed_m_s`` (a constant, m/s)
  or the accelerations file's ``speed_m_s`` column). Column layouts:
  :mod:`susp_bo.data.importers`. The geometry file stays required, so that a forgotten
  file is named rather than imported as a run without geometry.

A folder stands for the files in it (not its sub-folders). Every problem raises
:class:`~susp_bo.data.measured.MeasuredDataError` naming the file and what is expected.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

from susp_bo.data.importers import read_csv_run
from susp_bo.data.mat_files import read_mat_run
from susp_bo.data.measured import MeasuredDataError, MeasuredRun

ImportKind = Literal["csv", "mat"]
IMPORT_KINDS: tuple[ImportKind, ...] = ("csv", "mat")
CSV_ROLES = ("accelerations", "geometry", "speed")


def input_files(kind: ImportKind, inputs: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """The ``.<kind>`` files named by ``inputs`` (files, or folders of files), sorted, unique.

    Raises:
        MeasuredDataError: an empty path, a path that does not exist, a file of another
            type, or no ``.<kind>`` file at all.
    """
    suffix = f".{kind}"
    found: set[Path] = set()
    for item in inputs:
        if not str(item):  # Path("") is the current folder: never what was meant
            raise MeasuredDataError(
                f"FILES_OR_DIR: '' is not allowed (empty); expected a {suffix} file or a "
                "folder of them"
            )
        path = Path(item)
        if path.is_dir():
            found.update(p for p in path.iterdir() if p.is_file() and p.suffix.lower() == suffix)
        elif path.is_file():
            if path.suffix.lower() != suffix:
                raise MeasuredDataError(
                    f"{path}: not a {suffix} file; 'susp-bo import {kind}' reads {suffix} "
                    f"files (kinds: {', '.join(IMPORT_KINDS)})"
                )
            found.add(path)
        else:
            raise MeasuredDataError(f"{path}: no such file or folder")
    if not found:
        listed = ", ".join(str(Path(i)) for i in inputs)
        raise MeasuredDataError(f"{listed}: no {suffix} files found")
    return sorted(found)


def csv_groups(files: Sequence[Path]) -> dict[str, dict[str, Path]]:
    """Group CSV files into runs by their ``<run>_<role>.csv`` names.

    Returns:
        ``{run name: {role: path}}`` with roles accelerations, geometry (and speed).

    Raises:
        MeasuredDataError: a file whose name has no role suffix, a run without its
            accelerations or geometry file, or a run name given twice.
    """
    groups: dict[str, dict[str, Path]] = {}
    for path in files:
        stem, _, role = path.stem.rpartition("_")
        if not stem or role not in CSV_ROLES:
            raise MeasuredDataError(
                f"{path}: cannot tell which run and file this is; name CSV files "
                "<run>_accelerations.csv, <run>_geometry.csv and (optional) <run>_speed.csv"
            )
        run = groups.setdefault(stem, {})
        if role in run:
            raise MeasuredDataError(f"{path}: run {stem!r} already has a {role} file ({run[role]})")
        run[role] = path
    for name, run in groups.items():
        missing = [role for role in ("accelerations", "geometry") if role not in run]
        if missing:
            have = ", ".join(str(p) for p in run.values())
            raise MeasuredDataError(
                f"run {name!r}: missing {' and '.join(f'{name}_{m}.csv' for m in missing)} "
                f"(found {have})"
            )
    return dict(sorted(groups.items()))


def read_runs(
    kind: ImportKind,
    inputs: Sequence[str | os.PathLike[str]],
    speed_m_s: float | None = None,
) -> list[tuple[str, MeasuredRun]]:
    """Read every run named by ``inputs``.

    Args:
        kind: ``"csv"`` or ``"mat"``.
        inputs: files and folders.
        speed_m_s: constant speed (m/s) for CSV runs without a speed file (else the
            accelerations' ``speed_m_s`` column is used); ignored for ``mat``.

    Returns:
        ``(run name, run)`` pairs, sorted by name; every run in m/s² (:meth:`MeasuredRun.to_si`).

    Raises:
        MeasuredDataError: as :func:`input_files`, :func:`csv_groups` and the importers;
            and a run with an acceleration unit that cannot be converted to m/s², naming
            its file.
    """
    if kind not in IMPORT_KINDS:
        raise MeasuredDataError(f"kind: {kind!r} is not allowed; expected one of {IMPORT_KINDS}")
    files = input_files(kind, inputs)
    if kind == "mat":
        return [(path.stem, _in_si(path, read_mat_run(path))) for path in files]
    runs = []
    for name, group in csv_groups(files).items():
        speed = group.get("speed", speed_m_s)
        path = group["accelerations"]
        runs.append((name, _in_si(path, read_csv_run(path, group["geometry"], speed))))
    return runs


def _in_si(path: Path, run: MeasuredRun) -> MeasuredRun:
    """``run`` with every channel in m/s² (:meth:`MeasuredRun.to_si`).

    Raises:
        MeasuredDataError: ``"<path>: unit mismatch: …"``, naming the channels, their units
            and the known ones.
    """
    try:
        return run.to_si()
    except MeasuredDataError as error:
        raise MeasuredDataError(f"{path}: {error}") from None
