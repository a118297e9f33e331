"""The entries of a rig spec (:mod:`susp_bo.rig.spec`): the calibrated parameters and
their admissible and acceptable intervals, the sensors, the simulation defaults, and the
sign rules every named parameter obeys. Each checks itself when built, naming the entry,
the value and what is allowed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

SENSOR_DIRECTIONS = ("vertical", "lateral")
TRACK_QUALITIES = ("low", "high")
# Parameter-name fragments and the sign they require (first match wins).
_POSITIVE_WORDS = ("mass", "inertia", "radius", "coefficient", "spacing", "wheelbase", "height")
_NON_NEGATIVE_WORDS = ("stiffness", "damping", "knee", "ratio", "gap", "smoothing", "conicity")


def require_number(where: str, value: object) -> float:
    """``value`` as a float; ValueError naming ``where`` unless it is an int or a float."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{where}: got {value!r}; must be a number")
    return float(value)


def parameter_value_rule(name: str, value: float) -> str | None:
    """The sign rule ``value`` breaks for a parameter called ``name``, or None when it is
    admissible: e.g. ``"must be >= 0 (a damping cannot be negative)"``.

    Rules by meaning: finite always; names containing mass, inertia, radius,
    coefficient, spacing, wheelbase or height (above the rail top) must be > 0;
    stiffness, damping, knee, ratio, gap, smoothing or conicity must be >= 0. A per-component name
    ``<parameter>@<component>`` follows the rule of its ``<parameter>``.
    """
    if not math.isfinite(value):
        return "must be finite"
    meaning = name.split("@", 1)[0]
    for word in _POSITIVE_WORDS:  # first match wins
        if word in meaning:
            return None if value > 0.0 else f"must be > 0 (a {word} is positive)"
    for word in _NON_NEGATIVE_WORDS:
        if word in meaning:
            return None if value >= 0.0 else f"must be >= 0 (a {word} cannot be negative)"
    return None


def check_parameter_value(name: str, value: float) -> None:
    """Raise ValueError unless ``value`` is admissible for a parameter called ``name``
    (the sign rules of :func:`parameter_value_rule`)."""
    rule = parameter_value_rule(name, value)
    if rule is not None:
        raise ValueError(f"parameter {name}: got {value}; {rule}")


