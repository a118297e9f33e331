"""Fitting the kriging surrogate of log L: :func:`fit_surrogate`.

A BoTorch ``SingleTaskGP`` (Matérn-5/2 ARD kernel with BoTorch's dimension-scaled
lengthscale prior, float64, outcome standardised) on unit-cube inputs, its
hyperparameters fitted by maximum a posteriori. The choices it makes — output warping,
prior mean (:func:`auto_means`), fixed or learned observation noise, a known bowl as
the fixed mean — and what was measured for each are in :mod:`.surrogate`'s docstring;
the fitted model is a :class:`~susp_bo.calibration.surrogate.Surrogate`.
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import torch
from botorch.fit import fit_gpytorch_mll
from botorch.models import SingleTaskGP
from botorch.models.transforms.outcome import Standardize
from botorch.models.utils.gpytorch_modules import get_covar_module_with_dim_scaled_prior
from gpytorch.constraints import GreaterThan
from gpytorch.kernels import ScaleKernel
from gpytorch.likelihoods import GaussianLikelihood
from gpytorch.means import ConstantMean, Mean
from gpytorch.mlls import ExactMarginalLogLikelihood
from gpytorch.priors import GammaPrior, LogNormalPrior

from susp_bo.calibration.additive_kernel import PairwiseAdditiveKernel
from susp_bo.calibration.surrogate import (
    MeanKind,
    NoiseKind,
    OutputWarping,
    Surrogate,
    SurrogateSettings,
)
from susp_bo.calibration.surrogate_means import (
    fixed_bowl_mean,
    initial_full_quadratic_mean,
    initial_quadratic_mean,
)

logger = logging.getLogger(__name__)


_QUADRATIC_MAXITER = 100
"""L-BFGS iterations allowed to the quadratic-mean fit (uncapped it took ~1 500 marginal
likelihood evaluations and ~30 s at n = 190 in 7-D, against ~40 and 1 s for the constant
mean; capped at 100: 2.4 s, leave-one-out score 1.032 against 1.035)."""


_ADDITIVE_MAXITER = 200
"""L-BFGS iterations allowed to a fit with the pairwise additive kernel. (Session 12
probe, with GPyTorch's ``NewtonGirardAdditiveKernel`` of the same form: at 100 one fit of
310 points in 5-D stopped far from its optimum, 59 nats rms error at the posterior
against 0.9 at 200; not re-measured with :class:`PairwiseAdditiveKernel`.)"""


def _optimizer_options(mean: str, kernel: str = "matern") -> dict[str, Any]:
    quadratic = mean in ("quadratic", "full_quadratic")
    if kernel == "additive_pairs":
        return {"options": {"maxiter": _ADDITIVE_MAXITER}}
    return {"options": {"maxiter": _QUADRATIC_MAXITER}} if quadratic else {}


@dataclass(frozen=True)
class Bowl:
    """A known Gaussian-shaped trend of log L: −½ (u − c)ᵀ P (u − c) + const.

    Used as the GP's fixed prior mean (only the constant is fitted), so that the GP
    models what is left: e.g. the Laplace approximation of the local phase
    (:mod:`.local_search`), in the fitting unit cube.

    Args:
        centre: (q,) c, unit-cube coordinates.
        precision: (q x q) P, symmetric positive definite, nats per unit² (log L units).
    """

    centre: np.ndarray
    precision: np.ndarray


def fit_surrogate(
    x_unit: np.ndarray,
    y: np.ndarray,
    settings: SurrogateSettings,
    seed: int,
    bowl: Bowl | None = None,
) -> Surrogate:
    """Fits the GP to (unit-cube inputs, log L) and returns the surrogate.

    With ``transform="auto"`` both warpings (with ``mean="auto"`` every prior mean of
    :func:`auto_means`, with ``kernel="auto"`` both kernels) are fitted and the one with
    the higher :meth:`Surrogate.loo_log_score` is returned; with a ``bowl``, only the
    kernel is chosen so.

    Args:
        x_unit: (n x q) inputs in the unit cube.
        y: (n,) finite log-likelihood values (impute failures before).
        settings: surrogate settings.
        seed: seed of the (rare) random restarts of the hyperparameter fit.
        bowl: a known quadratic trend of log L used as the fixed prior mean (then
            ``settings.mean`` is not used; needs ``transform="none"``).

    Returns:
        The fitted :class:`Surrogate`.
    """
    kernels = ("matern", "additive_pairs") if settings.kernel == "auto" else (settings.kernel,)
    if bowl is not None:
        if settings.transform != "none":
            raise ValueError("bowl: a fixed quadratic mean needs transform='none'")
        candidates = [replace(settings, kernel=k) for k in kernels]
    else:
        transforms = (
            ("none", "log_deficit") if settings.transform == "auto" else (settings.transform,)
        )
        means = auto_means(settings.noise) if settings.mean == "auto" else (settings.mean,)
        candidates = [
            replace(settings, transform=t, mean=m, kernel=k)
            for k in kernels
            for t in transforms
            for m in means
        ]
    fits = [_fit_one(x_unit, y, c, seed, bowl) for c in candidates]
    if len(fits) == 1:
        return fits[0]
    scores = [f.loo_log_score() for f in fits]
    logger.debug("surrogate LOO scores %s", scores)
    return fits[int(np.argmax(scores))]


def auto_means(noise: NoiseKind) -> tuple[MeanKind, ...]:
    """The prior means ``mean="auto"`` fits (with several, the best leave-one-out score is
    kept).

    A deterministic log L (``noise="fixed"``): constant and quadratic. A noisy one
    (``noise="learned"``): the full quadratic alone. The noise hides the fine structure
    the GP would otherwise resolve, while a correlated bowl as the mean carries the
    posterior's shape and lets the noise average out over every evaluation; and the
    leave-one-out score of noisy values does not pick it reliably (on one of two noisy
    7-D data sets it kept the diagonal bowl, whose error over the posterior was 3.5 x
    larger: ``tests/calibration/test_surrogate_noise.py``). Module docstring,
    "Observation noise".
    """
    if noise == "learned":
        return ("full_quadratic",)
    return ("constant", "quadratic")


def _fit_one(
    x_unit: np.ndarray,
    y: np.ndarray,
    settings: SurrogateSettings,
    seed: int,
    bowl: Bowl | None = None,
) -> Surrogate:
    """Fits the GP to (unit-cube inputs, log L) and returns the surrogate.

    Args:
        x_unit: (n x q) inputs in the unit cube.
        y: (n,) finite log-likelihood values (impute failures before).
        settings: surrogate settings.
        seed: seed of the (rare) random restarts of the hyperparameter fit.

    Returns:
        The fitted :class:`Surrogate`.
    """
    x_unit = np.asarray(x_unit, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if x_unit.ndim != 2 or y.shape != (x_unit.shape[0],):
        raise ValueError(f"x_unit, y: shapes {x_unit.shape}, {y.shape} do not match (n x q), (n,)")
    if not np.all(np.isfinite(y)):
        raise ValueError("y: must be finite (impute failed evaluations first)")
    q = x_unit.shape[1]
    scale = float(settings.deficit_scale) if settings.deficit_scale is not None else float(q)
    warping = OutputWarping(settings.transform, float(np.max(y)), scale)
    z = warping.forward(y)
    train_x = torch.as_tensor(x_unit, dtype=torch.float64)
    train_z = torch.as_tensor(z, dtype=torch.float64)[:, None]
    # Standardize divides by the unbiased variance; the 1.001 margin keeps the standardised
    # noise at or above GPyTorch's 1e-6 floor (below it GPyTorch warns and rounds up).
    z_var = float(np.var(z, ddof=1)) if z.size > 1 and np.var(z) > 0 else 1.0
    if settings.noise == "learned":
        train_var = None
        likelihood = _learned_noise_likelihood(settings, warping, z_var)
    else:
        train_var = torch.full_like(train_z, 1.001 * settings.noise_variance * z_var)
        likelihood = None
    base_kernel = (
        PairwiseAdditiveKernel(ard_num_dims=q)
        if settings.kernel == "additive_pairs"
        else get_covar_module_with_dim_scaled_prior(ard_num_dims=q, use_rbf_kernel=False)
    )
    covar = ScaleKernel(base_kernel, outputscale_prior=GammaPrior(2.0, 0.15))
    with torch.random.fork_rng():
        torch.manual_seed(seed)
        std_z = ((train_z - train_z.mean()) / train_z.std())[:, 0]
        if bowl is not None:
            mean_module: Mean = fixed_bowl_mean(bowl, float(train_z.std()), std_z)
        elif settings.mean == "quadratic":
            mean_module = initial_quadratic_mean(train_x, std_z)
        elif settings.mean == "full_quadratic":
            mean_module = initial_full_quadratic_mean(train_x, std_z)
        else:
            mean_module = ConstantMean()
        model = SingleTaskGP(
            train_x,
            train_z,
            train_var,
            likelihood=likelihood,
            covar_module=covar,
            mean_module=mean_module,
            outcome_transform=Standardize(m=1),
        )
        mll = ExactMarginalLogLikelihood(model.likelihood, model)
        with torch.enable_grad(), warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            fit_gpytorch_mll(
                mll,
                optimizer_kwargs=_optimizer_options(
                    "constant" if bowl else settings.mean, settings.kernel
                ),
            )
    for w in caught:
        logger.debug("surrogate fit: %s: %s", w.category.__name__, w.message)
    model.eval()
    return Surrogate(model, warping, train_x, y, learned_noise=settings.noise == "learned")


def _learned_noise_likelihood(
    settings: SurrogateSettings, warping: OutputWarping, z_var: float
) -> GaussianLikelihood:
    """Gaussian likelihood whose noise is fitted, with its prior set in nats.

    The GP works in standardised units (outcome divided by sd(z) = sqrt(z_var)), so the
    guess of the noise sd in nats, σ₀ (mapped to the latent scale by the warping's slope
    at the maximum: 1 without warping, 1/s for the log deficit), becomes the standardised
    variance σ₀² (dz/dy)² / z_var: the prior's median, and the starting value.
    """
    slope = 1.0 if warping.kind == "none" else 1.0 / warping.scale
    guess = (settings.noise_sd_guess * slope) ** 2 / z_var
    guess = max(guess, 1e-7)
    likelihood = GaussianLikelihood(
        noise_prior=LogNormalPrior(math.log(guess), settings.noise_prior_width),
        noise_constraint=GreaterThan(1e-8),
    )
    likelihood.noise = torch.tensor(guess, dtype=torch.float64)
    return likelihood.to(torch.float64)
