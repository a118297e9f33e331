"""Track design: curvature, cant and gradient against chainage (curves, transitions, grades).

The design is the line as built — tangents, clothoid transitions and circular
curves with their cant, and the vertical alignment (gradient) — on which the
measured irregularities (:class:`~susp_bo.rig.track.TrackGeometry`) are the
deviations. :class:`TrackDesign` holds it as *knots*: chainage ``s_k`` (m, the
same track coordinate as the geometry: ``s = 0`` is the first geometry sample)
and, at each knot, the curvature ``κ`` (1/m), the cant and the gradient;
between knots every quantity is linear in ``s``. This covers exactly the
classical elements: a tangent (κ = 0), a clothoid transition (κ and cant
linear in s) and a circular curve (constant κ and cant); a sampled design
record (measured runs) is piecewise linear between its samples as well. Two
knots at the same chainage make a step (a curve without transition).

Sign conventions (those of the geometry: x forward, y left, z up):

* ``curvature_1_m``: + for a left-hand curve (centre of the curve on the left, +y).
* ``cant_m``: superelevation as a signed cross-level, + when the left rail is
  higher; the cant of a left-hand curve raises the right (outer) rail, so it
  is negative there. The track-plane roll is ``θ = asin(cant / e0)`` with
  ``e0 = 1.5 m`` the distance between the rail centres (standard gauge).
* ``gradient``: rise over run (-), + uphill in the running direction.

With these, the specific force that a body following the track in a steady
curve feels along the track-plane lateral axis (+ left) is
``V² κ cos θ + g sin θ`` — for a left-hand curve ``V²/R − g·φ`` with
``φ = cant / e0``: the uncompensated (cant-deficiency) lateral acceleration.

Limits checked when a design is built (before any simulation):

* radius ``1/|κ|`` ≥ :data:`MIN_RADIUS_M` = 150 m: the smallest horizontal radius
  a TSI-compliant passenger vehicle must negotiate (TSI LOC&PAS, Reg. (EU)
  1302/2014, 4.2.3.5.2: "minimum curve radius of 150 m"); tighter curves are also
  outside the small-angle kinematics of this rig;
* ``|cant|`` ≤ :data:`MAX_CANT_M` = 0.180 m: the design-cant limit for standard
  gauge (TSI INF, Reg. (EU) 1299/2014, 4.2.4.2, and EN 13803: 180 mm);
* ``|gradient|`` ≤ :data:`MAX_GRADIENT` = 0.040 (40 ‰; TSI INF 4.2.3.3 allows up to
  35 ‰ on high-speed passenger lines);
* chainage within ``±``:data:`MAX_LINE_LENGTH_M` = 20 000 km: the longest run the
  simulation limits allow (200 m/s for 1e5 s); longer values are typos (``1e300``)
  that would overflow the design's integrals;
* unit slips are named: a cant above 1 m (a value in mm given as m), a
  curvature above 0.5 1/m (a radius given as a curvature), a gradient above 1
  (‰ or % given as a fraction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from susp_bo.rig._array_checks import as_finite_vector
from susp_bo.rig.spec_entries import SIMULATION_LIMITS

FloatArray = NDArray[np.float64]
GRAVITY_M_S2 = 9.81
RAIL_CENTRES_M = 1.5  # e0: distance between the rail centres, standard gauge (DESIGN.md)
MIN_RADIUS_M = 150.0
MAX_CANT_M = 0.180
MAX_GRADIENT = 0.040
MAX_LINE_LENGTH_M = (
    SIMULATION_LIMITS["speed_m_s"][1] * SIMULATION_LIMITS["duration_s"][1]
)  # 2e7 m: the longest run the [simulation] limits allow
DESIGN_COMPONENTS = ("curvature_1_m", "cant_m", "gradient")
DESIGN_UNITS = {"chainage_m": "m", "curvature_1_m": "1/m", "cant_m": "m", "gradient": "1"}


class DesignError(ValueError):
    """A track design that cannot be used (bad values, units, or not covering the run)."""


def _check_limits(where: str, chainage: FloatArray, values: dict[str, FloatArray]) -> None:
    """Raise DesignError at the first knot outside the physical limits or with a unit slip."""
    checks = (
        (
            "curvature_1_m",
            0.5,
            "looks like a radius in m, not a curvature in 1/m (curvature = 1 / radius)",
            1.0 / MIN_RADIUS_M,
            lambda v: (
                f"radius {1.0 / abs(v):.1f} m is below the minimum {MIN_RADIUS_M:g} m for "
                "this vehicle class (TSI LOC&PAS 4.2.3.5.2)"
            ),
        ),
        (
            "cant_m",
            1.0,
            "a cant above 1 m suggests millimetres given as metres (cant_m is in m)",
            MAX_CANT_M,
            lambda v: (
                f"cant {abs(v) * 1000:.0f} mm is above the allowed maximum "
                f"{MAX_CANT_M * 1000:.0f} mm for standard gauge (TSI INF 4.2.4.2, EN 13803)"
            ),
        ),
        (
            "gradient",
            1.0,
            "a gradient above 1 suggests per mille or percent given as a fraction "
            "(gradient is rise/run, e.g. 0.012 for 12 per mille)",
            MAX_GRADIENT,
            lambda v: (
                f"gradient {abs(v) * 1000:.1f} per mille is above the maximum "
                f"{MAX_GRADIENT * 1000:.0f} per mille (TSI INF 4.2.3.3)"
            ),
        ),
    )
    for name, unit_slip, slip_message, limit, limit_message in checks:
        magnitude = np.abs(values[name])
        for bound, message in ((unit_slip, lambda v, m=slip_message: m), (limit, limit_message)):
            bad = magnitude > bound * (1 + 1e-9)
            if np.any(bad):
                i = int(np.argmax(bad))
                raise DesignError(
                    f"{where}.{name}: got {values[name][i]:g} at chainage {chainage[i]:g} m; "
                    f"{message(values[name][i])}"
                )


@dataclass(frozen=True, eq=False)
class TrackDesign:
    """Curvature, cant and gradient against chainage, linear between knots.

    Args:
        chainage_m: knot chainages (K,) m, non-decreasing, K >= 2, last > first;
            two equal chainages make a step.
        curvature_1_m: curvature at the knots (K,) 1/m, + left-hand curve.
        cant_m: cant at the knots (K,) m, signed cross-level (+ left rail higher).
        gradient: gradient at the knots (K,), rise/run, + uphill.
        source: where the design came from (file name), used in messages.

    Raises:
        DesignError: shapes, order, non-finite values, limits or unit slips (see module).
    """

    chainage_m: FloatArray
    curvature_1_m: FloatArray
    cant_m: FloatArray
    gradient: FloatArray
    source: str = "design"
    _integrals: tuple[FloatArray, FloatArray, FloatArray] = field(
        init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        where = self.source
        try:
            chainage = as_finite_vector(f"{where}.chainage_m", self.chainage_m, min_length=2)
            values = {
                name: as_finite_vector(f"{where}.{name}", getattr(self, name), min_length=2)
                for name in DESIGN_COMPONENTS
            }
        except ValueError as error:
            raise DesignError(str(error)) from None
        for name, array in values.items():
            if array.size != chainage.size:
                raise DesignError(
                    f"{where}.{name}: has {array.size} values but chainage_m has {chainage.size}"
                )
        too_far = np.abs(chainage) > MAX_LINE_LENGTH_M
        if np.any(too_far):
            i = int(np.argmax(too_far))
            raise DesignError(
                f"{where}.chainage_m: got {chainage[i]:g} m at knot {i}; the design must lie "
                f"within ±{MAX_LINE_LENGTH_M:g} m (the longest run the [simulation] limits "
                "allow)"
            )
        steps = np.diff(chainage)
        if np.any(steps < 0):
            i = int(np.argmax(steps < 0))
            raise DesignError(
                f"{where}.chainage_m: must be non-decreasing; chainage_m[{i + 1}] = "
                f"{chainage[i + 1]:g} m < chainage_m[{i}] = {chainage[i]:g} m"
            )
        if not chainage[-1] > chainage[0]:
            raise DesignError(f"{where}.chainage_m: covers no length ({chainage[0]:g} m only)")
        _check_limits(where, chainage, values)
        object.__setattr__(self, "chainage_m", chainage)
        for name, array in values.items():
            object.__setattr__(self, name, array)
        object.__setattr__(self, "_integrals", self._knot_integrals())

    # --- evaluation -------------------------------------------------------------------
    @property
    def start_m(self) -> float:
        """First chainage covered (m)."""
        return float(self.chainage_m[0])

    @property
    def end_m(self) -> float:
        """Last chainage covered (m)."""
        return float(self.chainage_m[-1])

    def _knot_integrals(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Heading ∫κ, lateral ∫∫κ and height ∫gradient at the knots (exact, piecewise)."""
        length = np.diff(self.chainage_m)
        k0, k1 = self.curvature_1_m[:-1], self.curvature_1_m[1:]
        g0, g1 = self.gradient[:-1], self.gradient[1:]
        heading = np.concatenate([[0.0], np.cumsum(0.5 * (k0 + k1) * length)])
        lateral = np.concatenate(
            [[0.0], np.cumsum(heading[:-1] * length + (k0 / 3 + k1 / 6) * length**2)]
        )
        height = np.concatenate([[0.0], np.cumsum(0.5 * (g0 + g1) * length)])
        return heading, lateral, height

    def _locate(self, s: ArrayLike) -> tuple[NDArray[np.intp], FloatArray, FloatArray]:
        chainage = np.asarray(s, dtype=np.float64)
        tolerance = 1e-9 * max(1.0, abs(self.end_m))
        if np.any(chainage < self.start_m - tolerance) or np.any(chainage > self.end_m + tolerance):
            raise DesignError(
                f"{self.source}: chainage {float(np.min(chainage)):.3f} … "
                f"{float(np.max(chainage)):.3f} m is outside the design record "
                f"({self.start_m:g} … {self.end_m:g} m)"
            )
        index = np.clip(
            np.searchsorted(self.chainage_m, chainage, side="right") - 1,
            0,
            self.chainage_m.size - 2,
        )
        length = self.chainage_m[index + 1] - self.chainage_m[index]
        u = np.clip(chainage - self.chainage_m[index], 0.0, None)
        return index, u, length

    def _linear(self, values: FloatArray, s: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Value and slope d/ds of a knot quantity at chainages ``s`` (any shape)."""
        index, u, length = self._locate(s)
        safe = np.where(length > 0, length, 1.0)
        slope = np.where(length > 0, (values[index + 1] - values[index]) / safe, 0.0)
        return values[index] + slope * u, slope

    def curvature(self, s: ArrayLike) -> FloatArray:
        """Curvature κ(s) (1/m) at chainages ``s`` (m), same shape."""
        return self._linear(self.curvature_1_m, s)[0]

    def cant(self, s: ArrayLike) -> FloatArray:
        """Cant (m, signed cross-level) at chainages ``s``."""
        return self._linear(self.cant_m, s)[0]

    def roll_rad(self, s: ArrayLike) -> FloatArray:
        """Track-plane roll ``θ = asin(cant / e0)`` (rad, + left rail higher) at ``s``."""
        return np.arcsin(self.cant(s) / RAIL_CENTRES_M)

    def grade(self, s: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Gradient (-) and vertical curvature dG/ds (1/m, + sag) at chainages ``s``."""
        return self._linear(self.gradient, s)

    def heading_rad(self, s: ArrayLike) -> FloatArray:
        """Heading ``∫κ ds`` from the first knot (rad) at ``s``."""
        index, u, length = self._locate(s)
        heading = self._integrals[0]
        k0 = self.curvature_1_m[index]
        dk = np.where(
            length > 0,
            (self.curvature_1_m[index + 1] - k0) / np.where(length > 0, length, 1.0),
            0.0,
        )
        return heading[index] + k0 * u + 0.5 * dk * u**2

    def lateral_m(self, s: ArrayLike) -> FloatArray:
        """Small-angle lateral position ``∫∫κ`` of the centre line from the first knot (m)."""
        index, u, length = self._locate(s)
        heading, lateral, _ = self._integrals
        k0 = self.curvature_1_m[index]
        safe = np.where(length > 0, length, 1.0)
        dk = np.where(length > 0, (self.curvature_1_m[index + 1] - k0) / safe, 0.0)
        return lateral[index] + heading[index] * u + 0.5 * k0 * u**2 + dk * u**3 / 6.0

    def height_m(self, s: ArrayLike) -> FloatArray:
        """Height ``∫ gradient ds`` of the design profile from the first knot (m)."""
        index, u, length = self._locate(s)
        height = self._integrals[2]
        g0 = self.gradient[index]
        safe = np.where(length > 0, length, 1.0)
        dg = np.where(length > 0, (self.gradient[index + 1] - g0) / safe, 0.0)
        return height[index] + g0 * u + 0.5 * dg * u**2

    def check_covers(self, lowest_m: float, highest_m: float, what: str = "the run") -> None:
        """Raise DesignError unless the design covers chainages ``lowest_m … highest_m``."""
        tolerance = 1e-9 * max(1.0, abs(highest_m))
        if lowest_m < self.start_m - tolerance or highest_m > self.end_m + tolerance:
            raise DesignError(
                f"{self.source}: the design record covers {self.start_m:g} … {self.end_m:g} m but "
                f"{what} needs {lowest_m:.3f} … {highest_m:.3f} m; give a design that covers "
                "the whole run"
            )

    def is_tangent(self) -> bool:
        """True when the design is straight, level and uncanted everywhere."""
        return not (np.any(self.curvature_1_m) or np.any(self.cant_m) or np.any(self.gradient))

    def sampled(self, spacing_m: float, n_samples: int) -> TrackDesign:
        """The design sampled at ``s = 0, ds, …`` (the grid of a TrackGeometry), as knots."""
        s = np.arange(n_samples, dtype=np.float64) * spacing_m
        return TrackDesign(
            chainage_m=s,
            curvature_1_m=self.curvature(s),
            cant_m=self.cant(s),
            gradient=self.grade(s)[0],
            source=self.source,
        )


def design_specific_force(
    design: TrackDesign, chainage_m: ArrayLike, speed_m_s: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Quasi-static specific force of a point following the design (vehicle-independent).

    Lateral (+ left, track-plane axis) ``V² κ cos θ + g sin θ``; vertical change
    from ``g`` (+ up) ``g (cos θ cos α − 1) − V² κ sin θ + V² dG/ds`` with
    ``α = atan G``. (A sensor reads this plus the terms of its body's reference
    frame and the vehicle's own response, see :mod:`susp_bo.rig.curving`.)

    Args:
        design: the line.
        chainage_m: chainages of the point (any shape) m.
        speed_m_s: speeds, broadcastable to ``chainage_m`` (m/s).

    Returns:
        ``(lateral, vertical)`` in m/s², shaped like ``chainage_m``.
    """
    v2 = np.asarray(speed_m_s, dtype=np.float64) ** 2
    kappa = design.curvature(chainage_m)
    theta = design.roll_rad(chainage_m)
    gradient, vertical_curvature = design.grade(chainage_m)
    lateral = v2 * kappa * np.cos(theta) + GRAVITY_M_S2 * np.sin(theta)
    vertical = (
        GRAVITY_M_S2 * (np.cos(theta) * np.cos(np.arctan(gradient)) - 1.0)
        - v2 * kappa * np.sin(theta)
        + v2 * vertical_curvature
    )
    return lateral, vertical


def cant_deficiency_m(radius_m: float, speed_m_s: float, cant_m: float) -> float:
    """Cant deficiency ``e0 V² / (g R) − cant`` (m) of a steady curve (cant >= 0, outer rail)."""
    return RAIL_CENTRES_M * speed_m_s**2 / (GRAVITY_M_S2 * radius_m) - cant_m


def balancing_cant_m(radius_m: float, speed_m_s: float) -> float:
    """The cant (m) that makes ``V²/R − g sin θ`` vanish: ``e0 V² / (g R)`` (small angles)."""
    return RAIL_CENTRES_M * math.sin(math.atan(speed_m_s**2 / (GRAVITY_M_S2 * radius_m)))
