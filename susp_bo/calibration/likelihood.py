"""Likelihood of measured spectra given simulated ones (eq. 4 of the paper): the unpaired model.

This is the model for runs whose track is known only by its statistics (the
simulated tracks x_j are other realizations than the measured ones). When every
run comes with its own measured track (the default of a study), the paired model
of :mod:`susp_bo.calibration.paired_error` applies instead; the README section
"Which output-error model applies" says when to use which.

    log L(w) = Σ_i log( (1/μ) Σ_j p_B(y_exp,i − h(x_j, w)) )

with ν measured log-amplitude spectra ``y_exp,i`` (each C channels x F frequencies)
and μ simulated spectra ``h(x_j, w)`` on μ track realizations. The inner mean is
taken with log-sum-exp, so the result stays finite when every p_B underflows
(log p_B is routinely −10⁴ far from the maximum).

The output error B (model + measurement error, eq. 2) is Gaussian with zero mean:

- default: independent over channels and frequencies, per-channel standard
  deviation σ_c (in natural-log units of the amplitude spectral density, so 0.1 ≈ 10 %);
- option: a Gaussian process over the frequency band Ω (the paper's wording),
  per channel: Cov(B_c(f), B_c(f')) = σ_c² exp(−|f − f'| / ℓ), ℓ the correlation
  length in Hz (exponential / Matérn-1/2 kernel: well conditioned on any grid).
  Channels stay independent.

How σ_B is set (:func:`estimate_output_error`): σ_B is a plug-in (empirical Bayes)
value fixed before the calibration, because it sets the sharpness of L and a
joint estimate would make every surrogate point depend on it. With simulated
spectra at a pilot parameter (nominal values, or a first joint MAP for a
second pass) σ_c is the maximum-likelihood value of the eq. 4 mixture at that
pilot (EM over the ν x μ responsibilities); with measured spectra only (ν ≥ 2)
σ_c² = 2 x the replicate variance of the measured spectra about their mean (the
difference of two independent realizations). A floor keeps σ_c away from 0.
With ``correlated=True`` the correlation length is set from the lag-1
autocorrelation ρ of the residuals along frequency: ℓ = −Δf / ln ρ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.special import logsumexp

from susp_bo.calibration.paired_error import PairedOutputError, paired_expected_log_likelihood
from susp_bo.calibration.track_statistics import (
    TrackStatisticsError,
    track_statistics_expected_log_likelihood,
)


@dataclass(frozen=True)
class OutputError:
    """Gaussian output error B of eq. 2.

    Args:
        sigma: (C,) per-channel standard deviation of B, natural-log units (> 0).
        correlation_length_hz: None for independent frequencies, else the length ℓ (Hz, > 0)
            of the exponential correlation exp(−|f − f'| / ℓ) along frequency.
    """

    sigma: tuple[float, ...]
    correlation_length_hz: float | None = None

    expectation_bounds_maximum: ClassVar[bool] = False
    """σ_B is the scatter between runs on different tracks, not the residual's scale of
    runs on their own tracks: log L at the truth sits far above the expectation, which
    therefore says nothing of the maximum (second review, session 27)."""

    def __post_init__(self) -> None:
        sigma = tuple(float(s) for s in np.atleast_1d(np.asarray(self.sigma, dtype=np.float64)))
        if not sigma or not all(math.isfinite(s) and s > 0.0 for s in sigma):
            raise ValueError(f"sigma: {sigma} must be non-empty, finite and > 0 per channel")
        object.__setattr__(self, "sigma", sigma)
        ell = self.correlation_length_hz
        if ell is not None and not (math.isfinite(ell) and ell > 0.0):
            raise ValueError(f"correlation_length_hz: {ell} must be None or a finite value > 0 Hz")

    @property
    def n_channels(self) -> int:
        """Number of channels C."""
        return len(self.sigma)

    def whitening(self, frequencies_hz: np.ndarray | None, n_frequencies: int) -> np.ndarray:
        """Lower Cholesky factor L (F x F) of the unit-variance frequency correlation R.

        Returns the identity when frequencies are independent.
        """
        if self.correlation_length_hz is None:
            return np.eye(n_frequencies)
        if frequencies_hz is None:
            raise ValueError("frequencies_hz: required when correlation_length_hz is set")
        f = _check_frequencies(frequencies_hz, n_frequencies)
        corr = np.exp(-np.abs(f[:, None] - f[None, :]) / self.correlation_length_hz)
        return np.linalg.cholesky(corr + 1e-10 * np.eye(n_frequencies))


def _check_frequencies(frequencies_hz: np.ndarray, n_frequencies: int) -> np.ndarray:
    """The (F,) grid as float64, refused unless finite and strictly increasing."""
    f = np.asarray(frequencies_hz, dtype=np.float64)
    if f.shape != (n_frequencies,):
        raise ValueError(f"frequencies_hz: shape {f.shape}, expected ({n_frequencies},)")
    bad = np.flatnonzero(~np.isfinite(f))
    if bad.size:
        raise ValueError(
            f"frequencies_hz: value {f[bad[0]]} at index {bad[0]}; expected finite values in Hz"
        )
    bad = np.flatnonzero(np.diff(f) <= 0.0)
    if bad.size:
        i = bad[0]
        raise ValueError(
            f"frequencies_hz: {f[i]} at index {i} then {f[i + 1]}; the grid must be strictly "
            "increasing"
        )
    return f


def _check_spectra(name: str, a: np.ndarray, n_channels: int) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim < 3 or a.shape[-2] != n_channels:
        raise ValueError(f"{name}: shape {a.shape}, expected (... x {n_channels} x F)")
    if a.size == 0:
        raise ValueError(
            f"{name}: shape {a.shape} is empty; expected at least one spectrum and one frequency"
        )
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: contains NaN or inf")
    return a


def _whiten(a: np.ndarray, error: OutputError, chol: np.ndarray) -> np.ndarray:
    """Maps (... x C x F) spectra to independent standard-normal coordinates."""
    sigma = np.asarray(error.sigma)[:, None]
    if error.correlation_length_hz is None:
        return a / sigma
    solved = np.linalg.solve(chol, np.moveaxis(a, -1, 0).reshape(a.shape[-1], -1))
    return np.moveaxis(solved.reshape((a.shape[-1], *a.shape[:-1])), 0, -1) / sigma


def pair_log_densities(
    measured: np.ndarray,
    simulated: np.ndarray,
    error: OutputError,
    frequencies_hz: np.ndarray | None = None,
) -> np.ndarray:
    """log p_B(y_exp,i − h_j) for every pair, batched over parameter vectors.

    Args:
        measured: (ν x C x F) measured log-amplitude spectra.
        simulated: (μ x C x F) or (b x μ x C x F) simulated spectra (b parameter vectors).
        error: output error model.
        frequencies_hz: (F,) grid, needed for the correlated option.

    Returns:
        (ν x μ) or (b x ν x μ) log densities.
    """
    c = error.n_channels
    measured = _check_spectra("measured", measured, c)
    simulated = _check_spectra("simulated", simulated, c)
    if measured.ndim != 3 or simulated.ndim not in (3, 4):
        raise ValueError("measured: (ν x C x F); simulated: (μ x C x F) or (b x μ x C x F)")
    n_freq = measured.shape[-1]
    if simulated.shape[-1] != n_freq:
        raise ValueError(f"simulated: {simulated.shape[-1]} frequencies, measured has {n_freq}")
    chol = error.whitening(frequencies_hz, n_freq)
    zm = _whiten(measured, error, chol).reshape(measured.shape[0], -1)  # ν x CF
    zs = _whiten(simulated, error, chol)
    zs = zs.reshape(*zs.shape[:-2], -1)  # (b x) μ x CF
    sq = np.sum((zm[:, None, :] - zs[..., None, :, :]) ** 2, axis=-1)  # (b x) ν x μ
    log_det = 2.0 * n_freq * np.sum(np.log(error.sigma)) + c * 2.0 * np.sum(np.log(np.diag(chol)))
    return -0.5 * sq - 0.5 * log_det - 0.5 * c * n_freq * math.log(2.0 * math.pi)


def log_likelihood(
    measured: np.ndarray,
    simulated: np.ndarray,
    error: OutputError,
    frequencies_hz: np.ndarray | None = None,
) -> float | np.ndarray:
    """Eq. 4 of the paper, in logs: Σ_i log((1/μ) Σ_j p_B(y_exp,i − h(x_j, w))).

    Args:
        measured: (ν x C x F) measured log-amplitude spectra y_exp,i.
        simulated: (μ x C x F) simulated spectra h(x_j, w) for one w, or (b x μ x C x F)
            for b parameter vectors at once.
        error: output error model B.
        frequencies_hz: (F,) finite, strictly increasing frequency grid in Hz; required with
            a frequency correlation (ignored without one).

    Returns:
        log L as a float, or (b,) array for batched ``simulated``.
    """
    logp = pair_log_densities(measured, simulated, error, frequencies_hz)
    mu = logp.shape[-1]
    value = np.sum(logsumexp(logp, axis=-1) - math.log(mu), axis=-1)
    return float(value) if np.ndim(value) == 0 else value


def estimate_output_error(
    measured: np.ndarray,
    simulated: np.ndarray | None = None,
    *,
    frequencies_hz: np.ndarray | None = None,
    correlated: bool = False,
    floor: float = 0.01,
    em_iterations: int = 50,
) -> OutputError:
    """Plug-in estimate of the output error B (see the module docstring).

    Args:
        measured: (ν x C x F) measured log-amplitude spectra.
        simulated: (μ x C x F) simulated spectra at a pilot parameter, or None to use the
            replicate scatter of the measured spectra (then ν ≥ 2).
        frequencies_hz: (F,) finite, strictly increasing grid in Hz, required when
            ``correlated`` (then F ≥ 2).
        correlated: also estimate the frequency correlation length.
        floor: smallest σ_c returned (natural-log units, finite, > 0).
        em_iterations: EM iterations (≥ 1) for the mixture maximum likelihood.

    Returns:
        The estimated :class:`OutputError`.
    """
    if isinstance(floor, bool) or not isinstance(floor, (int, float, np.integer, np.floating)):
        raise TypeError(f"floor: {floor!r} must be a real number > 0")
    if not (math.isfinite(floor) and floor > 0.0):
        raise ValueError(f"floor: {floor} must be finite and > 0")
    if isinstance(em_iterations, bool) or not isinstance(em_iterations, (int, np.integer)):
        raise TypeError(f"em_iterations: {em_iterations!r} must be an integer ≥ 1")
    if em_iterations < 1:
        raise ValueError(f"em_iterations: {em_iterations} must be ≥ 1")
    measured = np.asarray(measured, dtype=np.float64)
    if measured.ndim != 3:
        raise ValueError(f"measured: shape {measured.shape}, expected (ν x C x F)")
    if measured.size == 0:
        raise ValueError(
            f"measured: shape {measured.shape} is empty; expected ν ≥ 1 runs, C ≥ 1 channels "
            "and F ≥ 1 frequencies"
        )
    if not np.all(np.isfinite(measured)):
        raise ValueError("measured: contains NaN or inf")
    nu, n_ch, n_freq = measured.shape
    f = None
    if correlated:
        if frequencies_hz is None:
            raise ValueError("frequencies_hz: required when correlated=True")
        if n_freq < 2:
            raise ValueError(f"measured: F = {n_freq}; correlated=True needs F ≥ 2 frequencies")
        f = _check_frequencies(frequencies_hz, n_freq)
    if simulated is None:
        if nu < 2:
            raise ValueError(f"measured: ν = {nu}; need ν ≥ 2 without simulated spectra")
        resid = (measured - measured.mean(axis=0))[:, None]  # ν x 1 x C x F
        var = 2.0 * np.sum(resid**2, axis=(0, 1, 3)) / ((nu - 1) * n_freq)
        weights = np.ones((nu, 1)) * nu / (nu - 1)
    else:
        simulated = _check_spectra("simulated", simulated, n_ch)
        if simulated.ndim != 3 or simulated.shape[-1] != n_freq:
            raise ValueError(
                f"simulated: shape {simulated.shape}, expected (μ x {n_ch} x {n_freq}) "
                "like measured"
            )
        resid = measured[:, None] - simulated[None]  # ν x μ x C x F
        ss = np.sum(resid**2, axis=-1)  # ν x μ x C
        var = ss.mean(axis=(0, 1)) / n_freq
        for _ in range(em_iterations):
            logp = -0.5 * np.sum(ss / var, axis=-1)  # ν x μ (common terms cancel)
            resp = np.exp(logp - logsumexp(logp, axis=1, keepdims=True))
            var = np.maximum(np.einsum("ij,ijc->c", resp, ss) / (nu * n_freq), floor**2)
        weights = np.exp(logp - logsumexp(logp, axis=1, keepdims=True))
    sigma = np.maximum(np.sqrt(var), floor)
    ell = None
    if f is not None:
        z = resid / sigma[:, None]
        lag0 = np.einsum("ij,ijcf->", weights, z**2)
        lag1 = np.einsum("ij,ijcf->", weights, z[..., 1:] * z[..., :-1])
        rho = float(np.clip(lag1 / lag0 * n_freq / (n_freq - 1), 1e-3, 0.999))
        ell = float(np.mean(np.diff(f))) / -math.log(rho)
    return OutputError(tuple(float(s) for s in sigma), ell)


def expected_log_likelihood_at_truth(
    error: OutputError | PairedOutputError | TrackStatisticsError,
    measured: np.ndarray,
    frequencies_hz: np.ndarray | None = None,
) -> tuple[float, float]:
    """Mean and sd (nats) of log L at the true parameters, as the error model B predicts.

    For the rule "the optimum was not reached": a best evaluated log L far below
    ``mean − 3 sd`` means the search missed the region of the truth.

    Args:
        error: the study's output error model.
        measured: (ν x C x F) measured log-amplitude spectra.
        frequencies_hz: (F,) grid, needed for an unpaired model with a correlation length.

    Returns:
        ``(mean, sd)``. Paired: :func:`~.paired_error.paired_expected_log_likelihood`
        (exact to second order when the simulator is exact; nan when there is no sensor
        noise, since then only the profiled model error is left). Summary model of
        tracks known only by their statistics:
        :func:`~.track_statistics.track_statistics_expected_log_likelihood`. Unpaired: every pair
        residual y_i − h_j ~ N(0, Σ_B) gives log p_B = −½ (ln |2π Σ_B| + χ²_{CF}), so
        mean −½ ν (ln |2π Σ_B| + C F) and sd √(ν C F / 2); the mixture over the μ tracks
        adds at most ln μ per run (Jensen), so this mean is a lower bound to within that.
    """
    if isinstance(error, PairedOutputError):
        return paired_expected_log_likelihood(error, measured)
    if isinstance(error, TrackStatisticsError):
        return track_statistics_expected_log_likelihood(error)
    y = _check_spectra("measured", measured, error.n_channels)
    if y.ndim != 3:
        raise ValueError(f"measured: shape {y.shape}, expected (ν x C x F)")
    nu, c, f = y.shape
    chol = error.whitening(frequencies_hz, f)
    log_det = 2.0 * f * np.sum(np.log(error.sigma)) + c * 2.0 * np.sum(np.log(np.diag(chol)))
    n = c * f
    mean = -0.5 * nu * (log_det + n * math.log(2.0 * math.pi) + n)
    return float(mean), math.sqrt(nu * n / 2.0)
