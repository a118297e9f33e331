"""Helpers shared by the command implementations: parameter files, output folders, logging."""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from pathlib import Path

from susp_bo.cli import UsageError
from susp_bo.output_folder import check_output_folder


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
