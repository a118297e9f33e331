"""The MH kernel is exact: moments match the truth and emcee; both drivers agree."""

from __future__ import annotations

import math

import emcee
import numpy as np
import pytest
import torch

from susp_bo.calibration.mcmc import (
    RandomWalkMetropolis,
    chain_diagnostics,
    run_pyro,
    run_vectorized,
)

Q = 4
_A = torch.tensor(
    [[1.0, 0.0, 0.0, 0.0], [0.8, 0.6, 0.0, 0.0], [-0.5, 0.3, 0.7, 0.0], [0.2, -0.4, 0.1, 0.5]],
    dtype=torch.float64,
)
COV = (
    _A
    @ _A.T
    * torch.tensor([1.0, 2.0, 0.5, 3.0], dtype=torch.float64)
    .sqrt()
    .outer(torch.tensor([1.0, 2.0, 0.5, 3.0], dtype=torch.float64).sqrt())
)
MEAN = torch.tensor([1.0, -2.0, 0.5, 3.0], dtype=torch.float64)
PREC = torch.linalg.inv(COV)


def gaussian_potential(w: torch.Tensor) -> torch.Tensor:
    r = w - MEAN
    return 0.5 * torch.einsum("bi,ij,bj->b", r, PREC, r)


def banana_potential(w: torch.Tensor) -> torch.Tensor:
    """x1 ~ N(0, 1), x2 | x1 ~ N(x1², 0.5²): E[x2] = 1, Var[x2] = 2 + 0.25."""
    return 0.5 * w[:, 0] ** 2 + 0.5 * ((w[:, 1] - w[:, 0] ** 2) / 0.5) ** 2


def _starts(n: int, q: int, seed: int) -> torch.Tensor:
    return 2.0 * torch.randn(n, q, generator=torch.Generator().manual_seed(seed))


def _check_mean(draws: torch.Tensor, truth: torch.Tensor, sd: torch.Tensor) -> None:
    """Posterior means within 5 Monte Carlo standard errors (ESS from Pyro's diagnostics)."""
    _, ess = chain_diagnostics(draws)
    flat = draws.reshape(-1, draws.shape[-1])
    z = (flat.mean(0) - truth) / (sd / ess.sqrt())
    assert torch.all(z.abs() < 5.0), z


def test_gaussian_moments_vectorized_and_pyro_are_identical() -> None:
    kernel = RandomWalkMetropolis(gaussian_potential, _starts(32, Q, 0), seed=7)
    draws = run_vectorized(kernel, 2500, 800)
    again = run_pyro(RandomWalkMetropolis(gaussian_potential, _starts(32, Q, 0), seed=7), 2500, 800)
    torch.testing.assert_close(draws, again, rtol=0, atol=0)  # same kernel, same draws
    _check_mean(draws, MEAN, COV.diagonal().sqrt())
    flat = draws.reshape(-1, Q)
    torch.testing.assert_close(torch.cov(flat.T), COV, atol=0.08 * COV.diagonal().max(), rtol=0.05)
    r_hat, ess = chain_diagnostics(draws)
    assert torch.all(r_hat < 1.02) and torch.all(ess > 2000)
    assert abs(kernel.diagnostics()["acceptance rate"] - 0.28) < 0.05


