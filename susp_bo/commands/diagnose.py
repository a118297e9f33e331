"""``susp-bo diagnose RESULT_DIR --out DIR``: the model-discrepancy workflow on a calibration.

0. reads the calibration's reliability verdict (``result.json["reliability"]``,
   the shared contract). Not ``trusted`` (or absent: a result from an older
   version) → ``verdict: "calibration_not_trusted"`` with the calibration's
   reasons and what to do (a larger budget, ``--resume``), no band reported as
   model discrepancy, exit code 0 and the sentence on stderr: the residuals of an
   unfinished fit are not missing physics. ``--force`` runs the workflow anyway;
   its findings are then kept under ``forced_diagnosis`` and
   ``residual_bands_untrusted_fit``, never as the answer. One exception: a
   calibration not trusted only because of ``below_expected_fit`` (the loop
   finished by its own criteria, but its best log L is far below what the
   output-error model expects at the true parameters), possibly with ``at_bound``
   (parameters pushed to C_w's bounds to make up for the missing physics), is a
   finished fit that misses the data — what this workflow is for — so it
   proceeds, and says so (``calibration_reliability.fit_finished``). The study file
   (``RESULT_DIR/study.toml``) is read first in either case: the not-trusted answer is
   to resume it, so a study file that does not load (not TOML, a rig or data folder that
   is gone) is refused naming it (exit code 2) rather than answered with a ``--resume``
   that cannot run.

Then, on a finished calibration, reads the study of ``RESULT_DIR`` (``study.toml``,
the measured runs it names) and (:mod:`susp_bo.discrepancy.workflow`):

1. checks the calibrated model — posterior draws (joint MAP plus Gaussian draws
   with the posterior sd) re-simulated with the study's simulator (PyBullet) on
   every measured track — and flags bands (BH at q = 0.05);
2. ranks the candidate effects by refit evidence on the linearised rig (fast
   path; base and every candidate refitted on it, so its own model error
   cancels in the comparison) and applies the naming rule
   (:mod:`susp_bo.discrepancy.verdict`): named, or unexplained disagreement;
3. recalibrates the rig with the named effect switched on and its parameters
   appended to C_w, with the study's own loop (design, kriging, EGO, MCMC) and
   budget, a new evaluation store in ``DIR/augmented``, the same measured
   spectra, tracks and output error, **warm-started from the ranking's refit**:
   every parameter is calibrated in a window around the refit (base parameters
   ±max(4 sd, 15 % of the range), effect parameters ±max(4 sd, 10 %), within C_w;
   the base parameters' window also reaches the base calibration's MAP, since the
   ranking's linearised rig can misplace a base parameter) and the refit itself
   and the base MAP with the refit's effect parameters are points of the design;
4. checks the augmented model the same way and accepts it only if it beats the
   base model over all bins (:func:`~susp_bo.discrepancy.verdict.accept_augmented`);
   the recalibration's own verdict (``augmented_reliability``; with the same log L
   expected at the truth, which needs the data and B only) says whether the
   augmented model now reproduces the data as B expects;
   writes ``discrepancy.json`` (verdict, flagged, ranking, named_effect, gap_before,
   gap_after, …) and the figures, and the verdict's sentence on stderr.

Optional attributes of ``args``: ``simulator`` (``pybullet`` default, or
``linear`` for the fast path throughout), ``budget`` (evaluations of the
recalibration) and ``force``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from susp_bo import __version__
from susp_bo.cli import UsageError
from susp_bo.commands._common import output_folder
from susp_bo.json_files import json_ready, write_json
from susp_bo.output_folder import CONFIG_NAME, RESULT_NAME

DOCUMENT_NAME = "discrepancy.json"


def _result_vector(payload: dict[str, Any], key: str, study: Any, result_file: Path) -> Any:
    """``payload[key]`` as (q,) float64: q finite numbers, inside C_w for the joint MAP,
    positive for the posterior sd (absent sd: None).

    Raises:
        UsageError: naming the file, the key, the value and what is allowed.
    """
    bounds = np.asarray(study.bounds, dtype=np.float64)
    q = bounds.shape[1]
    value = payload.get(key)
    if value is None and key == "posterior_sd":
        return None
    allowed = (
        f"{q} finite numbers inside the admissible intervals of {list(study.names)}"
        if key == "joint_map"
        else f"{q} finite numbers > 0"
    )
    try:
        vector = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        vector = np.full(0, np.nan)
    good = vector.shape == (q,) and bool(np.all(np.isfinite(vector)))
    if good and key == "joint_map":
        good = bool(np.all((bounds[0] <= vector) & (vector <= bounds[1])))
    if good and key == "posterior_sd":
        good = bool(np.all(vector > 0))
    if not good:
        raise UsageError(
            f"RESULT_DIR: {result_file}: {key} = {value!r} is not allowed; expected {allowed} "
            "(as susp-bo calibrate writes it); recalibrate, or restore the file"
        )
    return vector


def _fit_from_result(study: Any, payload: dict[str, Any], result_file: Path) -> Any:
    """The base calibration's point and spread (from ``result.json``) as the workflow's Fit.

    Raises:
        UsageError: a joint MAP or posterior sd that is missing or malformed.
    """
    from susp_bo.discrepancy.fitting import Fit

    bounds = np.asarray(study.bounds, dtype=np.float64)
    span = bounds[1] - bounds[0]
    w = _result_vector(payload, "joint_map", study, result_file)
    sd = _result_vector(payload, "posterior_sd", study, result_file)
    sd = span * 0.01 if sd is None else sd
    return Fit(
        spec=study.spec,
        names=tuple(study.names),
        bounds=bounds,
        w=w,
        log_likelihood=float(payload.get("best_log_likelihood") or np.nan),
        covariance_unit=np.diag((sd / span) ** 2),
        n_evaluations=0,
    )


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
    (:func:`_fit_from_result`), whose MAP widens the window and is a second start. Each
    call appends the recalibration's own reliability verdict (a dict, or None) to
    ``verdicts``."""
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


