"""A calibration study: rig + measured runs + config -> result folder.

This is what ``susp-bo calibrate`` (and ``susp-bo demo``) runs. Everything is
checked before the first simulation (rig, parameter names, measured runs
against the rig's channels and band, the output folder and its store;
:func:`.study_preparation.prepare_study`), then:

1. the measured spectra y_exp,i (ν x C x F) and the track stretches x_j are
   taken from the runs (μ = ν: each measured run's geometry and speed is one
   track realization);
2. the output error B is set (``[output_error] model``): ``unpaired`` (default:
   eq. 4's mixture over tracks; σ_B per channel from the scatter of the measured
   spectra between runs, or fixed in the config), ``paired`` (every run has its
   own measured track, so run i is compared with h(x_i, w) only; B = the Welch
   statistics of the sensor noise + a per-channel model error, profiled or fixed,
   :mod:`susp_bo.calibration.paired_error`; opt-in, see the README) or
   ``track_statistics`` (the runs' tracks not measured: the model simulates synthetic
   realizations of the track process and compares q summaries, with weights and
   covariance from a pilot run here before the loop, :func:`with_pilot`,
   :mod:`susp_bo.calibration.study_track_statistics`);
3. the four steps run (:func:`susp_bo.calibration.loop.calibrate`) with every
   simulator evaluation going through the evaluation store and the executor (with
   ``track_statistics``, the pilot's fit of the summaries is one point of the design,
   a warm start's too, :func:`loop_start`);
4. ``result.json``, the config used, the figures and the log are written, with
   the reliability verdict (:mod:`susp_bo.calibration.reliability`) in
   ``result.json["reliability"]`` and at the end of the log (the commands print its
   sentence last).

A budget below what the q parameters need (:func:`.study_inputs.check_budget`) is refused before
any simulation unless ``budget.allow_small`` (``--allow-small-budget``) is set; then
the study runs and its verdict is ``not_trusted`` with ``budget_too_small``.

A study killed at any point is resumed with ``resume=True``: the store returns
finished evaluations bit-for-bit and the loop is deterministic, so the result
equals that of an uninterrupted run.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import sys
import time
from concurrent.futures import Executor
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np

from susp_bo import __version__
from susp_bo.calibration.basin_search import BasinSettings
from susp_bo.calibration.evaluation import LikelihoodEvaluator
from susp_bo.calibration.likelihood import (
    expected_log_likelihood_at_truth as expected_at_truth_under,
)
from susp_bo.calibration.loop import (
    CalibrationResult,
    CalibrationSettings,
    IterationReport,
    calibrate,
)
from susp_bo.calibration.paired_error import PairedOutputError
from susp_bo.calibration.study_inputs import StudyError, store_mismatch
from susp_bo.calibration.study_preparation import (
    STORE_NAME,
    PreparedStudy,
    check_results_folder,
    prepare_study,
    store_fingerprint,
)
from susp_bo.calibration.study_track_statistics import (
    TrackStatisticsPlan,
    pilot_payload,
    pilot_point,
    run_pilot,
)
from susp_bo.calibration.surrogate import SurrogateSettings
from susp_bo.calibration.track_statistics import TrackStatisticsError
from susp_bo.execution import make_executor
from susp_bo.json_files import json_ready, write_json
from susp_bo.numerics import numerics_in_effect, one_blas_thread
from susp_bo.output_folder import (
    CONFIG_NAME,
    FIGURE_NAMES,
    LOG_NAME,
    RESULT_NAME,
    SAMPLES_NAME,
)
from susp_bo.output_lock import OutputFolderBusy, hold_output_folder, refuse_if_busy
from susp_bo.rig.spec import RigSpec
from susp_bo.store import EvaluationStore, StoreFileError, StoreMismatchError
from susp_bo.study_config import StudyConfig

MAX_SAVED_SAMPLES = 20_000


def study_evaluator(
    study: PreparedStudy,
    store: EvaluationStore,
    executor: Executor,
    progress: bool = True,
    spec: RigSpec | None = None,
    names: tuple[str, ...] | None = None,
) -> LikelihoodEvaluator:
    """``evaluate(W) -> log L`` on the study's data, for its rig or an augmented ``spec``."""
    return LikelihoodEvaluator(
        spec or study.spec,
        names or study.names,
        study.tracks,
        study.measured,
        study.error,
        store,
        executor,
        study.frequencies_hz,
        progress=progress,
        noise_m_s2=study.noise_m_s2,
        sample_rate_hz=study.runs[0].sample_rate_hz,
    )


