"""Welch band statistics under white noise: the exact R against Monte Carlo of spectra.py."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from susp_bo.calibration.welch_noise import band_relative_covariance, noise_residual_moments
from susp_bo.rig.spectra import SpectrumSettings, log_amplitude_spectra

RATE_HZ = 20.0
SETTINGS = SpectrumSettings(f_min_hz=0.5, f_max_hz=8.0, n_frequencies=12, segment_s=4.0)
N_SAMPLES = 400  # 20 s: 9 half-overlapping 4 s segments


def _band_power(records: np.ndarray) -> np.ndarray:
    names = [f"r{i}" for i in range(records.shape[0])]
    spectra = log_amplitude_spectra(records, RATE_HZ, names, SETTINGS)
    return np.exp(2.0 * spectra.log_amplitude)


def test_relative_covariance_matches_monte_carlo_of_the_production_spectra() -> None:
    rng = np.random.default_rng(11)
    power = _band_power(rng.normal(size=(20000, N_SAMPLES)))  # (runs x F)
    mean = power.mean(axis=0)
    empirical = np.cov(power.T) / np.outer(mean, mean)
    exact = band_relative_covariance(SETTINGS, N_SAMPLES, RATE_HZ)
    # each (co)variance from 20 000 records: relative MC error ≈ √(2/20000) = 1 %
    np.testing.assert_allclose(np.diag(empirical), np.diag(exact), rtol=0.05)
    np.testing.assert_allclose(empirical, exact, atol=0.05 * np.max(np.diag(exact)))
    # bands narrower than the 0.25 Hz resolution share bins: correlated, K ≈ one bin's
    k = 1.0 / np.diag(exact)
    assert k[0] < 12 < k[-1]
    assert exact[0, 1] / np.sqrt(exact[0, 0] * exact[1, 1]) > 0.4


def test_residual_moments_match_monte_carlo_of_signal_plus_noise() -> None:
    """y − h for a fixed broadband signal realization, noise redrawn: moments as predicted.

    (A pure spectral line is not locally white in its band: there the prediction is
    conservative, up to ≈ 1.4 x the sd; the rig's responses are broadband.)
    """
    rng = np.random.default_rng(5)
    signal = scipy.signal.lfilter([0.1], [1.0, -0.9], rng.normal(size=N_SAMPLES))
    sigma = 0.05
    noise_psd = 2 * sigma**2 / RATE_HZ
    h = 0.5 * np.log(_band_power(signal[None])[0] + noise_psd)
    y = 0.5 * np.log(_band_power(signal[None] + rng.normal(0, sigma, size=(8000, N_SAMPLES))))
    r = y - h
    mean, cov = noise_residual_moments(
        h, noise_psd, band_relative_covariance(SETTINGS, N_SAMPLES, RATE_HZ)
    )
    sd = np.sqrt(np.diag(cov))
    np.testing.assert_allclose(r.std(axis=0), sd, rtol=0.15)
    assert np.all(np.abs(r.mean(axis=0) - mean) < 0.2 * sd)


def test_record_length_must_hold_a_segment() -> None:
    with pytest.raises(ValueError):
        band_relative_covariance(SETTINGS, 10, RATE_HZ)
