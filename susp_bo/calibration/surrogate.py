"""Step 2: kriging (GP) surrogate of log L on the unit cube.

A BoTorch ``SingleTaskGP`` (GPyTorch ExactGP) with a Matérn-5/2 ARD kernel, float64,
inputs in the unit cube, outcome standardised, near-noiseless (fixed noise 1e-6 in
standardised units), hyperparameters (lengthscales with BoTorch's dimension-scaled
log-normal prior, outputscale, prior mean) refitted by maximum a posteriori
whenever the data grow (:func:`.surrogate_fit.fit_surrogate`).

Prior mean. ``"constant"`` (the usual kriging mean) or ``"quadratic"``: the
negative quadratic trend m(u) = m0 − ½ Σ ((u_k − c_k)/ω_k)² of
:class:`NegativeQuadraticMean` (as VBMC uses), whose centre and widths are fitted
with the other hyperparameters, so that the GP only models the departure of log L
from a Gaussian bowl and extrapolates downhill instead of back to a constant.
The default ``"auto"`` fits both at every refit and keeps the higher leave-one-out
score (below). (The quadratic mean's least-squares start solves the normal
equations: ``torch.linalg.lstsq`` gave run-to-run differences under CPU load, which
broke the seed-for-seed reproducibility that resumed and cluster studies rely on.)
Measured (``python benchmarks/posterior_accuracy.py --seeds 0 1 2``; mean MMTV over
3 seeds, batches of 8, 1 M final draws): the quadratic mean wins with few
evaluations, the constant one with more, and ``"auto"`` follows the better one
except on the banana at 100/200 evaluations — banana 2-D at 50: constant 0.045,
auto 0.023 (6 seeds); 7-D Gaussian at 112: 0.019 vs 0.015; 7-D weak direction at
112: 0.022 vs 0.008; banana at 200: 0.006 vs 0.009.

Dynamic range of log L. Far from the maximum log L is −10³…−10⁴ while the posterior
lives within a few nats of the maximum (the paper's open difficulty). Two outputs
can be kriged:

- ``"none"``: raw log L (standardised). Excellent when log L is close to quadratic
  over the box (a Matérn GP with a long lengthscale follows the bowl);
- ``"log_deficit"``: the output warping z = −log(1 + (y_max − y)/s), inverse
  y = y_max − s (exp(−z) − 1), y_max the best observed log L and s the deficit scale
  (default q nats: 2 (y_max − y) ~ χ²_q inside the posterior mass). Linear near the
  maximum, logarithmic compression of the far field: better when log L saturates or
  has plateaus away from the maximum (as a spectral misfit does once a resonance
  leaves the band). Predictions map back with the exact lognormal moment
  E[y] = y_max − s (exp(−μ_z + σ_z²/2) − 1).

``"auto"`` fits both at every refit and keeps the one with the higher closed-form
leave-one-out log predictive density of log L (Jacobian included) over the best
third of the points. Measured with benchmarks/posterior_accuracy.py (MMTV against
exact posteriors at equal budgets, 4 targets x 3 budgets, seed 0, constant mean,
session 1), raw log L was the most accurate in 10 of 12 cases and never far off,
while log-deficit and auto failed badly early in 7-D (MMTV 0.21 and 0.16 at 112
evaluations): the default transform is therefore ``"none"``; the far field is
handled by the refinement step, which only spends evaluations where the posterior
mass is. Use ``transform="auto"`` when log L has plateaus or saturates away from the
maximum.

Observation noise. The default ``noise="fixed"`` treats log L as deterministic (the
rig is, for a given track realisation): noise fixed at ``noise_variance`` (1e-6 in
standardised units). ``noise="learned"`` is for a log L observed with noise (e.g. a
simulator whose track or excitation is random per call): a homoscedastic Gaussian
noise whose variance is fitted with the other hyperparameters under a log-normal
prior set in nats (median ``noise_sd_guess``, default 1 nat, one prior sd a factor
e ≈ 2.7 in sd). The GP then smooths through the scatter, its mean estimates the
noiseless log L that the posterior needs, EI compares against the best *predicted*
value at the evaluated points (the best observed one is biased upwards by the noise),
and the held-out check (:mod:`.surrogate_check`) widens its band by the learned noise
sd. With a learned noise, ``mean="auto"`` is the full quadratic (:func:`.surrogate_fit.auto_means`):
the noise hides the fine structure a GP resolves on a deterministic log L, while a
correlated bowl as the prior mean carries the posterior's shape (correlations
included) and the noise then averages out over every evaluation. Measured
(``benchmarks/posterior_accuracy.py``, ``noisy_gaussian_7d``: log L + N(0, 1 nat²) per
evaluation, 450 evaluations, seeds 0–2): MMTV 0.023 / 0.009 / 0.020, all three
``trusted``, where the learned noise with the constant-or-diagonal ``auto`` gave
0.036 / 0.043 / 0.046, all ``not_converged`` (session 8), and the fixed default 0.114
(seed 0); PyVBMC, told the noise sd, 0.046 / 0.028 / 0.024. The learned level is
0.76–0.88 nats on 160 points (tests). Not resolved: at 0.3 nats of noise the fit
collapses to ~0.025 nats (the GP interpolates the scatter; log L spans ~270 nats sd
over those points). A learned-noise run takes 250–270 s on this target (2 cores).

Covariance. The default ``kernel="matern"`` is the Matérn-5/2 ARD kernel above.
``"additive_pairs"`` is a sum of one- and two-parameter squared-exponential terms
(:class:`~susp_bo.calibration.additive_kernel.PairwiseAdditiveKernel`), for a log L made
of terms that each involve one or two parameters (e.g. chained curved conditionals);
``"auto"`` fits both and keeps the better leave-one-out score. On the chained-banana
5-D target at 350 evaluations ``"auto"`` with ``refine_optimism=2`` brought MMTV from
.13–.16 to .03–.05 (:mod:`.additive_kernel`, ``benchmarks/posterior_accuracy.py``);
each refit costs about 4x, so it is opt-in.

A fast torch predictor (no GPyTorch lazy tensors) is precomputed from the fitted
model for MCMC: it evaluates the posterior mean (and variance) for thousands of
points per call.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch
from botorch.models import SingleTaskGP

from susp_bo.calibration.additive_kernel import PairwiseAdditiveKernel, pairwise_additive
from susp_bo.calibration.surrogate_means import (
    FullQuadraticMean,
    NegativeQuadraticMean,
)

logger = logging.getLogger(__name__)

Transform = Literal["auto", "log_deficit", "none"]
MeanKind = Literal["auto", "quadratic", "constant", "full_quadratic"]
NoiseKind = Literal["fixed", "learned"]
KernelKind = Literal["matern", "additive_pairs", "auto"]
_SQRT5 = math.sqrt(5.0)


@dataclass(frozen=True)
class SurrogateSettings:
    """Settings of the kriging surrogate.

    Args:
        transform: output warping: "none" (default, raw log L), "log_deficit", or "auto"
            (fit both, keep the better leave-one-out predictive density of log L on the best
            third of the points).
        deficit_scale: s of the log-deficit transform in nats (> 0); None means q.
        noise_variance: fixed observation noise in standardised units (>= 1e-6, GPyTorch's
            floor).
        mean: GP prior mean: "constant", "quadratic" (negative quadratic trend,
            :class:`NegativeQuadraticMean`), "full_quadratic" (the same with a full
            Hessian, :class:`FullQuadraticMean`: a correlated bowl) or "auto" (default:
            constant and quadratic fitted at every refit, the better leave-one-out score
            kept; with ``noise="learned"`` the full quadratic,
            :func:`.surrogate_fit.auto_means`; see the module docstring).
        noise: "fixed" (default: ``noise_variance``, a deterministic simulator) or
            "learned": a homoscedastic observation noise of log L fitted with the other
            hyperparameters (a stochastic simulator, e.g. log L from a finite number of
            random track realisations), under a log-normal prior on its variance centred
            at ``noise_sd_guess``, ``noise_prior_width`` wide (default 2: a factor e² in
            variance per prior sd) — see the module docstring.
        noise_sd_guess: centre of the learned noise's prior, sd of log L in nats (> 0).
        noise_prior_width: sd of that log-normal prior on the log of the noise variance
            (> 0; default 2, a factor e² either way). A small width (e.g. 0.05) holds the
            noise at ``noise_sd_guess``: a noise level known beforehand (say, from
            replicate runs at one point) rather than fitted.
        kernel: the GP's covariance: "matern" (default: Matérn-5/2 ARD),
            "additive_pairs" (first- and second-order additive squared-exponential terms,
            :class:`~susp_bo.calibration.additive_kernel.PairwiseAdditiveKernel`: a log L
            made of one- and two-parameter terms, such as a chain of curved
            conditionals) or "auto" (both fitted at every refit, the better
            leave-one-out score kept).
    """

    transform: Transform = "none"
    deficit_scale: float | None = None
    noise_variance: float = 1e-6
    mean: MeanKind = "auto"
    noise: NoiseKind = "fixed"
    noise_sd_guess: float = 1.0
    noise_prior_width: float = 2.0
    kernel: KernelKind = "matern"

    def __post_init__(self) -> None:
        if self.transform not in ("auto", "log_deficit", "none"):
            raise ValueError(f"transform: {self.transform!r}, expected auto/log_deficit/none")
        if self.deficit_scale is not None and not self.deficit_scale > 0.0:
            raise ValueError(f"deficit_scale: {self.deficit_scale} must be None or > 0 nats")
        if self.mean not in ("auto", "quadratic", "constant", "full_quadratic"):
            raise ValueError(
                f"mean: {self.mean!r}, expected 'auto', 'quadratic', 'full_quadratic' or 'constant'"
            )
        if not self.noise_variance >= 1e-6:
            raise ValueError(f"noise_variance: {self.noise_variance} must be >= 1e-6")
        if self.noise not in ("fixed", "learned"):
            raise ValueError(f"noise: {self.noise!r}, expected 'fixed' or 'learned'")
        if not self.noise_sd_guess > 0.0:
            raise ValueError(f"noise_sd_guess: {self.noise_sd_guess} must be > 0 nats")
        if not self.noise_prior_width > 0.0:
            raise ValueError(f"noise_prior_width: {self.noise_prior_width} must be > 0")
        if self.kernel not in ("matern", "additive_pairs", "auto"):
            raise ValueError(
                f"kernel: {self.kernel!r}, expected 'matern', 'additive_pairs' or 'auto'"
            )


@dataclass(frozen=True)
class OutputWarping:
    """The monotone map between log L (y) and the modelled latent value (z)."""

    kind: Literal["log_deficit", "none"]
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

    def log_abs_dz_dy(self, y: np.ndarray) -> np.ndarray:
        """log |dz/dy| at log L values y (Jacobian for densities on the log L scale)."""
        if self.kind == "none":
            return np.zeros_like(np.asarray(y, dtype=np.float64))
        return -np.log(self.scale + self.y_max - np.asarray(y, dtype=np.float64))

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
        learned_noise: True when the observation noise was fitted (``noise="learned"``).
    """

    def __init__(
        self,
        model: SingleTaskGP,
        warping: OutputWarping,
        train_x: torch.Tensor,
        train_y: np.ndarray,
        learned_noise: bool = False,
    ) -> None:
        self.model = model
        self.warping = warping
        self.train_x = train_x
        self.train_y = train_y
        self.learned_noise = learned_noise
        covar = model.covar_module
        self._inv_ls = (1.0 / covar.base_kernel.lengthscale.detach().reshape(-1)).clone()
        self._outputscale = float(covar.outputscale.detach())
        self._mix: float | None = None
        if isinstance(covar.base_kernel, PairwiseAdditiveKernel):
            self._mix = float(covar.base_kernel.mix.detach())
        mm = model.mean_module
        self._full: tuple[torch.Tensor, torch.Tensor] | None = None
        self._quadratic: tuple[torch.Tensor, torch.Tensor] | None = None
        if isinstance(mm, NegativeQuadraticMean):
            self._quadratic = (mm.centre.detach().clone(), mm.width.detach().clone())
        elif isinstance(mm, FullQuadraticMean):
            self._full = (mm.centre.detach().clone(), mm.factor.detach().clone())
        self._mean_constant = float(mm.constant.detach())
        self._y_mean = float(model.outcome_transform.means.detach().reshape(()))
        self._y_std = float(model.outcome_transform.stdvs.detach().reshape(()))
        targets = model.train_targets.detach()
        noise = model.likelihood.noise.detach().reshape(-1)
        kxx = self._kernel(train_x, train_x) + torch.diag(noise.expand(train_x.shape[0]))
        self._chol = torch.linalg.cholesky(kxx)
        prior_mean = self._prior_mean(train_x)
        self._alpha = torch.cholesky_solve((targets - prior_mean)[:, None], self._chol)[:, 0]
        self._xs = train_x * self._inv_ls
        self._xs_sq = (self._xs**2).sum(-1)

    @property
    def dim(self) -> int:
        """Number of parameters q."""
        return int(self.train_x.shape[1])

    @property
    def latent_noise_sd(self) -> float:
        """sd of the observation noise of the latent output z (nats when not warped)."""
        noise = float(self.model.likelihood.noise.detach().reshape(-1).max())
        return math.sqrt(noise) * self._y_std

    @property
    def kernel_kind(self) -> str:
        """The fitted covariance: "matern" or "additive_pairs"."""
        return "matern" if self._mix is None else "additive_pairs"

    def _kernel(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        if self._mix is not None:
            return self._outputscale * pairwise_additive(a, b, self._inv_ls, self._mix)
        a = a * self._inv_ls
        b = b * self._inv_ls
        d2 = (a**2).sum(-1)[:, None] + (b**2).sum(-1)[None, :] - 2.0 * a @ b.T
        r = _SQRT5 * torch.sqrt(d2.clamp_min(1e-30))
        return self._outputscale * (1.0 + r + r**2 / 3.0) * torch.exp(-r)

    def _prior_mean(self, u: torch.Tensor) -> torch.Tensor:
        if self._full is not None:
            centre, factor = self._full
            return self._mean_constant - 0.5 * (((u - centre) @ factor) ** 2).sum(-1)
        if self._quadratic is not None:
            centre, width = self._quadratic
            return self._mean_constant - 0.5 * (((u - centre) / width) ** 2).sum(-1)
        return torch.full(u.shape[:-1], self._mean_constant, dtype=u.dtype)

    def _cross(self, u: torch.Tensor) -> torch.Tensor:
        if self._mix is not None:
            return self._kernel(u, self.train_x)
        a = u * self._inv_ls
        d2 = (a**2).sum(-1)[:, None] + self._xs_sq[None, :] - 2.0 * a @ self._xs.T
        r = _SQRT5 * torch.sqrt(d2.clamp_min(1e-30))
        return self._outputscale * (1.0 + r + r * r / 3.0) * torch.exp(-r)

    def loo_log_score(self, top_fraction: float = 1.0 / 3.0) -> float:
        """Mean leave-one-out log predictive density of log L over the best training points.

        Closed form for a GP (hyperparameters kept): with P = (K + N)⁻¹ and α = P (t − m),
        the LOO mean is t_i − α_i / P_ii and the variance 1 / P_ii (standardised units);
        mapped to z and then to the log L scale with the Jacobian of the warping.
        """
        loo_mean, loo_var = self._loo_latent()
        z = torch.as_tensor(self.warping.forward(self.train_y), dtype=torch.float64)
        log_pz = -0.5 * (z - loo_mean) ** 2 / loo_var - 0.5 * torch.log(2 * math.pi * loo_var)
        log_py = log_pz.numpy() + self.warping.log_abs_dz_dy(self.train_y)
        k = max(3, math.ceil(top_fraction * self.train_y.size))
        best = np.argsort(self.train_y)[::-1][:k]
        return float(np.mean(log_py[best]))

    def _loo_latent(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Leave-one-out mean and variance of z at the training points ((n,), (n,))."""
        precision = torch.cholesky_inverse(self._chol)
        diag = precision.diagonal()
        targets = self.model.train_targets.detach()
        loo_mean = (targets - self._alpha / diag) * self._y_std + self._y_mean
        return loo_mean, (1.0 / diag) * self._y_std**2

    def loo_log_likelihood_uncertainty(self) -> tuple[np.ndarray, np.ndarray]:
        """E[log L̃] (n,) and sd of log L̃ (n,) (nats) at each training point, predicted by
        the GP without that point (closed form, hyperparameters kept): the predictive
        distribution of a new evaluation there, observation noise included (unlike
        :meth:`log_likelihood_uncertainty`, which is of the noiseless log L)."""
        mean, var = self._loo_latent()
        return (
            self.warping.mean_log_likelihood(mean, var).numpy(),
            (self.warping.slope(mean) * var.sqrt()).numpy(),
        )

    def latent_mean(self, u: torch.Tensor) -> torch.Tensor:
        """Posterior mean of z at unit-cube points u (m x q) -> (m,), fast path."""
        return (self._prior_mean(u) + self._cross(u) @ self._alpha) * self._y_std + self._y_mean

    def latent_mean_var(self, u: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Posterior mean and variance of z at u (m x q) -> ((m,), (m,))."""
        k = self._cross(u)
        mean = (self._prior_mean(u) + k @ self._alpha) * self._y_std + self._y_mean
        v = torch.linalg.solve_triangular(self._chol, k.T, upper=False)
        var = (self._outputscale - (v**2).sum(0)).clamp_min(1e-12) * self._y_std**2
        return mean, var

    def latent_covariance(self, u: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Posterior mean (m,) and joint covariance (m x m) of z at u (m x q)."""
        k = self._cross(u)
        mean = (self._prior_mean(u) + k @ self._alpha) * self._y_std + self._y_mean
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
