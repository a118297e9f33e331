"""Analytic test log-likelihoods with exact posteriors (uniform prior on a box).

They stand in for the rig in tests and benchmarks of the calibration core: each
target gives ``log L(w)`` for a batch of parameter vectors, exact posterior
draws and the exact marginal posterior densities, so that a calibration can be
scored by the mean marginal total variation (MMTV, Acerbi 2020):

    MMTV = (1/q) Σ_k ½ ∫ |p_k(w_k) − p̂_k(w_k)| dw_k

Every target is a product of independent blocks, each of which is either a
correlated Gaussian (marginals analytic; the box is checked to hold ±6 σ, so the
truncation is negligible) or a two-dimensional density whose marginals are
integrated on a fine grid over the box (exact to quadrature error, truncation
included).

The three targets of the issue:

- :func:`banana_2d` — a curved 2-D posterior (Rosenbrock-like banana);
- :func:`correlated_gaussian_7d` — a 7-D Gaussian with strong correlations;
- :func:`weakly_identified_7d` — 5 well identified parameters plus a pair whose
  sum is identified but whose difference is only bounded by the box (the
  paper's components 2 and 3 behave like that).

Parameters live in physical-looking units (boxes are not the unit cube) so the
normalisation of the calibration core is exercised too.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

_GRID = 801  # quadrature points per axis for 2-D blocks


@dataclass(frozen=True)
class GaussianBlock:
    """A correlated Gaussian block: log density −½ (w−m)ᵀ Σ⁻¹ (w−m) (maximum 0).

    Args:
        mean: (d,) mean vector.
        covariance: (d x d) symmetric positive definite covariance.
    """

    mean: np.ndarray
    covariance: np.ndarray

    def __post_init__(self) -> None:
        mean = np.asarray(self.mean, dtype=np.float64)
        cov = np.asarray(self.covariance, dtype=np.float64)
        if mean.ndim != 1 or cov.shape != (mean.size, mean.size):
            raise ValueError(
                f"covariance: shape {cov.shape} does not match mean of size {mean.size}"
            )
        if np.min(np.linalg.eigvalsh(cov)) <= 0.0:
            raise ValueError("covariance: must be positive definite")
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "covariance", cov)
        object.__setattr__(self, "_precision", np.linalg.inv(cov))

    @property
    def dim(self) -> int:
        """Number of parameters of the block."""
        return int(self.mean.size)

    def log_density(self, w: np.ndarray) -> np.ndarray:
        """Unnormalised log density, (b x d) -> (b,)."""
        r = w - self.mean
        return -0.5 * np.einsum("bi,ij,bj->b", r, self._precision, r)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """Draws (n x d) from the untruncated Gaussian."""
        return rng.multivariate_normal(self.mean, self.covariance, size=n, method="cholesky")

    def marginal_pdf(self, k: int, x: np.ndarray, lower: float, upper: float) -> np.ndarray:
        """Marginal density of component k on points x (box truncation negligible)."""
        del lower, upper
        return stats.norm.pdf(x, self.mean[k], np.sqrt(self.covariance[k, k]))

    def check_inside(self, lower: np.ndarray, upper: np.ndarray) -> None:
        """Raise ValueError unless the box holds the mean ± 6 marginal standard deviations."""
        sd = np.sqrt(np.diag(self.covariance))
        if np.any(self.mean - 6 * sd < lower) or np.any(self.mean + 6 * sd > upper):
            raise ValueError("bounds: a Gaussian block must fit inside the box with ±6 sd")


@dataclass(frozen=True)
class PlanarBlock:
    """A two-dimensional block with an arbitrary log density, integrated on a grid.

    Args:
        log_density_fn: maps (b x 2) to (b,) unnormalised log density.
        sampler_fn: exact sampler of the untruncated density, (n, Generator) -> (n x 2);
            the box is applied by the caller (rejection).
    """

    log_density_fn: Callable[[np.ndarray], np.ndarray]
    sampler_fn: Callable[[int, np.random.Generator], np.ndarray]
    dim: int = field(default=2, init=False)

    def log_density(self, w: np.ndarray) -> np.ndarray:
        """Unnormalised log density, (b x 2) -> (b,)."""
        return self.log_density_fn(w)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """Exact draws (n x 2) of the untruncated density."""
        return self.sampler_fn(n, rng)

    def marginal_pdf(
        self, k: int, x: np.ndarray, lower: np.ndarray, upper: np.ndarray
    ) -> np.ndarray:
        """Marginal density of component k (0 or 1) on points x, by quadrature over the box."""
        g0 = np.linspace(lower[0], upper[0], _GRID)
        g1 = np.linspace(lower[1], upper[1], _GRID)
        a, b = np.meshgrid(g0, g1, indexing="ij")
        logp = self.log_density(np.column_stack([a.ravel(), b.ravel()])).reshape(a.shape)
        p = np.exp(logp - logp.max())
        other = g1 if k == 0 else g0
        marginal = np.trapezoid(p, other, axis=1 - k)
        grid = g0 if k == 0 else g1
        marginal /= np.trapezoid(marginal, grid)
        return np.interp(x, grid, marginal, left=0.0, right=0.0)


@dataclass(frozen=True)
class AnalyticTarget:
    """A test log-likelihood with known posterior under a uniform prior on ``bounds``.

    Args:
        name: short identifier.
        bounds: (2 x q) lower and upper bounds of the admissible box.
        blocks: independent blocks, in parameter order; their dims sum to q.
        offset: constant added to log L (makes the maximum a realistic non-zero value).
    """

    name: str
    bounds: np.ndarray
    blocks: tuple[GaussianBlock | PlanarBlock, ...]
    offset: float = 0.0

    def __post_init__(self) -> None:
        bounds = np.asarray(self.bounds, dtype=np.float64)
        q = sum(b.dim for b in self.blocks)
        if bounds.shape != (2, q) or np.any(bounds[1] <= bounds[0]):
            raise ValueError(f"bounds: expected (2 x {q}) with upper > lower, got {bounds}")
        object.__setattr__(self, "bounds", bounds)
        for block, sl in zip(self.blocks, self._slices()):
            if isinstance(block, GaussianBlock):
                block.check_inside(bounds[0, sl], bounds[1, sl])

    @property
    def dim(self) -> int:
        """Number of parameters q."""
        return int(self.bounds.shape[1])

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names w1 … wq."""
        return tuple(f"w{k + 1}" for k in range(self.dim))

    def _slices(self) -> list[slice]:
        out, start = [], 0
        for b in self.blocks:
            out.append(slice(start, start + b.dim))
            start += b.dim
        return out

    def log_likelihood(self, w: np.ndarray) -> np.ndarray:
        """log L for a batch of parameter vectors, (b x q) -> (b,)."""
        w = np.atleast_2d(np.asarray(w, dtype=np.float64))
        total = np.full(w.shape[0], self.offset)
        for block, sl in zip(self.blocks, self._slices()):
            total = total + block.log_density(w[:, sl])
        return total

    def __call__(self, w: np.ndarray) -> np.ndarray:
        """Alias of :meth:`log_likelihood` (the ``evaluate`` callable of ``calibrate``)."""
        return self.log_likelihood(w)

    def sample(self, n: int, seed: int) -> np.ndarray:
        """Exact posterior draws (n x q) (truncated to the box by rejection)."""
        rng = np.random.default_rng(seed)
        parts = []
        for block, sl in zip(self.blocks, self._slices()):
            lo, hi = self.bounds[0, sl], self.bounds[1, sl]
            got: list[np.ndarray] = []
            count = 0
            while count < n:
                s = block.sample(n, rng)
                s = s[np.all((s >= lo) & (s <= hi), axis=1)]
                got.append(s)
                count += s.shape[0]
            parts.append(np.concatenate(got)[:n])
        return np.concatenate(parts, axis=1)

    def marginal_pdf(self, k: int, x: np.ndarray) -> np.ndarray:
        """Exact marginal posterior density of component k on points x (physical units)."""
        for block, sl in zip(self.blocks, self._slices()):
            if sl.start <= k < sl.stop:
                return block.marginal_pdf(
                    k - sl.start,
                    np.asarray(x, dtype=np.float64),
                    self.bounds[0, sl],
                    self.bounds[1, sl],
                )
        raise ValueError(f"k: {k} outside 0..{self.dim - 1}")


