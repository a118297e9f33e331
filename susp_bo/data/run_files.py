"""Measured-run files: write one, read one, and find and read a folder's runs.

A run is one HDF5 file (``.h5`` or ``.hdf5``, :data:`RUN_SUFFIXES`) in the format
documented in :mod:`susp_bo.data.measured`; :func:`save_run` writes it atomically,
:func:`load_run` reads it back (the HDF5 details are :mod:`susp_bo.data._hdf5`), and
:func:`load_runs` reads every run of a data folder with one channel set. Every problem
raises :class:`~susp_bo.data.measured.MeasuredDataError` naming the file.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Sequence
from pathlib import Path

from susp_bo.data.measured import MeasuredDataError, MeasuredRun, _channel_tuple


def save_run(run: MeasuredRun, path: str | os.PathLike[str]) -> Path:
    """Write ``run`` to an HDF5 file in the documented format (atomic replace).

    Args:
        run: the run.
        path: the file to write; its suffix is one :func:`load_runs` reads
            (:data:`RUN_SUFFIXES`: ``.h5``, ``.hdf5``).

    Returns:
        The path written.

    Raises:
        TypeError: ``run`` is not a :class:`MeasuredRun`.
        MeasuredDataError: ``path`` is a folder or has another suffix.
    """
    from susp_bo.data._hdf5 import write_run_file

    if not isinstance(run, MeasuredRun):
        raise TypeError(f"run: expected a MeasuredRun, got {type(run).__name__}")
    target = Path(path)
    if target.is_dir():
        raise MeasuredDataError(f"path: {target} is a folder; expected a run file (e.g. run.h5)")
    if target.suffix not in RUN_SUFFIXES:
        raise MeasuredDataError(
            f"path: {target} has suffix {target.suffix!r}, which load_runs does not read; "
            f"expected one of {sorted(RUN_SUFFIXES)}"
        )
    target.parent.mkdir(parents=True, exist_ok=True)
    # a unique name made like a plain file (mode 0666 less the umask; mkstemp's is 0600)
    temporary = str(target.parent / f".{target.name}.{uuid.uuid4().hex}.tmp")
    os.close(os.open(temporary, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))
    try:
        write_run_file(run, Path(temporary))
        os.replace(temporary, target)
    finally:
        if os.path.exists(temporary):
            os.remove(temporary)
    return target


def load_run(path: str | os.PathLike[str], *, allow_nan: bool = False) -> MeasuredRun:
    """Read one run from an HDF5 file in the documented format.

    Args:
        path: the file.
        allow_nan: keep NaN samples in the accelerations (dropouts) instead of
            refusing the file; :func:`validate_run` still reports them.

    Raises:
        MeasuredDataError: anything malformed, naming the file and the item.
    """
    from susp_bo.data._hdf5 import read_run_file

    return read_run_file(Path(path), allow_nan=allow_nan)


RUN_SUFFIXES = frozenset({".h5", ".hdf5"})
"""Extensions of a measured-run file."""


def run_paths(folder: str | os.PathLike[str]) -> list[Path]:
    """The measured-run files (``*.h5``, ``*.hdf5``) directly in ``folder``, sorted by name;
    empty for a folder that does not exist."""
    directory = Path(folder)
    if not directory.is_dir():
        return []
    return sorted(p for p in directory.iterdir() if p.suffix in RUN_SUFFIXES and p.is_file())


def load_runs(
    folder: str | os.PathLike[str],
    channels: Sequence[str] | None = None,
    *,
    allow_nan: bool = False,
) -> list[MeasuredRun]:
    """Read every ``*.h5`` / ``*.hdf5`` run in ``folder``, sorted by file name.

    Args:
        folder: the folder.
        channels: channels to keep (in this order); None requires every file to
            have the first file's channel set and orders them as the first file.
        allow_nan: as in :func:`load_run`.

    Raises:
        MeasuredDataError: no runs, an unreadable run, inconsistent channels, or
            ``channels`` a str or empty.
    """
    if channels is not None:
        channels = _channel_tuple(channels)
    directory = Path(folder)
    if not directory.is_dir():
        raise MeasuredDataError(f"{directory}: not a folder of measured runs")
    # named like a run but not a readable file (a folder, a broken link): refused, not
    # skipped (outside probe, session 29: the study then said "needs 2 runs (found 1)")
    odd = sorted(p for p in directory.iterdir() if p.suffix in RUN_SUFFIXES and not p.is_file())
    if odd:
        what = (
            "a folder"
            if odd[0].is_dir()
            else "a link to nothing"
            if odd[0].is_symlink()
            else ("not a regular file")
        )
        raise MeasuredDataError(
            f"{odd[0]}: named like a measured run but {what}; expected an HDF5 run file "
            "(move it out of the data folder, or restore the file)"
        )
    paths = run_paths(directory)
    if not paths:
        raise MeasuredDataError(f"{directory}: holds no measured runs (*.h5, *.hdf5)")
    runs = [load_run(p, allow_nan=allow_nan) for p in paths]
    wanted = tuple(runs[0].channels) if channels is None else tuple(channels)
    selected = []
    for path, run in zip(paths, runs):
        if channels is None and set(run.channels) != set(wanted):
            raise MeasuredDataError(
                f"{path}: channel set differs from {paths[0].name}: missing "
                f"{sorted(set(wanted) - set(run.channels))}, extra "
                f"{sorted(set(run.channels) - set(wanted))}"
            )
        try:
            selected.append(run.select(wanted))
        except MeasuredDataError as error:
            raise MeasuredDataError(f"{path}: {error}") from None
    return selected
