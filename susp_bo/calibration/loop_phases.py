"""The calibration loop's two optional phases, run from :func:`.loop.calibrate`.

- :func:`run_basin_phase`: the basin phase (:mod:`.basin_search`) on C_w, climbing modes
  seen at the fringe of the surrogate posterior;
- :func:`run_local_phase`: the local Gauss–Newton phase (:mod:`.local_search`) from the
  best point, for an evaluator that exposes its spectra.

Each one's simulations join the data (x, y) and the history as the loop's own do.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from susp_bo.calibration.basin_search import ClimbReport, basin_phase
from susp_bo.calibration.design import from_unit, to_unit
from susp_bo.calibration.iteration_record import PhaseRecorder
from susp_bo.calibration.local_search import LocalSearchResult, SpectraEvaluator, local_search
from susp_bo.calibration.loop_step import (
    Evaluate,
    derived_seed,
    evaluate_checked,
    fit_in_box,
    torch_state,
)
from susp_bo.calibration.result import IterationReport
from susp_bo.calibration.settings import CalibrationSettings
from susp_bo.calibration.surrogate import Surrogate
from susp_bo.calibration.trust_region import best_point

logger = logging.getLogger(__name__)


def run_basin_phase(
    evaluate: Evaluate,
    bounds: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    main_budget: int,
    iteration: int,
    settings: CalibrationSettings,
    history: list[IterationReport],
    on_iteration: Callable[[IterationReport], None] | None,
    bar: Any,
) -> tuple[np.ndarray, np.ndarray, int, list[ClimbReport], int]:
    """The basin phase (:mod:`.basin_search`) on C_w; its runs join the data.

    Returns:
        (x, y, iteration) with the phase's evaluations, its climbs, and the most confirmed
        peaks of the surrogate it counted (:attr:`.basin_search.BasinPhase.confirmed_peaks`).
    """
    data = PhaseRecorder(x, y, iteration, history, on_iteration, bar)

    def fit(x_unit: np.ndarray, values: np.ndarray) -> Surrogate:
        # the same data as (x_unit, values), as evaluated (no unit-cube round trip)
        return fit_in_box(data.x, data.y, bounds, settings, data.iteration + 1)

    caller = (torch.get_num_threads(), torch.get_default_dtype())

    def run(u: np.ndarray) -> np.ndarray:
        w = from_unit(u, bounds)
        with torch_state(*caller):  # evaluate sees the caller's torch state, as elsewhere
            values = evaluate_checked(evaluate, w)
        finite = values[np.isfinite(values)]
        data.add("basin", w, values, float(finite.max()) if finite.size else math.nan)
        return values

    with torch_state(settings.num_threads):
        outcome = basin_phase(
            to_unit(x, bounds),
            y,
            int(settings.basin.budget_fraction * (main_budget - x.shape[0])),
            settings.batch_size,
            settings.basin,
            fit,
            run,
            lambda: derived_seed(settings.seed, data.iteration + 1, 6),
            settings.acquisition_restarts,
            settings.acquisition_raw_samples,
        )
    for report in outcome.climbs:
        if report.stop_reason == "hunt":
            logger.info(
                "basin search: the surrogate has two or more confirmed peaks; %d evaluations "
                "where a mode may hide (its upper bound reaches the posterior), best log L %.6g",
                report.n_evaluations,
                report.end_log_likelihood,
            )
            continue
        logger.info(
            "basin search: climbed from log L %.6g to %.6g in %d evaluations (%s)",
            report.start_log_likelihood,
            report.end_log_likelihood,
            report.n_evaluations,
            report.stop_reason,
        )
    return data.x, data.y, data.iteration, outcome.climbs, outcome.confirmed_peaks


def run_local_phase(
    evaluate: SpectraEvaluator,
    bounds: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    main_budget: int,
    iteration: int,
    settings: CalibrationSettings,
    history: list[IterationReport],
    on_iteration: Callable[[IterationReport], None] | None,
    bar: Any,
) -> tuple[np.ndarray, np.ndarray, LocalSearchResult, int]:
    """The local phase (:mod:`.local_search`) from the best point; its runs join the data."""
    start = best_point(x, y)
    cap = int(settings.local_search_fraction * (main_budget - x.shape[0]))
    data = PhaseRecorder(x, y, iteration, history, on_iteration, bar)

    def record(w: np.ndarray, values: np.ndarray, gain: float) -> None:
        data.add("local", w, values, gain)

    result = local_search(evaluate, bounds, start, cap, on_evaluations=record)
    return data.x, data.y, result, data.iteration
