"""Robustness targets: exact marginals against the density itself (importance sampling
from a proposal that does not use the target's sampler, and 2-D quadrature), the noise."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import special, stats

from susp_bo.calibration.test_functions import (
    AnalyticTarget,
    CurvedChainBlock,
    GaussianMixtureBlock,
    StudentTBlock,
    curved_chain_5d,
    noisy_gaussian_7d,
    student_t_6d,
    trimodal_5d,
)


def _t_proposal(
    centres: np.ndarray, cov: np.ndarray, n: int, rng: np.random.Generator, nu: float = 4.0
) -> tuple[np.ndarray, np.ndarray]:
    """Equal-weight mixture of multivariate t's at ``centres``: draws, log density."""
    d = cov.shape[0]
    comp = rng.integers(len(centres), size=n)
    g = rng.gamma(nu / 2, 2 / nu, size=n)
    z = rng.multivariate_normal(np.zeros(d), cov, size=n) / np.sqrt(g)[:, None]
    x = centres[comp] + z
    logs = np.stack([stats.multivariate_t.logpdf(x, c, cov, df=nu) for c in centres], axis=1)
    return x, special.logsumexp(logs, axis=1) - np.log(len(centres))


def _importance_check(
    target: AnalyticTarget,
    centres: np.ndarray,
    cov: np.ndarray,
    n: int = 400_000,
    nu: float = 4.0,
) -> None:
    """Weighted histograms of every marginal (weights exp(log L) / proposal, box only)
    against the bin masses of ``marginal_pdf``: agreement within Monte Carlo error."""
    rng = np.random.default_rng(11)
    # in box-scaled units (scipy's multivariate_t drops directions of a covariance whose
    # entries span 1e-3 to 1e9, as physical units do); the Jacobian is a constant
    width = target.bounds[1] - target.bounds[0]
    u, log_r = _t_proposal(centres / width, cov / np.outer(width, width), n, rng, nu)
    x = u * width
    inside = np.all((x >= target.bounds[0]) & (x <= target.bounds[1]), axis=1)
    logw = np.where(inside, target.log_likelihood(x) - log_r, -np.inf)
    w = np.exp(logw - logw.max())
    w /= w.sum()
    ess = 1.0 / np.sum(w**2)
    assert ess > 5_000 and w.max() < 0.01, (ess, w.max())
    for k in range(target.dim):
        edges = np.linspace(target.bounds[0, k], target.bounds[1, k], 41)
        fine = np.linspace(edges[0], edges[-1], 40 * 200 + 1)
        pdf = target.marginal_pdf(k, fine)
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (pdf[1:] + pdf[:-1]) * np.diff(fine))])
        exact = np.diff(cum[::200])
        got = np.histogram(x[:, k], bins=edges, weights=w)[0]
        # delta-method sd of a self-normalised estimate: Σ w_i² (1[x_i in bin] − p)²
        which = np.clip(np.searchsorted(edges, x[:, k]) - 1, 0, len(exact) - 1)
        sd = np.array(
            [np.sqrt(np.sum(w**2 * ((which == b) - exact[b]) ** 2)) for b in range(len(exact))]
        )
        # plus the largest single weight: one draw in a bin is the estimate's resolution
        tol = 5.0 * sd + 2.0 * w.max() + 2e-4
        assert np.all(np.abs(got - exact) < tol), (k, np.max(np.abs(got - exact) / tol))
        assert cum[-1] == pytest.approx(1.0, abs=1e-4)


def test_curved_chain_marginals_match_the_density() -> None:
    target = curved_chain_5d()
    # proposal: a mixture of t's at 48 exact draws (it follows the curved ridges; any
    # proposal covering the support gives a consistent estimate of the density's marginals)
    draws = target.sample(20_000, seed=3)
    cov = np.cov(draws.T) * 0.6**2
    _importance_check(target, draws[:48], cov, n=200_000)


def test_student_t_truncated_marginals_match_the_density() -> None:
    target = student_t_6d()
    block = target.blocks[0]
    assert isinstance(block, StudentTBlock)
    # the box really truncates: some of each untruncated marginal lies outside it
    lo = (target.bounds[0] - block.loc) / block.scale
    hi = (target.bounds[1] - block.loc) / block.scale
    outside = stats.t.cdf(lo, 3) + stats.t.sf(hi, 3)
    assert np.all(outside > 1e-3)
    # proposal tails (ν = 2) heavier than the target's (ν = 3): bounded weights
    cov = np.diag((1.5 * block.scale) ** 2)
    _importance_check(target, block.loc[None, :], cov, n=200_000, nu=2.0)


