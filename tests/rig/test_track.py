"""Tests of susp_bo.rig.track against independent answers (analytic PSD, quadrature, FFT)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import scipy.signal
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from susp_bo.rig.track import (
    GEOMETRY_COMPONENTS,
    AxleExcitation,
    SpeedProfile,
    TrackGeometry,
    TrackPSD,
    axle_excitation,
)

# Figures measured on 20 km realizations (spacing 0.25 m, Welch 400 m segments, 12 log bands
# over 2–50 m wavelengths): seed 3 (used here) band-averaged sample PSD / analytic PSD within
# 0.97…1.02 and sample variance / ∫S dΩ within 0.993…1.003; worst over seeds 0–29: 8.3 % and
# 2.0 %. The tolerances cover every seed, and still catch a factor √2, 2 or 2π.
PSD_BAND_TOLERANCE = 0.10
VARIANCE_TOLERANCE = 0.03


def _ramp_geometry(length_m: float, spacing_m: float = 0.5) -> TrackGeometry:
    """Geometry whose vertical profile equals the track coordinate s (m): reveals positions."""
    s = np.arange(round(length_m / spacing_m) + 1) * spacing_m
    zeros = np.zeros_like(s)
    return TrackGeometry(spacing_m, s, zeros, zeros, zeros)


@pytest.fixture(scope="module")
def long_track() -> TrackGeometry:
    return TrackGeometry.synthetic("low", length_m=20_000.0, spacing_m=0.25, seed=3)


def _psd_integral(psd: TrackPSD, name: str, k_low: float, k_high: float) -> float:
    value, _ = quad(
        lambda k: float(psd.component(name, np.array(k))), k_low, k_high, limit=400, epsabs=0
    )
    return value


# --- TrackPSD -----------------------------------------------------------------------------


def test_psd_formulas_match_hand_values() -> None:
    psd = TrackPSD("low")
    k_c, k_r, k_s, b = 0.8246, 0.0206, 0.438, 0.75
    k = 0.3
    expected_vertical = 4.032e-7 * k_c**2 / ((k**2 + k_r**2) * (k**2 + k_c**2))
    assert psd.vertical(np.array([k]))[0] == pytest.approx(expected_vertical, rel=1e-12)
    expected_cross = (
        4.032e-7 / b**2 * k_c**2 * k**2 / ((k**2 + k_r**2) * (k**2 + k_c**2) * (k**2 + k_s**2))
    )
    assert psd.cross_level(k) == pytest.approx(expected_cross, rel=1e-12)
    # Between Ω_r and Ω_c the vertical spectrum is ≈ A_v / Ω².
    assert psd.vertical(0.15) * 0.15**2 == pytest.approx(4.032e-7, rel=0.06)
    assert psd.cross_level(0.0) == 0.0 and psd.gauge(0.0) == 0.0


def test_high_disturbance_is_rougher_by_the_published_ratios() -> None:
    k = np.geomspace(0.01, 6.0, 20)
    low, high = TrackPSD("low"), TrackPSD("high")
    np.testing.assert_allclose(high.vertical(k) / low.vertical(k), 1.08e-6 / 4.032e-7)
    np.testing.assert_allclose(high.alignment(k) / low.alignment(k), 6.125e-7 / 2.119e-7)
    np.testing.assert_allclose(high.gauge(k) / low.gauge(k), 1.032e-7 / 5.32e-8)
    assert low.vertical(k).shape == k.shape


def test_psd_rejects_unknown_quality_and_negative_wavenumber() -> None:
    with pytest.raises(ValueError, match=r"quality.*'medium'.*'low', 'high'"):
        TrackPSD("medium")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="wavenumbers"):
        TrackPSD().vertical(np.array([-1.0]))


# --- synthetic geometry -------------------------------------------------------------------


@pytest.mark.parametrize("name", GEOMETRY_COMPONENTS)
def test_sample_psd_matches_analytic_over_band(long_track: TrackGeometry, name: str) -> None:
    psd = TrackPSD("low")
    spacing = long_track.spacing_m
    f, p = scipy.signal.welch(getattr(long_track, name), fs=1 / spacing, nperseg=int(400 / spacing))
    k, sample = 2 * np.pi * f, p / (2 * np.pi)  # cycles/m -> rad/m, one-sided both
    edges = np.geomspace(2 * np.pi / 50.0, 2 * np.pi / 2.0, 13)
    for low, high in itertools.pairwise(edges):
        inside = (k >= low) & (k < high)
        ratio = sample[inside].mean() / psd.component(name, k[inside]).mean()
        assert abs(ratio - 1) < PSD_BAND_TOLERANCE, (name, 2 * np.pi / low, ratio)
    # Outside the band (wavelengths < 1 m) there is essentially no content.
    beyond = (k > 2 * np.pi / 0.9) & (k < 2 * np.pi / 0.6)
    assert np.all(sample[beyond] < 0.01 * psd.component(name, k[beyond]))


def test_long_wavelengths_up_to_200_m_are_present() -> None:
    track = TrackGeometry.synthetic("high", length_m=40_000.0, spacing_m=0.5, seed=11)
    psd = TrackPSD("high")
    f, p = scipy.signal.welch(track.vertical_m, fs=2.0, nperseg=4000)  # 2 km segments
    k, sample = 2 * np.pi * f, p / (2 * np.pi)
    inside = (k >= 2 * np.pi / 180.0) & (k < 2 * np.pi / 60.0)
    ratio = sample[inside].mean() / psd.vertical(k[inside]).mean()
    assert abs(ratio - 1) < 0.15


@pytest.mark.parametrize("name", GEOMETRY_COMPONENTS)
def test_variance_matches_psd_integral(long_track: TrackGeometry, name: str) -> None:
    expected = _psd_integral(TrackPSD("low"), name, 2 * np.pi / 200.0, 2 * np.pi / 1.0)
    assert np.var(getattr(long_track, name)) == pytest.approx(expected, rel=VARIANCE_TOLERANCE)


def test_synthetic_is_bit_for_bit_reproducible_and_seed_dependent() -> None:
    first = TrackGeometry.synthetic("low", length_m=1500.0, seed=42)
    second = TrackGeometry.synthetic("low", length_m=1500.0, seed=42)
    other = TrackGeometry.synthetic("low", length_m=1500.0, seed=43)
    for name in GEOMETRY_COMPONENTS:
        assert getattr(first, name).tobytes() == getattr(second, name).tobytes()
        assert not np.allclose(getattr(first, name), getattr(other, name))
    # The four components are independent streams, not copies of each other.
    assert abs(np.corrcoef(first.vertical_m, first.alignment_m)[0, 1]) < 0.3


def test_synthetic_grid_and_arrays() -> None:
    track = TrackGeometry.synthetic(length_m=100.1, spacing_m=0.25, seed=0)
    assert track.length_m >= 100.1 and track.length_m < 100.1 + 0.25
    assert track.position_m[1] == 0.25 and track.vertical_m.dtype == np.float64
    assert not track.vertical_m.flags.writeable


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"spacing_m": 0.5, "min_wavelength_m": 1.0}, r"min_wavelength_m.*1.0 m.*>= 4 x spacing"),
        ({"max_wavelength_m": 0.5}, r"max_wavelength_m.*0.5 m.*> min_wavelength_m"),
        ({"length_m": float("nan")}, r"length_m.*nan"),
        ({"spacing_m": -1.0}, r"spacing_m.*-1.0.*> 0"),
        ({"seed": -3}, r"seed.*-3"),
        ({"quality": "bad"}, r"quality"),
    ],
)
def test_synthetic_rejects_bad_arguments(kwargs: dict[str, object], pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern):
        TrackGeometry.synthetic(**kwargs)  # type: ignore[arg-type]


# --- TrackGeometry validation ---------------------------------------------------------------


def test_geometry_validation_names_field_and_value() -> None:
    good = np.zeros(10)
    bad = good.copy()
    bad[4] = np.nan
    with pytest.raises(ValueError, match=r"cross_level_rad.*non-finite.*index 4"):
        TrackGeometry(0.25, good, good, bad, good)
    with pytest.raises(ValueError, match=r"gauge_m.*inf"):
        TrackGeometry(0.25, good, good, good, np.full(10, np.inf))
    with pytest.raises(ValueError, match=r"vertical_m.*1 samples.*at least 2"):
        TrackGeometry(0.25, np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1))
    with pytest.raises(ValueError, match=r"alignment_m.*9 samples.*vertical_m has 10"):
        TrackGeometry(0.25, good, np.zeros(9), good, good)
    with pytest.raises(ValueError, match=r"spacing_m.*0.0.*> 0"):
        TrackGeometry(0.0, good, good, good, good)
    with pytest.raises(ValueError, match=r"vertical_m.*1-D"):
        TrackGeometry(0.25, np.zeros((2, 5)), good, good, good)


def test_geometry_copies_its_inputs() -> None:
    source = np.zeros(5)
    track = TrackGeometry(1.0, source, source, source, source)
    source[0] = 1.0
    assert track.vertical_m[0] == 0.0 and track.length_m == 4.0


# --- SpeedProfile ---------------------------------------------------------------------------


def test_constant_speed_distance() -> None:
    speed = SpeedProfile.constant(83.0, 10.0)
    assert speed.duration_s == 10.0
    np.testing.assert_allclose(speed.distance_m([0.0, 2.5, 10.0]), [0.0, 207.5, 830.0])
    np.testing.assert_allclose(speed.speed_at([0.0, 7.0]), [83.0, 83.0])


@settings(max_examples=60, deadline=None)
@given(
    v0=st.floats(1.0, 100.0),
    v1=st.floats(1.0, 100.0),
    duration=st.floats(0.5, 100.0),
    fraction=st.floats(0.0, 1.0),
)
def test_ramp_distance_is_the_exact_integral(
    v0: float, v1: float, duration: float, fraction: float
) -> None:
    speed = SpeedProfile(np.array([0.0, duration]), np.array([v0, v1]))
    t = fraction * duration
    acceleration = (v1 - v0) / duration
    assert speed.distance_m(t) == pytest.approx(v0 * t + 0.5 * acceleration * t**2, abs=1e-9)
    assert speed.speed_at(t) == pytest.approx(v0 + acceleration * t)


@settings(max_examples=40, deadline=None)
@given(
    speeds=st.lists(st.floats(0.5, 120.0), min_size=2, max_size=12),
    steps=st.lists(st.floats(0.01, 5.0), min_size=11, max_size=11),
)
def test_variable_speed_distance_is_monotone_and_trapezoidal(
    speeds: list[float], steps: list[float]
) -> None:
    time = np.concatenate([[0.0], np.cumsum(steps[: len(speeds) - 1])])
    profile = SpeedProfile(time, np.array(speeds))
    grid = np.linspace(0.0, profile.duration_s, 257)
    distance = profile.distance_m(grid)
    assert np.all(np.diff(distance) > 0)
    assert profile.total_distance_m == pytest.approx(np.trapezoid(speeds, time), rel=1e-12)


@pytest.mark.parametrize(
    ("time", "speed", "pattern"),
    [
        ([0.0, 1.0], [10.0, 0.0], r"speed_m_s.*> 0 m/s.*speed_m_s\[1\] = 0.0"),
        ([0.0, 1.0], [10.0, -5.0], r"speed_m_s.*-5.0"),
        ([0.0, 1.0], [10.0, np.nan], r"speed_m_s.*non-finite"),
        ([0.0, 1.0, 1.0], [1.0, 1.0, 1.0], r"time_s.*strictly increasing"),
        ([0.5, 1.0], [1.0, 1.0], r"time_s.*start at 0"),
        ([0.0, 1.0], [1.0, 1.0, 1.0], r"speed_m_s.*3 samples.*time_s has 2"),
        ([0.0], [1.0], r"time_s.*1 samples.*at least 2"),
    ],
)
def test_speed_validation(time: list[float], speed: list[float], pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern):
        SpeedProfile(np.array(time), np.array(speed))


def test_speed_rejects_times_outside_record() -> None:
    speed = SpeedProfile.constant(50.0, 2.0)
    with pytest.raises(ValueError, match=r"beyond the speed record.*duration_s = 2.0"):
        speed.distance_m(3.0)
    with pytest.raises(ValueError, match=r"duration_s.*0.0.*> 0"):
        SpeedProfile.constant(50.0, 0.0)
    with pytest.raises(ValueError, match=r"speed_m_s.*> 0"):
        SpeedProfile.constant(0.0, 1.0)


# --- axle_excitation ------------------------------------------------------------------------


@settings(max_examples=50, deadline=None)
@given(
    axles=st.lists(st.floats(-15.0, 15.0), min_size=1, max_size=4),
    speed=st.floats(5.0, 100.0),
    start_shift=st.one_of(st.none(), st.floats(0.0, 30.0)),
)
def test_axle_positions_follow_the_convention(
    axles: list[float], speed: float, start_shift: float | None
) -> None:
    """On a ramp track z(s) = s, the vertical input IS the axle position and its rate the speed."""
    duration = 2.0
    track = _ramp_geometry(100.0 + speed * duration)
    positions = np.array(axles)
    start = None if start_shift is None else -positions.min() + start_shift
    time = np.linspace(0.0, duration, 21)
    excitation = axle_excitation(
        track, SpeedProfile.constant(speed, duration), positions, time, start
    )
    expected_start = -positions.min() if start is None else start
    expected = expected_start + speed * time[None, :] + positions[:, None]
    np.testing.assert_allclose(excitation.vertical_m, expected, atol=1e-9)
    np.testing.assert_allclose(excitation.vertical_rate_m_s, speed, rtol=1e-9)
    if start is None:  # the rearmost axle starts at s = 0
        assert excitation.vertical_m[:, 0].min() == pytest.approx(0.0, abs=1e-9)


@pytest.fixture(scope="module")
def lag_track() -> TrackGeometry:
    return TrackGeometry.synthetic("low", length_m=2600.0, seed=5)


@settings(max_examples=15, deadline=None)
@given(spacing=st.floats(3.0, 25.0), speed=st.floats(20.0, 90.0))
def test_delay_between_axles_is_spacing_over_speed(
    lag_track: TrackGeometry, spacing: float, speed: float
) -> None:
    """The trailing axle meets, spacing/speed later, exactly the track the leading axle met.

    The lag is checked exactly, not estimated: at constant speed both axles sample the same
    spline at the same track coordinate, so ``trailing(t + spacing/speed) == leading(t)`` to
    rounding (measured worst 1e-13 of the signal scale over 2 000 random pairs), while half a
    sample (2.5 ms) off already differs by > 1 % (measured least 1.4 %). An earlier version
    located the peak of the raw cross-correlation of the two finite records with a parabolic
    refinement: that estimator is biased by the records' edges (the energy of the shifted
    window changes with the shift for a signal dominated by 50-200 m wavelengths), by up to
    1.03 samples over 300 random pairs, so its 1-sample tolerance failed by chance.
    """
    sample_rate = 200.0
    delay = spacing / speed
    time = np.arange(0.0, 22.0, 1.0 / sample_rate)  # t + delay stays inside the 24 s record
    profile = SpeedProfile.constant(speed, 24.0)
    axles = [spacing / 2, -spacing / 2]  # leading, trailing

    def seen(times: np.ndarray) -> np.ndarray:
        return axle_excitation(lag_track, profile, axles, times).vertical_m

    leading = seen(time)[0]
    scale = float(np.abs(leading).max())
    np.testing.assert_allclose(seen(time + delay)[1], leading, rtol=0, atol=1e-9 * scale)
    for wrong in (delay + 0.5 / sample_rate, delay - 0.5 / sample_rate, 0.0):
        assert np.abs(seen(time + wrong)[1] - leading).max() > 1e-3 * scale


def test_rates_equal_analytic_derivative_at_variable_speed() -> None:
    """Sine track z = a sin(2π s/λ); speed ramps 40 -> 80 m/s; compare to the chain rule."""
    amplitude, wavelength, spacing = 2e-3, 20.0, 0.25
    s = np.arange(0.0, 600.0 + spacing, spacing)
    z = amplitude * np.sin(2 * np.pi * s / wavelength)
    track = TrackGeometry(spacing, z, 0.5 * z, z / 0.75, 0.1 * z)
    speed = SpeedProfile(np.array([0.0, 5.0]), np.array([40.0, 80.0]))
    time = np.linspace(0.0, 5.0, 2001)
    excitation = axle_excitation(track, speed, [1.25, -1.25], time, start_m=10.0)
    position = 10.0 + 40.0 * time + 4.0 * time**2 + np.array([[1.25], [-1.25]])
    velocity = 40.0 + 8.0 * time
    k = 2 * np.pi / wavelength
    np.testing.assert_allclose(
        excitation.vertical_m, amplitude * np.sin(k * position), atol=2e-4 * amplitude
    )
    expected_rate = amplitude * k * np.cos(k * position) * velocity
    scale = amplitude * k * 80.0
    np.testing.assert_allclose(excitation.vertical_rate_m_s, expected_rate, atol=2e-3 * scale)
    np.testing.assert_allclose(
        excitation.alignment_rate_m_s, 0.5 * expected_rate, atol=2e-3 * scale
    )
    np.testing.assert_allclose(
        excitation.cross_level_rate_rad_s, expected_rate / 0.75, atol=3e-3 * scale
    )
    np.testing.assert_allclose(
        excitation.gauge_m, 0.1 * amplitude * np.sin(k * position), atol=1e-6
    )


def test_rates_match_time_differences_on_a_random_track() -> None:
    track = TrackGeometry.synthetic("high", length_m=800.0, seed=9)
    speed = SpeedProfile(np.array([0.0, 3.0, 6.0]), np.array([70.0, 90.0, 60.0]))
    time = np.arange(0.0, 6.0, 1e-4)
    excitation = axle_excitation(track, speed, [0.0], time)
    central = np.gradient(excitation.alignment_m[0], time)
    scale = np.abs(excitation.alignment_rate_m_s).max()
    np.testing.assert_allclose(  # interior: np.gradient is one-sided at the ends
        excitation.alignment_rate_m_s[0, 1:-1], central[1:-1], atol=1e-3 * scale
    )


def test_track_too_short_names_lengths() -> None:
    track = TrackGeometry.synthetic(length_m=500.0, seed=0)
    speed = SpeedProfile.constant(83.0, 6.0)
    with pytest.raises(ValueError, match=r"axles span s = 0.000 … 518.000 m.*covers 0 … 500.000"):
        axle_excitation(track, speed, [10.0, -10.0], np.linspace(0.0, 6.0, 61))
    with pytest.raises(ValueError, match=r"axles span s = -5.000"):
        axle_excitation(track, speed, [10.0, -10.0], [0.0], start_m=5.0)
    with pytest.raises(ValueError, match=r"beyond the speed record"):
        axle_excitation(track, speed, [0.0], [7.0])
    with pytest.raises(ValueError, match=r"axle_positions_m.*non-finite"):
        axle_excitation(track, speed, [np.nan], [0.0])


def test_axle_excitation_dataclass_checks_shapes() -> None:
    ok = np.zeros((2, 3))
    fields = dict.fromkeys(
        (
            "vertical_m",
            "vertical_rate_m_s",
            "alignment_m",
            "alignment_rate_m_s",
            "cross_level_rad",
            "cross_level_rate_rad_s",
            "gauge_m",
        ),
        ok,
    )
    assert AxleExcitation(time_s=np.arange(3.0), **fields).n_axles == 2
    with pytest.raises(ValueError, match=r"gauge_m.*shape \(2, 4\)"):
        AxleExcitation(time_s=np.arange(3.0), **{**fields, "gauge_m": np.zeros((2, 4))})
    with pytest.raises(ValueError, match=r"vertical_m.*NaN"):
        AxleExcitation(time_s=np.arange(3.0), **{**fields, "vertical_m": np.full((2, 3), math.nan)})
