"""MCMC on the surrogate posterior (step 4 glue between surrogate and MH kernel).

The posterior on the unit cube is π(u) ∝ L̃(u) · 1[u ∈ [0, 1]^q] (uniform prior on
C_w; the Jacobian of the affine map to physical units is constant). Three choices
of L̃ from the GP:

- ``"plug_in"`` (default): log L̃ = the GP mean mapped back through the warping (the
  median of log L̃; with no warping the plain GP mean of log L). Mean-only, fastest.
- ``"mean_log"``: E[log L̃] (exact lognormal moment of the warping).
- ``"expected"``: log E[L̃], the paper's E[L̃] = exp(μ + σ²/2) (Gauss–Hermite under
  warping). Optimistic where the GP is uncertain.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal

import numpy as np
import torch

from susp_bo.calibration.mcmc import RandomWalkMetropolis, run_pyro, run_vectorized
from susp_bo.calibration.surrogate import Surrogate

Estimator = Literal["plug_in", "mean_log", "expected"]
Backend = Literal["vectorized", "pyro"]


def surrogate_log_likelihood(
    surrogate: Surrogate, estimator: Estimator = "plug_in"
) -> Callable[[torch.Tensor], torch.Tensor]:
    """The surrogate log L̃ on the unit cube, (m x q) -> (m,), for the chosen estimator."""
    if estimator == "plug_in":
        return lambda u: surrogate.warping.plug_in(surrogate.latent_mean(u))
    if estimator == "mean_log":
        return surrogate.log_likelihood_mean
    if estimator == "expected":
        return surrogate.log_expected_likelihood
    raise ValueError(f"estimator: {estimator!r}, expected 'plug_in', 'mean_log' or 'expected'")


def surrogate_potential(
    surrogate: Surrogate, estimator: Estimator = "plug_in"
) -> Callable[[torch.Tensor], torch.Tensor]:
    """Potential U(u) = −log L̃(u) inside the unit cube, +inf outside."""
    log_l = surrogate_log_likelihood(surrogate, estimator)

    def potential(u: torch.Tensor) -> torch.Tensor:
        inside = torch.all((u >= 0.0) & (u <= 1.0), dim=-1)
        value = -log_l(u.clamp(0.0, 1.0))
        return torch.where(inside, value, torch.full_like(value, math.inf))

    return potential


def initial_positions(
    x_unit: np.ndarray, y: np.ndarray, n_chains: int, seed: int, jitter: float = 0.01
) -> torch.Tensor:
    """Chain starts: training points drawn with probability ∝ exp(y − max y), jittered.

    Args:
        x_unit: (n x q) unit-cube training inputs.
        y: (n,) finite log L values.
        n_chains: number of chains.
        seed: seed of the draw.
        jitter: standard deviation of the Gaussian jitter (unit-cube units).

    Returns:
        (n_chains x q) starts strictly inside the unit cube.
    """
    rng = np.random.default_rng(seed)
    w = np.exp(np.asarray(y) - np.max(y))
    idx = rng.choice(len(w), size=n_chains, p=w / w.sum())
    starts = x_unit[idx] + jitter * rng.standard_normal((n_chains, x_unit.shape[1]))
    return torch.as_tensor(np.clip(starts, 1e-6, 1.0 - 1e-6), dtype=torch.float64)


def sample_surrogate_posterior(
    surrogate: Surrogate,
    *,
    n_chains: int,
    warmup_steps: int,
    num_samples: int,
    seed: int,
    estimator: Estimator = "plug_in",
    backend: Backend = "vectorized",
    thin: int = 1,
    progress: bool = False,
) -> tuple[torch.Tensor, dict[str, float]]:
    """Runs the MH kernel on the surrogate posterior.

    Args:
        surrogate: the fitted surrogate.
        n_chains: number of chains, vectorised in one kernel step.
        warmup_steps: adaptation steps (discarded).
        num_samples: sampling steps per chain.
        seed: seed of starts and kernel.
        estimator: how L̃ is taken from the GP (module docstring).
        backend: "vectorized" (plain torch loop) or "pyro" (``pyro.infer.MCMC``).
        thin: keep every thin-th step (vectorized backend only).
        progress: a progress bar of the kernel steps on stderr.

    Returns:
        ((n_chains x draws x q) unit-cube draws, kernel diagnostics).
    """
    x = surrogate.train_x.numpy()
    starts = initial_positions(x, surrogate.train_y, n_chains, seed)
    q = x.shape[1]
    kernel = RandomWalkMetropolis(
        surrogate_potential(surrogate, estimator),
        starts,
        proposal_cov=(0.03**2) * torch.eye(q, dtype=torch.float64),
        seed=seed,
    )
    with torch.no_grad():
        if backend == "vectorized":
            draws = run_vectorized(kernel, num_samples, warmup_steps, thin, progress)
        elif backend == "pyro":
            draws = run_pyro(kernel, num_samples, warmup_steps, progress)
        else:
            raise ValueError(f"backend: {backend!r}, expected 'vectorized' or 'pyro'")
    return draws, kernel.diagnostics()
