"""Physical values as an engineer reads them: SI prefixes and three significant figures.

``format_quantity(28000, "N·s/m")`` gives ``"28.0 kN·s/m"``; ``format_quantity(4.9e6,
"N·s/m")`` gives ``"4.90 MN·s/m"``. The prefix goes on the unit's first symbol (N, m, s, Hz,
Pa, J, W, rad, A, V, g), so ``N·m/rad`` becomes ``kN·m/rad`` and ``m/s²`` becomes ``mm/s²``.
A mass in ``kg`` reads in ``g``, ``kg`` or ``t``. Units that take no prefix (``""``, ``%``,
``kg·m²``, ``1/s``, anything unknown) keep the plain value with three significant figures.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

PREFIXES: tuple[tuple[int, str], ...] = (
    (-9, "n"),
    (-6, "µ"),
    (-3, "m"),
    (0, ""),
    (3, "k"),
    (6, "M"),
    (9, "G"),
    (12, "T"),
)
"""(power of ten, symbol) of the engineering prefixes used."""

PREFIXABLE = frozenset({"N", "m", "s", "Hz", "Pa", "J", "W", "rad", "A", "V", "g"})
"""Unit symbols that take an SI prefix when they come first in a compound unit."""

_HEAD = re.compile(r"^([A-Za-z]+)(.*)$")
_MASS = ((-3, "g"), (0, "kg"), (3, "t"))


def _scales(unit: str) -> tuple[tuple[int, str], ...] | None:
    """(power of ten, prefixed unit) choices for ``unit``, or None when it takes no prefix."""
    if unit == "kg":
        return _MASS
    match = _HEAD.match(unit)
    if match is None or match.group(1) not in PREFIXABLE:
        return None
    return tuple((power, symbol + unit) for power, symbol in PREFIXES)


def unit_scale(magnitude: float, unit: str) -> tuple[float, str]:
    """The factor and prefixed unit that put ``magnitude`` in [1, 1000).

    Args:
        magnitude: a typical value in ``unit`` (e.g. the largest value an axis shows).
        unit: the SI unit, e.g. ``"N·s/m"``.

    Returns:
        ``(factor, prefixed_unit)``: divide values in ``unit`` by ``factor`` to read them in
        ``prefixed_unit``. ``(1.0, unit)`` when the unit takes no prefix or the value is 0.
    """
    choices = _scales(unit)
    m = abs(float(magnitude))
    if choices is None or not math.isfinite(m) or m == 0.0:
        return 1.0, unit
    exponent = math.floor(math.log10(m))
    best = choices[0]
    for power, name in choices:
        if power <= exponent:
            best = (power, name)
    return 10.0 ** best[0], best[1]


def _decimals(value: float, digits: int) -> int:
    """Decimals that show ``value`` with ``digits`` significant figures (0 or more)."""
    if value == 0.0 or not math.isfinite(value):
        return max(0, digits - 1)
    return max(0, digits - 1 - math.floor(math.log10(abs(value))))


def format_quantity(value: float, unit: str, digits: int = 3) -> str:
    """``value`` (in ``unit``) with an SI prefix and ``digits`` significant figures.

    Examples: ``28000, "N·s/m"`` → ``"28.0 kN·s/m"``; ``1.176e6, "N/m"`` → ``"1.18 MN/m"``;
    ``0.5, ""`` → ``"0.500"``.
    """
    v = float(value)
    if not math.isfinite(v):
        return f"{v} {unit}".strip()
    rounded = float(f"{v:.{digits}g}")  # 999.7 N rounds to 1.00 kN, not 1000 N
    factor, prefixed = unit_scale(rounded, unit)
    if _scales(unit) is None and rounded != 0.0 and not 1e-3 <= abs(rounded) < 1e6:
        return f"{v:.{digits - 1}e} {unit}".strip()
    m = rounded / factor
    return f"{m:.{_decimals(m, digits)}f} {prefixed}".strip()


def format_values(
    values: Sequence[float], unit: str, digits: int = 3, like: Sequence[float] | None = None
) -> tuple[list[str], str]:
    """Several values in one common prefixed unit, e.g. a MAP and its interval.

    The prefix follows the largest magnitude; the decimals show ``digits`` significant
    figures of the largest value and at least one of the smallest nonzero gap between values
    (so a narrow interval does not print as two equal numbers).

    Args:
        values: values in ``unit``.
        unit: the SI unit.
        digits: significant figures of the largest value.
        like: values that choose the prefix and decimals instead of ``values`` (to write a
            reference in the unit and precision of a MAP and its interval); default
            ``values``.

    Returns:
        ``(numbers, prefixed_unit)``: the formatted numbers (no unit) and the unit they are in.
    """
    out = [float(x) for x in values]
    v = out if like is None else [float(x) for x in like]
    finite = [abs(x) for x in v if math.isfinite(x)]
    top = max(finite, default=0.0)
    factor, prefixed = unit_scale(top, unit)
    decimals = _decimals(top / factor, digits)
    gaps = [abs(a - b) / factor for a in v for b in v if a != b]
    gaps = [g for g in gaps if math.isfinite(g) and g > 0.0]
    if gaps:
        decimals = max(decimals, _decimals(min(gaps), 1))
    decimals = min(decimals, 6)
    return [f"{x / factor:.{decimals}f}" for x in out], prefixed


def format_range(lower: float, upper: float, unit: str) -> str:
    """``"0.50–8.00 MN·s/m"``: a range in one prefixed unit."""
    (lo, hi), prefixed = format_values([lower, upper], unit)
    return f"{lo}–{hi} {prefixed}".strip()
