"""Goodness of fit of the summary likelihood: the summaries its fit does not use.

:mod:`.track_statistics` calibrates on q summaries s = Aᵀ y for q parameters, so the fit
zeroes them whatever the data: its log L has no goodness-of-fit power of its own, and a
model error the parameters can partly absorb goes unseen (session 34, exact summary fits
on the linearised rig: a conicity of 0.15 in the data against 0.10 in the model put a
parameter 3.5 sd off with the lack of fit between runs at F 1.1–1.7, under its limit).

This test looks where the fit cannot reach. Per channel, the mean log amplitude over each
of :data:`BAND_GROUPS` contiguous groups of bands (k = C x groups summaries), made
orthogonal to the Jacobian's q columns at the pilot point (B = (I − Q Qᵀ) G, Q an
orthonormal basis of the Jacobian's columns): to first order no change of the parameters
moves Bᵀ h̄(w), so at the fitted point, as at the truth,

    r = Bᵀ (ȳ − h̄(ŵ)) ~ N(0, κ C_B),  κ = 1/ν + 1/μ,  C_B = Bᵀ Σ B,

for an exact model (Σ the covariance of one run's spectrum over track realizations and
sensor noise, :mod:`.track_statistics`). C_B is the sample covariance of the M pilot runs'
B-summaries (B does not depend on them), so with x = r / √κ,

    T² = xᵀ Ĉ_B⁻¹ x ~ Hotelling T²(k, M − 1),  (M − k) / (k (M − 1)) T² ~ F(k, M − k),

for Gaussian spectra when both sides scatter alike. They do not quite: the model tracks'
spectra h̄ carry the sensor noise as a deterministic floor
(:func:`~susp_bo.rig.spectra.with_noise_floor`), so their share of the variance is below
C_B / μ and the test is conservative — it loses power, not false alarms (second review,
session 36, linearised demo rig, k = 30: the simulated side's variance a median 0.99 /
0.85 / 0.34 of the measured side's at 0.01 / 0.05 / 0.2 m/s²; the floor's shift of the
mean a non-centrality of 0.06 / 0.52 / 1.65, at most 0.0018 rejections at 10⁻³), as the
summary likelihood's κ C is (:mod:`.track_statistics`). A model error that shows in some
channel's level or shape (a missing mode, another conicity, a stiffer spring) and that
the q parameters cannot reproduce leaves r away from 0, and p = P(F ≥ observed) falls.
The verdict refuses a result whose p is below :data:`P_LIMIT` (``below_expected_fit``:
the model misses something in the data; :func:`.fit_rules.with_summary_misfit`), a rule
applied after the others like the lack of fit between runs (:mod:`.lack_of_fit`); unlike
that one it works with a single measured run. This module is NumPy and SciPy only: the
error carries its test into every simulator worker.

Measured (session 36; exact summary fits on the linearised rig, the demo's q = 7, ν = μ = 3,
noise 0.01 m/s², M = 100, k = 30; ``python benchmarks/track_statistics_misfit.py
--experiments 6 --seed 34``): data from the model p 0.044–0.82 (0 of 6 below the limit);
data from a vehicle with a conicity of 0.15 against the model's 0.10, p ≤ 4·10⁻¹⁶ (6 of
6; the lack of fit 0 of 6, one fit 3.5 sd off inside C_w), a 9 Hz carbody bending mode
p ≤ 6·10⁻²⁴ (6 of 6), an air-spring reservoir p ≤ 2·10⁻⁵ (6 of 6; the lack of fit 1 of 6). Data
from the model on more data sets (exact fits): 0 of 30 below the limit at 0.01 m/s²
(``--experiments 30 --seed 35 --changes none``), 1 of 30 at 0.05 (p 9·10⁻⁴), 1 of 16 on
the test suite's 8 s fast rig at 0.005 (p 9·10⁻⁴; ``--fast-rig DIR``): 2 of 82 where 10⁻³
would give 0.08 — the tail is heavier than Hotelling's (short records' log spectra are
not Gaussian), so a refusal by this rule alone is wrong about 1 time in 50 on an exact
model. On PyBullet data (``benchmarks/track_statistics_pybullet.py --fast-rig``): a
carbody mode 4 of 4, a conicity 1 of 4 (the one fit far off, p 8·10⁻⁴), the model's own
converged fits p 0.11–0.93.

What it cannot see: an error the q parameters reproduce in every channel-band group (the
fit absorbs it), or one confined to a band too narrow to move its group's mean beyond the
track scatter. The test is first order in the parameters: a best point far from the pilot
point leaves a residual of the parameters' own (second review, from the pilot point along
draws of the summary posterior: a non-centrality of median 0.06 at 1 sd, 0.33 at 2 sd,
4.3 at 3 sd, and one draw 888 at 3 sd, likely at a bound of C_w). The pilot's second
stage sits at the summaries' fit, which a converged loop's best point is near; a best
point 3 or more sd away can be refused by this test although the model is right (a
refusal, never a confident answer).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from susp_bo.numerics import one_blas_thread

BAND_GROUPS = 3
"""Contiguous groups of bands per channel (low, middle, high frequencies)."""
P_LIMIT = 1e-3
"""p-value below which the verdict refuses the result (one false refusal in 1 000 exact
models)."""


@dataclass(frozen=True)
class SummaryMisfitTest:
    """The summaries the fit does not use, and their covariance (module docstring).

    Args:
        directions: (C x F x k) B, orthogonal to the Jacobian's columns.
        covariance: (k x k) sample covariance of one run's B-summaries over the pilot runs.
        runs: M, the pilot runs the covariance came from (M > k + 1).
        n_measured: ν.
        n_simulated: μ.
        labels: (k,) what each summary is, channel by channel and band group by band group
            (:func:`group_labels`); () = "channel c, bands a–b" by index.

    Raises:
        ValueError: shapes that disagree, non-finite values, a covariance not positive
            definite, M ≤ k + 1, or labels that are not k, naming the field.
    """

    directions: np.ndarray
    covariance: np.ndarray
    runs: int
    n_measured: int
    n_simulated: int
    labels: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        b = np.array(self.directions, dtype=np.float64)
        c = np.array(self.covariance, dtype=np.float64)
        if b.ndim != 3 or not np.all(np.isfinite(b)):
            raise ValueError(f"directions: shape {b.shape}, expected finite (C x F x k)")
        k = b.shape[-1]
        if c.shape != (k, k) or not np.all(np.isfinite(c)):
            raise ValueError(f"covariance: shape {c.shape}, expected finite ({k} x {k})")
        try:
            np.linalg.cholesky(c)
        except np.linalg.LinAlgError as error:
            raise ValueError("covariance: not positive definite") from error
        if self.runs <= k + 1:
            raise ValueError(f"runs: {self.runs}; expected more than k + 1 = {k + 1}")
        for name in ("n_measured", "n_simulated"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}: {getattr(self, name)!r} must be >= 1")
        if self.labels and len(self.labels) != k:
            raise ValueError(f"labels: {len(self.labels)} labels for k = {k} summaries")
        if k % b.shape[0]:
            raise ValueError(
                f"directions: k = {k} is not a whole number of band groups of {b.shape[0]} channels"
            )
        b.setflags(write=False)
        c.setflags(write=False)
        object.__setattr__(self, "directions", b)
        object.__setattr__(self, "covariance", c)

    @property
    def dof(self) -> int:
        """k, the number of summaries tested."""
        return int(self.directions.shape[-1])

    @property
    def scale(self) -> float:
        """κ = 1/ν + 1/μ."""
        return 1.0 / self.n_measured + 1.0 / self.n_simulated

    def label(self, j: int) -> str:
        """What summary j is (its label, or channel and band indices)."""
        if self.labels:
            return self.labels[j]
        c, f, k = self.directions.shape
        groups = k // c
        edges = group_edges(f, groups)
        channel, group = divmod(j, groups)
        return f"channel {channel}, bands {edges[group]}–{edges[group + 1] - 1}"


def group_edges(bands: int, groups: int) -> np.ndarray:
    """(groups + 1,) the first band of each group and one past the last (contiguous groups
    whose sizes differ by at most one)."""
    return np.linspace(0, bands, groups + 1).round().astype(int)


def group_labels(
    test: SummaryMisfitTest, channels: Sequence[str], frequencies_hz: np.ndarray
) -> tuple[str, ...]:
    """(k,) "CHANNEL LO–HI Hz" for each summary of ``test``, in its order (channel by
    channel, low band group first), from the rig's channel names and band centres (Hz)."""
    c, f, k = test.directions.shape
    if len(channels) != c or len(frequencies_hz) != f:
        raise ValueError(
            f"channels: {len(channels)}, frequencies_hz: {len(frequencies_hz)}; expected "
            f"{c} and {f}"
        )
    edges = group_edges(f, k // c)
    return tuple(
        f"{name} {frequencies_hz[lo]:.3g}–{frequencies_hz[hi - 1]:.3g} Hz"
        for name in channels
        for lo, hi in itertools.pairwise(edges)
    )


def band_group_directions(channels: int, bands: int, groups: int) -> np.ndarray:
    """(C·F x C·groups) G: per channel, the indicator of each of ``groups`` contiguous
    groups of bands (their sizes differ by at most one)."""
    edges = group_edges(bands, groups)
    g = np.zeros((channels, bands, channels, groups))
    for c in range(channels):
        for k in range(groups):
            g[c, edges[k] : edges[k + 1], c, k] = 1.0
    return g.reshape(channels * bands, channels * groups)


def summary_misfit_test(
    pilot: np.ndarray,
    jacobian: np.ndarray,
    n_measured: int,
    n_simulated: int,
    band_groups: int = BAND_GROUPS,
) -> SummaryMisfitTest | None:
    """The test from the pilot's M runs and the Jacobian at the pilot point.

    Args:
        pilot: (M x C x F) log-amplitude spectra of the pilot runs (one point, fresh tracks,
            sensor noise), as for :func:`.track_statistics.track_statistics_error`.
        jacobian: (q x C x F) derivative of the simulated mean spectrum (any scaling).
        n_measured: ν.
        n_simulated: μ.
        band_groups: groups of bands per channel; fewer are used when M is too small for
            C x groups summaries (k ≤ (M − 1) / 2, and no more groups than bands).

    Returns:
        The test, or None when even one group per channel leaves too few pilot runs, or
        the summaries are degenerate (their covariance is not positive definite).
    """
    y = np.asarray(pilot, dtype=np.float64)
    j = np.asarray(jacobian, dtype=np.float64)
    m, c, f = y.shape
    groups = min(band_groups, f)
    while groups >= 1 and c * groups > (m - 1) // 2:
        groups -= 1
    if groups < 1:
        return None
    g = band_group_directions(c, f, groups)
    with one_blas_thread():  # the same bits under any load (README, "Reproducible")
        basis, _ = np.linalg.qr(j.reshape(j.shape[0], -1).T)  # p x q, orthonormal
        directions = g - basis @ (basis.T @ g)
        flat = y.reshape(m, -1)
        summaries = (flat - flat.mean(axis=0)) @ directions
        covariance = summaries.T @ summaries / (m - 1)
    try:
        return SummaryMisfitTest(
            directions.reshape(c, f, -1), covariance, m, n_measured, n_simulated
        )
    except ValueError:
        return None


def _summary_residual(y: np.ndarray, h: np.ndarray, test: SummaryMisfitTest) -> np.ndarray:
    """(k,) r = Bᵀ (ȳ − h̄) of (ν x C x F) measured and (μ x C x F) simulated spectra."""
    with one_blas_thread():
        return (y.mean(axis=0) - h.mean(axis=0)).reshape(-1) @ test.directions.reshape(-1, test.dof)


def summary_residuals_z(
    measured: np.ndarray, simulated: np.ndarray, test: SummaryMisfitTest
) -> np.ndarray:
    """(k,) each summary's residual over its own sd, r_j / √(κ Ĉ_B,jj): where the data and
    the model disagree (a summary alone, not the joint test; ±2 is the usual scatter).
    Shapes as :func:`summary_misfit` (not checked here)."""
    r = _summary_residual(np.asarray(measured, np.float64), np.asarray(simulated, np.float64), test)
    return r / np.sqrt(test.scale * np.diag(test.covariance))


def summary_misfit(
    measured: np.ndarray, simulated: np.ndarray, test: SummaryMisfitTest
) -> tuple[float, float]:
    """Hotelling's T² of the measured against the simulated spectra, and its p-value.

    Args:
        measured: (ν x C x F) measured log-amplitude spectra.
        simulated: (μ x C x F) simulated spectra at the fitted point (the model's tracks).
        test: the summaries and their covariance.

    Returns:
        ``(t2, p)``; NaN, NaN when a spectrum is not finite.

    Raises:
        ValueError: shapes other than the test's.
    """
    y = np.asarray(measured, dtype=np.float64)
    h = np.asarray(simulated, dtype=np.float64)
    c, f, k = test.directions.shape
    if y.shape != (test.n_measured, c, f) or h.shape != (test.n_simulated, c, f):
        raise ValueError(
            f"measured: shape {y.shape}, simulated: shape {h.shape}; expected "
            f"({test.n_measured} x {c} x {f}) and ({test.n_simulated} x {c} x {f})"
        )
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(h))):
        return math.nan, math.nan
    r = _summary_residual(y, h, test)
    with one_blas_thread():
        t2 = float(r @ np.linalg.solve(test.scale * test.covariance, r))
    n = test.runs
    statistic = (n - k) / (k * (n - 1)) * t2
    return t2, float(stats.f.sf(statistic, k, n - k))
