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

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.assembly import Assembly, build_assembly
from susp_bo.rig.curving import DesignInputs, design_inputs, steady_state
from susp_bo.rig.design import TrackDesign
from susp_bo.rig.elements import ElementGroup
from susp_bo.rig.spec import RigSpec, SensorSpec
from susp_bo.rig.spectra import SpectrumSettings, welch_psd
from susp_bo.rig.state_space import StateSpace

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
    sensors: Sequence[SensorSpec] = (),
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


def design_forcing(
    assembly: Assembly,
    system: StateSpace,
    terms: DesignInputs,
    dead_band_slopes: FloatArray | None = None,
) -> FloatArray:
    """The design's forcing ``F(t)`` of the state equation ``ż = A z + B x + F`` (T x size).

    Every element sees ``G (q + d) + H (x + x_d)`` (see :mod:`susp_bo.rig.curving`):
    springs and dead bands (at ``dead_band_slopes``, default their slope at 0), dampers
    on the offset rates, series elements on their spring and stroke; plus the loads.

    Args:
        assembly: the vehicle.
        system: its :class:`~susp_bo.rig.state_space.StateSpace` (same slopes).
        terms: the :class:`~susp_bo.rig.curving.DesignInputs` at the T instants.
        dead_band_slopes: the dead-band slopes the system was built with.
    """
    n = assembly.n_dofs

    def rows(group: ElementGroup) -> FloatArray:
        return np.hstack([group.coordinates, group.inputs])

    springs, dead, dampers, series = (
        assembly.springs,
        assembly.dead_bands,
        assembly.dampers,
        assembly.series,
    )
    slopes = dead.slope() if dead_band_slopes is None else dead_band_slopes
    g_k, g_d, g_c, g_s = (
        rows(springs.group),
        rows(dead.group),
        rows(dampers.group),
        rows(series.group),
    )
    stiffness = g_k[:, :n].T @ (springs.stiffness[:, None] * g_k)
    stiffness += g_d[:, :n].T @ (slopes[:, None] * g_d)
    stiffness += g_s[:, :n].T @ (series.stiffness[:, None] * g_s)
    damping = g_c[:, :n].T @ (dampers.slope()[:, None] * g_c)
    offsets, rates = terms.offsets, terms.rates
    force = terms.loads - offsets @ stiffness.T - rates @ damping.T
    size = system.a.shape[0]
    out = np.zeros((offsets.shape[0], size))
    out[:, n : 2 * n] = force / assembly.mass_diagonal
    out[:, 2 * n :] = (offsets @ g_s.T) * (series.stiffness / series.damping)
    return out


