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
   output-error model expects at the true parameters) or ``runs_not_reproduced``
   (residuals as large as the scatter between tracks), possibly with ``at_bound``
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

Step 3, the recalibration with the named effect, is
:mod:`susp_bo.commands.diagnose_recalibration`.
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

# ``name as name``: re-exported, importable from susp_bo.commands.diagnose as before the split.
from susp_bo.commands.diagnose_recalibration import _study_recalibration
from susp_bo.commands.diagnose_recalibration import (
    augmented_result_payload as augmented_result_payload,
)
from susp_bo.commands.diagnose_recalibration import refit_window as refit_window
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
    if config.output_error.model == "track_statistics":
        raise UsageError(
            f"RESULT_DIR: {result_dir} was calibrated with [output_error] model = "
            "'track_statistics' (the runs' tracks not measured); diagnose compares each run "
            "with the simulation on its own measured track, band by band, which such a study "
            "does not have: a model error shows there as the test of the summaries the fit "
            "does not use (result.json reliability evidence summary_misfit_p, and "
            "summary_misfit_worst: the channel and frequency range where the data and the "
            "model disagree most), the lack of fit between the runs (lack_of_fit_ratio) or "
            "parameters at C_w's bounds (at_bound); measure the tracks and calibrate with "
            "model = 'paired' to diagnose (nothing was computed)"
        )
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
            "true parameters, or residuals every run shares; or runs_not_reproduced: "
            "residuals as large as the scatter between tracks): looking for what is missing"
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
    if len(reasons) == 1 and (
        "lack_of_fit_ratio" in reasons[0] or "track_match_ratio" in reasons[0]
    ):
        return (
            f" The augmented model's calibration is NOT trusted ({reasons[0].get('code')}: "
            f"{reasons[0].get('message', '')}): the named effect does not explain all of "
            "the disagreement, and its parameter values are not an answer."
        )
    return (
        f" The augmented model's calibration is NOT trusted ({codes or 'no verdict'}): "
        "its parameter values are not an answer; diagnose again with a larger --budget."
    )
