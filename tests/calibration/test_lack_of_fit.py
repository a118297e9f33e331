"""Lack of fit from replicate runs: exact answers on Gaussian residuals, the rule's limit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from susp_bo.calibration.lack_of_fit import LIMIT, lack_of_fit_ratio, systematic_misfit


@pytest.mark.parametrize("runs", [2, 3, 6])
def test_independent_residuals_give_about_one(runs: int) -> None:
    """Residuals independent between runs (an exact model): F ~ F(P, P(ν − 1)), mean ≈ 1;
    P = 10 x 48 = 480 bins, so its sd is below 0.1 and 4 seeds stay within ±0.35."""
    for seed in range(4):
        rng = np.random.default_rng([seed, runs])
        y = rng.normal(size=(runs, 10, 48))
        h = 0.3 * rng.normal(size=(runs, 10, 48))
        scale = rng.uniform(0.01, 1.0, size=(1, 10, 48))  # heteroscedastic bins
        ratio = lack_of_fit_ratio(h + scale * y, h)
        assert 0.65 < ratio < 1.35, (seed, ratio)


def test_a_residual_every_run_shares_is_found_and_scales_as_expected() -> None:
    """A common offset d on top of unit noise: E[F] ≈ 1 + ν d² (the lack-of-fit mean square
    ν d² + 1 over the pure error 1); d = 0.5 with ν = 3 gives ≈ 1.75, d = 1.5 ≈ 7.75."""
    rng = np.random.default_rng(7)
    noise = rng.normal(size=(3, 10, 48))
    for d, expected in ((0.5, 1.75), (1.5, 7.75)):
        assert lack_of_fit_ratio(noise + d, np.zeros_like(noise)) == pytest.approx(
            expected, rel=0.15
        )


def test_one_run_no_scatter_or_failed_spectra_give_nan_and_bad_shapes_are_refused() -> None:
    y = np.ones((1, 2, 5))
    assert math.isnan(lack_of_fit_ratio(y, y))
    assert math.isnan(lack_of_fit_ratio(np.ones((3, 2, 5)), np.zeros((3, 2, 5))))
    h = np.zeros((3, 2, 5))
    h[1, 0, 0] = np.nan
    assert math.isnan(lack_of_fit_ratio(np.ones((3, 2, 5)), h))
    with pytest.raises(ValueError, match="measured, simulated: shapes"):
        lack_of_fit_ratio(np.ones((3, 2, 5)), np.ones((3, 2, 4)))


def test_the_rule_fires_above_the_limit_only() -> None:
    assert systematic_misfit(LIMIT, 3) is None
    assert systematic_misfit(math.nan, 3) is None
    reason = systematic_misfit(23.5, 3)
    assert reason is not None and reason["code"] == "below_expected_fit"
    assert reason["lack_of_fit_ratio"] == 23.5
    assert "F = 23.5" in reason["message"] and "3 runs" in reason["message"]
