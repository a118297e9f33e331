"""Argument types of the command line: numbers checked when the flags are parsed.

Each factory returns an ``argparse`` ``type=`` callable; a bad value makes argparse
print ``susp-bo <cmd>: error: argument --flag: <value> is not allowed; expected …``
and exit with code 2 before any work starts. Kept free of heavy imports (the
parser is built for ``--help`` too).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable


def integer(minimum: int, what: str = "") -> Callable[[str], int]:
    """An integer >= ``minimum`` (``what`` adds a unit or meaning to the message)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum:
            raise argparse.ArgumentTypeError(
                f"{text!r} is not allowed; expected an integer >= {minimum}{what}"
            )
        return value

    parse.__name__ = "integer"
    return parse


def number(
    minimum: float = -math.inf, *, strict: bool = False, unit: str = ""
) -> Callable[[str], float]:
    """A finite float >= ``minimum`` (> when ``strict``), in ``unit``."""
    relation = ">" if strict else ">="
    bound = "" if minimum == -math.inf else f" {relation} {minimum:g}"
    suffix = f" {unit}" if unit else ""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or value < minimum or (strict and value == minimum):
            raise argparse.ArgumentTypeError(
                f"{text!r} is not allowed; expected a finite number{bound}{suffix}"
            )
        return value

    parse.__name__ = "number"
    return parse
