"""Where do model and data disagree beyond the output error B? A posterior predictive check.

For K posterior draws ``w_k`` re-simulated on every measured track ``x_i``,
the standardised residual of run i, channel c, frequency f is

    z_icf = (y_icf − mean_k h_kicf − m_icf) / sqrt(var_k h_kicf + v_icf)

(posterior predictive spread: parameter uncertainty plus the output error B, whose
expected residual m and variance v come from :mod:`.detection_scale`: σ_c² and 0 for
an unpaired B; the Welch sensor-noise moments plus a robust model-error τ_c² for
paired runs, each with its own measured track).
The runs are combined as ``Z_cf = Σ_i z_icf / √ν`` (N(0, 1) under the model when
the runs are independent), two-sided p-values ``2 Φ(−|Z|)`` are tested over all
C × F bins with the Benjamini–Hochberg procedure at false-discovery rate q
(the multiple-testing control), and flagged bins adjacent in frequency on one
channel with one sign merge into bands. A band's sign is ``model_too_little``
when the data hold more energy than the model (Z > 0), else ``model_too_much``;
its strength is the mean |Z| and the mean residual in dB (20 log10 e × Δ ln).

**Whole-channel level.** A sensor gain error (or a mounting that shifts one channel's
level) moves every bin of a channel a little: on σ_B no single bin may pass BH (a
3 dB gain gave mean Z ≈ +2.3 per bin and came back ``consistent``). So each channel is
also tested as a whole: ``Z̄_c = √F · mean_f Z_cf`` (N(0, 1) for independent unit z's;
conservative on σ_B, whose z's are far narrower; not on the paired scale, where
neighbouring bands correlate positively and its variance exceeds 1), BH over the C
channels at q (a test of its own beside the bins' BH: the two together can reach a
false-discovery rate of about 2q — the 1 dB floor is what keeps false alarms rare), and a
channel is reported as a :class:`ChannelOffset` when it passes *and* the median over
its bands of the run-mean residual is at least :data:`MIN_CHANNEL_OFFSET_DB` — the
median, so that a strong band is not mistaken for a level shift, and a floor, because
a simulator's own level error on a channel (measured: ≤ 0.3 dB between PyBullet data
and the linearised rig) is no finding.

False alarms: under the paired scale the z's are ≈ N(0, 1) on null data (mean Z²
≈ 1, measured in the tests); under an unpaired σ_B (the scatter between runs on
*different* tracks) they are far narrower, the check is conservative and
under-powered on paired data. Neighbouring low bands share Welch bins and their z's
correlate positively; BH at q keeps its false-discovery control under such
dependence (measured on null data in the tests and the benchmark).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from scipy.stats import norm

from susp_bo.discrepancy.detection_scale import DetectionScale, unpaired_scale

FloatArray = np.ndarray
DB_PER_NEPER = 20.0 / math.log(10.0)


@dataclass(frozen=True)
class FlaggedBand:
    """A contiguous band of one channel where the model misses energy (or has too much).

    Attributes:
        channel: channel name.
        f_low_hz, f_high_hz: band edges (Hz).
        peak_hz: centre frequency of the bin with the largest |Z| (Hz).
        sign: ``model_too_little`` (data have more energy) or ``model_too_much``.
        strength_z: mean |Z| over the band's bins.
        residual_db: mean data − model log amplitude over the band, dB.
        n_bins: number of grid bins.
    """

    channel: str
    f_low_hz: float
    f_high_hz: float
    peak_hz: float
    sign: str
    strength_z: float
    residual_db: float
    n_bins: int

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (band as ``[f_low_hz, f_high_hz]``)."""
        return {
            "channel": self.channel,
            "band_hz": [self.f_low_hz, self.f_high_hz],
            "peak_hz": self.peak_hz,
            "sign": self.sign,
            "strength_z": self.strength_z,
            "residual_db": self.residual_db,
            "n_bins": self.n_bins,
        }


MIN_CHANNEL_OFFSET_DB = 1.0
"""Smallest whole-channel level difference (median over the channel's bands, dB) reported."""


