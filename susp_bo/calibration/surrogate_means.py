"""Prior means of the log L surrogate: Gaussian-shaped (negative quadratic) trends.

With such a mean the GP models only the departure of log L from a bowl (as VBMC does)
and extrapolates downhill instead of back to a constant. :class:`NegativeQuadraticMean`
has a diagonal Hessian; :class:`FullQuadraticMean` a full one. Both start from a
least-squares quadratic fit (normal equations: ``torch.linalg.lstsq`` gave run-to-run
differences under CPU load).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from gpytorch.constraints import Positive
from gpytorch.means import Mean


class NegativeQuadraticMean(Mean):
    """m(x) = m0 − ½ Σ_k ((x_k − c_k) / ω_k)²: a Gaussian-shaped log-likelihood trend.

    The GP then models departures from a Laplace-like bowl (as in VBMC), which a
    stationary kernel with a constant mean represents poorly over the dynamic range.
    """

    def __init__(self, dim: int, centre: torch.Tensor, height: float) -> None:
        super().__init__()
        f64 = torch.float64  # all float64: float32 parameters stall L-BFGS (232 s fits)
        self.register_parameter("constant", torch.nn.Parameter(torch.tensor(height, dtype=f64)))
        self.register_parameter("centre", torch.nn.Parameter(centre.to(f64).clone().reshape(dim)))
        self.register_parameter("raw_width", torch.nn.Parameter(torch.zeros(dim, dtype=f64)))
        self.register_constraint("raw_width", Positive())
        self.initialize(width=torch.full((dim,), 0.3, dtype=torch.float64))

    @property
    def width(self) -> torch.Tensor:
        """ω (q,), in unit-cube units."""
        return self.raw_width_constraint.transform(self.raw_width)

    @width.setter
    def width(self, value: torch.Tensor) -> None:
        self.initialize(raw_width=self.raw_width_constraint.inverse_transform(value))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(... x n x q) -> (... x n)."""
        return self.constant - 0.5 * (((x - self.centre) / self.width) ** 2).sum(-1)