def calibration_settings(config: StudyConfig) -> CalibrationSettings:
    """The loop settings a study config asks for."""
    return CalibrationSettings(
        seed=config.seeds.calibration,
        mcmc_seed=config.seeds.mcmc,
        batch_size=config.budget.batch_size,
        max_evaluations=config.budget.max_evaluations,
        initial_design_size=config.budget.initial_design,
        check_points=config.budget.check_points,
        mcmc_chains=config.mcmc.chains,
        mcmc_warmup=config.mcmc.warmup,
        mcmc_samples=config.mcmc.draws,
        mcmc_sampler=config.mcmc.sampler,  # type: ignore[arg-type]
        allow_small_budget=config.budget.allow_small,
        local_search=config.search.local,
        basin_search=config.search.basins,
        basin=BasinSettings()
        if config.search.hunt is None
        else BasinSettings(hunt_beta=config.search.hunt),
        refine_optimism=config.search.refine_optimism,
        kernel_switch=config.search.kernel_switch,
        surrogate=SurrogateSettings(kernel=config.search.kernel),  # type: ignore[arg-type]
    )


def config_as_run(config: StudyConfig) -> StudyConfig:
    """``config`` with ``[search] hunt`` written out as the run uses it: omitted, the
    default β (:class:`BasinSettings`) where the hunt can run (``basins = true``, ``local
    = false``) and 0 where it cannot. The results folder's ``study.toml`` then records the
    β its run used, whatever a later default becomes."""
    if config.search.hunt is not None:
        return config
    settings = calibration_settings(config)
    runs = settings.basin_search and settings.global_fixed_noise_search(settings.local_search)
    hunt = settings.basin.hunt_beta if runs else 0.0
    return dataclasses.replace(config, search=dataclasses.replace(config.search, hunt=hunt))


def expected_log_likelihood_at_truth(study: PreparedStudy) -> tuple[float, float] | None:
    """(mean, sd) of log L at the true parameters expected under the output-error model B.

    At the truth the residuals y_i − h(x_i, w) are draws of B, so this expectation needs
    B only, not the truth itself: it applies to measured data too. None until the
    output-error model provides it (wire it here); the verdict then also checks the best
    log L against it (``below_expected_fit``). None when the model cannot give it (no
    sensor noise with the paired model).
    """
    mean, sd = expected_at_truth_under(study.error, study.measured, study.frequencies_hz)
    if not (math.isfinite(mean) and math.isfinite(sd)):
        return None
    return float(mean), float(sd)


def _say(log: logging.Logger, line: str, progress: bool) -> None:
    """``line`` in the study's log, and on stderr with ``progress``."""
    log.info(line)
    if progress:
        print(line, file=sys.stderr)


def with_pilot(
    study: PreparedStudy, evaluator: LikelihoodEvaluator, log: logging.Logger, progress: bool
) -> PreparedStudy:
    """``study`` with the summary likelihood's error from its pilot (run, or replayed from
    the store), set on ``evaluator`` too (:mod:`.study_track_statistics`).

    Raises:
        StudyError: the pilot failed (:func:`.study_track_statistics.run_pilot`).
    """
    plan = study.error
    assert isinstance(plan, TrackStatisticsPlan)
    line = (
        f"summary likelihood (tracks known only by their statistics): pilot of 2 x "
        f"{plan.pilot_runs} runs on fresh track realizations and a fit of the "
        f"{len(study.names)} summaries on {plan.n_simulated} model tracks, outside the budget"
    )
    _say(log, line, progress)
    error, record = run_pilot(
        plan,
        study.runs,
        study.measured,
        study.bounds,
        evaluator,
        study.spec,
        study.noise_m_s2,
    )
    evaluator.error = error
    line = (
        f"pilot done: {record.simulations} simulator runs, second stage at the first fit "
        f"({'converged' if record.converged else 'not converged after its iterations'}), "
        f"Ledoit-Wolf shrinkage {record.shrinkage:.2f}"
    )
    _say(log, line, progress)
    return dataclasses.replace(study, error=error, pilot=record)