def marginal_total_variation(
    target: AnalyticTarget, samples: np.ndarray, n_grid: int = 2001
) -> np.ndarray:
    """Total variation between each exact marginal and a KDE of ``samples``.

    Args:
        target: the analytic target.
        samples: (draws x q) approximate posterior draws in physical units.
        n_grid: grid points per axis over the box.

    Returns:
        (q,) total variation distances in [0, 1]; their mean is the MMTV.
    """
    from susp_bo.calibration.posterior import marginal_density

    samples = np.asarray(samples, dtype=np.float64)
    out = np.empty(target.dim)
    for k in range(target.dim):
        grid = np.linspace(target.bounds[0, k], target.bounds[1, k], n_grid)
        exact = target.marginal_pdf(k, grid)
        approx = marginal_density(samples[:, k], grid, target.bounds[:, k])
        out[k] = 0.5 * np.trapezoid(np.abs(exact - approx), grid)
    return out


def banana_2d() -> AnalyticTarget:
    """Curved 2-D posterior: w1 ~ N(0.5, 0.15²), w2 | w1 ~ N(2.82 + 8 (w1 − 0.5)², 0.1²).

    Box [0, 1] x [2, 4.5]; the quadratic ridge bends the posterior into a banana.
    """
    s1, s2, curve = 0.15, 0.1, 8.0

    def ridge(w1: np.ndarray) -> np.ndarray:
        return 3.0 + curve * ((w1 - 0.5) ** 2 - s1**2)

    def logp(w: np.ndarray) -> np.ndarray:
        u = (w[:, 0] - 0.5) / s1
        v = (w[:, 1] - ridge(w[:, 0])) / s2
        return -0.5 * u**2 - 0.5 * v**2

    def draw(n: int, rng: np.random.Generator) -> np.ndarray:
        w1 = 0.5 + s1 * rng.standard_normal(n)
        return np.column_stack([w1, ridge(w1) + s2 * rng.standard_normal(n)])

    block = PlanarBlock(logp, draw)
    return AnalyticTarget("banana_2d", np.array([[0.0, 2.0], [1.0, 4.5]]), (block,), -12.0)


