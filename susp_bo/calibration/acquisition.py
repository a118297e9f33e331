"""Step 3: where to run the simulator next.

Two batch criteria, both in the unit cube:

- :func:`propose_ei_batch` — EGO with BoTorch's ``qLogExpectedImprovement`` on the
  surrogate's latent output (the warping is monotone, so improvement of z is
  improvement of log L): a joint batch of ``batch_size`` points so the simulator
  runs in parallel. Its value, EI relative to the spread of the observed latent
  values, drives the EGO stopping rule.
- :func:`select_uncertainty_batch` — posterior refinement (an addition to the
  paper, which only refines the maximum): among candidate points drawn from the
  current surrogate posterior (and a widened copy of it), greedily pick the points
  with the largest posterior-weighted uncertainty exp(E[log L̃] − max) · sd[log L̃],
  i.e. the largest local error of the posterior density; after each pick the GP
  variance is conditioned on that point (the variance does not depend on the
  unseen value, so this is exact), which spreads the batch. With ``optimism`` κ > 0
  the weight is the optimistic exp(E[log L̃] + κ sd[log L̃] − max) instead, recomputed
  after each pick: regions where the surrogate is unsure whether the posterior has
  mass (a curved posterior's arms that no evaluation came near) are refined too.
"""

from __future__ import annotations

import logging
import math
import warnings

import torch
from botorch.acquisition.logei import qLogExpectedImprovement
from botorch.optim import optimize_acqf
from botorch.sampling.normal import SobolQMCNormalSampler

from susp_bo.calibration.sampling import Estimator, sample_surrogate_posterior
from susp_bo.calibration.surrogate import Surrogate

logger = logging.getLogger(__name__)


def propose_ei_batch(
    surrogate: Surrogate,
    batch_size: int,
    seed: int,
    num_restarts: int = 6,
    raw_samples: int = 256,
    box: torch.Tensor | None = None,
    best_f: float | None = None,
) -> tuple[torch.Tensor, float]:
    """Joint batch maximising qLogEI on the latent output.

    The incumbent is the best observed latent value, or with a learned observation noise
    the best GP mean at the evaluated points, unless ``best_f`` is given.

    Args:
        surrogate: the fitted surrogate.
        batch_size: number of points b (>= 1).
        seed: seed of the QMC sampler and of the random restarts.
        num_restarts: L-BFGS-B restarts of the acquisition optimisation.
        raw_samples: raw points scored to choose the restarts.
        box: (2 x q) unit-cube sub-box to search in (default: the whole unit cube).
        best_f: the incumbent, latent units (a local climb's own best,
            :mod:`.basin_search`); None = as above.

    Returns:
        ((b x q) unit-cube points, relative EI = EI(batch) / sd(observed latent values)).
    """
    model = surrogate.model
    train_z = model.outcome_transform.untransform(model.train_targets[:, None])[0]
    best = float(train_z.max())
    if surrogate.learned_noise:
        # noisy observations: the best observed value is biased upwards by the noise; the
        # best posterior mean at the evaluated points is the incumbent (noisy EI, plug-in)
        with torch.no_grad():
            best = float(surrogate.latent_mean(surrogate.train_x).max())
    if best_f is not None:
        best = float(best_f)
    spread = float(train_z.std()) if train_z.numel() > 1 else 1.0
    q = surrogate.dim
    if box is None:
        bounds = torch.stack([torch.zeros(q), torch.ones(q)]).to(torch.float64)
    else:
        bounds = torch.as_tensor(box, dtype=torch.float64)
        if bounds.shape != (2, q) or not bool(torch.all(bounds[0] < bounds[1])):
            raise ValueError(f"box: shape {tuple(bounds.shape)}; expected (2 x {q}), lower < upper")
    with torch.random.fork_rng():
        torch.manual_seed(seed)
        sampler = SobolQMCNormalSampler(sample_shape=torch.Size([256]), seed=seed)
        acq = qLogExpectedImprovement(model, best_f=best, sampler=sampler)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            cand, value = optimize_acqf(
                acq,
                bounds=bounds,
                q=batch_size,
                num_restarts=num_restarts,
                raw_samples=raw_samples,
                options={"maxiter": 200},
            )
    for w in caught:
        logger.debug("EI optimisation: %s: %s", w.category.__name__, w.message)
    rel = math.exp(float(value)) / max(spread, 1e-300)
    return cand.detach(), rel


