"""The summary likelihood's pilot on the benchmarks' problems (fast path and PyBullet).

The pilot itself (two stages: M runs at the middle of C_w, a Gauss–Newton fit of the q
summaries, M runs again at that fit) is :mod:`susp_bo.calibration.track_statistics_pilot`,
which a study runs too; this module adapts a benchmark ``problem`` (``spectra(W)``,
``measured``, ``tracks``, ``spec``, ``evaluations``) to it and supplies the linearised
rig's pilot runs (:func:`linear_pilot`). The pilot's simulations are not part of the
loop's budget: ``problem.evaluations`` is restored after it. Used by ``coverage.py
--error statistics`` through :class:`fast_path.FastPathProblem`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from fast_path import linear_run

from susp_bo.calibration.track_statistics import TrackStatisticsError, minimum_pilot_runs
from susp_bo.calibration.track_statistics_pilot import PILOT_RUNS, PilotRecord
from susp_bo.calibration.track_statistics_pilot import summary_fit as _summary_fit
from susp_bo.calibration.track_statistics_pilot import two_stage_error as _two_stage_error
from susp_bo.calibration.track_statistics_pilot import whitened_jacobian as _whitened_jacobian
from susp_bo.rig.linear import LinearisedRig
from susp_bo.rig.simulator import synthetic_track
from susp_bo.rig.spec import RigSpec

__all__ = ["PILOT_RUNS", "PilotRecord", "linear_pilot", "summary_fit", "two_stage_error"]


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


def linear_pilot(problem, w: np.ndarray, runs: int, seed: int) -> np.ndarray:
    """The fast path's pilot runs: :func:`pilot_spectra` with the problem's rig and noise."""
    return pilot_spectra(problem.spec, w, runs, seed, problem.options.noise)


def summary_fit(problem, error: TrackStatisticsError, u0: np.ndarray) -> tuple[np.ndarray, bool]:
    """The package's Gauss–Newton summary fit on ``problem`` (unit coordinates)."""
    return _summary_fit(
        problem.spectra, problem.measured, error, problem.spec.calibration_bounds, u0
    )


def whitened_jacobian(
    problem, error: TrackStatisticsError, u: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The package's whitened summary residuals and their Jacobian on ``problem``."""
    return _whitened_jacobian(
        problem.spectra, problem.measured, error, problem.spec.calibration_bounds, u
    )


def two_stage_error(
    problem, seed: int, runs: int = PILOT_RUNS, simulate_pilot: Callable = linear_pilot
) -> tuple[TrackStatisticsError, PilotRecord]:
    """The two-stage pilot on ``problem``; stage s's runs use seed ``seed + s``.

    ``simulate_pilot(problem, w, runs, seed) -> (runs x C x F)``: spectra at w (physical
    units) on ``runs`` fresh track realizations with sensor noise.
    """
    runs = max(runs, minimum_pilot_runs(len(problem.names)))
    before = problem.evaluations
    error, record = _two_stage_error(
        problem.spectra,
        lambda w, stage: simulate_pilot(problem, w, runs, seed + stage),
        problem.measured,
        problem.spec.calibration_bounds,
        len(problem.tracks),
    )
    problem.evaluations = before  # the pilot is not the loop's budget
    return error, record