def correlated_gaussian_7d() -> AnalyticTarget:
    """7-D Gaussian with correlations up to ±0.8 and scales from 2 % to 6 % of the box."""
    lower = np.array([1.0e5, 10.0, 0.0, -1.0, 2.0e3, 0.1, 50.0])
    upper = np.array([5.0e5, 30.0, 1.0, 1.0, 8.0e3, 0.9, 150.0])
    width = upper - lower
    mean = lower + width * np.array([0.42, 0.55, 0.35, 0.6, 0.5, 0.65, 0.45])
    sd = width * np.array([0.05, 0.06, 0.03, 0.04, 0.05, 0.02, 0.06])
    corr = np.eye(7)
    pairs = {(0, 1): 0.8, (2, 3): -0.6, (1, 4): 0.4, (5, 6): 0.7, (0, 6): -0.2}
    for (i, j), r in pairs.items():
        corr[i, j] = corr[j, i] = r
    cov = corr * np.outer(sd, sd)
    return AnalyticTarget(
        "correlated_gaussian_7d", np.vstack([lower, upper]), (GaussianBlock(mean, cov),), -250.0
    )


def weakly_identified_7d() -> AnalyticTarget:
    """7-D: six identified parameters plus a pair (w2, w3) of which only the sum is identified.

    In normalised units u = (w − lower)/(upper − lower), u2 + u3 has sd 0.03·√2 while
    u2 − u3 has sd 0.6·√2, i.e. that direction is bounded by the box only: the marginals
    of w2 and w3 are broad, flat-topped and truncated (the paper's components 2 and 3).
    """
    lower = np.array([0.5, 1.0e4, 1.0e4, 0.2, 100.0, 0.0, 1.0])
    upper = np.array([1.5, 5.0e4, 5.0e4, 0.8, 300.0, 10.0, 3.0])
    width = upper - lower
    first = GaussianBlock(lower[:1] + 0.4 * width[:1], np.array([[(0.04 * width[0]) ** 2]]))
    mean4 = lower[3:] + width[3:] * np.array([0.55, 0.6, 0.45, 0.5])
    sd4 = width[3:] * np.array([0.05, 0.03, 0.05, 0.04])
    corr4 = np.eye(4)
    corr4[0, 2] = corr4[2, 0] = 0.5
    corr4[1, 3] = corr4[3, 1] = -0.4
    rest = GaussianBlock(mean4, corr4 * np.outer(sd4, sd4))

    w_lo, w_hi = lower[1:3], upper[1:3]
    sd_sum, sd_diff = 0.03, 0.6
    rot = np.array([[1.0, 1.0], [1.0, -1.0]]) / np.sqrt(2.0)
    centre_rot = np.array([1.1, 0.1]) / np.sqrt(2.0)

    def logp_pair(w: np.ndarray) -> np.ndarray:
        u = (w - w_lo) / (w_hi - w_lo)
        r = u @ rot.T - centre_rot
        return -0.5 * (r[:, 0] / sd_sum) ** 2 - 0.5 * (r[:, 1] / sd_diff) ** 2

    def draw(n: int, rng: np.random.Generator) -> np.ndarray:
        r = centre_rot + rng.standard_normal((n, 2)) * np.array([sd_sum, sd_diff])
        return w_lo + (w_hi - w_lo) * (r @ rot)

    pair = PlanarBlock(logp_pair, draw)
    return AnalyticTarget(
        "weakly_identified_7d", np.vstack([lower, upper]), (first, pair, rest), -400.0
    )


