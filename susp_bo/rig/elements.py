"""Force elements of the suspension, vectorised over all elements of a kind.

Every element is a scalar force law acting along one *element coordinate*

    u = G q + H x(t),      u̇ = G q̇ + H ẋ(t),

with ``q`` (n) the generalised coordinates of the vehicle, ``x`` (n_in) the
track inputs at the axles, ``G`` (m x n) and ``H`` (m x n_in) the (small-angle)
kinematic rows of the m elements of a group. The element force ``f`` (m,) is
tension-positive along ``u`` and its generalised force on the vehicle is
``Q = -Gᵀ f``. The same groups feed the PyBullet world (force laws evaluated each
step) and the linearised model (slopes at the static equilibrium ``u = u̇ = 0``),
so the frequency-domain cross-check checks the time integration, not a second
hand-written model.

Kinds: linear springs, bilinear dampers (a knee velocity after which the slope
drops to ``slope_ratio`` × the initial one: blow-off), smoothed dead-band springs
(bump stops, flange contact) and series spring–damper elements (yaw dampers)
whose damper stroke is an internal state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def bilinear_force(
    velocity: FloatArray, damping: FloatArray, slope_ratio: FloatArray, knee: FloatArray
) -> FloatArray:
    """Force of bilinear dampers (N) at velocities (m/s), elementwise.

    ``f = c v`` for ``|v| <= knee``, then slope ``slope_ratio · c`` beyond the knee.
    """
    speed = np.abs(velocity)
    return (
        np.sign(velocity)
        * damping
        * (np.minimum(speed, knee) + slope_ratio * np.maximum(speed - knee, 0.0))
    )


def bilinear_velocity(
    force: FloatArray, damping: FloatArray, slope_ratio: FloatArray, knee: FloatArray
) -> FloatArray:
    """Inverse of :func:`bilinear_force`: the damper velocity (m/s) carrying ``force`` (N).

    Requires ``damping > 0`` and ``slope_ratio > 0``.
    """
    reduced = np.abs(force) / damping
    return np.sign(force) * (
        np.minimum(reduced, knee) + np.maximum(reduced - knee, 0.0) / slope_ratio
    )


def dead_band_force(
    displacement: FloatArray, stiffness: FloatArray, gap: FloatArray, smoothing: FloatArray
) -> FloatArray:
    """Smoothed dead-band spring (N): ≈0 inside ``|u| < gap``, slope ``k`` beyond it.

    ``f = k s (softplus((u - gap)/s) - softplus((-u - gap)/s))`` with smoothing length ``s``.
    """
    return (
        stiffness
        * smoothing
        * (
            np.logaddexp(0.0, (displacement - gap) / smoothing)
            - np.logaddexp(0.0, (-displacement - gap) / smoothing)
        )
    )


def dead_band_slope(stiffness: FloatArray, gap: FloatArray, smoothing: FloatArray) -> FloatArray:
    """d f / d u of :func:`dead_band_force` at ``u = 0`` (N/m): ``2 k σ(-gap/s)``."""
    return 2.0 * stiffness / (1.0 + np.exp(gap / smoothing))


@dataclass(frozen=True)
class ElementGroup:
    """Kinematics of m scalar elements: names (m,), G (m x n), H (m x n_in)."""

    names: tuple[str, ...]
    coordinates: FloatArray
    inputs: FloatArray

    def __post_init__(self) -> None:
        g = np.asarray(self.coordinates, dtype=np.float64)
        h = np.asarray(self.inputs, dtype=np.float64)
        if g.ndim != 2 or h.ndim != 2 or g.shape[0] != len(self.names) or h.shape[0] != g.shape[0]:
            raise ValueError(
                f"ElementGroup: G {g.shape} and H {h.shape} need one row per element "
                f"({len(self.names)})"
            )
        object.__setattr__(self, "coordinates", g)
        object.__setattr__(self, "inputs", h)

    @property
    def size(self) -> int:
        """Number of elements m."""
        return len(self.names)


@dataclass(frozen=True)
class Springs:
    """Linear springs: ``f = k u`` (k in N/m or N·m/rad)."""

    group: ElementGroup
    stiffness: FloatArray

    def force(self, u: FloatArray) -> FloatArray:
        """Element forces (m,) for element coordinates ``u`` (m,)."""
        return self.stiffness * u

    def slope(self) -> FloatArray:
        """Linearised stiffness per element (m,)."""
        return self.stiffness


@dataclass(frozen=True)
class Dampers:
    """Bilinear dampers: initial slope ``damping`` (N·s/m), ``slope_ratio`` after ``knee`` m/s."""

    group: ElementGroup
    damping: FloatArray
    slope_ratio: FloatArray
    knee: FloatArray

    def force(self, v: FloatArray) -> FloatArray:
        """Element forces (m,) for element velocities ``v`` (m,)."""
        return bilinear_force(v, self.damping, self.slope_ratio, self.knee)

    def slope(self) -> FloatArray:
        """Linearised damping per element (m,): the initial slope."""
        return self.damping


@dataclass(frozen=True)
class DeadBands:
    """Smoothed dead-band springs (bump stops): stiffness N/m beyond ``gap`` m."""

    group: ElementGroup
    stiffness: FloatArray
    gap: FloatArray
    smoothing: FloatArray

    def force(self, u: FloatArray) -> FloatArray:
        """Element forces (m,) for element coordinates ``u`` (m,)."""
        return dead_band_force(u, self.stiffness, self.gap, self.smoothing)

    def slope(self) -> FloatArray:
        """Linearised stiffness at u = 0 per element (m,)."""
        return dead_band_slope(self.stiffness, self.gap, self.smoothing)


@dataclass(frozen=True)
class SeriesDampers:
    """Spring ``stiffness`` (N/m) in series with a bilinear damper; state = damper stroke ``s``.

    Force ``f = k (u - s)``; the stroke moves at the damper velocity carrying ``f``:
    ``ṡ = bilinear_velocity(f)``. Its relaxation rate ``k / (slope_ratio c)`` is slow
    compared with the step, so the stiff damper no longer limits an explicit step.
    """

    group: ElementGroup
    stiffness: FloatArray
    damping: FloatArray
    slope_ratio: FloatArray
    knee: FloatArray

    def force(self, u: FloatArray, stroke: FloatArray) -> FloatArray:
        """Element forces (m,) for coordinates ``u`` and damper strokes ``stroke`` (m,)."""
        return self.stiffness * (u - stroke)

    def stroke_rate(self, force: FloatArray) -> FloatArray:
        """Damper stroke velocity (m/s) under element force ``force`` (N)."""
        return bilinear_velocity(force, self.damping, self.slope_ratio, self.knee)


def linearised(elements: Dampers | DeadBands) -> Springs | Dampers:
    """The element group with its force law replaced by the slope at the origin."""
    if isinstance(elements, Dampers):
        return Dampers(
            elements.group,
            elements.damping,
            np.ones_like(elements.damping),
            np.full_like(elements.damping, np.inf),
        )
    return Springs(elements.group, elements.slope())
