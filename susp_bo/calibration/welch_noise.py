"""Sampling statistics of band-averaged Welch spectra under white sensor noise.

A measured spectrum y_i (:func:`susp_bo.rig.spectra.log_amplitude_spectra`) is the
Welch estimate of the accelerations ``s + n`` on track x_i, ``n`` white sensor noise of
variance σ². The simulator on the *same* track gives the Welch estimate of ``s`` (its
own realization, not an expectation), and the known noise floor N = 2σ²/fs is added
to it (:func:`~susp_bo.rig.spectra.with_noise_floor`). Their difference in band b is
therefore only the noise's part of the estimate, in power

    e_b = 2 sᵀ Q_b n + (nᵀ Q_b n − σ² tr Q_b),

where Q_b is the quadratic form (``n_t x n_t``) that maps a record to its band value
(Hann segments, mean removed, one-sided scaling, the band weights of spectra.py).
With ``s`` locally white in each band (level σ_s,b²) and ρ_b = N / (σ_s,b² + N) the
noise share of band b's power:

    cov(e_b, e_b') / (P_b P_b') = R_bb' · [2 √(ρ_b ρ_b' (1 − ρ_b)(1 − ρ_b')) + ρ_b ρ_b'],
    R_bb' = 2 tr(Q_b Q_b') / (tr Q_b · tr Q_b'),

exactly for Gaussian ``n`` (a pure spectral line is not locally white: there the formula
overestimates the variance, by up to ≈ 2x). R (F x F) depends only on the record length
and the spectrum settings; R_bb = 1/K_b, K_b the effective number of averaged
independent estimates in the band (about 5.7 for one 8 s Hann bin of a 30 s record, many
more at high frequency). Log-amplitude is ``0.5 ln P``, so to second order the residual
r = y − h has covariance ``Σ = R ∘ [...] / 4`` and mean ``−diag(Σ)`` (E ln(1 + ε) ≈ −var
ε / 2). Bands narrower than the Welch resolution share bins: R is then close to rank-
deficient at low frequency, which is exactly why treating those bands as independent
would count the same information several times.

R is computed exactly (no Monte Carlo): the rows of A_s are the real and imaginary
parts of segment s's windowed, mean-removed DFT at every bin any band touches, so
Q_b = Σ_s A_sᵀ diag(d_b) A_s and tr(Q_b Q_b') = Σ_s,s' d_bᵀ (G_ss' ∘ G_ss') d_b' with
G_ss' = A_s A_s'ᵀ, which depends only on the lag between overlapping segments (cost
independent of the record length).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy.signal

from susp_bo.rig.spectra import SpectrumSettings


@lru_cache(maxsize=16)
def _band_relative_covariance(
    n_samples: int,
    sample_rate_hz: float,
    f_min_hz: float,
    f_max_hz: float,
    n_frequencies: int,
    segment_s: float,
    overlap: float,
) -> np.ndarray:
    settings = SpectrumSettings(f_min_hz, f_max_hz, n_frequencies, segment_s, overlap)
    rate = float(sample_rate_hz)
    nperseg = min(max(round(settings.segment_s * rate), 2), n_samples)
    noverlap = min(round(settings.overlap * nperseg), nperseg - 1)
    step = nperseg - noverlap
    n_seg = (n_samples - nperseg) // step + 1
    df = rate / nperseg
    edges = settings.band_edges_hz()
    k_max = int(np.ceil(edges[-1] / df)) + 1
    bins = np.arange(k_max + 1)
    cell_low = (bins - 0.5) * df
    overlap_hz = np.minimum(edges[1:, None], cell_low[None, :] + df) - np.maximum(
        edges[:-1, None], cell_low[None, :]
    )
    weights = np.clip(overlap_hz, 0.0, None) / np.diff(edges)[:, None]  # F x K
    used = np.flatnonzero(weights.sum(axis=0) > 0)
    window = scipy.signal.get_window("hann", nperseg)
    t = np.arange(nperseg)
    # one segment's operator: DFT of the windowed, mean-removed segment (K_used x nperseg)
    dft = np.exp(-2j * np.pi * np.outer(bins[used], t) / nperseg) * window[None, :]
    seg_op = dft - dft.sum(axis=1, keepdims=True) / nperseg
    rows = np.concatenate([seg_op.real, seg_op.imag])  # (2 K_used x nperseg)
    d = np.concatenate([weights[:, used], weights[:, used]], axis=1)  # F x 2 K_used
    trace_q = n_seg * (d @ np.sum(rows * rows, axis=1))  # (F,)
    # tr(Q_b Q_b') = sum over segment pairs; segments s, s + lag overlap for lag·step < nperseg
    trace_qq = np.zeros((d.shape[0], d.shape[0]))
    for lag in range(n_seg):
        shift = lag * step
        if shift >= nperseg:
            break
        gram = rows[:, shift:] @ rows[:, : nperseg - shift].T  # segment s rows vs s + lag rows
        block = d @ (gram * gram) @ d.T
        if lag == 0:
            trace_qq += n_seg * block
        else:
            trace_qq += (n_seg - lag) * (block + block.T)
    return 2.0 * trace_qq / np.outer(trace_q, trace_q)


def band_relative_covariance(
    settings: SpectrumSettings, n_samples: int, sample_rate_hz: float
) -> np.ndarray:
    """R (F x F): relative covariance of the band values of white noise (see module doc).

    Args:
        settings: the spectrum settings of the measured runs.
        n_samples: record length (samples) the spectra are computed from.
        sample_rate_hz: sampling rate (Hz).

    Returns:
        R with R_bb = 1/K_b (K_b: effective number of independent averages in band b).

    Raises:
        ValueError: a record shorter than one Welch segment or f_max beyond Nyquist.
    """
    settings.check_sample_rate(sample_rate_hz, int(n_samples) / float(sample_rate_hz))
    r = _band_relative_covariance(
        int(n_samples),
        float(sample_rate_hz),
        float(settings.f_min_hz),
        float(settings.f_max_hz),
        int(settings.n_frequencies),
        float(settings.segment_s),
        float(settings.overlap),
    )
    return r.copy()


def noise_residual_moments(
    simulated: np.ndarray, noise_psd: float, relative_covariance: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of y − h from sensor noise, given the floored simulation h.

    Args:
        simulated: (... x F) log-amplitude spectra h with the noise floor included.
        noise_psd: one-sided noise PSD N = 2σ²/fs ((m/s²)²/Hz), >= 0.
        relative_covariance: R (F x F) of :func:`band_relative_covariance`.

    Returns:
        ``(mean, cov)``: (... x F) and (... x F x F), natural-log amplitude units.
    """
    h = np.asarray(simulated, dtype=np.float64)
    rho = np.clip(noise_psd * np.exp(-2.0 * h), 0.0, 1.0)
    a = np.sqrt(rho * (1.0 - rho))
    bracket = 2.0 * a[..., :, None] * a[..., None, :] + rho[..., :, None] * rho[..., None, :]
    cov = 0.25 * relative_covariance * bracket
    mean = -np.diagonal(cov, axis1=-2, axis2=-1)
    return mean, cov
