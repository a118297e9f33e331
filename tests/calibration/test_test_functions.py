"""The analytic targets: exact sampler and exact marginals agree; log L peaks where stated."""

from __future__ import annotations

import numpy as np
import pytest

from susp_bo.calibration.test_functions import TARGETS, marginal_total_variation


@pytest.mark.parametrize("name", sorted(TARGETS))
def test_exact_draws_match_exact_marginals(name: str) -> None:
    target = TARGETS[name]()
    draws = target.sample(40000, seed=1)
    assert draws.shape == (40000, target.dim)
    assert np.all(draws >= target.bounds[0]) and np.all(draws <= target.bounds[1])
    tv = marginal_total_variation(target, draws)
    assert np.all(tv < 0.02), tv  # KDE + Monte Carlo floor at 4e4 draws is about 0.008
    grid = np.linspace(target.bounds[0, 0], target.bounds[1, 0], 3001)
    assert np.trapezoid(target.marginal_pdf(0, grid), grid) == pytest.approx(1.0, abs=1e-4)


def test_mmtv_detects_a_shifted_posterior() -> None:
    target = TARGETS["correlated_gaussian_7d"]()
    draws = target.sample(20000, seed=2)
    shifted = draws + 0.5 * draws.std(0)
    assert marginal_total_variation(target, shifted).mean() > 0.15


def test_gaussian_log_likelihood_peaks_at_its_mean() -> None:
    target = TARGETS["correlated_gaussian_7d"]()
    mean = target.blocks[0].mean
    assert target.log_likelihood(mean[None])[0] == pytest.approx(target.offset)
    assert np.all(target.log_likelihood(target.sample(100, 0)) < target.offset)