def design_signals(
    assembly: Assembly,
    system: StateSpace,
    design: TrackDesign,
    speed_m_s: float,
    sample_rate_hz: float,
    n_samples: int,
    sensors: Sequence[SensorSpec],
    dead_band_slopes: FloatArray | None = None,
    time_step_s: float | None = None,
) -> FloatArray:
    """The linear vehicle's response to the design, minus its removed part, (C x n_samples).

    The deterministic part of the sensors on a designed line — the quasi-static
    roll-out and offsets plus the transients at the transitions — that remains
    after :func:`~susp_bo.rig.curving.reference_specific_force` is removed: the
    state is the quasi-static ``z_qs = −A⁻¹ F(t)`` plus the dynamic deviation
    ``ż_dyn = A z_dyn − ż_qs`` from rest at t = 0 (the rig starts in the steady
    state), solved by FFT with zero padding. Sensors as in the time-domain rig:
    mean acceleration over each sample interval plus the averaged gravity pick-up,
    samples at the interval centres ``(k + 1/2) / fs``, the car's rearmost axle at
    chainage 0 at t = 0, constant speed.

    Args:
        assembly: the vehicle.
        system: its :class:`~susp_bo.rig.state_space.StateSpace`.
        design: the line.
        speed_m_s: constant speed (m/s).
        sample_rate_hz: output rate (Hz).
        n_samples: output samples (from t = 0).
        sensors: sensor specs in channel order.
        dead_band_slopes: the dead-band slopes the system was built with.
        time_step_s: step of the forcing (s), a divisor of ``1 / sample_rate_hz`` (the
            transition ends are kinks: a fine step resolves their transients); default
            the sample interval.
    """
    interval = 1.0 / sample_rate_hz
    per_sample = 1 if time_step_s is None else max(1, round(interval / time_step_s))
    dt = interval / per_sample
    times = np.arange(n_samples * per_sample + 1) * dt
    car = -float(np.min(assembly.axle_positions_m)) + speed_m_s * times
    terms = design_inputs(assembly, design, car, np.full(times.size, speed_m_s), dt, sensors)
    forcing = design_forcing(assembly, system, terms, dead_band_slopes)
    a = system.a
    quasi_static = -np.linalg.solve(a, forcing.T)  # (size x T)
    drive = -np.gradient(quasi_static, dt, axis=1)  # −ż_qs, nonzero in transitions only
    padded = 2 * times.size
    spectrum = np.fft.rfft(drive, n=padded, axis=1)
    omega = 2.0 * np.pi * np.fft.rfftfreq(padded, dt)
    values, vectors = np.linalg.eig(a)
    modal = np.linalg.solve(vectors, spectrum) / (1j * omega[None, :] - values[:, None])
    dynamic = np.fft.irfft(vectors @ modal, n=padded, axis=1)[:, : times.size]
    state = (quasi_static + dynamic)[:, ::per_sample]  # at the sample-interval ends
    n = assembly.n_dofs
    velocity = assembly.sensor_acceleration @ state[n : 2 * n]  # (C x n_samples + 1)
    position = assembly.sensor_displacement @ state[:n]
    return np.diff(velocity, axis=1) / interval + 0.5 * (position[:, 1:] + position[:, :-1])


def steady_curving_state(
    assembly: Assembly,
    sensors: Sequence[SensorSpec],
    radius_m: float,
    cant_m: float,
    speed_m_s: float,
    direction: str = "left",
) -> dict[str, dict[str, float]]:
    """Quasi-static state in a steady curve (see :meth:`LinearisedRig.steady_curving`).

    Returns:
        ``q`` by coordinate name, ``sensors`` (m/s², specific force in the body frame:
        design term plus gravity pick-up of the body roll) by channel, ``dead_bands``
        deflections (m) by element name.
    """
    from susp_bo.rig.line_file import design_from_segments

    length = 4.0 * float(np.ptp(assembly.axle_positions_m)) + 10.0
    design = design_from_segments(
        [
            {
                "type": "curve",
                "length_m": length,
                "radius_m": radius_m,
                "cant_mm": cant_m * 1000.0,
                "direction": direction,
            }
        ],
        source="steady_curving",
    )
    q, u, terms = point_state(assembly, design, 0.5 * length, speed_m_s, sensors)
    readings = assembly.sensor_displacement @ q + terms
    return {
        "q": dict(zip(assembly.dof_names, q.tolist())),
        "sensors": dict(zip(assembly.channels, readings.tolist())),
        "dead_bands": dict(zip(assembly.dead_bands.group.names, u.tolist())),
    }