def _grid_sampler(
    log_density: Callable[[np.ndarray], np.ndarray], lower: np.ndarray, upper: np.ndarray
) -> Callable[[int, np.random.Generator], np.ndarray]:
    """Sampler of a 2-D density on the box: a grid cell by its mass, uniform inside it."""
    g0 = np.linspace(lower[0], upper[0], _GRID)
    g1 = np.linspace(lower[1], upper[1], _GRID)
    a, b = np.meshgrid(g0, g1, indexing="ij")
    logp = log_density(np.column_stack([a.ravel(), b.ravel()]))
    p = np.exp(logp - logp.max())
    p /= p.sum()
    step = np.array([g0[1] - g0[0], g1[1] - g1[0]])
    centres = np.column_stack([a.ravel(), b.ravel()])

    def draw(n: int, rng: np.random.Generator) -> np.ndarray:
        idx = rng.choice(p.size, size=n, p=p)
        return centres[idx] + step * (rng.uniform(size=(n, 2)) - 0.5)

    return draw


def oscillator_2d() -> AnalyticTarget:
    """Realistic likelihood: log spectra of a base-excited 1-DOF suspension (eq. 4, ν = μ = 1).

    w = (stiffness k in N/m, damping c in N·s/m), mass 1000 kg; the "measured" spectrum
    is log|acceleration transmissibility| at k = 8e5 N/m, c = 6e3 N·s/m on 80 frequencies
    0.5–20 Hz plus N(0, 0.3²) output error; log L is eq. 4 with σ_B = 0.3. Unlike the
    Gaussian targets, log L is far from quadratic away from the maximum (the resonance
    leaves the band and the misfit saturates), like a rig likelihood. The exact posterior
    is integrated on an 801² grid.
    """
    from susp_bo.calibration.likelihood import OutputError, log_likelihood

    mass = 1000.0
    omega = 2.0 * np.pi * np.geomspace(0.5, 20.0, 80)

    def log_spectrum(w: np.ndarray) -> np.ndarray:
        k, c = w[:, :1], w[:, 1:2]
        h = (k + 1j * omega * c) / (k - mass * omega**2 + 1j * omega * c) * omega**2
        return np.log(np.abs(h))[:, None, :]  # b x C=1 x F

    measured = log_spectrum(np.array([[8.0e5, 6.0e3]]))
    measured = measured + 0.3 * np.random.default_rng(0).standard_normal(measured.shape)
    error = OutputError((0.3,))

    def logp(w: np.ndarray) -> np.ndarray:
        out = np.empty(w.shape[0])
        for i in range(0, w.shape[0], 20000):
            sim = log_spectrum(w[i : i + 20000])[:, None]  # b x μ=1 x C x F
            out[i : i + 20000] = log_likelihood(measured, sim, error)
        return out

    lower, upper = np.array([2.0e5, 1.0e3]), np.array([2.0e6, 3.0e4])
    block = PlanarBlock(logp, _grid_sampler(logp, lower, upper))
    return AnalyticTarget("oscillator_2d", np.vstack([lower, upper]), (block,))


TARGETS: dict[str, Callable[[], AnalyticTarget]] = {
    "banana_2d": banana_2d,
    "correlated_gaussian_7d": correlated_gaussian_7d,
    "weakly_identified_7d": weakly_identified_7d,
    "oscillator_2d": oscillator_2d,
}
