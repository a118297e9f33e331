"""Benjamini–Hochberg, band merging and the gap metric on constructed residuals."""

from __future__ import annotations

import numpy as np

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
