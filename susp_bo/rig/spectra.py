"""Log-amplitude acceleration spectra on a shared frequency grid (the paper's ``y(ω)``).

Pipeline for each channel (signal in m/s², sampled at ``fs`` Hz):

1. Welch's method (:func:`scipy.signal.welch`): Hann segments of
   ``segment_s`` seconds, ``overlap`` fraction overlap, mean removed per
   segment, one-sided PSD in (m/s²)²/Hz on bins ``k · df`` with
   ``df = fs / nperseg``.
2. Band averaging onto the shared grid: ``n_frequencies`` log-spaced bands
   with edges ``geomspace(f_min_hz, f_max_hz, F + 1)``. Each band's value is
   the power in the band divided by its width, with the Welch PSD treated as
   piecewise constant over its bins (``[f_k - df/2, f_k + df/2]``), bins cut
   by a band edge counted by the fraction inside. Power is conserved: white
   noise of PSD ``S`` gives ``S`` in every band, a sine of amplitude ``A``
   inside one band gives ``A²/2`` divided by that band's width. Averaging many
   Welch bins per band lowers the variance of the estimate at high
   frequencies; where a band is narrower than ``df`` it inherits the variance
   of a single Welch bin (lengthen ``segment_s`` for steadier low bands).
3. ``log_amplitude = 0.5 · ln(band PSD)``: the natural log of the amplitude
   spectral density in (m/s²)/√Hz. The grid frequency reported for a band is
   the geometric mean of its edges.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.signal
from numpy.typing import ArrayLike, NDArray

from susp_bo.numerics import one_blas_thread
from susp_bo.rig._array_checks import require_positive

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SpectrumSettings:
    """How time signals become log-amplitude spectra.

    Args:
        f_min_hz: lower edge of the band (Hz); at least ``2 / segment_s`` so that
            the Hann main lobe around DC stays out of the band.
        f_max_hz: upper edge of the band (Hz), > f_min_hz; must lie below the
            Nyquist frequency of the signals (checked per record).
        n_frequencies: number F of log-spaced bands, >= 1.
        segment_s: Welch segment length (s); frequency resolution ``1/segment_s`` Hz.
        overlap: fraction of a segment shared with the next, in [0, 1).
    """

    f_min_hz: float = 0.5
    f_max_hz: float = 20.0
    n_frequencies: int = 48
    segment_s: float = 8.0
    overlap: float = 0.5

    def __post_init__(self) -> None:
        for name, unit in (("f_min_hz", "Hz"), ("f_max_hz", "Hz"), ("segment_s", "s")):
            object.__setattr__(
                self, name, require_positive(f"[spectrum] {name}", getattr(self, name), unit)
            )
        if self.f_max_hz <= self.f_min_hz:
            raise ValueError(
                f"[spectrum] f_max_hz: got {self.f_max_hz} Hz; must be > f_min_hz = "
                f"{self.f_min_hz} Hz"
            )
        if (
            isinstance(self.n_frequencies, bool)
            or not isinstance(self.n_frequencies, (int, np.integer))
            or self.n_frequencies < 1
        ):
            raise ValueError(
                f"[spectrum] n_frequencies: got {self.n_frequencies!r}; must be an int >= 1"
            )
        object.__setattr__(self, "n_frequencies", int(self.n_frequencies))
        overlap = float(self.overlap)
        if not (0.0 <= overlap < 1.0):
            raise ValueError(f"[spectrum] overlap: got {self.overlap!r}; must be in [0, 1)")
        object.__setattr__(self, "overlap", overlap)
        lowest = 2.0 / self.segment_s
        if self.f_min_hz < lowest * (1 - 1e-12):
            raise ValueError(
                f"[spectrum] f_min_hz: got {self.f_min_hz} Hz; must be >= 2 / segment_s = "
                f"{lowest:g} Hz (Welch resolution); raise f_min_hz or lengthen segment_s to >= "
                f"{2.0 / self.f_min_hz:g} s"
            )

    def band_edges_hz(self) -> FloatArray:
        """Edges of the F bands, (F + 1,) Hz, log-spaced from f_min_hz to f_max_hz."""
        return np.geomspace(self.f_min_hz, self.f_max_hz, self.n_frequencies + 1)

    def frequencies_hz(self) -> FloatArray:
        """The shared grid: geometric centres of the bands, (F,) Hz."""
        edges = self.band_edges_hz()
        return np.sqrt(edges[:-1] * edges[1:])

    def check_sample_rate(self, sample_rate_hz: float, duration_s: float) -> None:
        """Raise ValueError unless a record of this rate and length can give the band.

        Args:
            sample_rate_hz: sampling rate (Hz); Nyquist ``fs/2`` must exceed f_max_hz.
            duration_s: record length (s); must hold at least one Welch segment.
        """
        rate = require_positive("sample_rate_hz", sample_rate_hz, "Hz")
        duration = require_positive("duration_s", duration_s, "s")
        if self.f_max_hz >= 0.5 * rate:
            raise ValueError(
                f"sample_rate_hz: got {rate:g} Hz, Nyquist {0.5 * rate:g} Hz is not above "
                f"f_max_hz = {self.f_max_hz:g} Hz; need sample_rate_hz > {2 * self.f_max_hz:g} Hz"
            )
        if duration < self.segment_s * (1 - 1e-9):
            raise ValueError(
                f"duration_s: got {duration:g} s, shorter than one Welch segment (segment_s = "
                f"{self.segment_s:g} s) needed to resolve f_min_hz = {self.f_min_hz:g} Hz"
            )


@dataclass(frozen=True, eq=False)
class Spectra:
    """Log-amplitude spectra of several channels on one frequency grid.

    Args:
        frequencies_hz: the grid (F,) Hz, strictly increasing.
        channels: channel names (C,), unique.
        log_amplitude: natural log of the amplitude spectral density (C x F),
            ln((m/s²)/√Hz).
    """

    frequencies_hz: FloatArray
    channels: tuple[str, ...]
    log_amplitude: FloatArray

    def __post_init__(self) -> None:
        frequencies = np.array(self.frequencies_hz, dtype=np.float64)
        if frequencies.ndim != 1 or frequencies.size < 1 or not np.all(np.isfinite(frequencies)):
            raise ValueError(
                f"Spectra.frequencies_hz: must be finite, 1-D, non-empty; got "
                f"shape {frequencies.shape}"
            )
        if np.any(np.diff(frequencies) <= 0) or frequencies[0] <= 0:
            raise ValueError("Spectra.frequencies_hz: must be > 0 and strictly increasing")
        channels = tuple(self.channels)
        if not all(isinstance(c, str) and c for c in channels):
            raise ValueError(f"Spectra.channels: must be non-empty strings; got {channels!r}")
        if len(set(channels)) != len(channels):
            raise ValueError(f"Spectra.channels: names must be unique; got {channels!r}")
        values = np.array(self.log_amplitude, dtype=np.float64)
        if values.shape != (len(channels), frequencies.size):
            raise ValueError(
                f"Spectra.log_amplitude: shape {values.shape}; expected (C, F) = "
                f"({len(channels)}, {frequencies.size})"
            )
        if not np.all(np.isfinite(values)):
            raise ValueError("Spectra.log_amplitude: contains NaN or inf")
        for array in (frequencies, values):
            array.setflags(write=False)
        object.__setattr__(self, "frequencies_hz", frequencies)
        object.__setattr__(self, "channels", channels)
        object.__setattr__(self, "log_amplitude", values)

    def channel(self, name: str) -> FloatArray:
        """Log-amplitude spectrum of one channel, (F,)."""
        if name not in self.channels:
            raise KeyError(f"Spectra: no channel {name!r}; channels are {', '.join(self.channels)}")
        return self.log_amplitude[self.channels.index(name)]


def _band_average(psd: FloatArray, bin_width_hz: float, edges_hz: FloatArray) -> FloatArray:
    """Mean PSD over each band, PSD piecewise constant on its bins: (C x K) -> (C x F).

    Uses the overlap of each bin cell ``[f_k - df/2, f_k + df/2]`` with each band as
    weights (no cumulative sums, so no cancellation where the PSD is small).
    """
    cell_low = (np.arange(psd.shape[-1]) - 0.5) * bin_width_hz
    overlap = np.minimum(edges_hz[1:, None], cell_low[None, :] + bin_width_hz) - np.maximum(
        edges_hz[:-1, None], cell_low[None, :]
    )
    weights = np.clip(overlap, 0.0, None) / np.diff(edges_hz)[:, None]  # (F x K)
    with one_blas_thread():  # the same bits whatever the thread count
        return psd @ weights.T


def welch_psd(data: FloatArray, sample_rate_hz: float, settings: SpectrumSettings) -> FloatArray:
    """Welch PSD (C x K) (m/s²)²/Hz of signals (C x n_t) on bins ``k fs / nperseg`` (step 1).

    Hann segments of ``segment_s`` (at most the record), ``overlap``, mean removed per
    segment, one-sided density: the estimator behind every spectrum here.
    """
    nperseg = min(max(round(settings.segment_s * sample_rate_hz), 2), data.shape[-1])
    noverlap = min(round(settings.overlap * nperseg), nperseg - 1)
    _, psd = scipy.signal.welch(
        data,
        fs=sample_rate_hz,
        window="hann",
        nperseg=nperseg,
        noverlap=noverlap,
        detrend="constant",
        scaling="density",
        axis=-1,
    )
    return psd


def log_amplitude_spectra(
    signals: ArrayLike,
    sample_rate_hz: float,
    channels: Sequence[str],
    settings: SpectrumSettings | None = None,
) -> Spectra:
    """Welch log-amplitude spectra of accelerations, band-averaged onto the shared grid.

    Args:
        signals: accelerations (C x n_t) m/s² (a 1-D array is one channel).
        sample_rate_hz: sampling rate (Hz).
        channels: channel names (C,).
        settings: band, resolution and averaging; default :class:`SpectrumSettings()`.

    Returns:
        Spectra with ``log_amplitude`` (C x F) in ln((m/s²)/√Hz).

    Raises:
        ValueError: non-finite or mis-shaped signals, f_max beyond Nyquist, a
            record shorter than one segment, or a channel with no power in a band.
    """
    settings = SpectrumSettings() if settings is None else settings
    data = np.array(signals, dtype=np.float64)
    if data.ndim == 1:
        data = data[None, :]
    names = tuple(channels)
    if data.ndim != 2 or data.shape[0] != len(names):
        raise ValueError(
            f"signals: shape {np.shape(signals)}; expected (C, n_t) with C = {len(names)} channels"
        )
    if not np.all(np.isfinite(data)):
        row = int(np.argmax(~np.all(np.isfinite(data), axis=1)))
        raise ValueError(f"signals: channel {names[row]!r} contains NaN or inf")
    rate = require_positive("sample_rate_hz", sample_rate_hz, "Hz")
    settings.check_sample_rate(rate, data.shape[1] / rate)
    nperseg = min(max(round(settings.segment_s * rate), 2), data.shape[1])
    psd = welch_psd(data, rate, settings)
    band_psd = _band_average(psd, rate / nperseg, settings.band_edges_hz())
    if np.any(band_psd <= 0):
        row, column = np.argwhere(band_psd <= 0)[0]
        raise ValueError(
            f"signals: channel {names[row]!r} has no power in the band around "
            f"{settings.frequencies_hz()[column]:.3g} Hz; its log-amplitude would be -inf"
        )
    return Spectra(
        frequencies_hz=settings.frequencies_hz(),
        channels=names,
        log_amplitude=0.5 * np.log(band_psd),
    )


__all__ = ["Spectra", "SpectrumSettings", "log_amplitude_spectra"]


def with_noise_floor(
    log_amplitude: FloatArray, noise_m_s2: float, sample_rate_hz: float
) -> FloatArray:
    """Spectra as an accelerometer with white noise of ``noise_m_s2`` rms would measure them.

    The noise adds its one-sided PSD ``2 σ² / fs`` ((m/s²)²/Hz) to the signal's PSD
    in every band (signal and noise are independent), so the log-amplitude becomes
    ``0.5 ln(exp(2 y) + 2 σ² / fs)``. This is the measurement model applied to
    simulated spectra before they are compared with measured ones.

    Args:
        log_amplitude: (... x F) log-amplitude spectra, ln((m/s²)/√Hz).
        noise_m_s2: sensor noise standard deviation (m/s² rms), >= 0.
        sample_rate_hz: sampling rate of the measured signals (Hz), > 0.

    Returns:
        Array of the same shape (the input itself when ``noise_m_s2`` is 0).
    """
    if not noise_m_s2 >= 0.0:
        raise ValueError(f"noise_m_s2: got {noise_m_s2}; expected >= 0 m/s^2")
    require_positive("sample_rate_hz", sample_rate_hz)
    if noise_m_s2 == 0.0:
        return log_amplitude
    floor = 2.0 * noise_m_s2**2 / sample_rate_hz
    return 0.5 * np.log(np.exp(2.0 * np.asarray(log_amplitude, dtype=np.float64)) + floor)