def test_trimodal_marginals_match_the_density() -> None:
    target = trimodal_5d()
    block = target.blocks[0]
    assert isinstance(block, GaussianMixtureBlock)
    # equal-weight proposal at the modes: checks the weights 0.5 / 0.3 / 0.2 too
    cov = np.mean(block.covariances, axis=0) * 2.0
    _importance_check(target, block.means, cov)


def test_modes_are_well_separated_and_weighted_as_stated() -> None:
    block = trimodal_5d().blocks[0]
    draws = block.sample(60_000, np.random.default_rng(0))
    nearest = np.argmin(
        [
            np.sum((draws - m) ** 2 / np.diag(c), axis=1)
            for m, c in zip(block.means, block.covariances)
        ],
        axis=0,
    )
    np.testing.assert_allclose(np.bincount(nearest) / draws.shape[0], [0.5, 0.3, 0.2], atol=0.01)
    for i in range(3):
        for j in range(i + 1, 3):
            gap = np.abs(block.means[i] - block.means[j])
            sd = np.sqrt(np.minimum(np.diag(block.covariances[i]), np.diag(block.covariances[j])))
            assert np.sum(gap / sd > 9.0) >= 2


def _grid_marginals(block, lower: np.ndarray, upper: np.ndarray, n: int = 1201):
    g0, g1 = np.linspace(lower[0], upper[0], n), np.linspace(lower[1], upper[1], n)
    a, b = np.meshgrid(g0, g1, indexing="ij")
    p = np.exp(block.log_density(np.column_stack([a.ravel(), b.ravel()]))).reshape(a.shape)
    m0, m1 = np.trapezoid(p, g1, axis=1), np.trapezoid(p, g0, axis=0)
    return (g0, m0 / np.trapezoid(m0, g0)), (g1, m1 / np.trapezoid(m1, g1))


@pytest.mark.parametrize("kind", ["chain", "student"])
def test_two_dimensional_blocks_agree_with_brute_force_quadrature(kind: str) -> None:
    if kind == "chain":
        block = CurvedChainBlock(np.array([0.0, 0.0]), np.array([1.0, 2.0]))
        lower, upper = np.array([-6.0, -8.0]), np.array([6.0, 30.0])
    else:  # heavily truncated: the exact marginal must include the cut
        block = StudentTBlock(np.array([0.0, 1.0]), np.array([1.0, 0.5]), nu=3.0)
        lower, upper = np.array([-2.0, -1.0]), np.array([5.0, 2.5])
    for k, (grid, brute) in enumerate(_grid_marginals(block, lower, upper)):
        exact = block.marginal_pdf(k, grid, lower, upper)
        assert 0.5 * np.trapezoid(np.abs(exact - brute), grid) < 2e-3


def test_boxes_that_cut_the_chain_or_a_mode_are_refused() -> None:
    block = CurvedChainBlock(np.array([0.5, 0.5]), np.array([0.1, 0.1]))
    with pytest.raises(ValueError, match="component 1 of the chain loses"):
        AnalyticTarget("cut", np.array([[0.0, 0.2], [1.0, 0.6]]), (block,))
    mix = trimodal_5d().blocks[0]
    box = trimodal_5d().bounds.copy()
    box[1, 0] = 0.75  # the second mode sits at 0.7 with sd 0.03
    with pytest.raises(ValueError, match="±6 sd"):
        AnalyticTarget("cut", box, (mix,))


def test_noisy_target_adds_unit_noise_reproducibly() -> None:
    target = noisy_gaussian_7d()
    x = target.sample(20_000, seed=0)
    exact = target.exact.log_likelihood(x)
    first = target(x) - exact
    assert np.std(first) == pytest.approx(1.0, abs=0.02)
    assert abs(np.mean(first)) < 0.03
    second = target(x) - exact
    assert not np.allclose(first, second)  # fresh noise on every call
    replay = target.reseeded(0)
    np.testing.assert_array_equal(replay(x) - exact, first)
    np.testing.assert_array_equal(replay(x) - exact, second)
    other = target.reseeded(1)(x) - exact
    assert abs(np.corrcoef(other, first)[0, 1]) < 0.05
    # the exact posterior is the noiseless target's
    grid = np.linspace(target.bounds[0, 2], target.bounds[1, 2], 11)
    np.testing.assert_array_equal(target.marginal_pdf(2, grid), target.exact.marginal_pdf(2, grid))
    with pytest.raises(ValueError, match="noise_sd"):
        type(target)(target.exact, 0.0)
