"""Small validators shared by track.py and spectra.py: errors name field, value and range."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray


def require_positive(name: str, value: object, unit: str = "") -> float:
    """Return ``value`` as a float, or raise ValueError unless it is finite and > 0.

    Args:
        name: field name used in the message, e.g. ``"TrackGeometry.spacing_m"``.
        value: the value to check.
        unit: unit appended to the value in the message.
    """
    suffix = f" {unit}" if unit else ""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name}: got {value!r}; must be a finite number > 0{suffix}") from None
    if not (math.isfinite(number) and number > 0.0):
        raise ValueError(f"{name}: got {value!r}{suffix}; must be finite and > 0{suffix}")
    return number


def as_finite_vector(name: str, values: ArrayLike, min_length: int = 1) -> NDArray[np.float64]:
    """A read-only float64 copy of a 1-D array, or ValueError naming the problem.

    Args:
        name: field name used in the message.
        values: the data, (N,).
        min_length: smallest allowed N.
    """
    try:
        array = np.array(values, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name}: cannot be read as float64 numbers ({error})") from None
    if array.ndim != 1:
        raise ValueError(f"{name}: must be 1-D; got shape {array.shape}")
    if array.size < min_length:
        raise ValueError(f"{name}: has {array.size} samples; needs at least {min_length}")
    bad = ~np.isfinite(array)
    if np.any(bad):
        index = int(np.argmax(bad))
        raise ValueError(
            f"{name}: {int(bad.sum())} non-finite value(s), first {array[index]} at index "
            f"{index}; all values must be finite"
        )
    array.setflags(write=False)
    return array
