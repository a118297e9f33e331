"""Track irregularities: German high-speed PSDs, synthetic geometry, speed, axle inputs.

The rig is excited by the track geometry, sampled in space (``s`` in m along
the track), seen by every axle at its own position along the train. This module
holds the four pieces between a track spectrum and the wheel inputs:

* :class:`TrackPSD` — the German high-speed irregularity spectra (low / high
  disturbance), ``S(Ω)`` one-sided in wavenumber ``Ω`` (rad/m), i.e. the
  variance of the profile over a band is ``∫ S(Ω) dΩ`` over that band (Ω > 0).
* :class:`TrackGeometry` — vertical profile, alignment, cross-level, gauge on a
  regular grid ``s = 0, ds, 2 ds, …``; :meth:`TrackGeometry.synthetic` draws a
  realization by the spectral representation (deterministic amplitudes
  ``sqrt(2 S(Ω_k) ΔΩ)``, independent uniform phases) over a wavelength band.
* :class:`SpeedProfile` — the train speed against time (constant or variable,
  piecewise linear), with the travelled distance.
* :func:`axle_excitation` — the geometry under each axle against time, with
  rates (time derivatives) taken analytically from the interpolant.

Sign conventions (x forward, y left, z up): vertical is the mean of the two
rails, + up; alignment the mean lateral rail position, + left; cross-level the
roll angle of the rail plane, + when the left rail is higher; gauge the
deviation from nominal, + wider.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline

from susp_bo.rig._array_checks import as_finite_vector, require_positive

FloatArray = NDArray[np.float64]
TrackQuality = Literal["low", "high"]

# German high-speed track spectra (DESIGN.md), Ω in rad/m.
CUTOFF_WAVENUMBER = 0.8246  # Ω_c, rad/m
LOW_WAVENUMBER = 0.0206  # Ω_r, rad/m
CROSS_LEVEL_WAVENUMBER = 0.438  # Ω_s, rad/m
HALF_GAUGE_M = 0.75  # b, m (half the distance between the rail contact points)
_ROUGHNESS: dict[str, dict[str, float]] = {
    # A_v (vertical, m·rad), A_a (alignment, m·rad), A_g (gauge, m·rad)
    "low": {"vertical": 4.032e-7, "alignment": 2.119e-7, "gauge": 5.32e-8},
    "high": {"vertical": 1.08e-6, "alignment": 6.125e-7, "gauge": 1.032e-7},
}
GEOMETRY_COMPONENTS = ("vertical_m", "alignment_m", "cross_level_rad", "gauge_m")


@dataclass(frozen=True)
class TrackPSD:
    """German high-speed track irregularity spectra, one-sided in wavenumber.

    With ``Ω`` the wavenumber (rad/m), ``Ω_c = 0.8246``, ``Ω_r = 0.0206``,
    ``Ω_s = 0.438`` rad/m and ``b = 0.75`` m:

    * vertical:    ``A_v Ω_c² / ((Ω² + Ω_r²)(Ω² + Ω_c²))``            m²/(rad/m)
    * alignment:   ``A_a Ω_c² / ((Ω² + Ω_r²)(Ω² + Ω_c²))``            m²/(rad/m)
    * cross-level: ``A_v b⁻² Ω_c² Ω² / ((Ω²+Ω_r²)(Ω²+Ω_c²)(Ω²+Ω_s²))`` rad²/(rad/m)
    * gauge:       ``A_g Ω_c² Ω² / ((Ω²+Ω_r²)(Ω²+Ω_c²)(Ω²+Ω_s²))``    m²/(rad/m)

    Args:
        quality: ``"low"`` (low disturbance, good track) or ``"high"``.
    """

    quality: TrackQuality = "low"

    def __post_init__(self) -> None:
        if self.quality not in _ROUGHNESS:
            raise ValueError(
                f"TrackPSD.quality: got {self.quality!r}; allowed values are 'low', 'high'"
            )

    def _base(self, k: ArrayLike) -> FloatArray:
        omega = np.asarray(k, dtype=np.float64)
        if np.any(~np.isfinite(omega)) or np.any(omega < 0):
            raise ValueError("TrackPSD: wavenumbers k must be finite and >= 0 rad/m")
        return omega

    def vertical(self, k: ArrayLike) -> FloatArray:
        """Vertical profile PSD (m²/(rad/m)) at wavenumbers ``k`` (rad/m), same shape."""
        omega2 = self._base(k) ** 2
        a_v = _ROUGHNESS[self.quality]["vertical"]
        c2 = CUTOFF_WAVENUMBER**2
        return a_v * c2 / ((omega2 + LOW_WAVENUMBER**2) * (omega2 + c2))

    def alignment(self, k: ArrayLike) -> FloatArray:
        """Alignment PSD (m²/(rad/m)) at wavenumbers ``k`` (rad/m), same shape."""
        omega2 = self._base(k) ** 2
        a_a = _ROUGHNESS[self.quality]["alignment"]
        c2 = CUTOFF_WAVENUMBER**2
        return a_a * c2 / ((omega2 + LOW_WAVENUMBER**2) * (omega2 + c2))

    def _cross_shape(self, k: ArrayLike) -> FloatArray:
        omega2 = self._base(k) ** 2
        c2 = CUTOFF_WAVENUMBER**2
        return (
            c2
            * omega2
            / ((omega2 + LOW_WAVENUMBER**2) * (omega2 + c2) * (omega2 + CROSS_LEVEL_WAVENUMBER**2))
        )

    def cross_level(self, k: ArrayLike) -> FloatArray:
        """Cross-level (roll angle) PSD (rad²/(rad/m)) at wavenumbers ``k`` (rad/m)."""
        a_v = _ROUGHNESS[self.quality]["vertical"]
        return a_v / HALF_GAUGE_M**2 * self._cross_shape(k)

    def gauge(self, k: ArrayLike) -> FloatArray:
        """Gauge deviation PSD (m²/(rad/m)) at wavenumbers ``k`` (rad/m), same shape."""
        return _ROUGHNESS[self.quality]["gauge"] * self._cross_shape(k)

    def component(self, name: str, k: ArrayLike) -> FloatArray:
        """PSD of a geometry component by its :class:`TrackGeometry` field name.

        Args:
            name: one of ``vertical_m``, ``alignment_m``, ``cross_level_rad``, ``gauge_m``.
            k: wavenumbers (rad/m).
        """
        functions = {
            "vertical_m": self.vertical,
            "alignment_m": self.alignment,
            "cross_level_rad": self.cross_level,
            "gauge_m": self.gauge,
        }
        if name not in functions:
            raise ValueError(
                f"TrackPSD.component: got name {name!r}; allowed: {', '.join(functions)}"
            )
        return functions[name](k)


@dataclass(frozen=True, eq=False)
class TrackGeometry:
    """Track irregularities sampled in space at ``s = 0, ds, 2 ds, …`` (m).

    Arrays are stored as read-only float64 copies.

    Args:
        spacing_m: sample spacing ``ds`` (m), > 0.
        vertical_m: vertical profile, mean of the two rails, + up (N,) m.
        alignment_m: mean lateral rail position, + left (N,) m.
        cross_level_rad: roll angle of the rail plane, + left rail higher (N,) rad.
        gauge_m: gauge deviation from nominal, + wider (N,) m.
    """

    spacing_m: float
    vertical_m: FloatArray
    alignment_m: FloatArray
    cross_level_rad: FloatArray
    gauge_m: FloatArray

    def __post_init__(self) -> None:
        require_positive("TrackGeometry.spacing_m", self.spacing_m, unit="m")
        object.__setattr__(self, "spacing_m", float(self.spacing_m))
        n_samples = None
        for name in GEOMETRY_COMPONENTS:
            values = as_finite_vector(f"TrackGeometry.{name}", getattr(self, name), min_length=2)
            if n_samples is None:
                n_samples = values.size
            elif values.size != n_samples:
                raise ValueError(
                    f"TrackGeometry.{name}: has {values.size} samples but vertical_m has "
                    f"{n_samples}; all components must share one grid"
                )
            object.__setattr__(self, name, values)

    @property
    def n_samples(self) -> int:
        """Number of samples N along the track."""
        return int(self.vertical_m.size)

    @property
    def length_m(self) -> float:
        """Track length covered by the samples, ``(N - 1) ds`` (m)."""
        return (self.n_samples - 1) * self.spacing_m

    @property
    def position_m(self) -> FloatArray:
        """Track coordinates of the samples, (N,) m."""
        return np.arange(self.n_samples, dtype=np.float64) * self.spacing_m

    def stacked(self) -> FloatArray:
        """Components stacked in :data:`GEOMETRY_COMPONENTS` order, (4 x N)."""
        return np.stack([getattr(self, name) for name in GEOMETRY_COMPONENTS])

    @classmethod
    def synthetic(
        cls,
        quality: TrackQuality = "low",
        length_m: float = 2000.0,
        spacing_m: float = 0.25,
        seed: int = 0,
        max_wavelength_m: float = 200.0,
        min_wavelength_m: float | None = None,
    ) -> TrackGeometry:
        """A random track drawn from the German high-speed PSDs.

        Spectral representation on the FFT grid: each component is
        ``Σ_k sqrt(2 S(Ω_k) ΔΩ) cos(Ω_k s + φ_k)`` over the wavenumbers
        ``Ω_k = k ΔΩ`` inside ``[2π/max_wavelength_m, 2π/min_wavelength_m]``,
        with independent uniform phases ``φ_k`` (one independent stream per
        component, spawned from ``seed``). The realization is synthesised on a
        periodic grid at least ``max(length_m, 10 · max_wavelength_m)`` long
        (so that ``ΔΩ`` resolves the longest waves) and truncated to
        ``length_m``. The same arguments give bit-for-bit the same track.

        Args:
            quality: ``"low"`` or ``"high"`` disturbance.
            length_m: track length (m); the grid ends at the first sample at or
                beyond it.
            spacing_m: sample spacing (m).
            seed: seed of the random phases.
            max_wavelength_m: longest wavelength (m), ≈200 m for carbody modes at 83 m/s.
            min_wavelength_m: shortest wavelength (m), at least ``4 spacing_m``;
                default ``max(1.0, 4 spacing_m)``.

        Returns:
            The geometry; its variance per component equals the PSD integrated
            over the band (midpoint rule on the grid ``ΔΩ``).
        """
        psd = TrackPSD(quality)
        require_positive("TrackGeometry.synthetic.spacing_m", spacing_m, unit="m")
        require_positive("TrackGeometry.synthetic.length_m", length_m, unit="m")
        if min_wavelength_m is None:
            min_wavelength_m = max(1.0, 4.0 * spacing_m)
        require_positive("TrackGeometry.synthetic.min_wavelength_m", min_wavelength_m, unit="m")
        if min_wavelength_m < 4.0 * spacing_m:
            raise ValueError(
                f"TrackGeometry.synthetic.min_wavelength_m: got {min_wavelength_m} m; must be "
                f">= 4 x spacing_m = {4.0 * spacing_m} m (at least 4 samples per wavelength)"
            )
        if not (math.isfinite(max_wavelength_m) and max_wavelength_m > min_wavelength_m):
            raise ValueError(
                f"TrackGeometry.synthetic.max_wavelength_m: got {max_wavelength_m} m; must be "
                f"finite and > min_wavelength_m = {min_wavelength_m} m"
            )
        if length_m < 2.0 * spacing_m:
            raise ValueError(
                f"TrackGeometry.synthetic.length_m: got {length_m} m; must be >= 2 x spacing_m "
                f"= {2.0 * spacing_m} m"
            )
        if not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"TrackGeometry.synthetic.seed: got {seed!r}; must be an int >= 0")
        n_samples = math.ceil(length_m / spacing_m - 1e-9) + 1
        n_grid = scipy.fft.next_fast_len(
            max(n_samples, math.ceil(10.0 * max_wavelength_m / spacing_m)), real=True
        )
        d_omega = 2.0 * math.pi / (n_grid * spacing_m)
        omega = np.arange(n_grid // 2 + 1, dtype=np.float64) * d_omega
        in_band = (omega >= 2.0 * math.pi / max_wavelength_m) & (
            omega <= 2.0 * math.pi / min_wavelength_m
        )
        generators = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(4)]
        components: dict[str, FloatArray] = {}
        for name, generator in zip(GEOMETRY_COMPONENTS, generators):
            phases = generator.uniform(0.0, 2.0 * math.pi, size=omega.size)
            amplitude = np.zeros_like(omega)
            amplitude[in_band] = np.sqrt(2.0 * psd.component(name, omega[in_band]) * d_omega)
            spectrum = 0.5 * n_grid * amplitude * np.exp(1j * phases)
            profile = scipy.fft.irfft(spectrum, n=n_grid)
            components[name] = np.ascontiguousarray(profile[:n_samples], dtype=np.float64)
        return cls(spacing_m=float(spacing_m), **components)


def _speed_arrays(time_s: ArrayLike, speed_m_s: ArrayLike) -> tuple[FloatArray, FloatArray]:
    time = as_finite_vector("SpeedProfile.time_s", time_s, min_length=2)
    speed = as_finite_vector("SpeedProfile.speed_m_s", speed_m_s, min_length=2)
    if speed.size != time.size:
        raise ValueError(
            f"SpeedProfile.speed_m_s: has {speed.size} samples but time_s has {time.size}"
        )
    if time[0] != 0.0:
        raise ValueError(f"SpeedProfile.time_s: must start at 0 s; got time_s[0] = {time[0]} s")
    steps = np.diff(time)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0))
        raise ValueError(
            f"SpeedProfile.time_s: must be strictly increasing; time_s[{i + 1}] = "
            f"{time[i + 1]} s <= time_s[{i}] = {time[i]} s"
        )
    if np.any(speed <= 0):
        i = int(np.argmax(speed <= 0))
        raise ValueError(
            f"SpeedProfile.speed_m_s: must be > 0 m/s; got speed_m_s[{i}] = {speed[i]} m/s"
        )
    return time, speed


@dataclass(frozen=True, eq=False)
class SpeedProfile:
    """Train speed against time, piecewise linear between the samples.

    Args:
        time_s: sample times (n,) s, strictly increasing from 0.
        speed_m_s: speeds at those times (n,) m/s, all > 0.
    """

    time_s: FloatArray
    speed_m_s: FloatArray
    _distance_at_knots: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        time, speed = _speed_arrays(self.time_s, self.speed_m_s)
        object.__setattr__(self, "time_s", time)
        object.__setattr__(self, "speed_m_s", speed)
        knots = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(time))])
        knots.setflags(write=False)
        object.__setattr__(self, "_distance_at_knots", knots)

    @classmethod
    def constant(cls, speed_m_s: float, duration_s: float) -> SpeedProfile:
        """A constant speed ``speed_m_s`` (m/s) held for ``duration_s`` (s)."""
        require_positive("SpeedProfile.constant.duration_s", duration_s, unit="s")
        return cls(time_s=np.array([0.0, duration_s]), speed_m_s=np.array([speed_m_s] * 2))

    @property
    def duration_s(self) -> float:
        """Length of the record (s)."""
        return float(self.time_s[-1])

    @property
    def total_distance_m(self) -> float:
        """Distance travelled over the whole record (m)."""
        return float(self._distance_at_knots[-1])

    def _segments(self, t: ArrayLike) -> tuple[FloatArray, NDArray[np.intp], FloatArray]:
        times = np.asarray(t, dtype=np.float64)
        tolerance = 1e-9 * max(1.0, self.duration_s)
        if np.any(~np.isfinite(times)) or np.any(times < -tolerance):
            raise ValueError("SpeedProfile: times must be finite and >= 0 s")
        if np.any(times > self.duration_s + tolerance):
            raise ValueError(
                f"SpeedProfile: time {float(np.max(times))} s is beyond the speed record "
                f"(duration_s = {self.duration_s} s)"
            )
        times = np.clip(times, 0.0, self.duration_s)
        index = np.clip(
            np.searchsorted(self.time_s, times, side="right") - 1, 0, self.time_s.size - 2
        )
        return times, index, times - self.time_s[index]

    def speed_at(self, t: ArrayLike) -> FloatArray:
        """Speed (m/s) at times ``t`` (s), any shape, within ``[0, duration_s]``."""
        _, index, tau = self._segments(t)
        slope = np.diff(self.speed_m_s) / np.diff(self.time_s)
        return self.speed_m_s[index] + slope[index] * tau

    def distance_m(self, t: ArrayLike) -> FloatArray:
        """Distance travelled since t = 0 (m) at times ``t`` (s), exact for the linear speed."""
        _, index, tau = self._segments(t)
        slope = np.diff(self.speed_m_s) / np.diff(self.time_s)
        return (
            self._distance_at_knots[index]
            + self.speed_m_s[index] * tau
            + 0.5 * slope[index] * tau**2
        )


@dataclass(frozen=True, eq=False)
class AxleExcitation:
    """Track geometry under each axle against time (the rig's input ``x(t)``).

    Args:
        time_s: sample times (n_t,) s.
        vertical_m, alignment_m, cross_level_rad, gauge_m: geometry under each
            axle (n_axles x n_t), m / rad.
        vertical_rate_m_s, alignment_rate_m_s, cross_level_rate_rad_s: their
            time derivatives (n_axles x n_t), m/s / rad/s.
    """

    time_s: FloatArray
    vertical_m: FloatArray
    vertical_rate_m_s: FloatArray
    alignment_m: FloatArray
    alignment_rate_m_s: FloatArray
    cross_level_rad: FloatArray
    cross_level_rate_rad_s: FloatArray
    gauge_m: FloatArray

    def __post_init__(self) -> None:
        time = as_finite_vector("AxleExcitation.time_s", self.time_s, min_length=1)
        object.__setattr__(self, "time_s", time)
        shape = None
        for name in (
            "vertical_m",
            "vertical_rate_m_s",
            "alignment_m",
            "alignment_rate_m_s",
            "cross_level_rad",
            "cross_level_rate_rad_s",
            "gauge_m",
        ):
            values = np.array(getattr(self, name), dtype=np.float64)
            if values.ndim != 2 or values.shape[1] != time.size:
                raise ValueError(
                    f"AxleExcitation.{name}: shape {values.shape}; expected (n_axles, {time.size})"
                )
            if shape is not None and values.shape != shape:
                raise ValueError(f"AxleExcitation.{name}: shape {values.shape} != {shape}")
            if not np.all(np.isfinite(values)):
                raise ValueError(f"AxleExcitation.{name}: contains NaN or inf")
            shape = values.shape
            values.setflags(write=False)
            object.__setattr__(self, name, values)

    @property
    def n_axles(self) -> int:
        """Number of axles."""
        return int(self.vertical_m.shape[0])


def axle_excitation(
    geometry: TrackGeometry,
    speed: SpeedProfile,
    axle_positions_m: ArrayLike,
    time_s: ArrayLike,
    start_m: float | None = None,
) -> AxleExcitation:
    """Geometry seen by each axle at each time, with analytic rates.

    Axle ``a`` at time ``t`` sits at track coordinate
    ``s_a(t) = start_m + distance_m(t) + x_a``. The geometry is interpolated by
    a cubic spline in ``s`` (not-a-knot); rates are the spline's slope times
    the speed, ``dz/dt = z'(s) · v(t)``, not finite differences in time.

    Args:
        geometry: the track.
        speed: the speed record; ``time_s`` must lie within it.
        axle_positions_m: axle positions relative to the carbody centre, + forward (n_axles,) m.
        time_s: sample times (n_t,) s.
        start_m: track coordinate of the carbody centre at t = 0 (m); default puts
            the rearmost axle at s = 0.

    Returns:
        The excitation, arrays (n_axles x n_t).

    Raises:
        ValueError: when an axle leaves the track (message names the lengths), or
            inputs are non-finite / out of the speed record.
    """
    axles = as_finite_vector("axle_excitation.axle_positions_m", axle_positions_m, min_length=1)
    times = as_finite_vector("axle_excitation.time_s", time_s, min_length=1)
    if start_m is None:
        start_m = -float(np.min(axles))
    elif not math.isfinite(start_m):
        raise ValueError(f"axle_excitation.start_m: got {start_m}; must be finite")
    travelled = speed.distance_m(times)
    position = start_m + travelled[None, :] + axles[:, None]
    tolerance = 1e-9 * max(1.0, geometry.length_m)
    lowest, highest = float(np.min(position)), float(np.max(position))
    if lowest < -tolerance or highest > geometry.length_m + tolerance:
        raise ValueError(
            f"axle_excitation: the axles span s = {lowest:.3f} … {highest:.3f} m but the track "
            f"covers 0 … {geometry.length_m:.3f} m (start_m = {start_m:.3f} m, travelled "
            f"{float(travelled.max()):.3f} m, axle positions {float(axles.min()):.3f} … "
            f"{float(axles.max()):.3f} m); use a track at least {highest - lowest:.3f} m long"
        )
    position = np.clip(position, 0.0, geometry.length_m)
    spline = CubicSpline(geometry.position_m, geometry.stacked(), axis=1)
    values = spline(position)  # (4, n_axles, n_t)
    slopes = spline(position, 1)
    rates = slopes * speed.speed_at(times)[None, None, :]
    return AxleExcitation(
        time_s=times,
        vertical_m=values[0],
        vertical_rate_m_s=rates[0],
        alignment_m=values[1],
        alignment_rate_m_s=rates[1],
        cross_level_rad=values[2],
        cross_level_rate_rad_s=rates[2],
        gauge_m=values[3],
    )