class FullQuadraticMean(Mean):
    """m(x) = m0 − ½ ‖Lᵀ (x − c)‖²: a Gaussian-shaped trend with a full Hessian −L Lᵀ.

    L is lower triangular with a positive diagonal (so the bowl is always concave). Near
    a sharp optimum log L is a correlated quadratic (a least-squares misfit: Gauss–Newton
    Hessian JᵀJ); the diagonal :class:`NegativeQuadraticMean` cannot follow a ridge that
    runs across the axes, this one can, and the GP then only models what is left.
    """

    def __init__(self, dim: int, centre: torch.Tensor, height: float, factor: torch.Tensor):
        super().__init__()
        f64 = torch.float64
        rows, cols = torch.tril_indices(dim, dim, -1)
        self.register_buffer("rows", rows)
        self.register_buffer("cols", cols)
        self.register_parameter("constant", torch.nn.Parameter(torch.tensor(height, dtype=f64)))
        self.register_parameter("centre", torch.nn.Parameter(centre.to(f64).clone().reshape(dim)))
        self.register_parameter("raw_diag", torch.nn.Parameter(torch.zeros(dim, dtype=f64)))
        self.register_constraint("raw_diag", Positive())
        self.register_parameter(
            "lower", torch.nn.Parameter(factor.to(f64)[rows, cols].clone().reshape(-1))
        )
        self.initialize(raw_diag=self.raw_diag_constraint.inverse_transform(factor.diagonal()))

    @property
    def factor(self) -> torch.Tensor:
        """L (q x q), lower triangular, in unit-cube units."""
        diag = self.raw_diag_constraint.transform(self.raw_diag)
        out = torch.diag(diag)
        return out.index_put((self.rows, self.cols), self.lower)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(... x n x q) -> (... x n)."""
        v = (x - self.centre) @ self.factor
        return self.constant - 0.5 * (v**2).sum(-1)


def fixed_bowl_mean(bowl: Any, z_sd: float, std_z: torch.Tensor) -> FullQuadraticMean:
    """A :class:`FullQuadraticMean` fixed to a known bowl; only the constant is fitted.

    Args:
        bowl: :class:`~susp_bo.calibration.surrogate_fit.Bowl` (centre, precision in log-L
            units per unit²).
        z_sd: sd of the GP's outputs (the ``Standardize`` scale), to express the bowl in
            standardised units.
        std_z: (n,) standardised outputs (the constant starts at their maximum).
    """
    precision = torch.as_tensor(np.asarray(bowl.precision), dtype=torch.float64) / z_sd
    precision = 0.5 * (precision + precision.T)
    factor = torch.linalg.cholesky(precision)
    centre = torch.as_tensor(np.asarray(bowl.centre), dtype=torch.float64)
    mean = FullQuadraticMean(centre.numel(), centre, float(std_z.max()), factor)
    for name in ("centre", "raw_diag", "lower"):
        getattr(mean, name).requires_grad_(False)
    return mean


def initial_full_quadratic_mean(x: torch.Tensor, z: torch.Tensor) -> FullQuadraticMean:
    """The full negative quadratic trend, started at the least-squares quadratic fit.

    z ≈ b0 + bᵀu + uᵀ B u (B symmetric) by least squares (normal equations, as in
    :func:`initial_quadratic_mean`); A = −2 B with its eigenvalues raised to at least
    0.01 (a width of at most 10 unit-cube units: a concave bowl), c = A⁻¹ b, L the
    Cholesky factor of A, the height anchored at the best point. With fewer points
    than the quadratic has coefficients the diagonal start is used.

    Args:
        x: (n x q) unit-cube inputs.
        z: (n,) standardised outputs.
    """
    n, q = x.shape
    diagonal = initial_quadratic_mean(x, z)
    best = x[int(torch.argmax(z))]
    rows, cols = torch.triu_indices(q, q)
    n_coef = 1 + q + rows.numel()
    if n < n_coef + q:
        with torch.no_grad():
            factor = torch.diag(1.0 / diagonal.width.detach())
            return FullQuadraticMean(q, diagonal.centre.detach(), float(diagonal.constant), factor)
    pairs = x[:, rows] * x[:, cols]
    features = torch.cat([torch.ones(n, 1, dtype=x.dtype), x, pairs], dim=1)
    gram = features.T @ features
    ridge = 1e-10 * torch.trace(gram) * torch.eye(n_coef, dtype=x.dtype)
    coef = torch.linalg.solve(gram + ridge, features.T @ z)
    b = coef[1 : q + 1]
    upper = torch.zeros(q, q, dtype=x.dtype).index_put((rows, cols), coef[q + 1 :])
    hessian_half = 0.5 * (upper + upper.T)  # B: the diagonal counted once, pairs split
    a = -2.0 * hessian_half
    a = 0.5 * (a + a.T)
    values, vectors = torch.linalg.eigh(a)
    a = (vectors * values.clamp_min(0.01)) @ vectors.T
    centre = torch.linalg.solve(a, b).clamp(-0.5, 1.5)
    factor = torch.linalg.cholesky(a)
    curvature = float((((best - centre) @ factor) ** 2).sum())
    return FullQuadraticMean(q, centre, float(z.max()) + 0.5 * curvature, factor)


def initial_quadratic_mean(x: torch.Tensor, z: torch.Tensor) -> NegativeQuadraticMean:
    """The negative quadratic trend, started at the least-squares diagonal quadratic fit.

    z ≈ b0 + Σ_k (b1_k u_k + b2_k u_k²) by least squares; where b2_k < 0 this is
    m0 − ½ ((u_k − c_k)/ω_k)² with ω_k² = −1 / (2 b2_k), c_k = −b1_k / (2 b2_k). Axes
    without curvature start wide (ω = 3) at the best point. Started there, the marginal
    likelihood fit converges in ~10x fewer steps than from a generic start.

    Args:
        x: (n x q) unit-cube inputs.
        z: (n,) standardised outputs.
    """
    n, q = x.shape
    best = x[int(torch.argmax(z))]
    mean = NegativeQuadraticMean(q, best, float(z.max()))
    if n < 2 * q + 2:
        return mean
    features = torch.cat([torch.ones(n, 1, dtype=x.dtype), x, x**2], dim=1)
    # normal equations, not torch.linalg.lstsq: its LAPACK driver gave run-to-run
    # differences under CPU load, which broke seed-for-seed reproducibility
    gram = features.T @ features
    ridge = 1e-10 * torch.trace(gram) * torch.eye(gram.shape[0], dtype=x.dtype)
    coef = torch.linalg.solve(gram + ridge, features.T @ z)
    b1, b2 = coef[1 : q + 1], coef[q + 1 :]
    concave = b2 < -1e-9
    safe_b2 = torch.where(concave, b2, torch.full_like(b2, -1.0))
    centre = torch.where(concave, (-b1 / (2 * safe_b2)).clamp(-0.5, 1.5), best)
    width = torch.where(concave, (-1.0 / (2 * safe_b2)).sqrt(), torch.full_like(b2, 3.0))
    width = width.clamp(0.01, 10.0)
    curvature = (((best - centre) / width) ** 2).sum()
    with torch.no_grad():
        mean.centre.copy_(centre)
        mean.constant.copy_(z.max() + 0.5 * curvature)
    mean.width = width
    return mean
