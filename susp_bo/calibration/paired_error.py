"""Output error B for paired data: each measured run y_i with its own measured track x_i.

When run i was measured on a track whose geometry was measured too (the paper's
setting, the demo's, and every run of the measured-data format), the simulator
reproduces that run's response, not just its statistics, and B is the paired
residual ``r_i = y_i − h(x_i, w)``. On synthetic data with an exact model the
track-to-track scatter is absent from r_i; what is left is

1. **sensor noise**, whose effect on a band-averaged Welch log spectrum is known
   from h, the noise level and the Welch/band settings
   (:mod:`susp_bo.calibration.welch_noise`): heteroscedastic (variance ∝ noise
   share ρ of the band's power / number of averages K_b), biased by −var, and
   correlated between neighbouring bands (bands narrower than the Welch resolution
   share bins);
2. **model error** (what the simulator misses on real data): per channel, white
   over the decorrelated bands, variance τ_c² — profiled out (the maximum of the
   likelihood over τ_c ≥ 0 at each w) unless fixed in the study config.

Measured on the linearised rig (the fast path; demo truth; 18 runs = 6 seeds x 3;
``python benchmarks/paired_residuals.py --noise 0.005 0.01 0.05 --seeds 6``; a 3-run
check in ``tests/calibration/test_paired_error.py``): at the true parameters the
paired residual has rms 0.003–0.08 (log-amplitude) while the replicate-scatter σ_B
is 0.14–0.23, so eq. 4's σ_B is 8–30 x too large (mean of (r/σ_B)² = 0.007, 0.013,
0.070 at noise 0.005, 0.01, 0.05 m/s²). Standardised by the Welch noise model
(diagonal) the residuals have mean square 0.98 (0.95–1.01 in each quarter of the
band, 0.93–1.05 per channel); after projection onto the range of R and whitening
with the full covariance, 0.96–0.97 (χ² over 40 dimensions per run and channel: mean
38.6, variance 62, against 40 and 80). Neighbouring low bands correlate up to 1.0,
as predicted, so they must not be counted as independent. PyBullet data with the
PyBullet model on the same tracks (demo seed 2024, noise 0.005): mean square 0.88.
log L at the truth sits 0.8 sd (≈ 20 nats) above :func:`paired_expected_log_likelihood`
on average (the model's variance is ≈ 3.5 % high at the lowest bands): conservative
for an "optimum not reached" rule.

The likelihood, per run i and channel c: the residual ``y − h − m`` (m the
second-order bias) is projected onto the range of R_i (bands that are exact linear
combinations of the same Welch bins carry no new information: R_i has F − F'
zero eigenvalues, 8 of 48 for the reference rig), rotated to the eigenvectors of
its covariance Σ' (eigenvalues λ_k), and

    log L(w) = Σ_c max_{t ≥ 0} −½ Σ_i Σ_k [ln 2π(λ_ik + t) + z_ik² / (λ_ik + t)],

t = τ_c². With no sensor noise the inner maximum is the Student-t/Jeffreys form
−(n_c/2) ln SS_c + const (profile and marginal agree up to a constant). Far from
the optimum the profiled τ_c absorbs the misfit, so log L falls like
−(n/2) ln(misfit) rather than quadratically (a range the surrogate can fit).
Deterministic and float64; rounded to 1e-6 nats (see ``_ROUND_DECIMALS``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import ClassVar

import numpy as np

from susp_bo.calibration.welch_noise import band_relative_covariance, noise_residual_moments
from susp_bo.numerics import one_blas_thread
from susp_bo.rig.spectra import SpectrumSettings

_RANK_TOLERANCE = 1e-8  # eigenvalues of R below this x the largest are treated as 0
_GOLDEN_STEPS = 90
_ROUND_DECIMALS = 6
"""log L is rounded to 1e-6 nats: LAPACK/BLAS give last-bit differences between thread
counts and CPUs (measured: 1 vs 2 OpenBLAS threads changed 5 of 5 values in the last
1–4 bits, |log L| ≈ 4600); rounded, two machines differ only when a value falls within
≈1e-12 nats of a rounding boundary (≈1e-6 chance per value), and the surrogate, which
is refitted on these values, sees the same numbers."""


@dataclass(frozen=True)
class PairedOutputError:
    """Output error B of paired runs (see the module docstring).

    Args:
        noise_m_s2: white sensor noise (m/s² rms, >= 0) of the measured accelerations.
        sample_rate_hz: sampling rate of the measured runs (Hz, > 0).
        n_samples: (ν,) number of samples of each run's record (the Welch input).
        spectrum: the spectrum settings the measured and simulated spectra use.
        model_error_sigma: (C,) fixed per-channel model-error sd τ_c (log-amplitude),
            or None to profile τ_c at every w.
        model: always ``"paired"`` (recorded in fingerprints and result.json).
    """

    noise_m_s2: float
    sample_rate_hz: float
    n_samples: tuple[int, ...]
    spectrum: SpectrumSettings
    model_error_sigma: tuple[float, ...] | None = None
    model: str = field(default="paired", init=False)

    expectation_bounds_maximum: ClassVar[bool] = True
    """log L expected at the truth is on the residual's own scale, so the maximum of log L
    lies within a χ²_q spread of it (:func:`.reliability.plausible_max_log_likelihood`)."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.noise_m_s2) and self.noise_m_s2 >= 0.0):
            raise ValueError(f"noise_m_s2: {self.noise_m_s2} must be finite and >= 0 m/s^2")
        if not (math.isfinite(self.sample_rate_hz) and self.sample_rate_hz > 0.0):
            raise ValueError(f"sample_rate_hz: {self.sample_rate_hz} must be > 0 Hz")
        n = tuple(int(v) for v in self.n_samples)
        if not n or min(n) < 2:
            raise ValueError(f"n_samples: {self.n_samples} must be non-empty, each >= 2")
        object.__setattr__(self, "n_samples", n)
        sigma = self.model_error_sigma
        if sigma is not None:
            sigma = tuple(float(s) for s in sigma)
            if not sigma or not all(math.isfinite(s) and s > 0.0 for s in sigma):
                raise ValueError(f"model_error_sigma: {sigma} must be None or finite > 0")
            object.__setattr__(self, "model_error_sigma", sigma)

    @property
    def noise_psd(self) -> float:
        """One-sided noise PSD N = 2σ²/fs ((m/s²)²/Hz)."""
        return 2.0 * self.noise_m_s2**2 / self.sample_rate_hz

    def projection(self, run: int) -> tuple[np.ndarray, np.ndarray]:
        """``(R, P)`` of run ``run``: R (F x F), P (F x F') an orthonormal basis of its range."""
        return _projection(self.spectrum, self.n_samples[run], self.sample_rate_hz)


