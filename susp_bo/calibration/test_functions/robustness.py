"""Targets for the surrogate's robustness (issue 10, part 3): curved, heavy-tailed,
multimodal posteriors in ≥ 5-D and a noisy log L, each with exact marginals.

- :func:`curved_chain_5d` — banana-shaped conditionals chained over 5 dimensions
  (:class:`CurvedChainBlock`): each parameter's ridge is a (saturating) parabola of the
  previous one, so every pair (w_k, w_k+1) is a banana. Marginals by forward 1-D
  quadrature along the chain (a Markov chain: p_k+1(y) = ∫ p(y | x) p_k(x) dx).
- :func:`student_t_6d` — a 6-D multivariate Student-t with ν = 3 (:class:`StudentTBlock`):
  polynomial tails, all components dependent through the shared scale. The box truncates
  it noticeably; its exact truncated marginals come from the scale-mixture form by a
  1-D quadrature over the mixing variable.
- :func:`trimodal_5d` — three well-separated correlated Gaussian modes of weights
  0.5 / 0.3 / 0.2 (:class:`GaussianMixtureBlock`); marginals are Gaussian mixtures.
- :func:`noisy_gaussian_7d` — a correlated 7-D Gaussian whose log L is observed with
  N(0, 1 nat²) noise per evaluation (:class:`NoisyTarget`); the exact posterior is the
  noiseless one (the noise is not part of the model, only of the observation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import special, stats

from susp_bo.calibration.test_functions.blocks import AnalyticTarget, GaussianBlock

_CHAIN_GRID = 3001  # grid points of the standardised chain coordinate
_CHAIN_HALF_WIDTH = 10.0  # the grid spans ±10 (standardised units)
_MAX_OUTSIDE = 1e-6  # largest mass a block's marginal may lose outside the box
_MIX_GRID = 1500  # nodes of the quadrature over log g (Student-t mixing variable)


def _saturating_square(z: np.ndarray, c: float) -> np.ndarray:
    """h(z) = c² (1 − exp(−z²/c²)): z² near 0, bounded by c² (keeps the chain's tails finite)."""
    return c * c * -np.expm1(-(z * z) / (c * c))


@dataclass(frozen=True)
class CurvedChainBlock:
    """Banana-shaped conditionals chained over d parameters.

    In standardised coordinates x = (w − loc) / scale:
    x_1 ~ N(0, 1); x_k+1 | x_k ~ N(β h((x_k − m_k)/s_k), σ²), h the saturating square
    :func:`_saturating_square` with saturation c, m_k and s_k the exact mean and sd of
    x_k (so every link bends around the middle of its predecessor's mass).

    Args:
        loc: (d,) physical location of x = 0.
        scale: (d,) physical size of a unit of x.
        beta: curvature of the ridges.
        sigma: conditional sd around a ridge (standardised units).
        c: saturation of the square (standardised units).
    """

    loc: np.ndarray
    scale: np.ndarray
    beta: float = 0.6
    sigma: float = 0.3
    c: float = 2.5
    dim: int = field(init=False)

    def __post_init__(self) -> None:
        loc = np.asarray(self.loc, dtype=np.float64)
        scale = np.asarray(self.scale, dtype=np.float64)
        if loc.ndim != 1 or scale.shape != loc.shape or np.any(scale <= 0):
            raise ValueError(f"loc, scale: shapes {loc.shape}, {scale.shape}; scale must be > 0")
        object.__setattr__(self, "loc", loc)
        object.__setattr__(self, "scale", scale)
        object.__setattr__(self, "dim", int(loc.size))
        grid = np.linspace(-_CHAIN_HALF_WIDTH, _CHAIN_HALF_WIDTH, _CHAIN_GRID)
        dens = [stats.norm.pdf(grid)]
        moments = []
        for _ in range(self.dim - 1):
            p = dens[-1]
            m = np.trapezoid(grid * p, grid)
            s = math.sqrt(np.trapezoid((grid - m) ** 2 * p, grid))
            moments.append((m, s))
            ridge = self.beta * _saturating_square((grid - m) / s, self.c)
            # p_k+1(y) = ∫ N(y; ridge(x), σ²) p_k(x) dx on the grid (rows: y, columns: x)
            kernel = stats.norm.pdf(grid[:, None], ridge[None, :], self.sigma)
            nxt = np.trapezoid(kernel * p[None, :], grid, axis=1)
            dens.append(nxt / np.trapezoid(nxt, grid))
        object.__setattr__(self, "_grid", grid)
        object.__setattr__(self, "_densities", tuple(dens))
        object.__setattr__(self, "_moments", tuple(moments))

    def _ridge(self, k: int, x: np.ndarray) -> np.ndarray:
        """Mean of x_k+1 given x_k (k 0-based), standardised units."""
        m, s = self._moments[k]
        return self.beta * _saturating_square((x - m) / s, self.c)

    def log_density(self, w: np.ndarray) -> np.ndarray:
        """Unnormalised log density, (b x d) -> (b,); 0 on the ridge through x_1 = 0."""
        x = (w - self.loc) / self.scale
        out = -0.5 * x[:, 0] ** 2
        for k in range(self.dim - 1):
            out = out - 0.5 * ((x[:, k + 1] - self._ridge(k, x[:, k])) / self.sigma) ** 2
        return out

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """Exact draws (n x d) by ancestral sampling along the chain."""
        x = np.empty((n, self.dim))
        x[:, 0] = rng.standard_normal(n)
        for k in range(self.dim - 1):
            x[:, k + 1] = self._ridge(k, x[:, k]) + self.sigma * rng.standard_normal(n)
        return self.loc + self.scale * x

    def marginal_pdf(
        self, k: int, x: np.ndarray, lower: np.ndarray, upper: np.ndarray
    ) -> np.ndarray:
        """Marginal density of component k on points x (truncation < 1e-6, checked)."""
        del lower, upper
        u = (np.asarray(x, dtype=np.float64) - self.loc[k]) / self.scale[k]
        return np.interp(u, self._grid, self._densities[k], left=0.0, right=0.0) / self.scale[k]

    def check_inside(self, lower: np.ndarray, upper: np.ndarray) -> None:
        """Raise ValueError when a marginal has more than 1e-6 of its mass outside the box."""
        for k in range(self.dim):
            lo = (lower[k] - self.loc[k]) / self.scale[k]
            hi = (upper[k] - self.loc[k]) / self.scale[k]
            p = self._densities[k]
            inside = (self._grid >= lo) & (self._grid <= hi)
            outside = 1.0 - np.trapezoid(np.where(inside, p, 0.0), self._grid)
            if outside > _MAX_OUTSIDE:
                raise ValueError(
                    f"bounds: component {k} of the chain loses {outside:.2g} of its mass "
                    f"outside the box (allowed {_MAX_OUTSIDE:g})"
                )


@dataclass(frozen=True)
class StudentTBlock:
    """Multivariate Student-t with ν degrees of freedom and a diagonal scale matrix.

    log p(w) = −(ν + d)/2 · log(1 + Σ_k x_k² / ν), x = (w − loc)/scale: the components are
    uncorrelated but dependent (one shared scale), with polynomial tails. As a scale
    mixture, x | g ~ N(0, I/g), g ~ Gamma(ν/2, rate ν/2); with a diagonal scale the box
    factorises given g, so the marginal of the *truncated* density is exact by one 1-D
    quadrature over g:

        p(x_k | box) ∝ ∫ Gamma(g) √g φ(√g x_k) Π_{j≠k} [Φ(√g b_j) − Φ(√g a_j)] dg

    with [a_j, b_j] the box in standardised units.

    Args:
        loc: (d,) physical location.
        scale: (d,) physical scales.
        nu: degrees of freedom (> 0).
    """

    loc: np.ndarray
    scale: np.ndarray
    nu: float = 3.0
    dim: int = field(init=False)

    def __post_init__(self) -> None:
        loc = np.asarray(self.loc, dtype=np.float64)
        scale = np.asarray(self.scale, dtype=np.float64)
        if loc.ndim != 1 or scale.shape != loc.shape or np.any(scale <= 0) or self.nu <= 0:
            raise ValueError("loc, scale, nu: need (d,) shapes, scale > 0 and nu > 0")
        object.__setattr__(self, "loc", loc)
        object.__setattr__(self, "scale", scale)
        object.__setattr__(self, "dim", int(loc.size))

    def log_density(self, w: np.ndarray) -> np.ndarray:
        """Unnormalised log density, (b x d) -> (b,); maximum 0 at loc."""
        x = (w - self.loc) / self.scale
        return -0.5 * (self.nu + self.dim) * np.log1p(np.sum(x * x, axis=1) / self.nu)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """Exact draws (n x d) of the untruncated density (Gaussian over √g)."""
        g = rng.gamma(0.5 * self.nu, 2.0 / self.nu, size=n)
        z = rng.standard_normal((n, self.dim))
        return self.loc + self.scale * z / np.sqrt(g)[:, None]

    def _mixing_nodes(self) -> tuple[np.ndarray, np.ndarray]:
        """Nodes g and weights (Gamma density x dg, trapezoid in log g)."""
        t = np.linspace(math.log(1e-7), math.log(60.0), _MIX_GRID)
        g = np.exp(t)
        a = 0.5 * self.nu
        log_gamma_pdf = a * math.log(a) - special.gammaln(a) + (a - 1) * t - a * g
        w = np.exp(log_gamma_pdf + t)  # dg = g dt
        w *= np.gradient(t)
        return g, w

    def marginal_pdf(
        self, k: int, x: np.ndarray, lower: np.ndarray, upper: np.ndarray
    ) -> np.ndarray:
        """Exact marginal density of component k of the box-truncated density on x."""
        g, wt = self._mixing_nodes()
        a = (np.asarray(lower) - self.loc) / self.scale
        b = (np.asarray(upper) - self.loc) / self.scale
        sg = np.sqrt(g)[:, None]
        inside = stats.norm.cdf(sg * b[None, :]) - stats.norm.cdf(sg * a[None, :])  # G x d
        others = np.prod(np.delete(inside, k, axis=1), axis=1)  # G
        norm = float(np.sum(wt * others * inside[:, k]))
        u = (np.asarray(x, dtype=np.float64) - self.loc[k]) / self.scale[k]
        dens = np.sqrt(g)[None, :] * stats.norm.pdf(np.sqrt(g)[None, :] * u.reshape(-1, 1))
        pdf = dens @ (wt * others) / norm / self.scale[k]
        pdf = np.where((u >= a[k]) & (u <= b[k]), pdf, 0.0)
        return pdf.reshape(np.shape(x))


@dataclass(frozen=True)
class GaussianMixtureBlock:
    """A mixture of correlated Gaussians: log p = log Σ_i π_i N(w; m_i, C_i) − its maximum.

    Args:
        weights: (K,) mixture weights (> 0, summing to 1).
        means: (K x d) component means.
        covariances: (K x d x d) component covariances (positive definite).
    """

    weights: np.ndarray
    means: np.ndarray
    covariances: np.ndarray
    dim: int = field(init=False)

    def __post_init__(self) -> None:
        weights = np.asarray(self.weights, dtype=np.float64)
        means = np.asarray(self.means, dtype=np.float64)
        covs = np.asarray(self.covariances, dtype=np.float64)
        k, d = means.shape
        if weights.shape != (k,) or covs.shape != (k, d, d) or not np.isclose(weights.sum(), 1):
            raise ValueError("weights, means, covariances: need (K,), (K x d), (K x d x d)")
        if np.any(weights <= 0) or min(np.linalg.eigvalsh(c).min() for c in covs) <= 0:
            raise ValueError("weights must be > 0 and covariances positive definite")
        object.__setattr__(self, "weights", weights)
        object.__setattr__(self, "means", means)
        object.__setattr__(self, "covariances", covs)
        object.__setattr__(self, "dim", int(d))
        comps = [GaussianBlock(m, c) for m, c in zip(means, covs)]
        log_norm = np.array([-0.5 * np.linalg.slogdet(c)[1] for c in covs])
        object.__setattr__(self, "_components", tuple(comps))
        object.__setattr__(self, "_log_coef", np.log(weights) + log_norm)
        peak = max(float(self._log_mixture(m[None, :])[0]) for m in means)
        object.__setattr__(self, "_peak", peak)

    def _log_mixture(self, w: np.ndarray) -> np.ndarray:
        terms = np.stack([c.log_density(w) for c in self._components], axis=1) + self._log_coef
        return special.logsumexp(terms, axis=1)

    def log_density(self, w: np.ndarray) -> np.ndarray:
        """Unnormalised log density, (b x d) -> (b,) (about 0 at the highest mode)."""
        return self._log_mixture(w) - self._peak

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """Exact draws (n x d): a component by its weight, then a Gaussian draw."""
        counts = rng.multinomial(n, self.weights)
        parts = [c.sample(int(m), rng) for c, m in zip(self._components, counts)]
        draws = np.concatenate(parts)
        return draws[rng.permutation(n)]

    def marginal_pdf(
        self, k: int, x: np.ndarray, lower: np.ndarray, upper: np.ndarray
    ) -> np.ndarray:
        """Mixture of the components' Gaussian marginals (truncation negligible, checked)."""
        return sum(
            p * c.marginal_pdf(k, x, lower, upper) for p, c in zip(self.weights, self._components)
        )

    def check_inside(self, lower: np.ndarray, upper: np.ndarray) -> None:
        """Raise ValueError unless every component fits inside the box with ±6 sd."""
        for c in self._components:
            c.check_inside(lower, upper)


class NoisyTarget:
    """An analytic target whose log L is observed with Gaussian noise of sd ``noise_sd`` nats.

    Each call of :meth:`log_likelihood` draws fresh noise for each row, from a generator
    seeded by (``noise_seed``, call number): a rerun in the same order sees the same
    noise; the same point evaluated twice gets different values. The exact posterior is
    the noiseless target's (:meth:`sample`, :meth:`marginal_pdf` delegate to it). Use
    :meth:`reseeded` for a fresh counter per run.

    Args:
        exact: the noiseless target.
        noise_sd: sd of the noise (nats, > 0).
        noise_seed: seed of the noise stream.
    """

    def __init__(self, exact: AnalyticTarget, noise_sd: float = 1.0, noise_seed: int = 0) -> None:
        if not noise_sd > 0.0:
            raise ValueError(f"noise_sd: {noise_sd} must be > 0 nats")
        self.exact = exact
        self.noise_sd = float(noise_sd)
        self.noise_seed = int(noise_seed)
        self.name = exact.name
        self.bounds = exact.bounds
        self.calls = 0

    @property
    def dim(self) -> int:
        """Number of parameters q."""
        return self.exact.dim

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names w1 … wq."""
        return self.exact.names

    def reseeded(self, noise_seed: int) -> NoisyTarget:
        """A copy with another noise seed and the call counter at 0."""
        return NoisyTarget(self.exact, self.noise_sd, noise_seed)

    def log_likelihood(self, w: np.ndarray) -> np.ndarray:
        """Noisy log L, (b x q) -> (b,): exact log L + N(0, noise_sd²) per row."""
        exact = self.exact.log_likelihood(w)
        rng = np.random.default_rng(np.random.SeedSequence([self.noise_seed, self.calls]))
        self.calls += 1
        return exact + self.noise_sd * rng.standard_normal(exact.shape)

    def __call__(self, w: np.ndarray) -> np.ndarray:
        """Alias of :meth:`log_likelihood` (the ``evaluate`` callable of ``calibrate``)."""
        return self.log_likelihood(w)

    def sample(self, n: int, seed: int) -> np.ndarray:
        """Exact posterior draws (n x q) (the noiseless target's)."""
        return self.exact.sample(n, seed)

    def marginal_pdf(self, k: int, x: np.ndarray) -> np.ndarray:
        """Exact marginal posterior density of component k (the noiseless target's)."""
        return self.exact.marginal_pdf(k, x)


def curved_chain_5d() -> AnalyticTarget:
    """Banana-shaped conditionals chained over 5 parameters (:class:`CurvedChainBlock`).

    β = 0.6, σ = 0.3, c = 2.5: each conditional sd is about a third of its parameter's
    marginal sd, and 2 sd off the ridge's vertex the ridge has moved by 8 conditional sd.
    Physical units of different sizes; the box leaves < 1e-6 of each marginal outside.
    """
    lower = np.array([0.0, 1.0e4, 10.0, -2.0, 200.0])
    upper = np.array([1.0, 5.0e4, 50.0, 2.0, 800.0])
    width = upper - lower
    loc = lower + width * np.array([0.5, 0.3, 0.28, 0.35, 0.3])
    scale = width * np.array([0.1, 0.09, 0.08, 0.1, 0.085])
    block = CurvedChainBlock(loc, scale)
    return AnalyticTarget("curved_chain_5d", np.vstack([lower, upper]), (block,), -30.0)


def student_t_6d() -> AnalyticTarget:
    """6-D multivariate Student-t, ν = 3, diagonal scales 4–6 % of the box, off-centre.

    The box cuts the tails (0.14–0.45 % of each untruncated marginal's mass lies outside
    it); the exact marginals account for it (:class:`StudentTBlock`).
    """
    lower = np.array([0.0, 1.0e5, -5.0, 10.0, 0.1, 1.0e3])
    upper = np.array([1.0, 4.0e5, 5.0, 20.0, 0.5, 9.0e3])
    width = upper - lower
    loc = lower + width * np.array([0.45, 0.6, 0.4, 0.55, 0.35, 0.5])
    scale = width * np.array([0.05, 0.06, 0.04, 0.06, 0.05, 0.045])
    block = StudentTBlock(loc, scale, nu=3.0)
    return AnalyticTarget("student_t_6d", np.vstack([lower, upper]), (block,), -80.0)


def trimodal_5d() -> AnalyticTarget:
    """Three correlated Gaussian modes in 5-D, weights 0.5 / 0.3 / 0.2.

    The modes are ≥ 9 sd apart in at least two coordinates each (no overlap between
    them: the posterior density between modes is below e⁻²⁰ of the peaks) and differ in
    shape (scales 2–5 % of the box, correlations of either sign).
    """
    lower = np.array([0.0, 100.0, -1.0, 1.0e3, 0.0])
    upper = np.array([1.0, 300.0, 1.0, 3.0e3, 50.0])
    width = upper - lower
    frac_means = np.array(
        [
            [0.30, 0.35, 0.40, 0.60, 0.50],
            [0.70, 0.65, 0.45, 0.35, 0.55],
            [0.45, 0.70, 0.75, 0.70, 0.30],
        ]
    )
    frac_sd = np.array(
        [
            [0.04, 0.03, 0.05, 0.04, 0.03],
            [0.03, 0.04, 0.03, 0.05, 0.04],
            [0.025, 0.03, 0.03, 0.03, 0.05],
        ]
    )
    corrs = []
    for pairs in ({(0, 1): 0.6, (2, 3): -0.4}, {(0, 2): -0.5, (3, 4): 0.5}, {(1, 4): 0.4}):
        corr = np.eye(5)
        for (i, j), r in pairs.items():
            corr[i, j] = corr[j, i] = r
        corrs.append(corr)
    means = lower + width * frac_means
    covs = np.stack([c * np.outer(width * s, width * s) for c, s in zip(corrs, frac_sd)])
    block = GaussianMixtureBlock(np.array([0.5, 0.3, 0.2]), means, covs)
    return AnalyticTarget("trimodal_5d", np.vstack([lower, upper]), (block,), -60.0)


def noisy_gaussian_7d(noise_seed: int = 0) -> NoisyTarget:
    """A correlated 7-D Gaussian observed with N(0, 1 nat²) noise on every log L evaluation.

    Scales 3–6 % of the box, correlations up to ±0.7; exact posterior = the noiseless one.
    """
    lower = np.array([0.0, 1.0e4, 1.0, -3.0, 50.0, 0.0, 1.0e5])
    upper = np.array([2.0, 9.0e4, 4.0, 3.0, 250.0, 1.0, 6.0e5])
    width = upper - lower
    mean = lower + width * np.array([0.55, 0.4, 0.6, 0.45, 0.5, 0.35, 0.62])
    sd = width * np.array([0.05, 0.04, 0.06, 0.05, 0.03, 0.05, 0.045])
    corr = np.eye(7)
    pairs = {(0, 1): -0.7, (1, 2): 0.5, (3, 4): 0.6, (5, 6): -0.5, (2, 6): 0.3, (0, 5): 0.4}
    for (i, j), r in pairs.items():
        corr[i, j] = corr[j, i] = r
    exact = AnalyticTarget(
        "noisy_gaussian_7d",
        np.vstack([lower, upper]),
        (GaussianBlock(mean, corr * np.outer(sd, sd)),),
        -150.0,
    )
    return NoisyTarget(exact, 1.0, noise_seed)
