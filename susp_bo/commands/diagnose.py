"""``susp-bo diagnose RESULT_DIR --out DIR``: the model-discrepancy workflow on a calibration.

Reads the study of ``RESULT_DIR`` (``study.toml``, ``result.json``, the measured
runs it names), then (:mod:`susp_bo.discrepancy.workflow`):

1. checks the calibrated model — posterior draws (joint MAP plus Gaussian draws
   with the posterior sd) re-simulated with the study's simulator (PyBullet) on
   every measured track — and flags bands (BH at q = 0.05);
2. ranks the candidate effects by refit evidence on the linearised rig (fast
   path; base and every candidate refitted on it, so its own model error
   cancels in the comparison);
3. recalibrates the rig with the named effect switched on and its parameters
   appended to C_w, with the study's own loop (design, kriging, EGO, MCMC) and
   budget, a new evaluation store in ``DIR/augmented``, the same measured
   spectra, tracks and output error; the ranking refit is reused to place the
   effect parameters' window (±max(4 sd, 10 % of the admissible range) around
   its maximum), so a small budget does not have to find the effect again;
4. checks the augmented model the same way and writes ``discrepancy.json``
   (flagged, ranking, named_effect, gap_before, gap_after, …) and the figures.

Optional attributes of ``args`` (for when the command line grows them):
``simulator`` (``pybullet`` default, or ``linear`` for the fast path
throughout) and ``budget`` (evaluations of the recalibration).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from susp_bo.cli import UsageError
from susp_bo.commands._common import output_folder
from susp_bo.json_files import json_ready, write_json


def _fit_from_result(study: Any, payload: dict[str, Any]) -> Any:
    from susp_bo.discrepancy.fitting import Fit

    bounds = np.asarray(study.bounds, dtype=np.float64)
    span = bounds[1] - bounds[0]
    sd = np.asarray(payload.get("posterior_sd") or span * 0.01, dtype=np.float64)
    return Fit(
        spec=study.spec,
        names=tuple(study.names),
        bounds=bounds,
        w=np.asarray(payload["joint_map"], dtype=np.float64),
        log_likelihood=float(payload.get("best_log_likelihood") or np.nan),
        covariance_unit=np.diag((sd / span) ** 2),
        n_evaluations=0,
    )


def _study_recalibration(study: Any, out: Path, budget: int | None, progress: bool) -> Any:
    """``recalibrate(best)``: the study loop on the augmented rig (PyBullet)."""
    from susp_bo.calibration.loop import calibrate
    from susp_bo.calibration.study import (
        STORE_NAME,
        calibration_settings,
        store_fingerprint,
        study_evaluator,
    )
    from susp_bo.discrepancy.effects import get_effect, with_effect
    from susp_bo.discrepancy.fitting import Fit
    from susp_bo.execution import make_executor
    from susp_bo.store import EvaluationStore

    def recalibrate(best: Any) -> Fit:
        effect = get_effect(best.effect)
        spec = with_effect(study.spec, best.effect, best.options, calibrate=True)
        extra = [p for p in effect.parameters if p.calibrated]
        names = tuple(study.names) + tuple(effect.parameter_name(p.key) for p in extra)
        # reuse the ranking refit: the effect's parameters are calibrated in a window of
        # ±max(4 sd, 10 % of the range) around the fast path's maximum (within the range)
        fitted = best.fit.parameters()
        sd = dict(zip(best.fit.names, best.fit.sd))
        window = []
        for p in extra:
            name = effect.parameter_name(p.key)
            half = max(4.0 * sd[name], 0.1 * (p.upper - p.lower))
            window.append((max(p.lower, fitted[name] - half), min(p.upper, fitted[name] + half)))
        bounds = np.hstack([study.bounds, np.array(window).T])
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
        print(f"susp-bo diagnose: recalibrating with {best.effect} ({names})", file=sys.stderr)
        config = study.config.executor
        with (
            EvaluationStore(folder / STORE_NAME, store_fingerprint(study, spec, names)) as store,
            make_executor(workers=config.workers, scheduler=config.scheduler) as executor,
        ):
            evaluator = study_evaluator(study, store, executor, progress, spec, names)
            result = calibrate(evaluator, bounds, names, settings, progress=progress)
        summary = result.summary.to_dict()
        span = bounds[1] - bounds[0]
        sd = np.maximum(np.asarray(summary["sd"], dtype=np.float64), 1e-9 * span)
        (folder / "result.json").write_text(
            json.dumps({"parameters": list(names), **json_ready(summary)}, indent=2) + "\n"
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

    return recalibrate


def run_diagnose(args: argparse.Namespace) -> int:
    """Run the workflow on ``args.result_dir`` and write ``discrepancy.json`` and figures."""
    from susp_bo.calibration.likelihood import OutputError, estimate_output_error
    from susp_bo.calibration.study import RESULT_NAME, StudyError, prepare_study
    from susp_bo.discrepancy.figures import write_figures
    from susp_bo.discrepancy.problem import DiagnosisProblem, LinearSimulator, make_simulator
    from susp_bo.discrepancy.workflow import WorkflowSettings, run_workflow
    from susp_bo.study_config import load_study_config

    result_dir = Path(args.result_dir)
    result_file = result_dir / RESULT_NAME
    config_file = result_dir / "study.toml"
    if not result_file.is_file() or not config_file.is_file():
        raise UsageError(
            f"RESULT_DIR: {result_dir} holds no finished calibration (need {RESULT_NAME} and "
            "study.toml, as written by susp-bo calibrate)"
        )
    kind = getattr(args, "simulator", None) or "pybullet"
    budget = getattr(args, "budget", None)
    try:
        payload = json.loads(result_file.read_text())
        config = dataclasses.replace(load_study_config(config_file), out=result_dir.resolve())
        study = prepare_study(config, resume=True)
        simulator = make_simulator(kind)
    except (StudyError, ValueError, OSError) as error:
        raise UsageError(str(error)) from error
    out = output_folder(args.out)
    metadata = study.runs[0].metadata or {}
    truth = metadata.get("truth") if isinstance(metadata.get("truth"), dict) else None
    problem = DiagnosisProblem(
        spec=study.spec,
        names=study.names,
        bounds=study.bounds,
        measured=study.measured,
        tracks=study.tracks,
        # the workflow's detection scale is σ_B per channel (unchanged for paired studies)
        error=study.error
        if isinstance(study.error, OutputError)
        else estimate_output_error(study.measured),
        noise_m_s2=study.noise_m_s2,
        reference=truth,
    )
    print(
        f"susp-bo diagnose: {len(study.runs)} runs of {study.spec.name}, checks on {kind}, "
        "ranking on the linearised rig",
        file=sys.stderr,
    )
    fast = LinearSimulator() if kind == "pybullet" else simulator
    report = run_workflow(
        problem,
        simulator,
        _fit_from_result(study, payload),
        WorkflowSettings(seed=study.config.seeds.calibration, polish_base=kind == "linear"),
        fast=fast,
        recalibrate=_study_recalibration(study, out, budget, progress=True)
        if kind == "pybullet"
        else None,
    )
    document = report.to_dict()
    document.update(result_dir=str(result_dir), rig=study.spec.name)
    write_json(out / "discrepancy.json", json_ready(document))
    write_figures(report, out)
    named = report.named_effect or "none (no significant disagreement explained)"
    print(
        f"susp-bo diagnose: {len(report.before.bands)} flagged bands; named effect: {named}; "
        f"gap {report.gap_before['value']:.3g} -> {report.gap_after['value']:.3g}; "
        f"results in {out}",
        file=sys.stderr,
    )
    return 0
