"""The scale a residual y − h is judged on: what the output error B allows, bin by bin.

**Unpaired** (σ_B per channel, :class:`~susp_bo.calibration.likelihood.OutputError`):
the residual of every run, channel c and band is allowed N(0, σ_c²). σ_B of a study
is estimated from the scatter between runs on *different* tracks; the check pairs
each run with its own track, so on paired data this scale is far too wide
(measured: paired residuals 0.003–0.05 log-amplitude at the truth against σ_B
0.12–0.19, mean Z² 0.03–0.04 on null data) and the check is under-powered.

**Paired** (:class:`~susp_bo.calibration.paired_error.PairedOutputError`, every run
with its own measured track): the residual of run i, channel c, band f is allowed

    y_icf − h_icf ~ N(m_icf, λ_icf + τ_c²),

m and λ the mean and variance that white sensor noise gives a band-averaged Welch
log spectrum (:func:`~susp_bo.calibration.welch_noise.noise_residual_moments`, at
the model's prediction h), τ_c the channel's model-error sd. τ_c is the study's
when fixed there; otherwise it is **estimated robustly** from the residuals being
checked: the t = τ_c² ≥ 0 at which the median over runs and bands of
(r − median r)² / (λ + t) equals the median of χ²₁ (0.455), r = y − h − m
(0 when the median is already below 0.455 at t = 0). The median makes the
estimate blind to a disagreement confined to less than half of the channel's
bins (the bands the check is looking for), and the centring makes a whole-channel
offset (a sensor gain error) a disagreement rather than model error. On null data
the mean Z² is then ≈ 1 (measured in the tests), as the check's BH control assumes.

**Where the paired scale applies, measured** (2026-11-27, the fast path, linearised
data and model, ν = 3, noise 0.01 m/s², seeds 0–2; ``tests/discrepancy/
test_detection_scale.py``): null data mean Z² 0.87–0.93 with the paired scale against
0.016–0.027 with σ_B; a 3 dB gain error on one whole channel flagged on 3/3 seeds
(channel mean Z 36–58), where σ_B gave ``consistent`` on 2/3 (mean Z 2.5–2.7). But
it is as sensitive to the *simulator's* own error: PyBullet data (linear elements)
checked on the linearised rig differ by 0.2–1.9 dB in bands of every channel (the two
integrate the same equations differently), which the paired scale flags as 30 bands
(15 % of the bins) and the naming rule then refuses a correct effect ("comparable
disagreement remains"). ``susp-bo diagnose`` ranks on the linearised rig and checks
real data with a simulator that is never exact, so it keeps σ_B (conservative,
README "Known limitation"); the paired scale is for data a simulator reproduces up to
sensor noise (synthetic studies of the fast path, :func:`~.scenarios.synthesize_problem`
with ``output_error="paired"``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from susp_bo.calibration.paired_error import PairedOutputError
from susp_bo.calibration.welch_noise import noise_residual_moments

FloatArray = np.ndarray

CHI2_1_MEDIAN = 0.454936423119572
"""Median of χ²₁ (scipy.stats.chi2(1).median())."""

_BISECTION_STEPS = 80


@dataclass(frozen=True)
class DetectionScale:
    """Expected residual and its variance under B, per run, channel and band.

    Attributes:
        model: ``paired`` or ``unpaired``.
        offset: (ν x C x F) expected y − h (the Welch noise bias; 0 unpaired).
        variance: (ν x C x F) variance of y − h under B (log-amplitude²).
        model_error_sd: (C,) τ_c (paired: fixed or robustly estimated) or σ_B (unpaired).
    """

    model: str
    offset: FloatArray
    variance: FloatArray
    model_error_sd: FloatArray


def unpaired_scale(sigma: FloatArray, shape: tuple[int, int, int]) -> DetectionScale:
    """σ_c² in every run and band of a (ν x C x F) array."""
    sd = np.asarray(sigma, dtype=np.float64)
    if sd.shape != (shape[1],):
        raise ValueError(f"sigma: shape {sd.shape}; expected ({shape[1]},) one per channel")
    return DetectionScale(
        model="unpaired",
        offset=np.zeros(shape),
        variance=np.broadcast_to(sd[None, :, None] ** 2, shape).copy(),
        model_error_sd=sd,
    )


def robust_model_error_variance(residual: FloatArray, noise_variance: FloatArray) -> float:
    """The τ² of the module docstring for one channel.

    Args:
        residual: (n,) residuals y − h − m of one channel (all runs and bands).
        noise_variance: (n,) their sensor-noise variances λ (>= 0).

    Returns:
        τ² >= 0 (log-amplitude²).
    """
    r = np.asarray(residual, dtype=np.float64).ravel()
    lam = np.clip(np.asarray(noise_variance, dtype=np.float64).ravel(), 0.0, None)
    d2 = (r - np.median(r)) ** 2
    if not np.any(d2 > 0):
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        at_zero = np.median(np.where(lam > 0, d2 / lam, np.where(d2 > 0, np.inf, 0.0)))
    if at_zero <= CHI2_1_MEDIAN:
        return 0.0
    lo, hi = 0.0, float(np.max(d2)) / CHI2_1_MEDIAN + 1e-300  # median at hi is <= target
    for _ in range(_BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        if np.median(d2 / (lam + mid)) > CHI2_1_MEDIAN:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def paired_scale(
    measured: FloatArray, predicted: FloatArray, error: PairedOutputError
) -> DetectionScale:
    """The paired scale of the module docstring.

    Args:
        measured: (ν x C x F) measured log-amplitude spectra.
        predicted: (ν x C x F) the model's spectra on each run's track (noise floor
            included), e.g. the mean over posterior draws.
        error: the study's paired error model (noise level, record lengths, spectrum).
    """
    y = np.asarray(measured, dtype=np.float64)
    h = np.asarray(predicted, dtype=np.float64)
    if y.ndim != 3 or h.shape != y.shape:
        raise ValueError(f"measured/predicted: shapes {y.shape}, {h.shape}; expected (ν x C x F)")
    if y.shape[0] != len(error.n_samples):
        raise ValueError(f"measured: {y.shape[0]} runs, the error model has {len(error.n_samples)}")
    offset = np.empty_like(y)
    noise = np.empty_like(y)
    for i in range(y.shape[0]):
        relative, _ = error.projection(i)
        mean, cov = noise_residual_moments(h[i], error.noise_psd, relative)
        offset[i] = mean
        noise[i] = np.diagonal(cov, axis1=-2, axis2=-1)
    if error.model_error_sigma is not None:
        tau2 = np.asarray(error.model_error_sigma, dtype=np.float64) ** 2
        if tau2.shape != (y.shape[1],):
            raise ValueError(f"model_error_sigma: {tau2.size} values for {y.shape[1]} channels")
    else:
        residual = y - h - offset
        tau2 = np.array(
            [robust_model_error_variance(residual[:, c], noise[:, c]) for c in range(y.shape[1])]
        )
    variance = noise + tau2[None, :, None]
    if not np.all(variance > 0):  # no noise and a model that matches to the last bit
        floor = max(float(np.max(variance)), 1.0) * 1e-24
        variance = np.maximum(variance, floor)
    return DetectionScale(
        model="paired",
        offset=offset,
        variance=variance,
        model_error_sd=np.sqrt(tau2),
    )


__all__ = [
    "CHI2_1_MEDIAN",
    "DetectionScale",
    "paired_scale",
    "robust_model_error_variance",
    "unpaired_scale",
]
