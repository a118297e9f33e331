"""The summary likelihood's pilot on the linearised fast path (tracks known only by statistics).

:mod:`susp_bo.calibration.track_statistics` needs, before the calibration, M pilot runs at
a pilot point on fresh track realizations (with sensor noise) and the Jacobian of the
simulated mean spectrum there. The pilot point should be near the truth (the summaries'
weights A are the score direction there; C, what calibrates the intervals, is estimated
at it), so the pilot runs twice (:func:`two_stage_error`):

1. at the middle of C_w, then a Gauss–Newton fit of the q summaries from there
   (:func:`summary_fit`: q equations in q unknowns, each step q + 1 points x μ runs);
2. again at that fit's point, on new track realizations: the error the calibration uses.

The pilot's simulations are not part of the loop's budget (they are counted in
``PilotRecord.simulations``). The second pilot point comes from a fit to the measured data,
so A and C depend (weakly, at second order) on the data; the SBC measures the whole
procedure, that included. A fit that has not converged after its iterations is recorded
(``PilotRecord.converged``), not hidden. Used by ``coverage.py --error statistics`` through
:class:`fast_path.FastPathProblem`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
from fast_path import linear_run

from susp_bo.calibration.track_statistics import (
    TrackStatisticsError,
    minimum_pilot_runs,
    summary_residuals,
    track_statistics_error,
)
from susp_bo.rig.linear import LinearisedRig
from susp_bo.rig.simulator import synthetic_track
from susp_bo.rig.spec import RigSpec

PILOT_RUNS = 100
"""M (the prototype's value; at least :func:`minimum_pilot_runs` (q))."""
STEP = 1e-4  # unit-cube step of the finite differences


@dataclasses.dataclass(frozen=True)
class PilotRecord:
    """What the two-stage pilot did (recorded in the SBC's experiment records)."""

    first_fit: tuple[float, ...]
    """(q,) the first stage's fit (unit coordinates of C_w): the second pilot point."""
    simulations: int
    """Simulator runs the pilot spent (pilot runs and Gauss–Newton points x μ)."""
    shrinkage: float
    converged: bool = True
    """Whether the first stage's Gauss–Newton fit met its step tolerance."""


def pilot_spectra(
    spec: RigSpec, w: np.ndarray, runs: int, seed: int, noise_m_s2: float
) -> np.ndarray:
    """(M x C x F) spectra at ``w`` on M fresh track realizations, with sensor noise."""
    rig = LinearisedRig(spec.with_parameters(dict(zip(spec.calibration_names, w.tolist()))))
    out = []
    for m in range(runs):
        track_seed = int(np.random.SeedSequence([seed, m, 17]).generate_state(1)[0])
        track = synthetic_track(spec, seed=track_seed)
        out.append(linear_run(rig, spec, track, noise_m_s2, [seed, m, 19])[0])
    return np.stack(out)


def mean_jacobian(problem, u: np.ndarray) -> np.ndarray:
    """(q x C x F) central differences of the simulated mean spectrum at u (unit cube)."""
    bounds = problem.spec.calibration_bounds
    span = bounds[1] - bounds[0]
    columns = []
    for k in range(len(u)):
        plus, minus = u.copy(), u.copy()
        plus[k], minus[k] = min(u[k] + STEP, 1.0), max(u[k] - STEP, 0.0)
        h = problem.spectra(bounds[0] + np.stack([plus, minus]) * span).mean(axis=1)
        columns.append((h[0] - h[1]) / (plus[k] - minus[k]))
    return np.stack(columns)


def linear_pilot(problem, w: np.ndarray, runs: int, seed: int) -> np.ndarray:
    """The fast path's pilot runs: :func:`pilot_spectra` with the problem's rig and noise."""
    return pilot_spectra(problem.spec, w, runs, seed, problem.options.noise)


def pilot_error(
    problem, u: np.ndarray, runs: int, seed: int, simulate_pilot: Callable = linear_pilot
) -> TrackStatisticsError:
    """The summary error with its pilot at u (unit coordinates)."""
    bounds = problem.spec.calibration_bounds
    w = bounds[0] + u * (bounds[1] - bounds[0])
    pilot = simulate_pilot(problem, w, runs, seed)
    return track_statistics_error(
        pilot, mean_jacobian(problem, u), len(problem.measured), len(problem.tracks)
    )


def whitened_jacobian(
    problem, error: TrackStatisticsError, u: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(r, J): the whitened summary residuals at u (q,) and their forward-difference
    Jacobian along the unit coordinates (q x q), one-sided inwards at the upper face."""
    bounds = problem.spec.calibration_bounds
    span = bounds[1] - bounds[0]
    steps = np.where(u + STEP <= 1.0, STEP, -STEP)
    points = np.vstack([u, u + np.diag(steps)])
    residuals = summary_residuals(
        problem.measured, problem.spectra(bounds[0] + points * span), error
    )
    return residuals[0], (residuals[1:] - residuals[0]).T / steps


def summary_fit(
    problem, error: TrackStatisticsError, u0: np.ndarray, iterations: int = 12
) -> tuple[np.ndarray, bool]:
    """Gauss–Newton on the whitened summary residuals from u0, kept in [0, 1]^q.

    Returns ``(u, converged)``: the last point and whether a step fell below 1e-7.
    """
    u = np.asarray(u0, dtype=np.float64).copy()
    for _ in range(iterations):
        residual, jac = whitened_jacobian(problem, error, u)
        step = np.linalg.lstsq(jac, -residual, rcond=None)[0]
        moved = np.clip(u + step, 0.0, 1.0)
        if np.max(np.abs(moved - u)) < 1e-7:
            return moved, True
        u = moved
    return u, False


def two_stage_error(
    problem, seed: int, runs: int = PILOT_RUNS, simulate_pilot: Callable = linear_pilot
) -> tuple[TrackStatisticsError, PilotRecord]:
    """The two-stage pilot (module docstring); returns the error and what it did.

    ``simulate_pilot(problem, w, runs, seed) -> (runs x C x F)``: spectra at w (physical
    units) on ``runs`` fresh track realizations with sensor noise.
    """
    q = len(problem.names)
    runs = max(runs, minimum_pilot_runs(q))
    before = problem.evaluations
    first = pilot_error(problem, np.full(q, 0.5), runs, seed, simulate_pilot)
    u1, converged = summary_fit(problem, first, np.full(q, 0.5))
    error = pilot_error(problem, u1, runs, seed + 1, simulate_pilot)
    mu = len(problem.tracks)
    spent = 2 * runs + (problem.evaluations - before) * mu
    problem.evaluations = before  # the pilot is not the loop's budget
    return error, PilotRecord(tuple(u1.tolist()), spent, error.shrinkage, converged)
