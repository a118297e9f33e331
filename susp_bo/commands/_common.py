"""Helpers shared by the command implementations: parameter files, output folders, logging."""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from pathlib import Path

from susp_bo.cli import UsageError
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


def checked_output_folder(out: str | Path, label: str = "--out") -> Path:
    """The output folder, checked (not created): refuses a path that is an existing file.

    Raises:
        UsageError: naming ``label``, the path and what is allowed.
    """
    try:
        return check_output_folder(out, label)
    except ValueError as error:
        raise UsageError(str(error)) from None


def output_folder(out: str | Path, label: str = "--out") -> Path:
    """Create (if needed) and return the output folder (checked first)."""
    folder = checked_output_folder(out, label)
    folder.mkdir(parents=True, exist_ok=True)
    return folder


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