class CurvedLineMethods:
    """The design-related methods of :class:`~susp_bo.rig.linear.LinearisedRig`.

    Kept here, with the rest of the curved-line model; they use the rig's ``spec``
    and ``_system(parameters, speed, dead_band_slopes)``.
    """

    spec: RigSpec

    def _system(
        self,
        parameters: Mapping[str, float] | None,
        speed_m_s: float,
        dead_band_slopes: FloatArray | None = None,
    ) -> StateSpace:
        raise NotImplementedError  # pragma: no cover - provided by LinearisedRig

    def operating_points(
        self,
        design: TrackDesign,
        parameters: Mapping[str, float] | None = None,
        speed_m_s: float | None = None,
    ) -> list[OperatingPoint]:
        """Steady curving states along the recorded stretch of a default run on ``design``.

        The car runs at constant speed with its rearmost axle at chainage 0 at t = 0;
        the recorded stretch follows the warm-up (the rig's simulation settings).

        Raises:
            LinearModelNotApplicable: a curve puts a flange or bump stop into contact.
            DesignError: the design does not cover the run.
        """
        sim = self.spec.simulation
        speed = sim.speed_m_s if speed_m_s is None else float(speed_m_s)
        assembly = build_assembly(self.spec.with_parameters(parameters))
        start = -float(np.min(assembly.axle_positions_m))
        return operating_points(
            assembly,
            design,
            speed,
            start + speed * sim.warm_up_s,
            start + speed * (sim.warm_up_s + sim.duration_s),
        )

    def steady_curving(
        self,
        radius_m: float,
        cant_m: float,
        parameters: Mapping[str, float] | None = None,
        speed_m_s: float | None = None,
        direction: str = "left",
    ) -> dict[str, object]:
        """Quasi-static state of the vehicle in a steady curve (nonlinear dead bands).

        Args:
            radius_m: curve radius (m), >= 150.
            cant_m: cant on the outer rail (m), 0 … 0.18.
            parameters: named parameter values (default: the rig's).
            speed_m_s: speed (default: the rig's).
            direction: ``left`` or ``right``.

        Returns:
            ``q`` (n,) coordinates (deviations from the reference frames, by name),
            ``sensors`` (C,) quasi-static readings in m/s² (specific force in the body
            frame: design term plus gravity pick-up of the body roll),
            ``dead_bands`` (m_dead,) deflections in m, by name.
        """
        speed = self.spec.simulation.speed_m_s if speed_m_s is None else float(speed_m_s)
        if not (math.isfinite(speed) and speed >= 0.0):  # NaN/inf ended in a Newton failure
            raise ValueError(
                f"speed_m_s: got {speed_m_s!r}; expected a finite speed >= 0 m/s (0: standing "
                "in the curve)"
            )
        spec = self.spec.with_parameters(parameters)
        return steady_curving_state(
            build_assembly(spec), spec.sensors, radius_m, cant_m, speed, direction
        )

    def design_welch(
        self,
        design: TrackDesign,
        parameters: Mapping[str, float] | None = None,
        speed_m_s: float | None = None,
        settings: SpectrumSettings | None = None,
        time_step_s: float = 0.005,
    ) -> FloatArray:
        """Welch PSD (K x C) of the deterministic part the design leaves in the signals.

        The vehicle's response to the design of a default run (rearmost axle at
        chainage 0 at t = 0, the rig's warm-up and duration), minus the removed
        reference specific force (:func:`~susp_bo.rig.linear_curving.design_signals`),
        linearised about the run's main operating point; Welch-estimated over the
        recorded part exactly as the signals are (same segments, window and
        detrending). Being deterministic, it adds to the expected PSD of the random
        part. Bins ``k / segment_s`` (K = segment_s fs / 2 + 1).
        """
        settings = self.spec.spectrum if settings is None else settings
        sim = self.spec.simulation
        speed = sim.speed_m_s if speed_m_s is None else float(speed_m_s)
        points = self.operating_points(design, parameters, speed)
        main = max(points, key=lambda point: point.weight)
        system = self._system(parameters, speed, main.dead_band_slopes)
        rate = sim.sample_rate_hz
        signals = design_signals(
            system.assembly,
            system,
            design,
            speed,
            rate,
            round((sim.warm_up_s + sim.duration_s) * rate),
            self.spec.with_parameters(parameters).sensors,
            main.dead_band_slopes,
            time_step_s,
        )[:, round(sim.warm_up_s * rate) :]
        return welch_psd(signals, rate, settings).T
