"""Step 2: kriging (GP) surrogate of log L on the unit cube.

A BoTorch ``SingleTaskGP`` (GPyTorch ExactGP) with a Matérn-5/2 ARD kernel, float64,
inputs in the unit cube, outcome standardised, near-noiseless (fixed noise 1e-6 in
standardised units), hyperparameters (lengthscales with BoTorch's dimension-scaled
log-normal prior, outputscale, constant mean) refitted by maximum a posteriori
whenever the data grow.

Dynamic range of log L. Far from the maximum log L is −10³…−10⁴ while the posterior
lives within a few nats of the maximum; a stationary GP fitted to raw log L spends
its flexibility on the far bowl and is imprecise exactly where the posterior
lives (the paper's open difficulty). The default fix is an output warping, the
*log-deficit* transform

    z = −log(1 + (y_max − y) / s)          y = y_max − s (exp(−z) − 1)

with y_max the best observed log L and s the deficit scale (default q nats, the
order of the deficits inside the posterior mass: 2 (y_max − y) ~ χ²_q there). It
is linear within a few s of the maximum and compresses the far field
logarithmically. The GP models z; predictions are mapped back with the exact
lognormal moment E[y] = y_max − s (exp(−μ_z + σ_z²/2) − 1). ``transform="none"``
models raw log L (measured against the default in benchmarks/posterior_accuracy.py).

A fast torch predictor (no GPyTorch lazy tensors) is precomputed from the fitted
model for MCMC: it evaluates the posterior mean (and variance) for thousands of
points per call.
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch
from botorch.fit import fit_gpytorch_mll
from botorch.models import SingleTaskGP
from botorch.models.transforms.outcome import Standardize
from botorch.models.utils.gpytorch_modules import get_covar_module_with_dim_scaled_prior
from gpytorch.kernels import ScaleKernel
from gpytorch.mlls import ExactMarginalLogLikelihood
from gpytorch.priors import GammaPrior

logger = logging.getLogger(__name__)

Transform = Literal["log_deficit", "none"]
_SQRT5 = math.sqrt(5.0)


@dataclass(frozen=True)
class SurrogateSettings:
    """Settings of the kriging surrogate.

    Args:
        transform: output warping, "log_deficit" (default) or "none".
        deficit_scale: s of the log-deficit transform in nats (> 0); None means q.
        noise_variance: fixed observation noise in standardised units (>= 1e-6, GPyTorch's
            floor).
    """

    transform: Transform = "log_deficit"
    deficit_scale: float | None = None
    noise_variance: float = 1e-6

    def __post_init__(self) -> None:
        if self.transform not in ("log_deficit", "none"):
            raise ValueError(f"transform: {self.transform!r}, expected 'log_deficit' or 'none'")
        if self.deficit_scale is not None and not self.deficit_scale > 0.0:
            raise ValueError(f"deficit_scale: {self.deficit_scale} must be None or > 0 nats")
        if not self.noise_variance >= 1e-6:
            raise ValueError(f"noise_variance: {self.noise_variance} must be >= 1e-6")


@dataclass(frozen=True)
class OutputWarping:
    """The monotone map between log L (y) and the modelled latent value (z)."""

    kind: Transform
    y_max: float
    scale: float

    def forward(self, y: np.ndarray) -> np.ndarray:
        """log L -> latent z."""
        if self.kind == "none":
            return np.asarray(y, dtype=np.float64)
        return -np.log1p((self.y_max - np.asarray(y, dtype=np.float64)) / self.scale)

    def mean_log_likelihood(self, mean_z: torch.Tensor, var_z: torch.Tensor) -> torch.Tensor:
        """E[log L̃] under z ~ N(mean_z, var_z) (exact lognormal moment)."""
        if self.kind == "none":
            return mean_z
        return self.y_max - self.scale * torch.expm1(-mean_z + 0.5 * var_z)

    def plug_in(self, z: torch.Tensor) -> torch.Tensor:
        """log L at latent value z (the median of log L̃ when z is the GP mean)."""
        if self.kind == "none":
            return z
        return self.y_max - self.scale * torch.expm1(-z)

    def slope(self, z: torch.Tensor) -> torch.Tensor:
        """d log L / dz at z (for delta-method uncertainties)."""
        if self.kind == "none":
            return torch.ones_like(z)
        return self.scale * torch.exp(-z)


class Surrogate:
    """A fitted GP of the (warped) log-likelihood on the unit cube.

    Attributes:
        model: the BoTorch SingleTaskGP (unit-cube inputs, latent z outputs).
        warping: the output warping.
        train_x: (n x q) unit-cube training inputs (float64 tensor).
        train_y: (n,) log L used for training (failed evaluations imputed).
    """

    def __init__(
        self,
        model: SingleTaskGP,
        warping: OutputWarping,
        train_x: torch.Tensor,
        train_y: np.ndarray,
    ) -> None:
        self.model = model
        self.warping = warping
        self.train_x = train_x
        self.train_y = train_y
        covar = model.covar_module
        self._inv_ls = (1.0 / covar.base_kernel.lengthscale.detach().reshape(-1)).clone()
        self._outputscale = float(covar.outputscale.detach())
        self._const = float(model.mean_module.constant.detach())
        self._y_mean = float(model.outcome_transform.means.detach().reshape(()))
        self._y_std = float(model.outcome_transform.stdvs.detach().reshape(()))
        targets = model.train_targets.detach()
        noise = model.likelihood.noise.detach().reshape(-1)
        kxx = self._kernel(train_x, train_x) + torch.diag(noise.expand(train_x.shape[0]))
        self._chol = torch.linalg.cholesky(kxx)
        self._alpha = torch.cholesky_solve((targets - self._const)[:, None], self._chol)[:, 0]
        self._xs = train_x * self._inv_ls
        self._xs_sq = (self._xs**2).sum(-1)

    @property
    def dim(self) -> int:
        """Number of parameters q."""
        return int(self.train_x.shape[1])

    def _kernel(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        a = a * self._inv_ls
        b = b * self._inv_ls
        d2 = (a**2).sum(-1)[:, None] + (b**2).sum(-1)[None, :] - 2.0 * a @ b.T
        r = _SQRT5 * torch.sqrt(d2.clamp_min(1e-30))
        return self._outputscale * (1.0 + r + r**2 / 3.0) * torch.exp(-r)

    def _cross(self, u: torch.Tensor) -> torch.Tensor:
        a = u * self._inv_ls
        d2 = (a**2).sum(-1)[:, None] + self._xs_sq[None, :] - 2.0 * a @ self._xs.T
        r = _SQRT5 * torch.sqrt(d2.clamp_min(1e-30))
        return self._outputscale * (1.0 + r + r * r / 3.0) * torch.exp(-r)

    def latent_mean(self, u: torch.Tensor) -> torch.Tensor:
        """Posterior mean of z at unit-cube points u (m x q) -> (m,), fast path."""
        return (self._const + self._cross(u) @ self._alpha) * self._y_std + self._y_mean

    def latent_mean_var(self, u: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Posterior mean and variance of z at u (m x q) -> ((m,), (m,))."""
        k = self._cross(u)
        mean = (self._const + k @ self._alpha) * self._y_std + self._y_mean
        v = torch.linalg.solve_triangular(self._chol, k.T, upper=False)
        var = (self._outputscale - (v**2).sum(0)).clamp_min(1e-12) * self._y_std**2
        return mean, var

    def latent_covariance(self, u: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Posterior mean (m,) and joint covariance (m x m) of z at u (m x q)."""
        k = self._cross(u)
        mean = (self._const + k @ self._alpha) * self._y_std + self._y_mean
        v = torch.linalg.solve_triangular(self._chol, k.T, upper=False)
        cov = (self._kernel(u, u) - v.T @ v) * self._y_std**2
        return mean, cov

    def log_likelihood_mean(self, u: torch.Tensor) -> torch.Tensor:
        """E[log L̃(u)] (m,): the default surrogate of log L."""
        if self.warping.kind == "none":
            return self.latent_mean(u)
        mean, var = self.latent_mean_var(u)
        return self.warping.mean_log_likelihood(mean, var)

    def log_expected_likelihood(self, u: torch.Tensor, n_nodes: int = 24) -> torch.Tensor:
        """log E[L̃(u)] (m,), the paper's E[L̃] (= μ + σ²/2 without warping)."""
        mean, var = self.latent_mean_var(u)
        if self.warping.kind == "none":
            return mean + 0.5 * var
        nodes, weights = np.polynomial.hermite_e.hermegauss(n_nodes)
        t = torch.as_tensor(nodes, dtype=mean.dtype)
        logw = torch.log(torch.as_tensor(weights / weights.sum(), dtype=mean.dtype))
        z = mean[:, None] + var.sqrt()[:, None] * t[None, :]
        return torch.logsumexp(self.warping.plug_in(z) + logw, dim=1)

    def log_likelihood_uncertainty(self, u: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """E[log L̃] (m,) and the delta-method standard deviation of log L̃ (m,)."""
        mean, var = self.latent_mean_var(u)
        return self.warping.mean_log_likelihood(mean, var), self.warping.slope(mean) * var.sqrt()


def fit_surrogate(
    x_unit: np.ndarray, y: np.ndarray, settings: SurrogateSettings, seed: int
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
    train_var = torch.full_like(train_z, 1.001 * settings.noise_variance * z_var)
    covar = ScaleKernel(
        get_covar_module_with_dim_scaled_prior(ard_num_dims=q, use_rbf_kernel=False),
        outputscale_prior=GammaPrior(2.0, 0.15),
    )
    with torch.random.fork_rng():
        torch.manual_seed(seed)
        model = SingleTaskGP(
            train_x, train_z, train_var, covar_module=covar, outcome_transform=Standardize(m=1)
        )
        mll = ExactMarginalLogLikelihood(model.likelihood, model)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            fit_gpytorch_mll(mll)
    for w in caught:
        logger.debug("surrogate fit: %s: %s", w.category.__name__, w.message)
    model.eval()
    return Surrogate(model, warping, train_x, y)
