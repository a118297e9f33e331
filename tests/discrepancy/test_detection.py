"""Benjamini–Hochberg, band merging and the gap metric on constructed residuals."""

from __future__ import annotations

import numpy as np
import pytest

from susp_bo.discrepancy.detection import benjamini_hochberg, gap_metrics, predictive_check


def test_benjamini_hochberg_matches_the_step_up_rule() -> None:
    p = np.array([0.001, 0.008, 0.039, 0.041, 0.042, 0.06, 0.074, 0.205, 0.212, 0.216])
    # q = 0.05, m = 10: p_(k) <= 0.005 k holds up to k = 2
    assert benjamini_hochberg(p, 0.05).tolist() == [True, True] + [False] * 8
    assert not benjamini_hochberg(np.full(50, 0.5), 0.05).any()


def test_false_alarms_on_pure_noise_stay_below_q(rng: np.random.Generator) -> None:
    any_flag = 0
    trials = 200
    for _ in range(trials):
        z = rng.standard_normal((10, 50))
        p = 2 * (1 - 0.5 * (1 + np.vectorize(__import__("math").erf)(np.abs(z) / np.sqrt(2))))
        any_flag += benjamini_hochberg(p, 0.05).any()
    assert any_flag / trials < 0.1  # FWER of BH under the global null = q = 0.05


def test_a_band_of_excess_energy_is_flagged_with_its_edges_and_sign(
    rng: np.random.Generator,
) -> None:
    nu, channels, n_f = 3, ("a", "b"), 30
    edges = np.geomspace(1.0, 30.0, n_f + 1)
    sigma = np.array([0.1, 0.1])
    truth = rng.normal(0.0, 0.01, (nu, 2, n_f))
    measured = truth.copy()
    measured[:, 1, 10:14] += 0.5  # data hold more energy in bins 10..13 of channel b
    predicted = truth[None] + rng.normal(0, 0.01, (5, nu, 2, n_f))
    detection = predictive_check(measured, predicted, sigma, channels, edges, q=0.05)
    assert len(detection.bands) == 1
    band = detection.bands[0]
    assert band.channel == "b" and band.sign == "model_too_little"
    assert (band.f_low_hz, band.f_high_hz) == (edges[10], edges[14])
    assert band.residual_db > 3.0
    gap = gap_metrics(detection, detection.flagged)
    assert gap["n_bins"] == 4 and gap["value"] > 25.0


def test_a_whole_channel_level_error_is_reported_a_band_or_a_small_level_is_not(
    rng: np.random.Generator,
) -> None:
    """A 3 dB gain on channel b: few (or no) bins pass BH on their own, the channel does;
    a strong band moves the channel's mean but not its median; 0.5 dB is below the floor."""
    nu, channels, n_f = 3, ("a", "b", "c"), 40
    edges = np.geomspace(1.0, 30.0, n_f + 1)
    sigma = np.array([0.4, 0.4, 0.4])
    truth = rng.normal(0.0, 0.01, (nu, 3, n_f))
    measured = truth.copy()
    measured[:, 1] += np.log(10 ** (3 / 20))  # 3 dB on every bin of b
    measured[:, 2, 10:18] += 1.5  # a strong band on c (8 of 40 bins)
    predicted = truth[None] + rng.normal(0, 0.01, (5, nu, 3, n_f))
    detection = predictive_check(measured, predicted, sigma, channels, edges, q=0.05)
    assert not any(b.channel == "b" for b in detection.bands)  # |Z| ≈ 1.5 per bin
    assert [o.channel for o in detection.offsets] == ["b"]
    assert detection.offsets[0].offset_db == pytest.approx(3.0, abs=0.05)
    assert detection.offsets[0].z > 5 and detection.offsets[0].p_value < 1e-6
    assert any(b.channel == "c" for b in detection.bands)
    small = truth.copy()
    small[:, 1] += np.log(10 ** (0.5 / 20))
    # σ such that the channel statistic passes (≈ 9) while no bin does (|Z| ≈ 1.5): the floor
    quiet = predictive_check(small, predicted, np.full(3, 0.066), channels, edges, q=0.05)
    assert not quiet.bands and not quiet.offsets
