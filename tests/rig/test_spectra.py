"""Tests of susp_bo.rig.spectra against analytic levels of sines and white noise."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from susp_bo.rig.spectra import Spectra, SpectrumSettings, log_amplitude_spectra

SAMPLE_RATE_HZ = 200.0


def _time(duration_s: float, sample_rate_hz: float = SAMPLE_RATE_HZ) -> np.ndarray:
    return np.arange(round(duration_s * sample_rate_hz)) / sample_rate_hz


def test_grid_is_log_spaced_between_the_band_edges() -> None:
    spectrum = SpectrumSettings(f_min_hz=0.5, f_max_hz=20.0, n_frequencies=10, segment_s=8.0)
    edges = spectrum.band_edges_hz()
    assert edges[0] == pytest.approx(0.5) and edges[-1] == pytest.approx(20.0)
    np.testing.assert_allclose(np.diff(np.log(edges)), np.log(40.0) / 10)
    centres = spectrum.frequencies_hz()
    assert centres.shape == (10,)
    np.testing.assert_allclose(centres, np.sqrt(edges[:-1] * edges[1:]))


def test_sine_at_a_band_centre_gives_power_over_band_width() -> None:
    spectrum = SpectrumSettings(f_min_hz=0.5, f_max_hz=40.0, n_frequencies=24, segment_s=8.0)
    edges, centres = spectrum.band_edges_hz(), spectrum.frequencies_hz()
    band = int(np.searchsorted(centres, 15.0))
    amplitude = 0.37
    signal = amplitude * np.sin(2 * np.pi * centres[band] * _time(64.0) + 0.4)
    result = log_amplitude_spectra(signal, SAMPLE_RATE_HZ, ["sine"], spectrum)
    expected = 0.5 * np.log(amplitude**2 / 2 / (edges[band + 1] - edges[band]))
    assert result.channel("sine")[band] == pytest.approx(expected, abs=0.01)
    # Far from the sine the level is many orders of magnitude lower.
    assert np.all(result.channel("sine")[: band - 3] < expected - 5)


@settings(max_examples=30, deadline=None)
@given(frequency=st.floats(1.0, 18.0), amplitude=st.floats(1e-3, 10.0), phase=st.floats(0, 6.3))
def test_band_averaging_conserves_the_power_of_a_sine(
    frequency: float, amplitude: float, phase: float
) -> None:
    spectrum = SpectrumSettings()  # 0.5–20 Hz, 48 bands, 8 s segments
    signal = amplitude * np.sin(2 * np.pi * frequency * _time(40.0) + phase)
    result = log_amplitude_spectra(signal, SAMPLE_RATE_HZ, ["a"], spectrum)
    widths = np.diff(spectrum.band_edges_hz())
    power = np.sum(np.exp(2 * result.log_amplitude[0]) * widths)
    assert power == pytest.approx(amplitude**2 / 2, rel=0.02)


def test_white_noise_gives_its_analytic_level() -> None:
    """Gaussian white noise of variance σ² sampled at fs has one-sided PSD 2σ²/fs."""
    sigma = 0.2
    noise = np.random.default_rng(7).normal(0.0, sigma, size=(3, round(600 * SAMPLE_RATE_HZ)))
    result = log_amplitude_spectra(noise, SAMPLE_RATE_HZ, ["x", "y", "z"])
    error = result.log_amplitude - 0.5 * np.log(2 * sigma**2 / SAMPLE_RATE_HZ)
    # 600 s / 8 s segments at 50 % overlap: K = 149 averages. ln(amplitude) of a mean of
    # n independent χ²₂/2 estimates has standard deviation ≈ 0.5/√n; a band holds
    # width/df Welch bins (at least one bin's worth of variance).
    segments = 149
    bins = np.maximum(np.diff(SpectrumSettings().band_edges_hz()) * 8.0, 1.0)
    sigma_log = 0.5 / np.sqrt(segments * bins)
    assert abs(error.mean()) < 0.01
    assert np.all(np.abs(error) < 5 * sigma_log)
    assert np.abs(error).max() < 0.2


@settings(max_examples=20, deadline=None)
@given(scale=st.floats(1e-4, 1e4), seed=st.integers(0, 2**16))
def test_scaling_a_signal_shifts_the_log_amplitude(scale: float, seed: int) -> None:
    signal = np.random.default_rng(seed).normal(size=(2, 2000))
    base = log_amplitude_spectra(signal, SAMPLE_RATE_HZ, ["a", "b"])
    scaled = log_amplitude_spectra(scale * signal, SAMPLE_RATE_HZ, ["a", "b"])
    np.testing.assert_allclose(scaled.log_amplitude, base.log_amplitude + np.log(scale), atol=1e-9)
    single = log_amplitude_spectra(signal[1], SAMPLE_RATE_HZ, ["b"])
    np.testing.assert_allclose(single.channel("b"), base.channel("b"), rtol=0, atol=1e-12)


def test_spectra_are_deterministic() -> None:
    signal = np.random.default_rng(1).normal(size=(2, 4000))
    first = log_amplitude_spectra(signal, SAMPLE_RATE_HZ, ["a", "b"])
    second = log_amplitude_spectra(signal.copy(), SAMPLE_RATE_HZ, ("a", "b"))
    assert first.log_amplitude.tobytes() == second.log_amplitude.tobytes()
    assert first.channels == ("a", "b")


def test_band_beyond_nyquist_is_rejected() -> None:
    spectrum = SpectrumSettings(f_max_hz=20.0)
    with pytest.raises(ValueError, match=r"sample_rate_hz.*Nyquist 15 Hz.*f_max_hz = 20.*> 40"):
        log_amplitude_spectra(np.ones((1, 600)), 30.0, ["a"], spectrum)
    with pytest.raises(ValueError, match=r"Nyquist 20 Hz"):
        spectrum.check_sample_rate(40.0, 100.0)
    spectrum.check_sample_rate(40.1, 100.0)


def test_record_shorter_than_a_segment_is_rejected() -> None:
    spectrum = SpectrumSettings(segment_s=8.0)
    with pytest.raises(ValueError, match=r"duration_s.*5 s.*segment_s = 8 s.*f_min_hz = 0.5"):
        log_amplitude_spectra(np.ones((1, 1000)), SAMPLE_RATE_HZ, ["a"], spectrum)
    with pytest.raises(ValueError, match=r"duration_s"):
        spectrum.check_sample_rate(200.0, 7.9)


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"f_min_hz": 0.1, "segment_s": 8.0}, r"f_min_hz.*0.1 Hz.*>= 2 / segment_s = 0.25.*20 s"),
        ({"f_max_hz": 0.4}, r"f_max_hz.*0.4 Hz.*> f_min_hz = 0.5"),
        ({"f_min_hz": float("nan")}, r"f_min_hz.*nan"),
        ({"n_frequencies": 0}, r"n_frequencies.*0.*>= 1"),
        ({"n_frequencies": 2.5}, r"n_frequencies.*2.5"),
        ({"overlap": 1.0}, r"overlap.*1.0.*\[0, 1\)"),
        ({"segment_s": -1.0}, r"segment_s.*-1.0"),
    ],
)
def test_settings_validation(kwargs: dict[str, float], pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern):
        SpectrumSettings(**kwargs)  # type: ignore[arg-type]


def test_bad_signals_are_rejected_with_the_channel_named() -> None:
    signal = np.random.default_rng(0).normal(size=(2, 4000))
    signal[1, 17] = np.nan
    with pytest.raises(ValueError, match=r"channel 'lat' contains NaN"):
        log_amplitude_spectra(signal, SAMPLE_RATE_HZ, ["vert", "lat"])
    with pytest.raises(ValueError, match=r"shape \(2, 4000\).*C = 3"):
        log_amplitude_spectra(signal, SAMPLE_RATE_HZ, ["a", "b", "c"])
    with pytest.raises(ValueError, match=r"channel 'dead' has no power"):
        log_amplitude_spectra(np.zeros((1, 4000)), SAMPLE_RATE_HZ, ["dead"])


def test_spectra_container_validation() -> None:
    frequencies = np.array([1.0, 2.0, 4.0])
    spectra = Spectra(frequencies, ("a", "b"), np.zeros((2, 3)))
    np.testing.assert_array_equal(spectra.channel("b"), np.zeros(3))
    with pytest.raises(KeyError, match=r"no channel 'c'.*a, b"):
        spectra.channel("c")
    with pytest.raises(ValueError, match=r"log_amplitude.*\(3, 2\).*\(2, 3\)"):
        Spectra(frequencies, ("a", "b"), np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"channels.*unique"):
        Spectra(frequencies, ("a", "a"), np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"strictly increasing"):
        Spectra(frequencies[::-1], ("a", "b"), np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"NaN or inf"):
        Spectra(frequencies, ("a", "b"), np.full((2, 3), -np.inf))


def test_noise_floor_adds_the_white_noise_psd_that_welch_measures() -> None:
    from susp_bo.rig.spectra import with_noise_floor

    settings = SpectrumSettings(f_min_hz=0.5, f_max_hz=20.0, n_frequencies=24, segment_s=8.0)
    fs, sigma = 100.0, 0.02
    noise = np.random.default_rng(3).normal(0.0, sigma, size=(1, int(600 * fs)))
    measured = log_amplitude_spectra(noise, fs, ("n",), settings).log_amplitude[0]
    floor_only = with_noise_floor(np.full(24, -60.0), sigma, fs)
    assert np.allclose(floor_only, 0.5 * np.log(2.0 * sigma**2 / fs))
    assert abs(np.mean(measured - floor_only)) < 0.02
    signal = np.linspace(-6.0, -3.0, 24)
    total = with_noise_floor(signal, sigma, fs)
    assert np.allclose(np.exp(2 * total) - np.exp(2 * signal), 2.0 * sigma**2 / fs)
    assert with_noise_floor(signal, 0.0, fs) is signal
    with pytest.raises(ValueError, match="noise_m_s2"):
        with_noise_floor(signal, -1.0, fs)