def _not_trusted_document(
    reliability: Any, result_dir: Path, payload: dict[str, Any], rig: str | None
) -> dict[str, Any]:
    """``discrepancy.json`` of a calibration that is not trusted (no detection run)."""
    from susp_bo.discrepancy.verdict import not_trusted_sentence

    sentence = not_trusted_sentence(reliability, str(result_dir), payload.get("n_evaluations"))
    return {
        "verdict": "calibration_not_trusted",
        "sentence": sentence,
        "calibration_reliability": reliability.to_dict(),
        "flagged": [],
        "ranking": [],
        "named_effect": None,
        "gap_before": None,
        "gap_after": None,
        "residual_bands_untrusted_fit": None,
        "forced": False,
        "result_dir": str(result_dir),
        "rig": rig,
    }


def run_diagnose(args: argparse.Namespace) -> int:
    """Run the workflow on ``args.result_dir`` and write ``discrepancy.json`` and figures."""
    if not args.result_dir:  # Path("") is the current folder: never what was meant
        raise UsageError(
            "RESULT_DIR: '' is not allowed (empty); expected the results folder of a "
            f"calibration ({RESULT_NAME} and {CONFIG_NAME}, as written by susp-bo calibrate)"
        )
    result_dir = Path(args.result_dir)
    result_file = result_dir / RESULT_NAME
    config_file = result_dir / CONFIG_NAME
    if not result_file.is_file() or not config_file.is_file():  # before torch is loaded
        raise UsageError(
            f"RESULT_DIR: {result_dir} holds no finished calibration (need {RESULT_NAME} and "
            f"{CONFIG_NAME}, as written by susp-bo calibrate)"
        )
    from susp_bo.calibration.likelihood import OutputError, estimate_output_error
    from susp_bo.calibration.study_inputs import StudyError
    from susp_bo.calibration.study_preparation import STORE_NAME, prepare_study
    from susp_bo.discrepancy.figures import write_figures
    from susp_bo.discrepancy.problem import (
        DiagnosisProblem,
        LinearSimulator,
        linear_model_problem,
        make_simulator,
    )
    from susp_bo.discrepancy.verdict import calibration_reliability
    from susp_bo.discrepancy.workflow import WorkflowSettings, run_workflow
    from susp_bo.monitoring.campaign_results import CampaignResultError, check_campaign_store
    from susp_bo.study_config import load_study_config

    kind = getattr(args, "simulator", None) or "pybullet"
    budget = getattr(args, "budget", None)
    force = bool(getattr(args, "force", False))
    if budget is not None and budget < 2:
        raise UsageError(f"--budget: got {budget}; expected an integer >= 2 evaluations")
    if budget is not None and kind == "linear":  # else silently ignored
        raise UsageError(
            f"--budget: got {budget} with --simulator linear, where the augmented model is "
            "the ranking's least-squares refit and nothing is recalibrated; --budget is the "
            "recalibration's evaluations with --simulator pybullet (the default): drop one "
            "of the two"
        )
    if args.out and (Path(args.out) / DOCUMENT_NAME).exists():
        # the recalibration's store and result would be replaced: never silently
        raise UsageError(
            f"--out: {args.out} already holds a diagnosis ({DOCUMENT_NAME}); give another "
            "--out, or move that folder away to diagnose again (nothing was changed)"
        )
    try:
        payload = json.loads(result_file.read_text())
    except (ValueError, OSError) as error:
        raise UsageError(f"RESULT_DIR: {result_file} is not readable JSON ({error})") from error
    if not isinstance(payload, dict):
        raise UsageError(f"RESULT_DIR: {result_file} holds no JSON object")
    try:  # also when not trusted: the answer then is `calibrate <study.toml> --resume`
        config = dataclasses.replace(load_study_config(config_file), out=result_dir.resolve())
    except (ValueError, OSError) as error:
        raise UsageError(
            f"RESULT_DIR: {error}; diagnose (and resuming the calibration) needs this study "
            "file as susp-bo calibrate wrote it, and what it names: restore it"
        ) from error
    reliability = calibration_reliability(payload)
    if not reliability.fit_finished and not force:
        out = output_folder(args.out)
        document = _not_trusted_document(reliability, result_dir, payload, payload.get("rig"))
        write_json(out / DOCUMENT_NAME, json_ready(document))
        print(f"susp-bo diagnose: {document['sentence']}", file=sys.stderr)
        return 0
    store = result_dir / STORE_NAME
    if not store.is_file():  # prepare_study's "--resume" wording is calibrate's, not ours
        raise UsageError(
            f"RESULT_DIR: {store} does not exist; diagnose reads the study's simulations from "
            "its evaluation store: give the results folder of a susp-bo calibrate run, with its "
            "evaluations.sqlite (nothing was computed)"
        )
    try:
        study = prepare_study(config, resume=True)
        simulator = make_simulator(kind)
    except (StudyError, ValueError, OSError) as error:
        raise UsageError(str(error)) from error
    problems = [p for p in (linear_model_problem(t) for t in study.tracks) if p]
    if problems:  # the ranking refits run on the linearised rig: tangent track, one speed
        raise UsageError(
            f"RESULT_DIR: {problems[0]}"
            + (f" (and {len(problems) - 1} more runs)" if len(problems) > 1 else "")
            + "; diagnose ranks the library's effects on the linearised rig, so it diagnoses "
            "runs on tangent track at a steady speed only (nothing was computed)"
        )
    try:  # the calibration must be of the data now in its folder (as calibrate --resume)
        check_campaign_store(study, finished=True, campaign_folder=study.config.data)
    except CampaignResultError as error:
        raise UsageError(
            f"RESULT_DIR: {error}. diagnose reads a calibration only against the data it "
            "was computed on: a disagreement with other data is not a model discrepancy"
        ) from None
    base_fit = _fit_from_result(study, payload, result_file)  # checked before --out is made
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
        "ranking on the linearised rig"
        + ("; FORCED on a calibration that is not trusted" if not reliability.fit_finished else "")
        + (
            "; the calibration finished but does not reproduce the data as an exact model "
            "would (below_expected_fit: a fit worse than its output-error model expects at the "
            "true parameters, or residuals every run shares): looking for what is missing"
            if reliability.fit_finished and not reliability.trusted
            else ""
        ),
        file=sys.stderr,
    )
    fast = LinearSimulator() if kind == "pybullet" else simulator
    recalibrate, verdicts = (
        _study_recalibration(study, out, budget, progress=True, base=base_fit)
        if kind == "pybullet"
        else (None, [])
    )
    report = run_workflow(
        problem,
        simulator,
        base_fit,
        WorkflowSettings(seed=study.config.seeds.calibration, polish_base=kind == "linear"),
        fast=fast,
        recalibrate=recalibrate,
    )
    document = report.to_dict()
    document.update(result_dir=str(result_dir), rig=study.spec.name)
    if verdicts:  # the model recalibrated by this run: its own reliability verdict
        document["augmented_reliability"] = verdicts[-1]
    document["calibration_reliability"] = reliability.to_dict()
    if not reliability.fit_finished:  # --force: findings kept aside, labelled, never the answer
        forced = document
        document = _not_trusted_document(reliability, result_dir, payload, study.spec.name)
        document.update(
            forced=True,
            residual_bands_untrusted_fit=forced["flagged"],
            forced_diagnosis=forced,
            sentence=document["sentence"] + " FORCED: the workflow ran anyway; what it "
            f"would say on this unfinished fit is under forced_diagnosis ({forced['verdict']}: "
            f"{len(forced['flagged'])} residual bands), not a model-discrepancy finding.",
        )
    document["sentence"] += augmented_model_note(
        report.verdict,
        report.answer_model,
        verdicts[-1] if verdicts else None,
        fit_finished=reliability.fit_finished,
    )
    write_json(out / DOCUMENT_NAME, json_ready(document))
    forced_note = (
        ""
        if reliability.fit_finished
        else "FORCED on a calibration that is not trusted: not a model-discrepancy finding"
    )
    write_figures(report, out, forced_note)
    print(f"susp-bo diagnose: {document['sentence']}", file=sys.stderr)
    g0, g1 = report.gap_before, report.gap_after
    if report.verdict == "named" and reliability.fit_finished:
        print(
            f"susp-bo diagnose: gap on the bins flagged before {g0['value']:.3g} -> "
            f"{g1['value']:.3g}; on all bins {g0['value_all_bins']:.3g} -> "
            f"{g1['value_all_bins']:.3g}; answer: {report.answer_model} model",
            file=sys.stderr,
        )
    print(f"susp-bo diagnose: results in {out}", file=sys.stderr)
    return 0


