"""The linearised rig on a designed line: operating points along the curves.

The linear model of :mod:`susp_bo.rig.linear` is written about the static
equilibrium on tangent track. In a curve the vehicle sits at its quasi-static
curving state (:func:`~susp_bo.rig.curving.steady_state`): springs, creep and
series dampers are linear, so only the dead bands (lateral bump stops, flange)
see a different slope there. The dynamic part of the response on a line is
modelled as quasi-stationary: the run's recorded stretch is sampled every
``spacing_m`` of car chainage, the vehicle is linearised about the steady state
at each sample (dead bands at their slope there), and the expected PSD is the
time-weighted mean of the operating points' PSDs. On tangent stretches the
operating point is the tangent one (bit-for-bit the tangent-track model).

Where a curve pushes a dead band to its clearance (``|u| > gap − 3 smoothing``:
flange contact or a bump stop closing), small oscillations about the steady
state cross the nonlinearity and the linear model does not apply:
:class:`LinearModelNotApplicable` is raised naming the chainage, element and
deflection — use the PyBullet rig (:class:`~susp_bo.rig.simulator.Rig`) there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.assembly import Assembly
from susp_bo.rig.curving import design_inputs, steady_state
from susp_bo.rig.design import TrackDesign

FloatArray = NDArray[np.float64]
CONTACT_MARGIN = 3.0  # smoothing lengths below the gap counted as contact
BUCKET = 0.002  # operating points closer than this fraction of the dead-band stiffness merge


class LinearModelNotApplicable(ValueError):
    """The linearised model cannot represent this line (a dead band in contact in a curve)."""


@dataclass(frozen=True)
class OperatingPoint:
    """One quasi-static state along a line and its share of the record.

    Attributes:
        weight: fraction of the recorded stretch (sums to 1 over a line).
        dead_band_slopes: dead-band slopes there (m_dead,) N/m, None on tangent track.
        q: the steady state (n,) (deviations from the reference frames).
        dead_band_deflection: dead-band deflections there (m_dead,) m.
    """

    weight: float
    dead_band_slopes: FloatArray | None
    q: FloatArray
    dead_band_deflection: FloatArray


def _slopes(assembly: Assembly, u: FloatArray) -> FloatArray:
    dead = assembly.dead_bands
    plus = 1.0 / (1.0 + np.exp(np.clip(-(u - dead.gap) / dead.smoothing, -700, 700)))
    minus = 1.0 / (1.0 + np.exp(np.clip(-(-u - dead.gap) / dead.smoothing, -700, 700)))
    return dead.stiffness * (plus + minus)


def point_state(
    assembly: Assembly,
    design: TrackDesign,
    car_chainage_m: float,
    speed_m_s: float,
    sensors: tuple[object, ...] = (),
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Steady state at one car chainage: ``(q, dead-band deflections, sensor terms (C,))``.

    Args:
        assembly: the vehicle.
        design: the line.
        car_chainage_m: chainage of the car centre (m).
        speed_m_s: speed (m/s).
        sensors: sensor specs in channel order, for the sensor terms.
    """
    terms = design_inputs(
        assembly, design, np.array([car_chainage_m]), np.array([speed_m_s]), 1.0, sensors
    )
    if not (np.any(terms.offsets) or np.any(terms.loads)):
        zeros = np.zeros(assembly.dead_bands.group.size)
        return np.zeros(assembly.n_dofs), zeros, terms.sensors[0]
    q, u = steady_state(assembly, terms.offsets[0], terms.loads[0])
    return q, u, terms.sensors[0]


def operating_points(
    assembly: Assembly,
    design: TrackDesign,
    speed_m_s: float,
    start_m: float,
    end_m: float,
    spacing_m: float = 20.0,
) -> list[OperatingPoint]:
    """Operating points of the car chainages ``start_m … end_m`` (constant speed).

    Args:
        assembly: the vehicle.
        design: the line; must cover the car and its axles over the stretch.
        speed_m_s: speed (m/s).
        start_m, end_m: car-centre chainage of the first and last recorded sample (m).
        spacing_m: sampling of the stretch (m).

    Returns:
        Distinct operating points with their weights (tangent first when present).

    Raises:
        LinearModelNotApplicable: a dead band at or near contact somewhere on the stretch.
        DesignError: the design does not cover the stretch.
    """
    xs = [float(b.cg_m[0]) for b in assembly.bodies]
    design.check_covers(start_m + min(xs), end_m + max(xs), "the recorded stretch")
    count = max(2, int(np.ceil((end_m - start_m) / spacing_m)) + 1)
    dead = assembly.dead_bands
    limit = dead.gap - CONTACT_MARGIN * dead.smoothing
    chainages = np.linspace(start_m, end_m, count)
    terms = design_inputs(assembly, design, chainages, np.full(count, float(speed_m_s)), 1.0)
    curved = np.any(terms.offsets, axis=1) | np.any(terms.loads, axis=1)
    q = np.zeros((count, assembly.n_dofs))
    u = np.zeros((count, dead.group.size))
    if np.any(curved):
        q[curved], u[curved] = steady_state(assembly, terms.offsets[curved], terms.loads[curved])
    over = np.abs(u) > limit
    if np.any(over):
        k, i = np.argwhere(over)[0]
        raise LinearModelNotApplicable(
            f"linearised rig: at car chainage {chainages[k]:.1f} m the steady curving state "
            f"puts {dead.group.names[i]} at {u[k, i] * 1000:.1f} mm, at or beyond its clearance "
            f"({dead.gap[i] * 1000:.1f} mm less {CONTACT_MARGIN:g} smoothing lengths); the "
            "linear model does not apply in contact — use the PyBullet rig (Rig) for this line"
        )
    groups: dict[bytes, list] = {}
    for k in range(count):
        slopes = _slopes(assembly, u[k]) if curved[k] else None
        # buckets of 0.2 % of each dead band's full stiffness; a bucket's mean state is used
        key = (
            b"tangent"
            if slopes is None
            else np.round(slopes / (BUCKET * dead.stiffness)).astype(np.int64).tobytes()
        )
        groups.setdefault(key, []).append((slopes, q[k], u[k]))
    points = []
    for members in sorted(groups.values(), key=lambda m: m[0][0] is not None):
        slopes = None if members[0][0] is None else np.mean([m[0] for m in members], axis=0)
        points.append(
            OperatingPoint(
                len(members) / count,
                slopes,
                np.mean([m[1] for m in members], axis=0),
                np.mean([m[2] for m in members], axis=0),
            )
        )
    return points
