"""The verdict's rules on how well the model fits the data, applied after the others.

Two rules look at the spectra at the best evaluated point rather than at log L, and both
answer ``below_expected_fit`` (the model misses something in the data) on a result no
other rule refused:

- the lack of fit between ν ≥ 2 runs (:func:`.lack_of_fit.with_lack_of_fit`), for every
  output-error model;
- under the summary likelihood (``track_statistics``, whose own log L has no
  goodness-of-fit power), the test of the summaries its fit does not use
  (:mod:`.summary_misfit`; :func:`with_summary_misfit`).

:func:`with_fit_rules` applies both; :func:`.loop.calibrate` calls it (unless its
``lack_of_fit`` is False, a benchmark's "before"), and so does a caller that calibrated
without them and applies them afterwards (``benchmarks/coverage.py``).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from susp_bo.calibration.lack_of_fit import with_lack_of_fit
from susp_bo.calibration.local_search import SpectraEvaluator
from susp_bo.calibration.reliability_rules import Reason
from susp_bo.calibration.result import CalibrationResult
from susp_bo.calibration.summary_misfit import (
    P_LIMIT,
    SummaryMisfitTest,
    summary_misfit,
    summary_residuals_z,
)
from susp_bo.calibration.trust_region import best_point


def summary_misfit_reason(
    t2: float, p: float, dof: int, worst: tuple[str, float] | None = None
) -> Reason | None:
    """``below_expected_fit`` when ``p`` < :data:`.summary_misfit.P_LIMIT`; None otherwise
    or when NaN. ``worst``: the summary that disagrees most and its z, named in the
    message (where to look)."""
    if not math.isfinite(p) or p >= P_LIMIT:
        return None
    where = "" if worst is None else f"; most in {worst[0]}, z = {worst[1]:+.1f}"
    return {
        "code": "below_expected_fit",
        "message": (
            f"the model misses something in the data: {dof} channel and band-group "
            "summaries that no change of the parameters moves (to first order) disagree "
            "with the simulation beyond the track and sensor scatter (Hotelling T^2 = "
            f"{t2:.1f}, p = {p:.1e}, limit {P_LIMIT:g}{where})"
        ),
        "summary_misfit_p": float(p),
    }


def with_summary_misfit(
    result: CalibrationResult,
    evaluator: SpectraEvaluator,
    measured: np.ndarray,
    test: SummaryMisfitTest | None,
) -> CalibrationResult:
    """``result`` with the summary likelihood's goodness of fit at its best evaluated point.

    The spectra at the best point come from the evaluator (a study's store: no new
    simulation), (μ x C x F) on the model's tracks. ``evidence`` gets
    ``summary_misfit_t2``, ``summary_misfit_p``, ``summary_misfit_dof`` and
    ``summary_misfit_worst`` (the summary whose residual is largest in its own sd, and
    that z: the nominal channel and band group where the data and the model disagree most;
    its direction, made orthogonal to the parameters' effect, weighs other bands a little
    too) — all null when
    ``test`` is None (a pilot too small for one band group per channel), p and T² null
    when the spectra there failed; a trusted sentence then says the test was not made. A
    result that was trusted and whose p is below :data:`.summary_misfit.P_LIMIT` becomes
    ``not_trusted`` (``below_expected_fit``).

    Args:
        result: a finished calibration.
        evaluator: what calibrated it (``spectra(W)`` -> (b x μ x C x F)).
        measured: (ν x C x F) the measured spectra.
        test: the error's test (:attr:`.track_statistics.TrackStatisticsError.misfit`).
    """
    reliability = result.reliability
    if reliability is None or not np.any(np.isfinite(result.y)):
        return result
    t2 = p = math.nan
    worst: tuple[str, float] | None = None
    if test is not None:
        best = np.asarray(best_point(result.X, result.y), dtype=np.float64)
        simulated = np.asarray(evaluator.spectra(best[None]))[0]
        c, f, _ = test.directions.shape
        y = np.asarray(measured, dtype=np.float64)
        if y.shape == (test.n_measured, c, f) and simulated.shape == (test.n_simulated, c, f):
            t2, p = summary_misfit(y, simulated, test)
            if math.isfinite(p):
                z = summary_residuals_z(y, simulated, test)
                j = int(np.argmax(np.abs(z)))
                worst = (test.label(j), float(z[j]))
    evidence: dict[str, Any] = dict(reliability.evidence) | {
        "summary_misfit_t2": None if math.isnan(t2) else t2,
        "summary_misfit_p": None if math.isnan(p) else p,
        "summary_misfit_dof": None if test is None else test.dof,
        "summary_misfit_worst": None if worst is None else {"summary": worst[0], "z": worst[1]},
    }
    trusted = reliability.trusted and test is not None
    reason = summary_misfit_reason(t2, p, test.dof, worst) if trusted else None
    return dataclasses.replace(result, reliability=reliability.with_rule(reason, evidence))


def with_fit_rules(
    result: CalibrationResult, evaluator: SpectraEvaluator, measured: np.ndarray
) -> CalibrationResult:
    """``result`` after the lack of fit between runs and, when the evaluator's error is the
    summary likelihood, its goodness-of-fit test (module docstring)."""
    result = with_lack_of_fit(result, evaluator, measured)
    error = getattr(evaluator, "error", None)
    if getattr(error, "model", None) == "track_statistics" and hasattr(error, "misfit"):
        result = with_summary_misfit(result, evaluator, measured, error.misfit)
    return result
