"""The summary likelihood for tracks known only by their statistics, against exact answers.

A linear-Gaussian stand-in for the rig: a run's spectrum y = m0 + G w + e with e ~ N(0, Σ)
strongly correlated (one shared "track" factor across every channel and band, as every
channel responds to the same track), so the posterior of w given the summaries is known
exactly and the intervals' calibration can be checked over many data sets.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from susp_bo.calibration.likelihood import expected_log_likelihood_at_truth
from susp_bo.calibration.track_statistics import (
    WEIGHT_SHARE,
    TrackStatisticsError,
    ledoit_wolf_to_diagonal,
    minimum_pilot_runs,
    summary_residuals,
    track_statistics_error,
    track_statistics_expected_log_likelihood,
    track_statistics_log_likelihood,
)
from tests.calibration.summary_toy import toy, toy_runs

C, F, Q = 3, 20, 2
NU, MU = 3, 3


def _toy(seed: int = 0):
    """(m0, G, chol Σ) of :func:`tests.calibration.summary_toy.toy` on C x F bins."""
    return toy(seed, C, F, Q)


def _runs(rng, m0, g, chol, w, n):
    """(n x C x F) runs at w."""
    return toy_runs(rng, m0, g, chol, w, n, shape=(C, F))


def _error(rng, m0, g, chol, pilot_runs=200):
    pilot = _runs(rng, m0, g, chol, np.zeros(Q), pilot_runs)
    return track_statistics_error(pilot, g.T.reshape(Q, C, F), NU, MU)


def test_ledoit_wolf_closed_form_matches_the_explicit_sum():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((15, 6)) @ rng.standard_normal((6, 6))
    covariance, a = ledoit_wolf_to_diagonal(x)
    n = len(x)
    xc = x - x.mean(axis=0)
    s = xc.T @ xc / n
    off = ~np.eye(6, dtype=bool)
    spread = sum(np.sum(((np.outer(v, v) - s)[off]) ** 2) for v in xc) / n**2
    expected_a = min(spread / np.sum(s[off] ** 2), 1.0)
    assert a == pytest.approx(expected_a, rel=1e-10)
    shrunk = (1 - a) * s + a * np.diag(np.diag(s))
    np.testing.assert_allclose(covariance, shrunk * n / (n - 1), rtol=1e-12)


def test_ledoit_wolf_shrinks_independent_columns_and_keeps_a_strong_correlation():
    rng = np.random.default_rng(2)
    _, a_independent = ledoit_wolf_to_diagonal(rng.standard_normal((30, 40)))
    factor = rng.standard_normal((400, 1))
    _, a_correlated = ledoit_wolf_to_diagonal(factor + 0.1 * rng.standard_normal((400, 40)))
    assert a_independent > 0.8
    assert a_correlated < 0.05


def test_log_likelihood_is_the_gaussian_density_of_the_summaries():
    m0, g, chol = _toy()
    rng = np.random.default_rng(3)
    error = _error(rng, m0, g, chol)
    measured = _runs(rng, m0, g, chol, np.array([0.3, -0.2]), NU)
    simulated = np.stack([_runs(rng, m0, g, chol, np.array([0.1, 0.0]), MU) for _ in range(4)])
    values = track_statistics_log_likelihood(measured, simulated, error)
    a = error.weights.reshape(-1, Q)
    for b in range(4):
        d = a.T @ (measured.mean(axis=0).ravel() - simulated[b].mean(axis=0).ravel())
        exact = multivariate_normal(np.zeros(Q), error.scale * error.covariance).logpdf(d)
        assert values[b] == pytest.approx(exact, rel=1e-10)
        single = track_statistics_log_likelihood(measured, simulated[b], error)
        assert single == pytest.approx(values[b], rel=1e-12)


def test_intervals_hold_the_truth_as_often_as_they_say_where_independent_bins_do_not():
    """400 data sets, each with its own truth, measured runs, simulated tracks and pilot:
    the summary posterior's z has rms ≈ 1 and its 95 % intervals hold the truth ≈ 95 % of
    the time; the Gaussian likelihood that takes every bin as independent (what eq. 4
    assumes) is far too narrow on the same data — so the check can fail."""
    m0, g, chol = _toy()
    variance = np.diag(chol @ chol.T)
    rng = np.random.default_rng(4)
    z_summary, z_independent = [], []
    for _ in range(400):
        truth = rng.uniform(-1.0, 1.0, Q)
        error = _error(rng, m0, g, chol)
        measured = _runs(rng, m0, g, chol, truth, NU)
        noise = _runs(rng, np.zeros_like(m0), np.zeros_like(g), chol, np.zeros(Q), MU)
        residual = measured.mean(axis=0).ravel() - m0 - noise.mean(axis=0).ravel()
        a = error.weights.reshape(-1, Q)
        for weights, covariance, out in (
            (a, error.covariance, z_summary),
            (g / variance[:, None], g.T @ (g / variance[:, None]), z_independent),
        ):
            jac = weights.T @ g  # summaries of ȳ − h̄(w) = weights.T @ residual − jac w
            solve = np.linalg.solve(
                error.scale * covariance, np.column_stack([jac, weights.T @ residual])
            )
            precision = jac.T @ solve[:, :Q]
            mean = np.linalg.solve(precision, jac.T @ solve[:, Q])
            out.append((mean - truth) / np.sqrt(np.diag(np.linalg.inv(precision))))
    z = np.array(z_summary)  # seeded: z rms 1.034, 93.9 % inside
    assert 0.90 < math.sqrt(np.mean(z**2)) < 1.10
    inside = np.mean(np.abs(z) < 1.96)
    assert 0.92 < inside < 0.98
    assert math.sqrt(np.mean(np.array(z_independent) ** 2)) > 2.0


def test_covariance_is_the_held_out_summaries_covariance_with_the_hartlap_factor():
    """C is estimated on the pilot runs A was not fitted to, and inflated by (n − 1) /
    (n − q − 2) so that C⁻¹ is unbiased: checked on the smallest pilot allowed, where the
    factor is far from 1."""
    m0, g, chol = _toy()
    rng = np.random.default_rng(8)
    runs = minimum_pilot_runs(Q)
    pilot = _runs(rng, m0, g, chol, np.zeros(Q), runs)
    error = track_statistics_error(pilot, g.T.reshape(Q, C, F), NU, MU)
    first = round(WEIGHT_SHARE * runs)
    held_out = pilot.reshape(runs, -1)[first:] @ error.weights.reshape(-1, Q)
    n = runs - first
    expected = np.cov(held_out.T) * (n - 1) / (n - Q - 2)
    np.testing.assert_allclose(error.covariance, expected, rtol=1e-10)
    assert (n - 1) / (n - Q - 2) > 1.1
    sigma, _ = ledoit_wolf_to_diagonal(pilot.reshape(runs, -1)[:first])
    np.testing.assert_allclose(
        error.weights.reshape(-1, Q), np.linalg.solve(sigma, g), rtol=1e-8, atol=1e-10
    )


def test_log_l_at_the_truth_matches_its_expectation():
    m0, g, chol = _toy()
    rng = np.random.default_rng(5)
    error = _error(rng, m0, g, chol, pilot_runs=2000)
    truth = np.array([0.4, 0.1])
    values = [
        track_statistics_log_likelihood(
            _runs(rng, m0, g, chol, truth, NU), _runs(rng, m0, g, chol, truth, MU), error
        )
        for _ in range(600)
    ]
    mean, sd = track_statistics_expected_log_likelihood(error)
    assert sd == pytest.approx(1.0)  # √(q / 2), q = 2
    assert np.mean(values) == pytest.approx(mean, abs=4 * sd / math.sqrt(600))
    assert np.std(values) == pytest.approx(sd, rel=0.15)
    dummy = np.zeros((NU, C, F))
    assert expected_log_likelihood_at_truth(error, dummy) == (mean, sd)


def test_residuals_are_batched_and_standard_at_the_truth():
    m0, g, chol = _toy()
    rng = np.random.default_rng(6)
    error = _error(rng, m0, g, chol)
    truth = np.zeros(Q)
    z = np.array(
        [
            summary_residuals(
                _runs(rng, m0, g, chol, truth, NU), _runs(rng, m0, g, chol, truth, MU), error
            )
            for _ in range(500)
        ]
    )
    np.testing.assert_allclose(np.cov(z.T), np.eye(Q), atol=0.2)
    batch = np.stack([_runs(rng, m0, g, chol, truth, MU) for _ in range(3)])
    measured = _runs(rng, m0, g, chol, truth, NU)
    assert summary_residuals(measured, batch, error).shape == (3, Q)


def test_bad_pilots_and_shapes_are_refused_naming_the_value():
    m0, g, chol = _toy()
    rng = np.random.default_rng(7)
    jacobian = g.T.reshape(Q, C, F)
    few = minimum_pilot_runs(Q) - 1
    with pytest.raises(ValueError, match=f"pilot: {few} runs; need at least {few + 1}"):
        track_statistics_error(_runs(rng, m0, g, chol, np.zeros(Q), few), jacobian, 3, 3)
    pilot = _runs(rng, m0, g, chol, np.zeros(Q), 60)
    with pytest.raises(ValueError, match="same channels and bands"):
        track_statistics_error(pilot, g.T.reshape(Q, C * F, 1), 3, 3)
    with pytest.raises(ValueError, match=r"rank 1 < q = 2 \(row 1 has norm 0"):
        track_statistics_error(pilot, np.stack([jacobian[0], 0.0 * jacobian[1]]), 3, 3)
    with pytest.raises(ValueError, match="rank 1 < q = 2"):
        track_statistics_error(pilot, np.stack([jacobian[0], 2.0 * jacobian[0]]), 3, 3)
    still = pilot.copy()
    still[:, 1, 4] = 0.5
    with pytest.raises(ValueError, match="channel 1, band 4 has the same value"):
        track_statistics_error(still, jacobian, 3, 3)
    pilot[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        track_statistics_error(pilot, jacobian, 3, 3)
    error = _error(rng, m0, g, chol)
    with pytest.raises(ValueError, match="n_measured: 0"):
        TrackStatisticsError(error.weights, error.covariance, 0, 3)
    with pytest.raises(ValueError, match="not positive definite"):
        TrackStatisticsError(error.weights, -error.covariance, 3, 3)
    with pytest.raises(ValueError, match="not symmetric"):
        TrackStatisticsError(error.weights, error.covariance + np.triu(np.ones((Q, Q)), 1), 3, 3)
    with pytest.raises(ValueError, match="shrinkage: 7"):
        TrackStatisticsError(error.weights, error.covariance, 3, 3, 100, 7.0)
    with pytest.raises(ValueError, match="pilot_runs: -5"):
        TrackStatisticsError(error.weights, error.covariance, 3, 3, -5)
    with pytest.raises(ValueError, match=r"measured: shape \(2, 3, 20\)"):
        summary_residuals(np.zeros((2, C, F)), np.zeros((MU, C, F)), error)
    measured = np.zeros((NU, C, F))
    measured[1, 2, 3] = np.inf
    with pytest.raises(ValueError, match="measured: contains NaN or inf"):
        summary_residuals(measured, np.zeros((MU, C, F)), error)
    with pytest.raises(ValueError, match=r"samples: shape \(\)"):
        ledoit_wolf_to_diagonal(np.float64(3.0))