@dataclass(frozen=True)
class ChannelOffset:
    """A channel whose whole spectrum sits above or below the model (a level error).

    Attributes:
        channel: channel name.
        offset_db: median over the channel's bands of the mean data − model residual, dB
            (> 0: the data hold more energy).
        z: the channel's combined statistic √F · mean_f Z.
        p_value: its two-sided p-value (BH over the channels at the check's q).
    """

    channel: str
    offset_db: float
    z: float
    p_value: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return asdict(self)

    def label(self) -> str:
        """``"<channel> +2.8 dB"``: how sentences, reasons and figures name it."""
        return f"{self.channel} {self.offset_db:+.1f} dB"


def channel_offsets(
    z: FloatArray, residual: FloatArray, channels: tuple[str, ...], q: float
) -> tuple[ChannelOffset, ...]:
    """The whole-channel level test of the module docstring.

    Args:
        z: (C x F) combined standardised residuals Z.
        residual: (C x F) mean over runs of the residual (natural-log units).
        channels: (C,) names.
        q: BH false-discovery rate.
    """
    n_f = z.shape[1]
    z_channel = np.sqrt(n_f) * np.mean(z, axis=1)
    p = 2.0 * norm.sf(np.abs(z_channel))
    level_db = DB_PER_NEPER * np.median(residual, axis=1)
    passes = benjamini_hochberg(p, q)
    return tuple(
        ChannelOffset(channels[c], float(level_db[c]), float(z_channel[c]), float(p[c]))
        for c in range(len(channels))
        if passes[c]
        and abs(level_db[c]) >= MIN_CHANNEL_OFFSET_DB
        and np.sign(level_db[c]) == np.sign(z_channel[c])
    )


@dataclass(frozen=True)
class Detection:
    """Outcome of the predictive check.

    Attributes:
        channels: (C,) names.
        frequencies_hz: (F,) grid.
        z: (C x F) combined standardised residuals Z.
        residual: (C x F) mean over runs of y − E[h] − m (natural-log units).
        p_values: (C x F) two-sided p-values.
        flagged: (C x F) bins rejected by BH.
        bands: the merged flagged bands.
        q: false-discovery rate of the test.
        log_predictive_density: Σ over runs and bins of log N(y; E[h] + m, var h + v).
        scale: the output error's scale the check used.
        offsets: channels whose whole level disagrees (:func:`channel_offsets`).
    """

    channels: tuple[str, ...]
    frequencies_hz: FloatArray
    z: FloatArray
    residual: FloatArray
    p_values: FloatArray
    flagged: FloatArray
    bands: tuple[FlaggedBand, ...]
    q: float
    log_predictive_density: float
    scale: DetectionScale | None = None
    offsets: tuple[ChannelOffset, ...] = ()

    @property
    def flagged_fraction(self) -> float:
        """Share of the C × F bins flagged."""
        return float(np.mean(self.flagged))


def benjamini_hochberg(p_values: FloatArray, q: float) -> FloatArray:
    """Boolean mask (same shape) of the hypotheses BH rejects at false-discovery rate q."""
    if not 0.0 < q < 1.0:
        raise ValueError(f"q: got {q}; must be in (0, 1)")
    p = np.asarray(p_values, dtype=np.float64).ravel()
    order = np.argsort(p)
    m = p.size
    below = p[order] <= q * np.arange(1, m + 1) / m
    reject = np.zeros(m, dtype=bool)
    if below.any():
        last = int(np.max(np.nonzero(below)[0]))
        reject[order[: last + 1]] = True
    return reject.reshape(np.shape(p_values))


