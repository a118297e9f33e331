"""Eq. 4 likelihood: brute-force agreement, stability, batching, output-error estimates."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats
from scipy.special import logsumexp

from susp_bo.calibration.likelihood import (
    OutputError,
    estimate_output_error,
    log_likelihood,
)


def _brute_force(measured, simulated, cov_per_channel):
    total = 0.0
    for y in measured:
        terms = []
        for h in simulated:
            terms.append(
                sum(
                    stats.multivariate_normal(np.zeros(y.shape[1]), cov).logpdf(y[c] - h[c])
                    for c, cov in enumerate(cov_per_channel)
                )
            )
        total += logsumexp(terms) - math.log(len(simulated))
    return total


def test_independent_error_matches_brute_force(rng: np.random.Generator) -> None:
    measured = rng.normal(size=(3, 2, 6))
    simulated = measured[:2] + 0.3 * rng.normal(size=(2, 2, 6))
    error = OutputError((0.4, 0.7))
    expected = _brute_force(measured, simulated, [0.4**2 * np.eye(6), 0.7**2 * np.eye(6)])
    assert log_likelihood(measured, simulated, error) == pytest.approx(expected, rel=1e-10)


def test_frequency_correlated_error_matches_brute_force(rng: np.random.Generator) -> None:
    f = np.linspace(1.0, 10.0, 8)
    measured = rng.normal(size=(2, 2, 8))
    simulated = rng.normal(size=(3, 2, 8))
    error = OutputError((0.5, 1.5), correlation_length_hz=2.0)
    corr = np.exp(-np.abs(f[:, None] - f[None, :]) / 2.0)
    expected = _brute_force(measured, simulated, [0.25 * corr, 2.25 * corr])
    got = log_likelihood(measured, simulated, error, frequencies_hz=f)
    assert got == pytest.approx(expected, rel=1e-8)


def test_log_sum_exp_is_stable_far_from_the_data(rng: np.random.Generator) -> None:
    measured = rng.normal(size=(2, 1, 50))
    simulated = measured[:1] + 40.0  # every p_B underflows in float64
    value = log_likelihood(measured, simulated, OutputError((0.1,)))
    assert np.isfinite(value) and value < -1e5


def test_batched_simulated_equals_loop(rng: np.random.Generator) -> None:
    measured = rng.normal(size=(2, 3, 5))
    batch = rng.normal(size=(4, 3, 3, 5))
    error = OutputError((0.5, 0.6, 0.7))
    got = log_likelihood(measured, batch, error)
    assert got.shape == (4,)
    np.testing.assert_allclose(got, [log_likelihood(measured, s, error) for s in batch])


def test_estimate_recovers_sigma_from_simulated_pilot(rng: np.random.Generator) -> None:
    truth = np.array([0.2, 0.5])
    simulated = rng.normal(size=(4, 2, 400))
    measured = simulated[[0, 2, 3]] + truth[None, :, None] * rng.normal(size=(3, 2, 400))
    est = estimate_output_error(measured, simulated)
    np.testing.assert_allclose(est.sigma, truth, rtol=0.05)
    assert est.correlation_length_hz is None


def test_estimate_from_replicates_and_correlation_length(rng: np.random.Generator) -> None:
    f = np.arange(2000) * 0.1
    rho = math.exp(-0.1 / 0.5)  # true exponential correlation, length 0.5 Hz
    noise = np.empty((6, 1, f.size))
    noise[..., 0] = rng.normal(size=(6, 1))
    for i in range(1, f.size):
        noise[..., i] = rho * noise[..., i - 1] + math.sqrt(1 - rho**2) * rng.normal(size=(6, 1))
    est = estimate_output_error(0.3 * noise, frequencies_hz=f, correlated=True)
    assert est.sigma[0] == pytest.approx(0.3 * math.sqrt(2.0), rel=0.1)
    assert est.correlation_length_hz == pytest.approx(0.5, rel=0.15)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"sigma": (0.1, -1.0)}, "sigma"),
        ({"sigma": (0.1,), "correlation_length_hz": 0.0}, "correlation_length_hz"),
    ],
)
def test_output_error_validation_names_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        OutputError(**kwargs)


def test_shape_and_value_errors(rng: np.random.Generator) -> None:
    error = OutputError((0.1, 0.2))
    with pytest.raises(ValueError, match="measured"):
        log_likelihood(rng.normal(size=(2, 3, 4)), rng.normal(size=(2, 2, 4)), error)
    bad = rng.normal(size=(2, 2, 4))
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="simulated"):
        log_likelihood(rng.normal(size=(2, 2, 4)), bad, error)
    with pytest.raises(ValueError, match="frequencies_hz"):
        log_likelihood(bad[1:], bad[1:], OutputError((0.1, 0.2), 1.0))


def test_expected_log_likelihood_at_truth_unpaired_matches_monte_carlo(
    rng: np.random.Generator,
) -> None:
    """ν = μ = 1, y − h ~ N(0, σ²) per channel: log L is exactly −½(ln|2πΣ| + χ²_CF)."""
    from susp_bo.calibration.likelihood import expected_log_likelihood_at_truth

    error = OutputError((0.1, 0.4))
    measured = rng.normal(size=(1, 2, 30))
    mean, sd = expected_log_likelihood_at_truth(error, measured)
    draws = [
        log_likelihood(
            measured,
            measured - np.array([0.1, 0.4])[None, :, None] * rng.normal(size=(1, 2, 30)),
            error,
        )
        for _ in range(4000)
    ]
    # 4000 draws: the sample mean's sd is sd / 63; the sample sd's relative sd ≈ 1.1 %
    assert np.mean(draws) == pytest.approx(mean, abs=5 * sd / math.sqrt(4000))
    assert np.std(draws) == pytest.approx(sd, rel=0.06)


@pytest.mark.parametrize(
    "grid",
    [np.zeros(6), np.full(6, np.nan), np.linspace(5.0, 1.0, 6), np.arange(3.0)],
    ids=["repeated", "nan", "decreasing", "wrong-length"],
)
def test_correlated_error_refuses_a_bad_frequency_grid(
    rng: np.random.Generator, grid: np.ndarray
) -> None:
    """A repeated, NaN, decreasing or short grid is refused naming ``frequencies_hz``, by
    both log L (not −3e13 or nan) and the estimate (not a negative or silent ℓ)."""
    measured = rng.normal(size=(3, 2, 6))
    with pytest.raises(ValueError, match="frequencies_hz"):
        log_likelihood(measured, measured[:2], OutputError((0.1, 0.1), 1.0), grid)
    with pytest.raises(ValueError, match="frequencies_hz"):
        estimate_output_error(measured, correlated=True, frequencies_hz=grid)


@pytest.mark.parametrize(
    ("measured", "simulated", "field"),
    [
        ((3, 2, 5), (0, 2, 5), "simulated"),
        ((0, 2, 5), (2, 2, 5), "measured"),
        ((3, 2, 0), (2, 2, 0), "measured"),
    ],
)
def test_log_likelihood_refuses_empty_spectra(
    rng: np.random.Generator, measured: tuple, simulated: tuple, field: str
) -> None:
    """μ = 0 or ν = 0 was a numpy reshape error, F = 0 returned log L = 0."""
    with pytest.raises(ValueError, match=rf"{field}: shape .* is empty"):
        log_likelihood(
            rng.normal(size=measured), rng.normal(size=simulated), OutputError((0.1, 0.2))
        )


def test_estimate_output_error_argument_checks(rng: np.random.Generator) -> None:
    """EM iterations < 1, a simulated grid of another F, NaN data and F = 1 with a
    correlation are refused naming the argument at fault (not sigma, not numpy)."""
    measured = rng.normal(size=(3, 2, 10))
    simulated = rng.normal(size=(4, 2, 10))
    for n in (0, -1):
        with pytest.raises(ValueError, match="em_iterations"):
            estimate_output_error(measured, simulated, em_iterations=n)
    with pytest.raises(TypeError, match="em_iterations"):
        estimate_output_error(measured, simulated, em_iterations=2.5)
    with pytest.raises(ValueError, match="simulated: shape"):
        estimate_output_error(measured, simulated[..., :5])
    bad = measured.copy()
    bad[0, 0, 0] = np.nan
    for sim in (None, simulated):
        with pytest.raises(ValueError, match="measured: contains NaN"):
            estimate_output_error(bad, sim)
    with pytest.raises(ValueError, match=r"measured: shape .* is empty"):
        estimate_output_error(measured[..., :0])
    with pytest.raises(ValueError, match="F ≥ 2"):
        estimate_output_error(measured[..., :1], correlated=True, frequencies_hz=np.ones(1))
    with pytest.raises(ValueError, match="floor"):
        estimate_output_error(measured, floor=math.inf)