@dataclass(frozen=True)
class CalibrationParameter:
    """One component of the calibrated parameter ``w`` and its admissible interval.

    Args:
        name: a named rig parameter, e.g. ``primary_vertical_stiffness``.
        lower: lower bound of the admissible interval (physical unit).
        upper: upper bound, > lower.
        reference: nominal value, within [lower, upper].
        unit: physical unit, e.g. ``N/m``.
        description: one line for engineers.
        acceptable: maintenance limits ``(lo, hi)`` in the same unit, strictly
            inside ``(lower, upper)`` (the admissible interval must be wider, so
            that a posterior can leave the acceptable domain); None = no limits.
            Not part of the rig fingerprint: the limits change no simulation,
            so evaluation stores stay valid when they are edited.
    """

    name: str
    lower: float
    upper: float
    reference: float
    unit: str = ""
    description: str = ""
    acceptable: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        where = f"calibration parameter {self.name}"  # no class name in a user's message
        for key in ("lower", "upper", "reference"):
            number = require_number(f"{where}.{key}", getattr(self, key))
            if not math.isfinite(number):
                raise ValueError(f"{where}.{key}: got {number}; must be finite")
            object.__setattr__(self, key, number)
        if not self.lower < self.upper:
            raise ValueError(f"{where}: lower {self.lower} must be < upper {self.upper}")
        for key in ("lower", "upper"):  # C_w holds only values the simulator may be given
            try:
                check_parameter_value(self.name, getattr(self, key))
            except ValueError as error:
                raise ValueError(
                    f"{where}.{key}: {error} (C_w may only hold physical values)"
                ) from None
        if not self.lower <= self.reference <= self.upper:
            raise ValueError(
                f"{where}.reference: got {self.reference}; must lie in [{self.lower}, {self.upper}]"
            )
        if self.acceptable is not None:
            object.__setattr__(self, "acceptable", self._checked_acceptable(where))

    def _checked_acceptable(self, where: str) -> tuple[float, float]:
        value = self.acceptable
        unit = f" {self.unit}" if self.unit else ""
        if (
            isinstance(value, str | bytes) or not hasattr(value, "__len__") or len(value) != 2  # type: ignore[arg-type]
        ):
            raise ValueError(
                f"{where}.acceptable: got {value!r}; expected [lo, hi] (two numbers{unit})"
            )
        lo, hi = (require_number(f"{where}.acceptable", v) for v in value)  # type: ignore[union-attr]
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise ValueError(f"{where}.acceptable: got [{lo}, {hi}]; must be finite")
        if not lo < hi:
            raise ValueError(f"{where}.acceptable: got [{lo}, {hi}]{unit}; lo must be < hi")
        if not self.lower < lo or not hi < self.upper:
            raise ValueError(
                f"{where}.acceptable: got [{lo}, {hi}]{unit}; must lie strictly inside the "
                f"admissible interval ({self.lower}, {self.upper}){unit} — C_w must be wider "
                "than the acceptable domain so that a posterior can leave it"
            )
        return (lo, hi)

    def outside_acceptable(self, values: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Which ``values`` (any shape, physical unit) lie outside the acceptable domain.

        Raises:
            ValueError: the parameter has no acceptable domain.
        """
        if self.acceptable is None:
            raise ValueError(f"calibration parameter {self.name}: no acceptable domain")
        lo, hi = self.acceptable
        values = np.asarray(values, dtype=np.float64)
        return (values < lo) | (values > hi)


@dataclass(frozen=True)
class SensorSpec:
    """An accelerometer: a named point on a body measuring along one body axis.

    Args:
        name: channel name, e.g. ``carbody_front_vertical``.
        body: body name (``carbody``, ``bogie_front``, ``bogie_rear``).
        position_m: (x, y, z) in vehicle coordinates (x from the car centre, + forward;
            z above the rail top), m.
        direction: ``vertical`` or ``lateral`` (body axes z or y).
    """

    name: str
    body: str
    position_m: tuple[float, float, float]
    direction: str

    def __post_init__(self) -> None:
        if self.direction not in SENSOR_DIRECTIONS:
            raise ValueError(
                f"sensor {self.name!r}.direction: got {self.direction!r}; allowed "
                f"{', '.join(SENSOR_DIRECTIONS)}"
            )
        where = f"sensor {self.name!r}.position_m"
        position = tuple(require_number(where, v) for v in self.position_m)
        if len(position) != 3 or not all(math.isfinite(v) for v in position):
            raise ValueError(
                f"sensor {self.name!r}.position_m: got {self.position_m!r}; need 3 finite numbers"
            )
        object.__setattr__(self, "position_m", position)


SIMULATION_LIMITS: dict[str, tuple[float, float, str]] = {
    "time_step_s": (0.0, 0.01, "s"),
    "speed_m_s": (0.0, 200.0, "m/s"),
    "duration_s": (0.0, 1e5, "s"),
    "sample_rate_hz": (0.0, 1e5, "Hz"),
    "max_displacement_m": (0.0, 10.0, "m"),
}
"""Allowed range (low, high] and unit of each numeric ``[simulation]`` setting."""


@dataclass(frozen=True)
class SimulationSettings:
    """Defaults of a time-domain run.

    Args:
        time_step_s: fixed PyBullet step (s), in (0, 0.01].
        speed_m_s: default train speed (m/s), > 0.
        duration_s: recorded time after the warm-up (s), > 0.
        warm_up_s: discarded initial transient (s), >= 0.
        sample_rate_hz: rate of the output signals (Hz); ``1/time_step_s`` must be
            an integer multiple of it.
        track_quality: ``low`` or ``high`` (German PSD) for synthetic tracks.
        max_displacement_m: divergence threshold on any body displacement (m) or
            rotation (rad); exceeding it raises SimulationFailed.
    """

    time_step_s: float = 0.002
    speed_m_s: float = 83.33
    duration_s: float = 30.0
    warm_up_s: float = 5.0
    sample_rate_hz: float = 100.0
    track_quality: str = "low"
    max_displacement_m: float = 0.2

    def __post_init__(self) -> None:
        for key, (low, high, unit) in SIMULATION_LIMITS.items():
            value = require_number(f"[simulation] {key}", getattr(self, key))
            if not (math.isfinite(value) and low < value <= high):
                raise ValueError(
                    f"[simulation] {key}: got {value:g}; allowed range ({low:g}, {high:g}] {unit}"
                )
            object.__setattr__(self, key, value)
        warm = require_number("[simulation] warm_up_s", self.warm_up_s)
        if not (math.isfinite(warm) and warm >= 0.0):
            raise ValueError(f"[simulation] warm_up_s: got {warm}; must be >= 0")
        object.__setattr__(self, "warm_up_s", warm)
        if self.track_quality not in TRACK_QUALITIES:
            raise ValueError(
                f"[simulation] track_quality: got {self.track_quality!r}; allowed "
                f"{', '.join(TRACK_QUALITIES)}"
            )
        ratio = 1.0 / (self.time_step_s * self.sample_rate_hz)
        if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
            raise ValueError(
                f"[simulation] sample_rate_hz: got {self.sample_rate_hz} Hz; "
                f"1/time_step_s = {1.0 / self.time_step_s} Hz must be an integer multiple of it"
            )

    @property
    def steps_per_sample(self) -> int:
        """PyBullet steps per output sample."""
        return round(1.0 / (self.time_step_s * self.sample_rate_hz))