@lru_cache(maxsize=32)
def _projection(
    spectrum: SpectrumSettings, n_samples: int, sample_rate_hz: float
) -> tuple[np.ndarray, np.ndarray]:
    r = band_relative_covariance(spectrum, n_samples, sample_rate_hz)
    values, vectors = np.linalg.eigh(r)
    basis = np.ascontiguousarray(vectors[:, values > _RANK_TOLERANCE * values[-1]])
    r.setflags(write=False)
    basis.setflags(write=False)
    return r, basis


def whitened_residuals(
    measured: np.ndarray, simulated: np.ndarray, error: PairedOutputError
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals in the eigenbasis of their sensor-noise covariance.

    Args:
        measured: (ν x C x F) measured log-amplitude spectra y_i.
        simulated: (ν x C x F) or (b x ν x C x F) simulated spectra h(x_i, w), noise floor
            included; run i of ``simulated`` is on run i's track.
        error: the paired error model.

    Returns:
        ``(z, lam)``: each ((b x) C x D), D = Σ_i F'_i: rotated residuals and the noise
        variance of each coordinate (0 when there is no sensor noise).
    """
    y = np.asarray(measured, dtype=np.float64)
    h = np.asarray(simulated, dtype=np.float64)
    if y.ndim != 3:
        raise ValueError(f"measured: shape {y.shape}, expected (ν x C x F)")
    single = h.ndim == 3
    if single:
        h = h[None]
    if h.ndim != 4 or h.shape[1:] != y.shape:
        raise ValueError(f"simulated: shape {h.shape}, expected (b x) {y.shape} (paired runs)")
    if y.shape[0] != len(error.n_samples):
        raise ValueError(f"measured: {y.shape[0]} runs, the error model has {len(error.n_samples)}")
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(h))):
        raise ValueError("measured/simulated: contain NaN or inf")
    zs, lams = [], []
    for i in range(y.shape[0]):
        r_full, basis = error.projection(i)
        mean, cov = noise_residual_moments(h[:, i], error.noise_psd, r_full)  # b x C x F (x F)
        resid = (y[i][None] - h[:, i] - mean) @ basis  # b x C x F'
        cov_p = basis.T @ cov @ basis
        lam, vec = np.linalg.eigh(cov_p)
        zs.append((np.swapaxes(vec, -1, -2) @ resid[..., None])[..., 0])
        lams.append(np.clip(lam, 0.0, None))
    z, lam = np.concatenate(zs, axis=-1), np.concatenate(lams, axis=-1)
    return (z[0], lam[0]) if single else (z, lam)


def _channel_log_likelihood(z2: np.ndarray, lam: np.ndarray, t: np.ndarray) -> np.ndarray:
    """−½ Σ_k [ln 2π(λ_k + t) + z_k² / (λ_k + t)] over the last axis; t broadcast (... ,)."""
    v = lam + t[..., None]
    return -0.5 * np.sum(np.log(2.0 * math.pi * v) + z2 / v, axis=-1)


def profile_model_error(z: np.ndarray, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-channel maximum over t = τ² >= 0 of the channel log-likelihood.

    Args:
        z: (... x C x D) whitened-basis residuals; lam: (... x C x D) noise variances.

    Returns:
        ``(log_l, t)``: (... x C) maximised values and the maximisers τ_c².
    """
    z2 = z * z
    scale = np.maximum(np.mean(z2, axis=-1), np.max(lam, axis=-1)) + 1e-300
    lo = np.log(scale) + math.log(1e-12)
    hi = np.log(scale) + math.log(10.0)
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = lo, hi
    c, d = b - ratio * (b - a), a + ratio * (b - a)
    fc = _channel_log_likelihood(z2, lam, np.exp(c))
    fd = _channel_log_likelihood(z2, lam, np.exp(d))
    for _ in range(_GOLDEN_STEPS):
        left = fc >= fd  # maximum in [a, d]
        b = np.where(left, d, b)
        a = np.where(left, a, c)
        new_c = b - ratio * (b - a)
        new_d = a + ratio * (b - a)
        c_next = np.where(left, new_c, d)
        d_next = np.where(left, c, new_d)
        f_new = _channel_log_likelihood(z2, lam, np.exp(np.where(left, new_c, new_d)))
        fc, fd = np.where(left, f_new, fd), np.where(left, fc, f_new)
        c, d = c_next, d_next
    t = np.exp(0.5 * (a + b))
    best = _channel_log_likelihood(z2, lam, t)
    if np.all(np.min(lam, axis=-1) > 0.0):
        zero = _channel_log_likelihood(z2, lam, np.zeros(t.shape))
        at_zero = zero >= best
        best = np.where(at_zero, zero, best)
        t = np.where(at_zero, 0.0, t)
    return best, t


def paired_log_likelihood(
    measured: np.ndarray, simulated: np.ndarray, error: PairedOutputError, exact: bool = False
) -> float | np.ndarray:
    """log L(w) of paired runs (module docstring).

    Args:
        measured: (ν x C x F) measured log-amplitude spectra.
        simulated: (ν x C x F) simulated spectra on the same tracks (noise floor included),
            or (b x ν x C x F) for b parameter vectors.
        error: the paired error model.
        exact: skip the rounding (for finite differences of a local model, which need
            more digits than 1e-6 nats; :mod:`.local_search`).

    Returns:
        log L as a float, or (b,) for batched ``simulated``; rounded to 1e-6 nats and
        computed with one BLAS thread, so that it does not depend on the thread count.
    """
    with one_blas_thread():
        z, lam = whitened_residuals(measured, simulated, error)
    if error.model_error_sigma is None:
        per_channel, _ = profile_model_error(z, lam)
    else:
        sigma = np.asarray(error.model_error_sigma)
        if sigma.shape != (z.shape[-2],):
            raise ValueError(f"model_error_sigma: {sigma.size} values for {z.shape[-2]} channels")
        t = np.broadcast_to(sigma**2, z.shape[:-1])
        per_channel = _channel_log_likelihood(z * z, lam, t)
    value = np.sum(per_channel, axis=-1)
    if not exact:
        value = np.round(value, _ROUND_DECIMALS)
    return float(value) if np.ndim(value) == 0 else value


def paired_expected_log_likelihood(
    error: PairedOutputError, measured: np.ndarray
) -> tuple[float, float]:
    """Mean and sd of log L at the true parameters when the simulator is exact.

    The noise covariance is evaluated at h ≈ y (true to first order at the truth), the
    residual coordinates are then independent N(0, λ_k): −½ Σ (ln 2πλ_k + z_k²/λ_k) has
    mean −½ Σ (ln 2πλ_k + 1) and sd √(D/2). Profiling τ_c adds ½ max(0, χ²₁)-like
    gains, 0.25 nats per channel on average (included in the mean; the sd is unchanged
    to this order). A fixed τ_c (``model_error_sigma``) is part of B: the coordinates are
    then N(0, λ_k + τ_c²) and the mean −½ Σ (ln 2π(λ_k + τ_c²) + 1) — before session 26 τ_c
    was left out here, and a study with a fixed ``[output_error] sigma`` was told
    ``below_expected_fit`` (tens of sd below) on data its model reproduced exactly. With no
    sensor noise (all λ = 0) and τ_c profiled there is nothing to compare against: returns
    ``(nan, nan)``.
    """
    y = np.asarray(measured, dtype=np.float64)
    _, lam = whitened_residuals(y, y, error)
    n = lam.size
    variance = lam
    if error.model_error_sigma is not None:
        variance = lam + np.asarray(error.model_error_sigma, dtype=np.float64)[:, None] ** 2
    if np.any(variance <= 0.0):
        return math.nan, math.nan
    mean = -0.5 * float(np.sum(np.log(2.0 * math.pi * variance) + 1.0))
    if error.model_error_sigma is None:
        mean += 0.25 * lam.shape[0]
    return mean, math.sqrt(n / 2.0)


def paired_fisher_information(
    simulated: np.ndarray, gradient: np.ndarray, error: PairedOutputError
) -> np.ndarray:
    """B's Fisher information about parameters from the spectra's mean, Σ_i G_iᵀ Σ_i⁻¹ G_i.

    The information the residual's mean carries (the covariance's dependence on the
    parameters adds a little more, ignored here), on the bands projected onto the range of
    R_i as in :func:`whitened_residuals`; with the profiled τ_c at 0 (an exact model).
    Its inverse is the Laplace posterior covariance of an exact, linear model.

    Args:
        simulated: (ν x C x F) spectra at the parameters (noise floor included).
        gradient: (q x ν x C x F) their derivatives with respect to the q parameters
            (any units: the information is in the inverse square of those units).
        error: the paired error model (sensor noise > 0).

    Returns:
        (q x q) symmetric positive semi-definite information matrix.

    Raises:
        ValueError: shapes that do not match, or no sensor noise (B's covariance is 0).
    """
    h = np.asarray(simulated, dtype=np.float64)
    g = np.asarray(gradient, dtype=np.float64)
    if h.ndim != 3 or g.ndim != 4 or g.shape[1:] != h.shape:
        raise ValueError(f"simulated {h.shape}, gradient {g.shape}: expected (ν x C x F) and "
                         "(q x ν x C x F)")  # fmt: skip
    if error.noise_m_s2 <= 0.0:
        raise ValueError("noise_m_s2: 0 leaves B without a covariance to weigh the bands with")
    info = np.zeros((g.shape[0], g.shape[0]))
    with one_blas_thread():
        for i in range(h.shape[0]):
            r_full, basis = error.projection(i)
            _, cov = noise_residual_moments(h[i], error.noise_psd, r_full)
            projected = g[:, i] @ basis  # q x C x F'
            solved = np.linalg.solve(basis.T @ cov @ basis, np.moveaxis(projected, 0, -1))
            info += np.einsum("kcf,cfl->kl", projected, solved)
    return 0.5 * (info + info.T)
