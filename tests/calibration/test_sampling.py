"""The surrogate posterior's sampler choice: "auto" keeps the random walk where it mixed
(bit for bit) and switches to reflective HMC where it did not, and says which it used."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
import torch

from susp_bo.calibration.mcmc import chain_diagnostics
from susp_bo.calibration.sampling import (
    HMC_CHAINS,
    mean_sd_at_draws,
    sample_surrogate_posterior,
)
from susp_bo.calibration.surrogate import Surrogate, SurrogateSettings
from susp_bo.calibration.surrogate_fit import fit_surrogate


def _banana(u: np.ndarray) -> np.ndarray:
    """x1 ~ N(0, 1), x2 | x1 ~ N(0.6 x1², 0.3²) (one link of the curved 5-D target)."""
    x1 = (u[:, 0] - 0.5) / 0.12
    x2 = (u[:, 1] - 0.25) / 0.1
    return -0.5 * x1**2 - 0.5 * ((x2 - 0.6 * x1**2) / 0.3) ** 2


def _gaussian(u: np.ndarray) -> np.ndarray:
    return -0.5 * np.sum(((u - 0.5) / 0.15) ** 2, axis=1)


def _surrogate(log_l: Callable[[np.ndarray], np.ndarray], seed: int) -> Surrogate:
    rng = np.random.default_rng(seed)
    t = rng.standard_normal(100)
    ridge = np.column_stack(
        [0.5 + 0.12 * t, 0.25 + 0.1 * (0.6 * t**2 + 0.3 * rng.standard_normal(100))]
    )
    x = np.vstack([rng.uniform(size=(150, 2)), np.clip(ridge, 0.0, 1.0)])
    return fit_surrogate(x, log_l(x), SurrogateSettings(), seed=0)


def test_auto_keeps_the_random_walk_bit_for_bit_where_it_mixed() -> None:
    surrogate = _surrogate(_gaussian, 1)
    kwargs = {"n_chains": 64, "warmup_steps": 100, "num_samples": 400, "seed": 3}
    walk, walk_diag = sample_surrogate_posterior(surrogate, sampler="random_walk", **kwargs)
    auto, auto_diag = sample_surrogate_posterior(surrogate, sampler="auto", **kwargs)
    r_hat, ess = chain_diagnostics(walk)
    assert float(r_hat.max()) <= 1.05 and float(ess.min()) >= 400  # the premise
    assert torch.equal(walk, auto)
    assert auto_diag == walk_diag and auto_diag["sampler"] == "random_walk"


def test_auto_switches_to_hmc_where_the_random_walk_did_not_mix() -> None:
    surrogate = _surrogate(_banana, 0)
    kwargs = {"n_chains": 32, "warmup_steps": 100, "num_samples": 300, "seed": 0}
    walk, _ = sample_surrogate_posterior(surrogate, sampler="random_walk", **kwargs)
    auto, diag = sample_surrogate_posterior(surrogate, sampler="auto", **kwargs)
    hmc, hmc_diag = sample_surrogate_posterior(surrogate, sampler="hmc", **kwargs)
    walk_r_hat = float(chain_diagnostics(walk)[0].max())
    assert walk_r_hat > 1.05  # the premise: the random walk did not mix
    assert diag["sampler"] == "hmc" and diag["random walk R-hat"] == pytest.approx(walk_r_hat)
    assert torch.equal(auto, hmc) and hmc_diag["sampler"] == "hmc"
    assert auto.shape == (32, 150, 2)  # HMC: half the draws
    r_hat, ess = chain_diagnostics(auto)
    assert float(r_hat.max()) <= 1.05 and float(ess.min()) >= 400
    # the same posterior as a random walk 25x as long (both within 5 Monte Carlo errors)
    long_walk, _ = sample_surrogate_posterior(
        surrogate, n_chains=64, warmup_steps=500, num_samples=4000, seed=1, sampler="random_walk"
    )
    ess_long = chain_diagnostics(long_walk)[1]
    sd = long_walk.reshape(-1, 2).std(0)
    error = sd * (1.0 / ess + 1.0 / ess_long).sqrt()
    z = (auto.reshape(-1, 2).mean(0) - long_walk.reshape(-1, 2).mean(0)) / error
    assert torch.all(z.abs() < 5.0), z


def test_hmc_runs_at_most_hmc_chains_chains_for_half_the_draws() -> None:
    surrogate = _surrogate(_gaussian, 1)
    draws, diag = sample_surrogate_posterior(
        surrogate, n_chains=HMC_CHAINS + 72, warmup_steps=2, num_samples=5, seed=0, sampler="hmc"
    )
    assert draws.shape == (HMC_CHAINS, 2, 2) and diag["sampler"] == "hmc"


def test_an_unknown_sampler_is_refused_by_name() -> None:
    surrogate = _surrogate(_gaussian, 1)
    with pytest.raises(ValueError, match="sampler: 'nuts', expected one of random_walk, hmc"):
        sample_surrogate_posterior(
            surrogate, n_chains=4, warmup_steps=1, num_samples=1, seed=0, sampler="nuts"
        )


def test_mean_sd_at_draws_is_small_where_evaluated_and_large_where_not() -> None:
    """The ``not_converged`` sub-rule's number: draws among the training points against
    draws in a corner no evaluation came near (the GP knows it does not know there)."""
    rng = np.random.default_rng(4)
    x = rng.uniform(0.3, 0.7, size=(120, 2))
    y = _gaussian(x) + 2.0 * np.sin(9.0 * x[:, 0]) * np.cos(7.0 * x[:, 1])  # no quadratic
    surrogate = fit_surrogate(x, y, SurrogateSettings(), seed=0)
    inside = torch.as_tensor(rng.uniform(0.35, 0.65, size=(4, 500, 2)))
    corner = torch.as_tensor(rng.uniform(0.0, 0.08, size=(4, 500, 2)))
    near = mean_sd_at_draws(surrogate, inside)
    far = mean_sd_at_draws(surrogate, corner)
    assert near < 0.3 < far, (near, far)
    # deterministic (evenly spaced draws, no random state) and chain-pooled
    assert mean_sd_at_draws(surrogate, inside) == near
    assert mean_sd_at_draws(surrogate, inside.reshape(-1, 2)) == pytest.approx(near)
    assert np.isnan(mean_sd_at_draws(surrogate, inside[:, :0]))