def test_banana_moments_match_truth_and_emcee() -> None:
    kernel = RandomWalkMetropolis(banana_potential, _starts(64, 2, 1) * 0.3, seed=3)
    draws = run_pyro(kernel, 2000, 1000)
    truth_mean = torch.tensor([0.0, 1.0], dtype=torch.float64)
    truth_sd = torch.tensor([1.0, math.sqrt(2.25)], dtype=torch.float64)
    _check_mean(draws, truth_mean, truth_sd)
    flat = draws.reshape(-1, 2)
    torch.testing.assert_close(flat.std(0), truth_sd, rtol=0.06, atol=0.0)

    sampler = emcee.EnsembleSampler(
        32, 2, lambda x: -banana_potential(torch.as_tensor(x)).numpy(), vectorize=True
    )
    sampler.random_state = np.random.RandomState(5).get_state()
    state = sampler.run_mcmc(np.random.default_rng(5).normal(size=(32, 2)) * 0.3, 1000)
    sampler.reset()
    sampler.run_mcmc(state, 4000)
    em = torch.as_tensor(sampler.get_chain()).transpose(0, 1)  # walkers x n x 2
    _, ess_em = chain_diagnostics(em)
    _, ess = chain_diagnostics(draws)
    diff = flat.mean(0) - em.reshape(-1, 2).mean(0)
    se = truth_sd * (1.0 / ess + 1.0 / ess_em).sqrt()
    assert torch.all(diff.abs() < 5.0 * se), (diff, se)

    # standard deviations within 4 of their combined Monte Carlo errors: se(sd) =
    # sd sqrt((kurtosis - 1) / (4 ESS)); x2 is skewed and heavy (kurtosis ~ 9), so its sd
    # carries a 3-4 % Monte Carlo error for each sampler here
    def sd_and_se(x: torch.Tensor, n_eff: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        centred = x.reshape(-1, 2) - x.reshape(-1, 2).mean(0)
        kurtosis = (centred**4).mean(0) / (centred**2).mean(0) ** 2
        sd = centred.std(0)
        return sd, sd * ((kurtosis - 1.0) / (4.0 * n_eff)).sqrt()

    (sd, sd_se), (sd_em, sd_em_se) = sd_and_se(draws, ess), sd_and_se(em, ess_em)
    assert torch.all((sd - sd_em).abs() < 4.0 * (sd_se**2 + sd_em_se**2).sqrt()), (sd, sd_em)


def test_support_is_respected_and_nan_potential_rejected() -> None:
    def boxed(w: torch.Tensor) -> torch.Tensor:
        inside = torch.all((w >= 0) & (w <= 1), dim=1)
        u = torch.zeros(w.shape[0], dtype=torch.float64)
        u[w[:, 0] > 0.9] = math.nan
        return torch.where(inside, u, torch.full_like(u, math.inf))

    start = torch.full((16, 2), 0.5, dtype=torch.float64)
    draws = run_vectorized(RandomWalkMetropolis(boxed, start, seed=0), 3000, 500)
    flat = draws.reshape(-1, 2)
    assert flat.min() >= 0.0 and flat.max() <= 1.0 and flat[:, 0].max() <= 0.9
    # uniform on [0, 0.9] x [0, 1]
    assert float(flat[:, 0].mean()) == pytest.approx(0.45, abs=0.02)
    assert float(flat[:, 1].mean()) == pytest.approx(0.5, abs=0.02)


def test_kernel_is_deterministic_and_does_not_touch_global_rng() -> None:
    torch.manual_seed(123)
    before = torch.get_rng_state()
    a = run_vectorized(RandomWalkMetropolis(gaussian_potential, _starts(4, Q, 0), seed=1), 50, 20)
    assert torch.equal(torch.get_rng_state(), before)
    b = run_vectorized(RandomWalkMetropolis(gaussian_potential, _starts(4, Q, 0), seed=1), 50, 20)
    c = run_vectorized(RandomWalkMetropolis(gaussian_potential, _starts(4, Q, 0), seed=2), 50, 20)
    assert torch.equal(a, b) and not torch.equal(a, c)


def test_invalid_arguments() -> None:
    with pytest.raises(ValueError, match="initial_params"):
        RandomWalkMetropolis(gaussian_potential, torch.zeros(Q, dtype=torch.float64))
    with pytest.raises(ValueError, match="target_accept"):
        RandomWalkMetropolis(gaussian_potential, _starts(2, Q, 0), target_accept=1.5)
    with pytest.raises(ValueError, match="finite"):
        RandomWalkMetropolis(lambda w: torch.full((w.shape[0],), math.inf), _starts(2, Q, 0))


@pytest.mark.parametrize("shape", [(4, 3, 2), (4, 0, 2), (4, 10)])
def test_chain_diagnostics_needs_four_draws_per_chain(shape: tuple[int, ...]) -> None:
    """Pyro's split R-hat asserts >= 4 draws per chain: a bare AssertionError before."""
    with pytest.raises(ValueError, match=r"draws: shape .* n_draws >= 4"):
        chain_diagnostics(torch.zeros(shape, dtype=torch.float64))


def test_a_constant_component_leaves_the_others_diagnostics_alone() -> None:
    """A pinned parameter has no R-hat or ESS (NaN); Pyro's batched ESS made every one NaN."""
    moving = torch.as_tensor(np.random.default_rng(0).uniform(size=(4, 100, 1)))
    pinned = torch.full((4, 100, 1), 0.3, dtype=torch.float64)
    r_hat, ess = chain_diagnostics(torch.cat([pinned, moving], dim=2))
    alone = chain_diagnostics(moving)
    assert torch.isnan(r_hat[0]) and torch.isnan(ess[0])
    assert torch.equal(r_hat[1:], alone[0]) and torch.equal(ess[1:], alone[1])
    r_hat, ess = chain_diagnostics(pinned)
    assert torch.isnan(r_hat).all() and torch.isnan(ess).all()


def test_a_warm_up_step_where_every_chain_jumped_leaves_the_scale_finite() -> None:
    """Review, session 25: with a given mixture and few chains, a warm-up step where every
    chain jumped adapted the random-walk scale on no proposal at all: NaN (9 of 20 seeds
    with 4 chains), and the random-walk moves died."""
    from susp_bo.calibration.mode_jumps import MixtureProposal

    def potential(w: torch.Tensor) -> torch.Tensor:
        a = -0.5 * (((w - 0.3) / 0.08) ** 2).sum(-1)
        b = -0.5 * (((w - 0.8) / 0.016) ** 2).sum(-1) + 2 * math.log(5.0)
        return -torch.logaddexp(a, b)

    g = torch.Generator().manual_seed(0)
    draws = torch.cat(
        [
            0.3 + 0.08 * torch.randn(2, 100, 2, generator=g, dtype=torch.float64),
            0.8 + 0.016 * torch.randn(2, 100, 2, generator=g, dtype=torch.float64),
        ]
    )
    mixture = MixtureProposal.of_chains(draws, [torch.arange(2), torch.arange(2, 4)])
    for seed in range(20):
        kernel = RandomWalkMetropolis(
            potential,
            draws[:, -1, :],
            proposal_cov=0.03**2 * torch.eye(2, dtype=torch.float64),
            seed=seed,
            jump_probability=0.3,
            mixture=mixture,
        )
        run_vectorized(kernel, 50, 300)
        assert math.isfinite(float(kernel.diagnostics()["scale"])), seed
