"""Reading a TOML file the tool was given: UTF-8 text, parsed, or a message naming the file.

Every TOML file the tool reads (a rig, ``--params``/``--truth``, a study, a campaign's
``campaign.toml``, a line file) goes through :func:`read_toml`, so that a file that is not
UTF-8 text (a binary file, a spreadsheet, a UTF-16 export) is refused with the same
clear message instead of a ``UnicodeDecodeError`` without the file's name.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

__all__ = ["TomlFileError", "read_toml"]


class TomlFileError(ValueError):
    """A TOML file that is not UTF-8 text or not valid TOML; the message names the file."""


def read_toml(path: str | Path) -> dict[str, Any]:
    """The TOML document of ``path`` as nested dicts.

    Args:
        path: the file; it must be UTF-8 text (TOML's encoding).

    Returns:
        The parsed document.

    Raises:
        OSError: the file cannot be read (FileNotFoundError, IsADirectoryError, …).
        TomlFileError: ``"<path>: not a UTF-8 text file (byte 0xff at position 0 …);
            expected a TOML file (UTF-8 text)"``, or ``"<path>: not valid TOML (…)"``.
    """
    file = Path(path)
    raw = file.read_bytes()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        byte = raw[error.start : error.start + 1].hex()
        raise TomlFileError(
            f"{file}: not a UTF-8 text file (byte 0x{byte} at position {error.start} is not "
            "UTF-8); expected a TOML file (UTF-8 text): save it as UTF-8"
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise TomlFileError(f"{file}: not valid TOML ({error})") from None
