"""Helpers shared by the command implementations: parameter files, output folders, logging."""

from __future__ import annotations

import math
import tempfile
import tomllib
from collections.abc import Mapping
from pathlib import Path

from susp_bo.cli import UsageError
from susp_bo.data.measured import run_paths
from susp_bo.output_folder import check_output_folder
from susp_bo.rig.spec import SIMULATION_LIMITS


def read_parameter_file(path: str | Path) -> dict[str, float]:
    """Parameter values from a TOML file: ``name = value`` at top level or under ``[parameters]``.

    Raises:
        UsageError: missing file, bad TOML, or a value that is not a finite number.
    """
    file = Path(path)
    if not file.is_file():
        raise UsageError(f"--params/--truth: file {str(file)!r} does not exist")
    try:
        data = tomllib.loads(file.read_text())
    except tomllib.TOMLDecodeError as error:
        raise UsageError(f"{file}: not valid TOML ({error})") from error
    table = data.get("parameters", data)
    if not isinstance(table, Mapping):
        raise UsageError(f"{file}: [parameters] must be a table of name = value")
    values: dict[str, float] = {}
    for name, value in table.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise UsageError(f"{file}: parameter {name!r} = {value!r} is not a number")
        if not math.isfinite(float(value)):
            raise UsageError(f"{file}: parameter {name!r} = {value!r} is not finite")
        values[str(name)] = float(value)
    return values


_ALLOWED_FOLDER = "expected a folder that exists or can be created, and can be written in"


def checked_output_folder(out: str | Path, label: str = "--out") -> Path:
    """The output folder, checked and left as it was: a folder that exists or can be
    created, and that this process can write in.

    An empty path is refused (it would write into the current folder). A folder that does
    not exist yet is created to try it, then removed again, so a refusal later (a bad flag)
    leaves nothing behind; an existing folder is tried with a temporary file.

    Raises:
        UsageError: naming ``label``, the path, the reason and what is allowed.
    """
    if not str(out):
        raise UsageError(
            f"{label}: {str(out)!r} is not allowed; expected the path of a folder (existing or "
            "new; '.' for the current folder)"
        )
    try:
        folder = check_output_folder(out, label)
        _try_writing(folder, label)
    except ValueError as error:
        raise UsageError(str(error)) from None
    except OSError as error:  # e.g. a name too long to look up
        raise UsageError(
            f"{label}: {str(out)!r} is not allowed ({_reason(error, out)}); {_ALLOWED_FOLDER}"
        ) from None
    return folder


def _try_writing(folder: Path, label: str) -> None:
    """Creates ``folder`` and removes it again, or writes a temporary file in it.

    Raises:
        UsageError: the folder cannot be created or written in (e.g. ``/proc/x``, a
            read-only file system, no permission, a name too long).
    """
    if folder.is_dir():
        try:
            with tempfile.TemporaryFile(dir=folder, prefix=".susp_bo_write_check_"):
                pass
        except OSError as error:
            raise UsageError(
                f"{label}: {str(folder)!r} is not allowed; cannot write in it "
                f"({error.strerror or error}); {_ALLOWED_FOLDER}"
            ) from None
        return
    missing = [folder]
    missing += [parent for parent in folder.parents if not parent.exists()]
    try:
        folder.mkdir(parents=True)
    except OSError as error:
        raise UsageError(
            f"{label}: {str(folder)!r} is not allowed; cannot create it "
            f"({_reason(error, folder)}); {_ALLOWED_FOLDER}"
        ) from None
    for created in missing:  # innermost first; one that another process filled stays
        try:
            created.rmdir()
        except OSError:
            break


def _reason(error: OSError, folder: str | Path) -> str:
    """``strerror`` of ``error``, with the path it is about when that is not ``folder``."""
    reason = error.strerror or str(error)
    if error.filename is None or str(error.filename) == str(folder):
        return reason
    return f"{reason}: {str(error.filename)!r}"


def output_folder(out: str | Path, label: str = "--out") -> Path:
    """Create (if needed) and return the output folder (checked first).

    Raises:
        UsageError: as :func:`checked_output_folder`, or the folder cannot be created.
    """
    folder = checked_output_folder(out, label)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise UsageError(
            f"{label}: {str(folder)!r} is not allowed; cannot create it ({_reason(error, folder)})"
        ) from None
    return folder


def existing_runs(folder: Path, also: tuple[str, ...] = ()) -> list[Path]:
    """The measured runs (``*.h5``, ``*.hdf5``, what ``calibrate`` reads) and the files named
    ``also`` that ``folder`` already holds, sorted; empty for a folder that does not exist."""
    named = [folder / name for name in also if (folder / name).is_file()]
    return sorted([*run_paths(folder), *named])


def listed(paths: list[Path], limit: int = 4) -> str:
    """``a.h5, b.h5, c.h5 and 5 more``: file names for a message."""
    names = [path.name for path in paths[:limit]]
    more = f" and {len(paths) - limit} more" if len(paths) > limit else ""
    return ", ".join(names) + more


def read_line_file(path: str | Path | None, spec: object) -> object:
    """The track design of ``--line FILE`` checked against a default run of ``spec``, or None.

    Raises:
        UsageError: missing or bad file, a design outside the limits, or one that does not
            cover the run (the message names the file, the value and what is allowed).
    """
    if path is None:
        return None
    from susp_bo.rig.design import DesignError
    from susp_bo.rig.line_file import load_line
    from susp_bo.rig.simulator import synthetic_track_length_m

    try:
        design = load_line(path)
        design.check_covers(0.0, synthetic_track_length_m(spec), "the run (--speed, --duration)")
    except DesignError as error:
        raise UsageError(f"--line: {error}") from error
    return design


def out_of_range(flag: str, key: str, value: float) -> str:
    """The refusal of a ``[simulation]`` setting given on the command line.

    E.g. ``--speed: 500 m/s is not allowed; allowed range (0, 200] m/s (the rig's
    [simulation] speed_m_s)``.
    """
    low, high, unit = SIMULATION_LIMITS[key]
    return (
        f"{flag}: {value:g} {unit} is not allowed; allowed range ({low:g}, {high:g}] {unit} "
        f"(the rig's [simulation] {key})"
    )
