"""The summary likelihood's pilot: where its weights A and covariance C come from.

:mod:`.track_statistics` needs, before the calibration, M pilot runs at a pilot point on
fresh track realizations (with sensor noise) and the Jacobian of the simulated mean
spectrum there. The pilot point should be near the truth (the summaries' weights A are the
score direction there; C, what calibrates the intervals, is estimated at it), so the pilot
runs twice (:func:`two_stage_error`):

1. at the middle of C_w, then a Gauss–Newton fit of the q summaries from there
   (:func:`summary_fit`: q equations in q unknowns, each step q + 1 points x μ runs);
2. again at that fit's point, on new track realizations: the error the calibration uses.

The pilot's simulations are not part of the calibration's budget (they are counted in
:attr:`PilotRecord.simulations`). The second pilot point comes from a fit to the measured
data, so A and C depend (weakly, at second order) on the data; the SBC
(``benchmarks/coverage.py --error statistics --unknown-tracks``) measures the whole
procedure, that included. A fit that has not converged after its iterations is recorded
(:attr:`PilotRecord.converged`), not hidden.

Two callables carry the simulator, so that the linearised fast path (``benchmarks/``) and
a study on PyBullet (:mod:`.study_track_statistics`, store-backed) run the same pilot:

- ``spectra(W) -> (b x μ x C x F)``: the model's simulated spectra (noise floor included) of
  the rows of W (b x q, physical units) on its μ track realizations;
- ``pilot_runs(w, stage) -> (M x C x F)``: spectra at w (q,) on M fresh track
  realizations with sensor noise, the realizations of ``stage`` (0 or 1) their own.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from susp_bo.calibration.track_statistics import (
    TrackStatisticsError,
    summary_residuals,
    track_statistics_error,
)

Spectra = Callable[[np.ndarray], np.ndarray]
"""``spectra(W)``: (b x q) physical units -> (b x μ x C x F) simulated spectra."""
PilotRuns = Callable[[np.ndarray, int], np.ndarray]
"""``pilot_runs(w, stage)``: (q,) physical units, stage 0 or 1 -> (M x C x F) spectra."""

PILOT_RUNS = 100
"""M per stage by default (at least :func:`.track_statistics.minimum_pilot_runs` (q))."""
STEP = 1e-4
"""Finite-difference step in unit coordinates of C_w."""
FIT_ITERATIONS = 12
"""Gauss–Newton steps of :func:`summary_fit` before it is recorded as not converged."""
FIT_TOLERANCE = 1e-7
"""A Gauss–Newton step (unit coordinates, largest component) below this has converged."""


@dataclasses.dataclass(frozen=True)
class PilotRecord:
    """What the two-stage pilot did (a study writes it to ``result.json``)."""

    first_fit: tuple[float, ...]
    """(q,) the first stage's fit (unit coordinates of C_w): the second pilot point."""
    simulations: int
    """Simulator runs the pilot spent (pilot runs and Gauss–Newton points x μ)."""
    shrinkage: float
    """The Ledoit–Wolf intensity of the final Σ̂ in [0, 1]."""
    converged: bool = True
    """Whether the first stage's Gauss–Newton fit met :data:`FIT_TOLERANCE`."""


def _physical(bounds: np.ndarray, u: np.ndarray) -> np.ndarray:
    return bounds[0] + u * (bounds[1] - bounds[0])