def pilot_start(study: PreparedStudy) -> np.ndarray | None:
    """(1 x q) the pilot's fit of the summaries (physical units), evaluated in the loop's
    design in place of one space-filling point; None without a pilot.

    The fit solves the q summary equations, so it sits in the summary likelihood's basin
    when the pilot's Gauss–Newton fit found it; a space-filling design of ~2q + 1 points
    can miss a narrow basin, and the search then settles elsewhere (session 34: the
    yaw damper at its lower bound, 4.1 nats below the truth's log L, on the demo's rig).
    Determined by the pilot's stored runs, so a resume replays it.
    """
    return None if study.pilot is None else pilot_point(study.pilot, study.bounds)[None, :]


def loop_start(
    study: PreparedStudy, design: np.ndarray | None
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``(design, initial_points)`` for :func:`.loop.calibrate`: the pilot's fit
    (:func:`pilot_start`) in place of one space-filling point, or, when a ``design`` is
    given (a monitoring campaign's warm start, centred on the previous posterior), as one
    more point after it (session 36: a part that changed more than the warm design's box
    allows is still in the summaries' basin). Without a pilot, ``(design, None)``."""
    start = pilot_start(study)
    if design is None or start is None:
        return design, start
    return np.vstack([np.asarray(design, dtype=np.float64), start]), None


def _logger(out: Path) -> logging.Logger:
    logger = logging.getLogger(f"susp_bo.study.{out.resolve()}")
    logger.setLevel(logging.INFO)
    logger.propagate = False
    if not logger.handlers:
        handler = logging.FileHandler(out / LOG_NAME)
        handler.setFormatter(logging.Formatter("%(asctime)s %(message)s"))
        logger.addHandler(handler)
    return logger


def output_error_payload(study: PreparedStudy) -> dict[str, Any]:
    """``result.json`` ``output_error``: which model B is, and its values.

    ``model`` is ``paired``, ``unpaired`` or ``track_statistics``; ``sigma`` is σ_B per
    channel (unpaired) or the fixed model-error sd τ_c (paired; None = profiled at every w);
    the summary likelihood records its pilot instead
    (:func:`.study_track_statistics.pilot_payload`).
    """
    error = study.error
    if isinstance(error, TrackStatisticsError):
        pilot = (
            {}
            if study.pilot is None
            else pilot_payload(error, study.pilot, study.bounds, study.names)
        )
        return {
            "model": "track_statistics",
            "channels": list(study.spec.channels),
            "sigma": None,
            "correlation_length_hz": None,
            "sensor_noise_m_s2": study.noise_m_s2,
            "simulated_tracks": int(error.n_simulated),
            "track_quality": study.spec.simulation.track_quality,
            **pilot,
        }
    if isinstance(error, TrackStatisticsPlan):
        raise ValueError("output_error_payload: the summary likelihood's pilot has not run")
    if isinstance(error, PairedOutputError):
        return {
            "model": "paired",
            "channels": list(study.spec.channels),
            "sigma": None if error.model_error_sigma is None else list(error.model_error_sigma),
            "model_error": "profiled" if error.model_error_sigma is None else "fixed",
            "sensor_noise": "welch",
            "correlation_length_hz": None,
            "sensor_noise_m_s2": study.noise_m_s2,
        }
    return {
        "model": "unpaired",
        "channels": list(study.spec.channels),
        "sigma": list(error.sigma),
        "correlation_length_hz": error.correlation_length_hz,
        "sensor_noise_m_s2": study.noise_m_s2,
    }


def result_payload(
    study: PreparedStudy,
    result: CalibrationResult,
    n_simulations: int,
    wall_time_s: float,
) -> dict[str, Any]:
    """The ``result.json`` content (DESIGN.md fields plus context), physical units."""
    payload: dict[str, Any] = {
        "parameters": list(study.names),
        "units": list(study.units),
        **result.to_dict(),  # the calibration's keys, after the names and their units
        "n_simulations": int(n_simulations),
        "reference": None if study.reference is None else study.reference.tolist(),
        "output_error": output_error_payload(study),
        "rig": study.spec.name,
        "data": str(study.config.data),
        "nu": len(study.runs),
        "mu": len(study.tracks),
        "seed": study.config.seeds.calibration,
        "wall_time_s": wall_time_s,
        "version": __version__,
        "numerics": numerics_in_effect(),
    }
    return payload


@one_blas_thread()  # main-process BLAS (log L, surrogate, chains) core-count independent
def run_study(
    config: StudyConfig,
    resume: bool = False,
    progress: bool = True,
    *,
    design: np.ndarray | None = None,
    design_note: dict[str, Any] | None = None,
    local_after_design: bool = False,
) -> tuple[dict[str, Any], CalibrationResult]:
    """Run (or resume) a calibration study and write its results folder.

    Args:
        config: the study config.
        resume: reuse the evaluation store of an interrupted run in ``config.out``.
        progress: progress bars (susp_bo.progress) and one-line iteration summaries on stderr.
        design: (n0 x q) initial design in physical units instead of the space-filling one
            (a warm start, :mod:`susp_bo.monitoring.warm_start`); a resume must pass the
            same design to replay the store.
        design_note: where ``design`` came from, written to ``result.json`` as
            ``warm_start`` (the key is absent after a cold start).
        local_after_design: with ``[search] local``, go to the local phase right after
            the design (no global EGO batches: ``max_ego_fraction = 0``) — for a design
            that already sits at the optimum's basin (a warm start).

    Returns:
        The ``result.json`` payload and the calibration result.

    Raises:
        StudyError: bad inputs, before any simulation.
    """
    try:  # first: a second run into a busy folder is told so, not to --resume into it
        refuse_if_busy(config.out)
    except OutputFolderBusy as error:
        raise StudyError(str(error)) from None
    study = prepare_study(config, resume=resume)
    check_results_folder(config, resume)
    out = config.out
    # a store without its study (emptied, or killed while being made) is started afresh
    # only when no result lies beside it that it would then seem to vouch for
    create = not resume or not any((out / n).exists() for n in (RESULT_NAME, SAMPLES_NAME))
    with ExitStack() as held:  # the folder lock: to the last file written
        with ExitStack() as stack:
            # the executor first: a scheduler that cannot be reached leaves the folder untouched
            executor = stack.enter_context(
                make_executor(workers=config.executor.workers, scheduler=config.executor.scheduler)
            )
            try:
                out.mkdir(parents=True, exist_ok=True)
            except OSError as error:  # e.g. under /proc, or no permission
                raise StudyError(
                    f"out: {str(out)!r} cannot be created ({error.strerror or error}); expected a "
                    "folder that exists or can be created, and can be written in"
                ) from None
            try:  # before anything is written: a refused resume leaves the folder as it was
                store = stack.enter_context(
                    EvaluationStore(out / STORE_NAME, store_fingerprint(study), create=create)
                )
            except StoreMismatchError as error:
                raise store_mismatch(out, error) from None
            except StoreFileError as error:
                raise StudyError(
                    f"out: {error}; it is left as it was: move it away to start this study afresh "
                    "(its evaluations cannot be read back), or choose another output folder"
                ) from None
            try:  # one writer per folder, from here to the last file written
                held.enter_context(hold_output_folder(out))
            except OutputFolderBusy as error:
                raise StudyError(str(error)) from None
            (out / CONFIG_NAME).write_text(config_as_run(config).with_absolute_paths().to_toml())
            log = _logger(out)
            log.info(
                "study %s: rig %s, %d runs, parameters %s",
                out,
                study.spec.name,
                len(study.runs),
                study.names,
            )
            stored = store.count()
            if resume and stored:
                line = (
                    f"resuming: {stored} simulator run(s) stored in {STORE_NAME} are reused, not "
                    "rerun (the log L evaluations below count from 0 and pass them quickly)"
                )
                _say(log, line, progress)
            started = time.perf_counter()
            evaluator = study_evaluator(study, store, executor, progress=progress)
            if isinstance(study.error, TrackStatisticsPlan):
                study = with_pilot(study, evaluator, log, progress)

            def report(item: IterationReport) -> None:
                line = (
                    f"iteration {item.iteration} [{item.phase}]: "
                    f"best log L {item.best_log_likelihood:.3f}, {item.criterion_text()}, "
                    f"evaluations {item.n_evaluations}, simulator runs {evaluator.simulations_run} "
                    f"(+{evaluator.simulations_reused} reused)"
                )
                _say(log, line, progress)

            settings = calibration_settings(config)
            if local_after_design and settings.local_search:
                settings = dataclasses.replace(settings, max_ego_fraction=0.0)
            start_design, start_points = loop_start(study, design)
            if design is not None and start_design is not design:  # the pilot's fit appended
                design_note = dict(design_note or {}) | {
                    "design_points": int(start_design.shape[0]),
                    "pilot_point_appended": True,
                }
            result = calibrate(
                evaluator,
                study.bounds,
                study.names,
                settings,
                progress=progress,
                on_iteration=report,
                expected_at_truth=expected_log_likelihood_at_truth(study),
                design=start_design,
                initial_points=start_points,
            )
            # calibrate weighs the lack of fit between the runs (the evaluator exposes the
            # spectra and the measured runs); its Gauss–Newton points (if any) are stored
            # simulations too: counted after them, a resumed study reports what an
            # uninterrupted one does
            n_simulations = store.count()
            if result.reliability is not None:  # a study's advice: its flags and keys
                result = dataclasses.replace(
                    result, reliability=result.reliability.worded_for("command_line")
                )
        if result.check is not None:
            line = result.check.line()
            if result.check.verdict != "ok":
                line += (
                    " — the posterior may be misshapen; rerun with a larger budget"
                    " (susp-bo calibrate ... --resume --budget N: the design and the early"
                    " iterations come from the store, not the simulator)"
                )
            _say(log, line, progress)
        payload = json_ready(
            result_payload(study, result, n_simulations, time.perf_counter() - started)
            | ({"warm_start": design_note or {}} if design is not None else {})
        )
        # a resume replaces a finished result: the old one goes first, so that a run killed
        # while writing leaves an unfinished folder (resume it), never a result.json beside
        # draws or figures of another run (figures titled with another verdict)
        for name in (RESULT_NAME, *FIGURE_NAMES):
            (out / name).unlink(missing_ok=True)
        save_samples(out / SAMPLES_NAME, result.samples)  # before result.json: "finished" = both
        write_json(out / RESULT_NAME, payload)
        write_figures(study, result, out)
        log.info("result written: %s", out / RESULT_NAME)
        if result.reliability is not None:  # the commands print it last, under their summary
            log.info("reliability: %s", result.reliability.sentence)
    return payload, result


def save_samples(path: Path, samples: np.ndarray, limit: int = MAX_SAVED_SAMPLES) -> Path:
    """Posterior draws (n x q, physical units, calibration order), thinned to at most ``limit``.

    The pooled draws are thinned with a regular stride (every chain contributes), so
    probabilities computed from the file (e.g. P(outside an acceptable domain) in
    :mod:`susp_bo.monitoring`) carry a Monte Carlo error of about
    sqrt(p (1 - p) / n_eff). Written atomically (temp file then rename).
    """
    samples = np.asarray(samples, dtype=np.float64)
    stride = max(1, -(-samples.shape[0] // limit))
    temporary = path.with_name(path.name + ".tmp.npy")
    np.save(temporary, np.ascontiguousarray(samples[::stride]))
    temporary.replace(path)
    return path


def write_figures(study: PreparedStudy, result: CalibrationResult, out: Path) -> list[Path]:
    """The paper's Fig. 1 and Fig. 2 and a pair plot, as PNG files in ``out``.

    The acceptable bands (rig spec, optional) and the reliability verdict (when the result
    carries one) are drawn on them.
    """
    from susp_bo import plots

    band = {c.name: getattr(c, "acceptable", None) for c in study.spec.calibration}
    reliability = getattr(result, "reliability", None)
    if reliability is not None and hasattr(reliability, "to_dict"):
        reliability = reliability.to_dict()
    return plots.posterior_figures(
        result.summary,
        result.samples,
        study.bounds,
        out,
        study.reference,
        study.units,
        acceptable=plots.acceptable_bands([band.get(name) for name in study.names]),
        reliability=reliability,
    )