def augmented_model_note(
    verdict: str, answer_model: str, augmented_verdict: object, *, fit_finished: bool
) -> str:
    """What the diagnosis sentence adds when the effect is named but the model recalibrated
    with it is not ``trusted``: its parameter values are then no answer.

    Args:
        verdict: the workflow's verdict (``"named"``, ``"unexplained"``, …).
        answer_model: which model's values answer (``"augmented"`` or ``"base"``).
        augmented_verdict: the recalibrated model's ``reliability`` dict, or None.
        fit_finished: the diagnosed calibration was trusted (not ``--force``).

    Returns:
        ``""`` when nothing is to be added, else a sentence that starts with a space. A
        verdict refused by the lack of fit alone (the runs share a residual no change of
        the parameters removes, after the Gauss–Newton steps: a finished fit that still
        misses the data, so more budget is no remedy) says that the named effect does not
        explain all of the disagreement; any other refusal asks for a larger ``--budget``.
    """
    if not (
        verdict == "named"
        and answer_model == "augmented"
        and isinstance(augmented_verdict, dict)
        and augmented_verdict.get("verdict") != "trusted"
        and fit_finished
    ):
        return ""
    reasons = augmented_verdict.get("reasons", []) or []
    codes = ", ".join(str(r.get("code")) for r in reasons)
    if len(reasons) == 1 and "lack_of_fit_ratio" in reasons[0]:
        return (
            " The augmented model's calibration is NOT trusted (below_expected_fit: "
            f"{reasons[0].get('message', '')}): the named effect does not explain all of "
            "the disagreement, and its parameter values are not an answer."
        )
    return (
        f" The augmented model's calibration is NOT trusted ({codes or 'no verdict'}): "
        "its parameter values are not an answer; diagnose again with a larger --budget."
    )
