"""``susp-bo diagnose``, step 3: recalibrating the rig with the named effect switched on.

The effect's parameters are appended to C_w and the study's own loop (design, kriging,
EGO, MCMC) runs on the augmented rig with a new evaluation store in ``DIR/augmented``,
warm-started from the ranking's refit: :func:`refit_window` gives the box (2 x q) around
the refit (and the base calibration's MAP), and :func:`augmented_result_payload` the
``DIR/augmented/result.json`` it writes. The command itself is
:mod:`susp_bo.commands.diagnose`.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path
from typing import Any

import numpy as np

from susp_bo import __version__
from susp_bo.json_files import json_ready, write_json
from susp_bo.output_folder import RESULT_NAME


def augmented_result_payload(
    result: Any, spec: Any, start: np.ndarray, base_w: np.ndarray, study: Any
) -> dict[str, Any]:
    """``DIR/augmented/result.json``: the recalibration's result as ``calibrate`` writes one.

    Args:
        result: the recalibration's :class:`~susp_bo.calibration.result.CalibrationResult`.
        spec: the augmented rig (its calibration entries give the units).
        start: (q,) the ranking's refit the recalibration was warm-started from.
        base_w: (n_base,) the base calibration's joint MAP.
        study: the base study (rig, data, output error and seed of the context).

    Returns:
        The calibration's keys of ``result.json`` (:meth:`CalibrationResult.to_dict`: the
        same names, layout — bounds as (q x 2) pairs — and meaning, its own reliability
        verdict), the units, the study's context, and ``warm_start`` (refit, base MAP).
    """
    unit = {c.name: c.unit for c in spec.calibration}
    return {
        "parameters": list(result.names),
        "units": [unit.get(name, "") for name in result.names],
        **result.to_dict(),
        "warm_start": {
            "ranking_refit": np.asarray(start, dtype=np.float64).tolist(),
            "base_map": np.asarray(base_w, dtype=np.float64).tolist(),
            "window": [[float(lo), float(hi)] for lo, hi in np.asarray(result.bounds).T],
        },
        "rig": spec.name,
        "data": str(study.config.data),
        "nu": len(study.runs),
        "seed": study.config.seeds.calibration,
        "version": __version__,
    }


def refit_window(
    fit: Any,
    names: tuple[str, ...],
    bounds: np.ndarray,
    n_base: int,
    base_w: np.ndarray | None = None,
) -> np.ndarray:
    """The recalibration's box (2 x q): ±max(4 sd, 15 % of the range) around the refit for
    the ``n_base`` base parameters, ±max(4 sd, 10 %) for the effect's, within ``bounds``.

    ``base_w`` ((n_base,), the base calibration's joint MAP on the study's own simulator):
    the base parameters' window then spans from the refit to that MAP (± the same
    half-width). The ranking refits on the linearised rig, whose own model error can put a
    base parameter far from where the study's simulator has it (measured: primary
    vertical damping refitted at 5.3 kN·s/m against 10.0 in the PyBullet calibration and
    the truth), and a window around the refit alone then excludes the truth.
    """
    values, sd = fit.parameters(), dict(zip(fit.names, fit.sd))
    window = np.array(bounds, dtype=np.float64, copy=True)
    for i, name in enumerate(names):
        lower, upper = bounds[0, i], bounds[1, i]
        share = 0.15 if i < n_base else 0.10
        half = max(4.0 * float(sd.get(name, 0.0)), share * (upper - lower))
        centre = min(max(values[name], lower), upper)
        low, high = centre, centre
        if base_w is not None and i < n_base:
            other = min(max(float(base_w[i]), lower), upper)
            low, high = min(centre, other), max(centre, other)
        window[0, i], window[1, i] = max(lower, low - half), min(upper, high + half)
    return window


def _study_recalibration(
    study: Any, out: Path, budget: int | None, progress: bool, base: Any
) -> tuple[Any, list[dict[str, Any] | None]]:
    """``(recalibrate, verdicts)``: ``recalibrate(best)`` runs the study loop on the
    augmented rig (PyBullet); ``base`` is the base calibration's fit
    (:func:`susp_bo.commands.diagnose._fit_from_result`), whose MAP widens the window and
    is a second start. Each call appends the recalibration's own reliability verdict (a
    dict, or None) to ``verdicts``."""
    from susp_bo.calibration.design import default_design_size
    from susp_bo.calibration.loop import calibrate
    from susp_bo.calibration.study import (
        calibration_settings,
        expected_log_likelihood_at_truth,
        study_evaluator,
    )
    from susp_bo.calibration.study_preparation import STORE_NAME, store_fingerprint
    from susp_bo.discrepancy.effects import get_effect, with_effect
    from susp_bo.discrepancy.fitting import Fit
    from susp_bo.execution import make_executor
    from susp_bo.store import EvaluationStore

    verdicts: list[dict[str, Any] | None] = []

    def recalibrate(best: Any) -> Fit:
        effect = get_effect(best.effect)
        spec = with_effect(study.spec, best.effect, best.options, calibrate=True)
        extra = [p for p in effect.parameters if p.calibrated]
        names = tuple(study.names) + tuple(effect.parameter_name(p.key) for p in extra)
        # warm start from the ranking refit: a window around its maximum, the refit in the design
        bounds = np.hstack([study.bounds, np.array([[p.lower for p in extra],
                                                    [p.upper for p in extra]])])  # fmt: skip
        base_w = np.asarray(base.w, dtype=np.float64)
        bounds = refit_window(best.fit, names, bounds, len(study.names), base_w)
        start = np.array([best.fit.parameters()[n] for n in names])
        # two starts: the ranking refit, and the base calibration's MAP with the refit's
        # effect parameters (the study's simulator's own optimum for the base parameters)
        hybrid = start.copy()
        hybrid[: len(study.names)] = base_w
        starts = np.clip(np.vstack([start, hybrid]), bounds[0], bounds[1])
        folder = out / "augmented"
        folder.mkdir(parents=True, exist_ok=True)
        (folder / STORE_NAME).unlink(missing_ok=True)
        # the recalibration is judged by the gap it closes, not by its own verdict: a small
        # --budget for it is allowed (the study itself was checked when it ran)
        settings = dataclasses.replace(calibration_settings(study.config), allow_small_budget=True)
        if budget is not None:
            settings = dataclasses.replace(
                settings,
                max_evaluations=budget,
                initial_design_size=min(budget, settings.initial_design_size or budget),
            )
        design_size = settings.initial_design_size or default_design_size(len(names))
        if design_size <= len(starts):  # a tiny --budget: one start
            starts = starts[:1]
        print(f"susp-bo diagnose: recalibrating with {best.effect} ({names})", file=sys.stderr)
        config = study.config.executor
        with (
            EvaluationStore(folder / STORE_NAME, store_fingerprint(study, spec, names)) as store,
            make_executor(workers=config.workers, scheduler=config.scheduler) as executor,
        ):
            evaluator = study_evaluator(study, store, executor, progress, spec, names)
            result = calibrate(
                evaluator,
                bounds,
                names,
                settings,
                progress=progress,
                initial_points=starts,
                # B's expectation at the truth needs the data and B only, not the model: the
                # augmented model's verdict says whether it now reproduces the data as B expects
                expected_at_truth=expected_log_likelihood_at_truth(study),
            )
        if result.reliability is not None:  # a command's advice: flags and study keys
            result = dataclasses.replace(
                result, reliability=result.reliability.worded_for("command_line")
            )
        summary = result.summary.to_dict()
        verdict = None if result.reliability is None else json_ready(result.reliability.to_dict())
        verdicts.append(verdict)
        span = bounds[1] - bounds[0]
        sd = np.maximum(np.asarray(summary["sd"], dtype=np.float64), 1e-9 * span)
        write_json(
            folder / RESULT_NAME,
            json_ready(augmented_result_payload(result, spec, start, base_w, study)),
        )
        return Fit(
            spec=spec,
            names=names,
            bounds=bounds,
            w=np.asarray(summary["joint_map"], dtype=np.float64),
            log_likelihood=float(np.nanmax(result.y)),
            covariance_unit=np.diag((sd / span) ** 2),
            n_evaluations=int(result.n_evaluations),
        )

    return recalibrate, verdicts