def mean_jacobian(spectra: Spectra, bounds: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(q x C x F) central differences of the simulated mean spectrum at u (unit cube),
    one-sided where u is within :data:`STEP` of a face."""
    columns = []
    for k in range(len(u)):
        plus, minus = u.copy(), u.copy()
        plus[k], minus[k] = min(u[k] + STEP, 1.0), max(u[k] - STEP, 0.0)
        h = spectra(_physical(bounds, np.stack([plus, minus]))).mean(axis=1)
        columns.append((h[0] - h[1]) / (plus[k] - minus[k]))
    return np.stack(columns)


def whitened_jacobian(
    spectra: Spectra,
    measured: np.ndarray,
    error: TrackStatisticsError,
    bounds: np.ndarray,
    u: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(r, J): the whitened summary residuals at u (q,) and their forward-difference
    Jacobian along the unit coordinates (q x q), one-sided inwards at the upper face."""
    steps = np.where(u + STEP <= 1.0, STEP, -STEP)
    points = np.vstack([u, u + np.diag(steps)])
    residuals = summary_residuals(measured, spectra(_physical(bounds, points)), error)
    return residuals[0], (residuals[1:] - residuals[0]).T / steps


def summary_fit(
    spectra: Spectra,
    measured: np.ndarray,
    error: TrackStatisticsError,
    bounds: np.ndarray,
    u0: np.ndarray,
    iterations: int = FIT_ITERATIONS,
) -> tuple[np.ndarray, bool]:
    """Gauss–Newton on the whitened summary residuals from u0, kept in [0, 1]^q.

    Returns ``(u, converged)``: the last point (unit coordinates) and whether a step fell
    below :data:`FIT_TOLERANCE`.
    """
    u = np.asarray(u0, dtype=np.float64).copy()
    for _ in range(iterations):
        residual, jac = whitened_jacobian(spectra, measured, error, bounds, u)
        step = np.linalg.lstsq(jac, -residual, rcond=None)[0]
        moved = np.clip(u + step, 0.0, 1.0)
        if np.max(np.abs(moved - u)) < FIT_TOLERANCE:
            return moved, True
        u = moved
    return u, False


def pilot_error(
    spectra: Spectra,
    pilot_runs: PilotRuns,
    n_measured: int,
    n_simulated: int,
    bounds: np.ndarray,
    u: np.ndarray,
    stage: int,
) -> TrackStatisticsError:
    """The summary error with its pilot at u (unit coordinates): ν measured runs, μ
    simulated tracks."""
    pilot = pilot_runs(_physical(bounds, u), stage)
    jacobian = mean_jacobian(spectra, bounds, u)
    return track_statistics_error(pilot, jacobian, n_measured, n_simulated)


def two_stage_error(
    spectra: Spectra,
    pilot_runs: PilotRuns,
    measured: np.ndarray,
    bounds: np.ndarray,
    n_simulated: int,
) -> tuple[TrackStatisticsError, PilotRecord]:
    """The two-stage pilot (module docstring); returns the error and what it did.

    Args:
        spectra: the model's spectra on its μ tracks (module docstring).
        pilot_runs: the pilot's runs at a point, per stage (module docstring); each call
            is counted by the number of spectra it returns.
        measured: (ν x C x F) measured log-amplitude spectra.
        bounds: (2 x q) C_w in physical units.
        n_simulated: μ, the track realizations ``spectra`` simulates on.

    Raises:
        ValueError: what :func:`.track_statistics.track_statistics_error` refuses (too
            few pilot runs, a parameter with no effect, ...).
    """
    bounds = np.asarray(bounds, dtype=np.float64)
    measured = np.asarray(measured, dtype=np.float64)
    counted = [0]

    def counting_spectra(W: np.ndarray) -> np.ndarray:
        H = spectra(W)
        counted[0] += H.shape[0] * H.shape[1]
        return H

    def counting_pilot(w: np.ndarray, stage: int) -> np.ndarray:
        runs = pilot_runs(w, stage)
        counted[0] += runs.shape[0]
        return runs

    q = bounds.shape[1]
    middle = np.full(q, 0.5)
    nu = len(measured)
    first = pilot_error(counting_spectra, counting_pilot, nu, n_simulated, bounds, middle, 0)
    u1, converged = summary_fit(counting_spectra, measured, first, bounds, middle)
    error = pilot_error(counting_spectra, counting_pilot, nu, n_simulated, bounds, u1, 1)
    return error, PilotRecord(tuple(u1.tolist()), counted[0], error.shrinkage, converged)