def predictive_check(
    measured: FloatArray,
    predicted: FloatArray,
    sigma: FloatArray | DetectionScale,
    channels: tuple[str, ...],
    edges_hz: FloatArray,
    q: float = 0.05,
) -> Detection:
    """The posterior predictive check of the module docstring.

    Args:
        measured: (ν x C x F) measured log-amplitude spectra.
        predicted: (K x ν x C x F) re-simulated spectra of K posterior draws on each run's track.
        sigma: (C,) σ_B (an unpaired B), or the :class:`~.detection_scale.DetectionScale`
            of B for these data (offset and variance (ν x C x F)).
        channels: (C,) names.
        edges_hz: (F + 1,) band edges of the grid (Hz).
        q: BH false-discovery rate.
    """
    y = np.asarray(measured, dtype=np.float64)
    h = np.asarray(predicted, dtype=np.float64)
    if h.ndim != 4 or h.shape[1:] != y.shape:
        raise ValueError(
            f"predicted: shape {h.shape}; expected (K x {' x '.join(map(str, y.shape))})"
        )
    nu = y.shape[0]
    mean = h.mean(axis=0)
    var = h.var(axis=0, ddof=1) if h.shape[0] > 1 else np.zeros_like(mean)
    scale = sigma if isinstance(sigma, DetectionScale) else unpaired_scale(sigma, y.shape)
    if scale.variance.shape != y.shape or scale.offset.shape != y.shape:
        raise ValueError(
            f"sigma: a scale of shape {scale.variance.shape}; expected {y.shape} (ν x C x F)"
        )
    total = var + scale.variance
    z_runs = (y - mean - scale.offset) / np.sqrt(total)
    z = z_runs.sum(axis=0) / math.sqrt(nu)
    residual = (y - mean - scale.offset).mean(axis=0)
    p = 2.0 * norm.sf(np.abs(z))
    flagged = benjamini_hochberg(p, q)
    lpd = float(np.sum(-0.5 * z_runs**2 - 0.5 * np.log(2 * math.pi * total)))
    centres = np.sqrt(edges_hz[:-1] * edges_hz[1:])
    bands: list[FlaggedBand] = []
    for c, channel in enumerate(channels):
        f = 0
        n_f = z.shape[1]
        while f < n_f:
            if not flagged[c, f]:
                f += 1
                continue
            sign = np.sign(z[c, f])
            end = f
            while end + 1 < n_f and flagged[c, end + 1] and np.sign(z[c, end + 1]) == sign:
                end += 1
            block = slice(f, end + 1)
            peak = f + int(np.argmax(np.abs(z[c, block])))
            bands.append(
                FlaggedBand(
                    channel=channel,
                    f_low_hz=float(edges_hz[f]),
                    f_high_hz=float(edges_hz[end + 1]),
                    peak_hz=float(centres[peak]),
                    sign="model_too_little" if sign > 0 else "model_too_much",
                    strength_z=float(np.mean(np.abs(z[c, block]))),
                    residual_db=float(DB_PER_NEPER * np.mean(residual[c, block])),
                    n_bins=end - f + 1,
                )
            )
            f = end + 1
    bands.sort(key=lambda b: -b.strength_z * b.n_bins)
    return Detection(
        channels=tuple(channels),
        frequencies_hz=centres,
        z=z,
        residual=residual,
        p_values=p,
        flagged=flagged,
        bands=tuple(bands),
        q=q,
        log_predictive_density=lpd,
        scale=scale,
        offsets=channel_offsets(z, residual, tuple(channels), q),
    )


def gap_metrics(detection: Detection, bins: FloatArray) -> dict[str, float]:
    """The discrepancy gap on a set of bins (usually those flagged before adding an effect).

    Returns:
        ``value`` = mean Z² over ``bins`` (1 ≈ consistent with B; the gap where the
        disagreement was), ``residual_energy_db`` = rms residual over ``bins`` in dB,
        ``value_all_bins`` and ``residual_energy_db_all_bins`` = the same over all
        C × F bins (an added effect must not buy the first with the second),
        ``flagged_fraction`` = share of all bins flagged, ``n_bins``, and
        ``log_predictive_density`` (all bins). Over all bins when ``bins`` is empty.
    """
    mask = np.asarray(bins, dtype=bool)
    if not mask.any():
        mask = np.ones_like(mask)
    z, residual = detection.z, detection.residual
    return {
        "value": float(np.mean(z[mask] ** 2)),
        "residual_energy_db": float(DB_PER_NEPER * np.sqrt(np.mean(residual[mask] ** 2))),
        "value_all_bins": float(np.mean(z**2)),
        "residual_energy_db_all_bins": float(DB_PER_NEPER * np.sqrt(np.mean(residual**2))),
        "flagged_fraction": detection.flagged_fraction,
        "n_bins": int(mask.sum()),
        "log_predictive_density": detection.log_predictive_density,
    }
