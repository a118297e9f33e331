"""The targets of issue 3 (session 1): banana 2-D, correlated and weakly identified 7-D,
and a base-excited oscillator (a realistic spectral likelihood)."""

from __future__ import annotations

import numpy as np

from susp_bo.calibration.test_functions.blocks import (
    AnalyticTarget,
    GaussianBlock,
    PlanarBlock,
    grid_sampler,
)


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
    block = PlanarBlock(logp, grid_sampler(logp, lower, upper))
    return AnalyticTarget("oscillator_2d", np.vstack([lower, upper]), (block,))
