"""Line files: a track design written as a list of segments (TOML).

Example (``--line FILE`` of ``susp-bo simulate`` / ``susp-bo synth``)::

    [line]
    name = "S-curve demo"            # optional

    [[segments]]
    type = "tangent"
    length_m = 400.0

    [[segments]]
    type = "transition"              # clothoid: curvature, cant (and gradient)
    length_m = 150.0                 # ramp linearly from the previous segment's end
                                     # to the next segment's start

    [[segments]]
    type = "curve"
    length_m = 900.0
    radius_m = 4000.0                # >= 150 m
    cant_mm = 120.0                  # on the outer rail, 0 … 180 mm
    direction = "left"               # centre of the curve on the left (or "right")
    gradient_permille = 4.0          # optional, + uphill; default 0

The first segment starts at chainage 0, the first sample of the track geometry.
A ``transition`` needs a segment on each side. Keys are checked by name and
unit before anything runs: unknown keys, a cant given in m under ``cant_mm``
(below 1), a radius below 150 m, a cant above 180 mm, a length above 2e7 m
(:data:`~susp_bo.rig.design.MAX_LINE_LENGTH_M`), … are refused with the
file, the segment number, the value and what is allowed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from susp_bo.rig.design import (
    MAX_CANT_M,
    MAX_GRADIENT,
    MAX_LINE_LENGTH_M,
    MIN_RADIUS_M,
    DesignError,
    TrackDesign,
)
from susp_bo.rig.toml_files import TomlFileError, read_toml

_KEYS = {
    "tangent": {"type", "length_m", "gradient_permille"},
    "transition": {"type", "length_m"},
    "curve": {"type", "length_m", "radius_m", "cant_mm", "direction", "gradient_permille"},
}


def _number(where: str, value: object, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise DesignError(f"{where}: got {value!r}; expected a finite number ({unit})")
    return float(value)


def _length(where: str, segment: Mapping[str, Any]) -> float:
    """The segment's ``length_m``: a finite number in (0, MAX_LINE_LENGTH_M] m."""
    length = _number(f"{where}.length_m", segment.get("length_m"), "m")
    if length <= 0:
        raise DesignError(f"{where}.length_m: got {length:g} m; must be > 0 m")
    if length > MAX_LINE_LENGTH_M:
        raise DesignError(
            f"{where}.length_m: got {length:g} m; above the maximum {MAX_LINE_LENGTH_M:g} m "
            f"({MAX_LINE_LENGTH_M / 1000:g} km: the longest run the [simulation] limits allow)"
        )
    return length


def _segment_state(where: str, segment: Mapping[str, Any]) -> tuple[float, float, float, float]:
    """(length, curvature, signed cant, gradient) of a tangent or curve segment."""
    length = _length(where, segment)
    gradient = _number(
        f"{where}.gradient_permille", segment.get("gradient_permille", 0.0), "per mille"
    )
    if 0 < abs(gradient) < 0.1:
        raise DesignError(
            f"{where}.gradient_permille: got {gradient:g}; that is below 0.1 per mille — a "
            "fraction given as per mille? (12 per mille is written 12.0)"
        )
    if abs(gradient) > MAX_GRADIENT * 1000.0:
        raise DesignError(
            f"{where}.gradient_permille: got {gradient:g}; above the maximum "
            f"{MAX_GRADIENT * 1000:.0f} per mille (TSI INF 4.2.3.3)"
        )
    if segment["type"] == "tangent":
        return length, 0.0, 0.0, gradient / 1000.0
    radius = _number(f"{where}.radius_m", segment.get("radius_m"), "m")
    if radius < MIN_RADIUS_M:
        raise DesignError(
            f"{where}.radius_m: got {radius:g} m; below the minimum {MIN_RADIUS_M:g} m for this "
            "vehicle class (TSI LOC&PAS 4.2.3.5.2)"
        )
    cant_mm = _number(f"{where}.cant_mm", segment.get("cant_mm", 0.0), "mm")
    if cant_mm < 0:
        raise DesignError(
            f"{where}.cant_mm: got {cant_mm:g} mm; the cant raises the outer rail, give it >= 0 "
            "and the curve's side with direction"
        )
    if 0 < cant_mm < 1.0:
        raise DesignError(
            f"{where}.cant_mm: got {cant_mm:g}; below 1 mm suggests metres given as "
            f"millimetres (cant_mm is in mm, e.g. 120.0; at most {MAX_CANT_M * 1000:.0f})"
        )
    if cant_mm > MAX_CANT_M * 1000.0:
        raise DesignError(
            f"{where}.cant_mm: got {cant_mm:g} mm; above the allowed maximum "
            f"{MAX_CANT_M * 1000:.0f} mm for standard gauge (TSI INF 4.2.4.2, EN 13803)"
        )
    direction = segment.get("direction")
    if direction not in ("left", "right"):
        raise DesignError(
            f"{where}.direction: got {direction!r}; allowed 'left' (centre on the left) or 'right'"
        )
    side = 1.0 if direction == "left" else -1.0
    # the outer rail is raised: right rail for a left-hand curve -> negative cross-level
    return length, side / radius, -side * cant_mm / 1000.0, gradient / 1000.0


