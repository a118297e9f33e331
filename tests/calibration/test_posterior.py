"""Posterior summaries: MAPs, the paper's interval, KDE, JSON and ArviZ export."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from scipy import stats

from susp_bo.calibration.posterior import (
    PosteriorSummary,
    marginal_density,
    marginal_map,
    summarize,
    to_inference_data,
)

BOUNDS = np.array([[0.0, 10.0], [1.0, 30.0]])


def _gaussian_draws(rng: np.random.Generator) -> np.ndarray:
    """(4 chains x 5000 x 2) unit-cube draws of N((0.4, 0.6), diag(0.05², 0.1²))."""
    return np.stack([rng.normal([0.4, 0.6], [0.05, 0.1], size=(5000, 2)) for _ in range(4)])


def test_summary_of_gaussian_draws(rng: np.random.Generator) -> None:
    draws = _gaussian_draws(rng)

    def log_density(u: torch.Tensor) -> torch.Tensor:
        return -0.5 * (((u - torch.tensor([0.4, 0.6])) / torch.tensor([0.05, 0.1])) ** 2).sum(-1)

    s = summarize(draws, BOUNDS, ["a", "b"], log_density)
    width = BOUNDS[1] - BOUNDS[0]
    truth = BOUNDS[0] + width * np.array([0.4, 0.6])
    np.testing.assert_allclose(s.joint_map, truth, atol=1e-6 * width.max())
    assert np.all(np.abs(s.marginal_map - truth) < 0.25 * width * np.array([0.05, 0.1]))
    # the paper's interval: symmetric around the marginal MAP, 1.96 sd wide for a Gaussian
    half = 0.5 * (s.interval95[:, 1] - s.interval95[:, 0])
    np.testing.assert_allclose(half, 1.96 * width * np.array([0.05, 0.1]), rtol=0.03)
    np.testing.assert_allclose(s.equal_tailed95[:, 0], truth - half, rtol=0.02)
    assert np.all(s.r_hat < 1.01) and np.all(s.ess > 10000)
    d = s.to_dict()
    assert json.loads(json.dumps(d)) == d
    assert d["parameters"] == ["a", "b"] and len(d["interval95"]) == 2


def test_paper_interval_holds_95_percent_for_a_skewed_marginal(rng: np.random.Generator) -> None:
    u = rng.beta(2.0, 8.0, size=(2, 20000, 1))
    s = summarize(u, BOUNDS[:, :1], ["x"])
    lo, hi = s.interval95[0]
    flat = u.reshape(-1)
    assert np.mean((flat >= lo) & (flat <= hi)) == pytest.approx(0.95, abs=0.005)
    assert lo == 0.0  # clipped at the bound: no mass below it
    assert s.marginal_map[0] == pytest.approx(1.0 / 8.0, abs=0.02)  # beta(2, 8) mode


def test_kde_normalised_and_reflected_at_bounds(rng: np.random.Generator) -> None:
    x = rng.exponential(0.1, size=50000)
    x = x[x < 1.0]
    grid = np.linspace(0.0, 1.0, 2001)
    dens = marginal_density(x, grid, (0.0, 1.0))
    assert np.trapezoid(dens, grid) == pytest.approx(1.0, abs=1e-3)
    exact = stats.expon(scale=0.1).pdf(grid) / stats.expon(scale=0.1).cdf(1.0)
    assert dens[0] == pytest.approx(exact[0], rel=0.1)  # no boundary bias at 0
    assert marginal_map(x, (0.0, 1.0)) < 0.01


def test_arviz_export(rng: np.random.Generator) -> None:
    draws = rng.normal(size=(3, 100, 2))
    idata = to_inference_data(draws, ["a", "b"])
    assert idata.posterior["a"].shape == (3, 100)
    np.testing.assert_array_equal(idata.posterior["b"].values, draws[:, :, 1])


def test_summary_validation() -> None:
    with pytest.raises(ValueError, match="joint_map"):
        PosteriorSummary(
            ("a",),
            np.zeros(2),
            np.zeros(1),
            np.zeros((1, 2)),
            np.zeros((1, 2)),
            np.zeros(1),
            np.zeros(1),
            np.zeros(1),
            np.zeros(1),
        )