def posterior_candidates(
    surrogate: Surrogate, count: int, estimator: Estimator, seed: int
) -> tuple[torch.Tensor, torch.Tensor]:
    """``(post, wide)``: ``count`` draws of the surrogate posterior and ``count`` widened
    ones (draws plus Gaussian noise of the draws' marginal sd, clipped), unit cube.

    32 chains, 300 warm-up steps, seeded by ``seed`` (deterministic).
    """
    chains = 32
    steps = max(1, math.ceil(2 * count / chains))
    draws, _ = sample_surrogate_posterior(
        surrogate,
        n_chains=chains,
        warmup_steps=300,
        num_samples=steps,
        seed=seed,
        estimator=estimator,
    )
    flat = draws.transpose(0, 1).reshape(-1, surrogate.dim)
    gen = torch.Generator().manual_seed(seed)
    pick = torch.randperm(flat.shape[0], generator=gen)[: 2 * count]
    post, wide = flat[pick[:count]], flat[pick[count:]]
    sd = flat.std(0).clamp_min(1e-3)
    wide = (wide + sd * torch.randn(wide.shape, generator=gen, dtype=torch.float64)).clamp(0, 1)
    return post, wide


def refinement_candidates(
    surrogate: Surrogate, count: int, estimator: Estimator, optimism: float, seed: int
) -> tuple[torch.Tensor, int]:
    """Candidates of :func:`select_uncertainty_batch` and how many lead as posterior draws.

    Posterior draws plus their widened copy; with ``optimism`` > 0 (and an estimator other
    than ``expected``) the widened copy is replaced by draws of the optimistic posterior
    exp(E[L̃]), which grows where the GP is unsure: candidates in regions the plug-in
    posterior does not visit.
    """
    post, wide = posterior_candidates(surrogate, count, estimator, seed)
    if optimism > 0.0 and estimator != "expected":
        extra, _ = posterior_candidates(surrogate, count, "expected", seed + 1)
        return torch.cat([post, extra]), post.shape[0]
    return torch.cat([post, wide]), post.shape[0]


def select_uncertainty_batch(
    surrogate: Surrogate,
    candidates: torch.Tensor,
    batch_size: int,
    posterior_count: int | None = None,
    optimism: float = 0.0,
) -> tuple[torch.Tensor, float]:
    """Greedy batch of largest posterior-weighted log L uncertainty.

    Args:
        surrogate: the fitted surrogate.
        candidates: (m x q) unit-cube candidate points (e.g. surrogate posterior draws).
        batch_size: number of points b to select (<= m).
        posterior_count: the first ``posterior_count`` candidates are posterior draws (default
            all); the stopping statistic averages over them.
        optimism: κ >= 0 of the optimistic weight (module docstring); 0 (default) weighs
            by exp(E[log L̃] − max), fixed over the batch.

    Returns:
        ((b x q) selected points, posterior mean of sd[log L̃] in nats: the refinement
        stopping statistic).
    """
    if candidates.shape[0] < batch_size:
        raise ValueError(f"candidates: {candidates.shape[0]} points < batch_size {batch_size}")
    if not (math.isfinite(optimism) and optimism >= 0.0):
        raise ValueError(f"optimism: {optimism} must be finite and >= 0")
    mean_z, cov_z = surrogate.latent_covariance(candidates)
    warping = surrogate.warping
    var_z = cov_z.diagonal().clamp_min(1e-12)
    log_l = warping.mean_log_likelihood(mean_z, var_z)
    slope = warping.slope(mean_z)
    cov = cov_z * slope[:, None] * slope[None, :]  # delta method: covariance of log L̃
    weight = torch.exp(log_l - log_l.max())
    n_post = candidates.shape[0] if posterior_count is None else posterior_count
    mean_sd = float(cov.diagonal()[:n_post].clamp_min(0.0).sqrt().mean())
    chosen: list[int] = []
    for _ in range(batch_size):
        var = cov.diagonal().clamp_min(0.0)
        if optimism > 0.0:
            optimistic = log_l + optimism * var.sqrt()
            weight = torch.exp(optimistic - optimistic.max())
        score = weight * var.sqrt()
        if chosen:
            score[chosen] = -1.0
        i = int(torch.argmax(score))
        chosen.append(i)
        col = cov[:, i].clone()
        cov = cov - torch.outer(col, col) / col[i].clamp_min(1e-300)
    return candidates[chosen].clone(), mean_sd
