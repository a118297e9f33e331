"""Posterior summaries: MAPs, the paper's interval, KDE, JSON and ArviZ export."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from scipy import stats

from susp_bo.calibration.posterior import (
    PosteriorSummary,
    kde_bandwidth,
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


@pytest.mark.parametrize("field", ["interval95", "equal_tailed95"])
@pytest.mark.parametrize("row", [[2.0, 1.0], [np.nan, 1.0]])
def test_summary_refuses_an_inverted_interval(field: str, row: list[float]) -> None:
    arrays = {"interval95": np.array([[0.0, 1.0], [0.0, 1.0]])}
    arrays["equal_tailed95"] = arrays["interval95"].copy()
    arrays[field] = np.array([[0.0, 1.0], row])
    with pytest.raises(ValueError, match=rf"{field}: not an interval .* for b;"):
        PosteriorSummary(("a", "b"), *[np.zeros(2)] * 2, arrays["interval95"],
                         arrays["equal_tailed95"], *[np.zeros(2)] * 4)  # fmt: skip


@pytest.mark.parametrize("n_draws", [0, 1, 3])
def test_summary_needs_four_draws_per_chain(n_draws: int, rng: np.random.Generator) -> None:
    with pytest.raises(ValueError, match=rf"draws_unit: {n_draws} draws per chain .* >= 4"):
        summarize(rng.uniform(size=(4, n_draws, 2)), BOUNDS, ["a", "b"])


@pytest.mark.parametrize(("shift", "shown"), [(5.0, "outside the unit cube"), (np.nan, "nan")])
def test_summary_refuses_draws_outside_the_unit_cube(
    shift: float, shown: str, rng: np.random.Generator
) -> None:
    """Outside draws gave an inverted interval95 ([3.6, 1.0]), NaN ones a numpy error."""
    draws = rng.uniform(size=(4, 100, 2))
    draws[1, 7, 0] += shift
    with pytest.raises(ValueError, match=rf"draws_unit: 1 values .*{shown}"):
        summarize(draws, BOUNDS, ["a", "b"])


@pytest.mark.parametrize("log_density", [None, lambda u: -((u - 0.3) ** 2).sum(-1)])
def test_summary_of_a_pinned_parameter(log_density: object, rng: np.random.Generator) -> None:
    """Constant draws of one parameter crashed numpy's histogram ("Too many bins")."""
    draws = np.stack([np.full((4, 400), 0.3), rng.uniform(size=(4, 400))], axis=-1)
    s = summarize(draws, BOUNDS, ["a", "b"], log_density)  # type: ignore[arg-type]
    pinned = BOUNDS[0, 0] + 0.3 * (BOUNDS[1, 0] - BOUNDS[0, 0])
    assert s.marginal_map[0] == pytest.approx(pinned, abs=1e-6)
    np.testing.assert_allclose(s.interval95[0], [pinned, pinned], atol=1e-6)
    np.testing.assert_allclose(s.equal_tailed95[0], [pinned, pinned], atol=1e-12)
    assert s.joint_map[0] == pytest.approx(pinned, abs=1e-9) and s.sd[0] < 1e-12
    assert np.isfinite(s.marginal_map[1]) and np.all(np.isfinite(s.interval95))
    assert np.isnan(s.r_hat[0]) and np.isnan(s.ess[0])  # no mixing to speak of
    assert np.isfinite(s.r_hat[1]) and np.isfinite(s.ess[1])
    assert marginal_map(np.full(1000, 0.3), (0.0, 1.0)) == pytest.approx(0.3, abs=1e-6)


def test_the_bandwidth_of_draws_a_few_ulps_wide_stays_at_their_scale() -> None:
    """Draws whose spread is not resolvable in float64 get the least resolvable bandwidth,
    not a jump to 1e-6 of their magnitude; constant draws keep that; others are untouched."""
    x = np.full(400, 4.4e6)
    x[::2] = np.nextafter(4.4e6, 5e6)
    h = kde_bandwidth(x)
    assert 0 < h < 1e-4  # was 1e-6 x 4.4e6 x 0.9 n^-0.2 = 1.2
    grid = np.linspace(x.min() - 6 * h, x.max() + 6 * h, 2048)
    assert np.unique(grid).size == grid.size  # distinct bins
    assert kde_bandwidth(np.full(400, 4.4e6)) == pytest.approx(0.9 * 4.4 * 400**-0.2)
    y = np.random.default_rng(0).normal(size=1000)
    iqr = np.subtract(*np.percentile(y, [75, 25]))
    assert kde_bandwidth(y) == 0.9 * min(np.std(y), iqr / 1.34) * 1000 ** (-0.2)


def test_repeated_names_are_refused(rng: np.random.Generator) -> None:
    """to_inference_data kept one variable of two named alike."""
    draws = rng.uniform(size=(2, 10, 2))
    with pytest.raises(ValueError, match=r"names: \['a', 'a'\] .*'a' is given more than once"):
        to_inference_data(draws, ["a", "a"])
    with pytest.raises(ValueError, match=r"names: .*'a' is given more than once"):
        summarize(draws, BOUNDS, ["a", "a"])