def design_from_segments(segments: list[Mapping[str, Any]], source: str = "line") -> TrackDesign:
    """A :class:`TrackDesign` from segment tables (see the module docstring).

    Raises:
        DesignError: naming ``source``, the segment number, the key and the value.
    """
    if not isinstance(segments, list) or not segments:
        raise DesignError(f"{source}: needs a non-empty [[segments]] list")
    states: list[tuple[float, float, float, float] | None] = []
    lengths: list[float] = []
    for number, segment in enumerate(segments, start=1):
        where = f"{source}: segment {number}"
        if not isinstance(segment, Mapping):
            raise DesignError(f"{where}: must be a table")
        kind = segment.get("type")
        if kind not in _KEYS:
            raise DesignError(f"{where}.type: got {kind!r}; allowed {', '.join(sorted(_KEYS))}")
        unknown = sorted(set(segment) - _KEYS[kind])
        if unknown:
            if "cant_m" in unknown:
                raise DesignError(f"{where}: got cant_m; write the cant in millimetres as cant_mm")
            raise DesignError(
                f"{where}: unknown key(s) {unknown} for a {kind}; allowed {sorted(_KEYS[kind])}"
            )
        if kind == "transition":
            length = _length(where, segment)
            if number in (1, len(segments)):
                raise DesignError(
                    f"{where}: a transition ramps between its neighbours; it cannot be the "
                    f"{'first' if number == 1 else 'last'} segment"
                )
            states.append(None)
            lengths.append(length)
        else:
            state = _segment_state(where, segment)
            states.append(state)
            lengths.append(state[0])
        if sum(lengths) > MAX_LINE_LENGTH_M:
            raise DesignError(
                f"{where}: the line reaches {sum(lengths):g} m at its end; above the maximum "
                f"{MAX_LINE_LENGTH_M:g} m ({MAX_LINE_LENGTH_M / 1000:g} km: the longest run the "
                "[simulation] limits allow)"
            )
    for number in range(1, len(states)):
        if states[number] is None and states[number - 1] is None:
            raise DesignError(f"{source}: segments {number} and {number + 1} are both transitions")
    chainage: list[float] = []
    values: list[tuple[float, float, float]] = []
    start = 0.0
    for state, length in zip(states, lengths):
        if state is not None:  # transitions are the straight line between their neighbours
            chainage += [start, start + length]
            values += [state[1:], state[1:]]
        start += length
    kappa, cant, gradient = (np.array(column) for column in zip(*values))
    return TrackDesign(
        chainage_m=np.array(chainage),
        curvature_1_m=kappa,
        cant_m=cant,
        gradient=gradient,
        source=source,
    )


def load_line(path: str | Path) -> TrackDesign:
    """Read a line file (TOML) into a :class:`TrackDesign`.

    Raises:
        DesignError: missing file, bad TOML, or bad segments (message names the file).
    """
    file = Path(path)
    if not file.is_file():
        raise DesignError(f"file {str(file)!r} does not exist")
    try:
        data = read_toml(file)
    except TomlFileError as error:  # not UTF-8 text, or not valid TOML: names the file
        raise DesignError(str(error)) from None
    unknown = sorted(set(data) - {"line", "segments"})
    if unknown:
        raise DesignError(f"{file}: unknown table(s) {unknown}; allowed [line], [[segments]]")
    header = data.get("line", {})
    if not isinstance(header, Mapping):
        raise DesignError(f"{file}: line = {header!r}; expected a [line] table (name = ...)")
    extra = sorted(set(header) - {"name"})
    if extra:  # e.g. a segment key written under [line]: it would be silently ignored
        raise DesignError(
            f"{file}: [line]: unknown key(s) {extra}; allowed: name (the segments' keys go "
            "under [[segments]])"
        )
    if "name" in header and not isinstance(header["name"], str):
        raise DesignError(f"{file}: [line] name = {header['name']!r}; expected a string")
    return design_from_segments(data.get("segments", []), source=str(file))
