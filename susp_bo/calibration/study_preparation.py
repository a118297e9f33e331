"""Step 0 of a study: every input checked and loaded before the first simulation.

:func:`prepare_study` loads the rig, checks the calibrated parameter names, the
output folder and its store, the budget, and the measured runs against the rig's
channels and band; it computes the measured spectra, names the track stretches and
sets the output-error model B (``[output_error]``). Anything wrong raises
:class:`~susp_bo.calibration.study_inputs.StudyError` naming the field, the value and
what is allowed. :func:`store_fingerprint` is what identifies the study's evaluations
in the store (a resume on other data or another rig is refused).
"""

from __future__ import annotations

import dataclasses
import json
import tomllib
from dataclasses import dataclass

import numpy as np

from susp_bo.calibration.evaluation import TrackRun
from susp_bo.calibration.likelihood import OutputError, estimate_output_error
from susp_bo.calibration.paired_error import PairedOutputError
from susp_bo.calibration.record_window import (
    RecordWindowError,
    check_track_covers_the_speed_record,
    compared_window,
)
from susp_bo.calibration.study_inputs import (
    StudyError,
    check_budget,
    check_runs_rig,
    check_sigma_table,
    import_hint,
    measured_log_spectra,
    reference_parameters,
    run_names,
    sensor_noise,
)
from susp_bo.calibration.study_track_statistics import (
    TrackStatisticsPlan,
    check_exchangeable_runs,
    model_tracks,
    plan_for,
)
from susp_bo.calibration.track_statistics import TrackStatisticsError
from susp_bo.calibration.track_statistics_pilot import PilotRecord
from susp_bo.data.measured import MeasuredRun
from susp_bo.data.run_files import load_runs
from susp_bo.data.run_validation import record_end_s, validate_run
from susp_bo.output_folder import (
    CONFIG_NAME,
    FIGURE_NAMES,
    LOG_NAME,
    RESULT_NAME,
    SAMPLES_NAME,
    check_output_files,
    check_output_folder,
)
from susp_bo.rig.simulator import axle_span_m
from susp_bo.rig.spec import RigSpec, load_rig_spec
from susp_bo.rig.step_stability import speed_problem
from susp_bo.store_fingerprint import study_fingerprint
from susp_bo.study_config import StudyConfig

STORE_NAME = "evaluations.sqlite"
"""The study's evaluation store in its results folder."""


@dataclass(frozen=True)
class PreparedStudy:
    """Everything a study needs, checked, before any simulation runs.

    Attributes:
        config: the study config.
        spec: the rig (non-calibrated parameters fixed at the rig file's values).
        names: calibrated parameter names (q,).
        bounds: (2 x q) admissible set C_w.
        runs: the ν measured runs (channels in the rig's order).
        measured: (ν x C x F) measured log-amplitude spectra.
        tracks: the μ track stretches: the runs' own, or with ``track_statistics``
            synthetic realizations of the track process.
        error: the output error model B (paired, unpaired, or the summary likelihood:
            its plan until ``run_study`` has run the pilot, then its error).
        noise_m_s2: accelerometer noise (m/s² rms) added to simulated spectra as a floor.
        reference: (q,) true parameters when the data are synthetic, else None.
        pilot: what the summary likelihood's pilot did (None for the other models, or
            before it ran).
    """

    config: StudyConfig
    spec: RigSpec
    names: tuple[str, ...]
    bounds: np.ndarray
    runs: tuple[MeasuredRun, ...]
    measured: np.ndarray
    tracks: tuple[TrackRun, ...]
    error: OutputError | PairedOutputError | TrackStatisticsPlan | TrackStatisticsError
    noise_m_s2: float
    reference: np.ndarray | None
    pilot: PilotRecord | None = None

    @property
    def units(self) -> tuple[str, ...]:
        """(q,) units of the calibrated parameters."""
        unit = {c.name: c.unit for c in self.spec.calibration}
        return tuple(unit[name] for name in self.names)

    @property
    def frequencies_hz(self) -> np.ndarray:
        """(F,) the shared frequency grid."""
        return self.spec.spectrum.frequencies_hz()


def _output_error(
    config: StudyConfig,
    measured: np.ndarray,
    channels: tuple[str, ...],
    runs: tuple[MeasuredRun, ...] = (),
    spec: RigSpec | None = None,
    noise_m_s2: float = 0.0,
) -> OutputError | PairedOutputError:
    sigma = config.output_error.sigma
    ell = config.output_error.correlation_length_hz
    if config.output_error.model == "paired":
        if spec is None or not runs:
            raise StudyError("output_error.model: 'paired' needs the runs and the rig")
        fixed = None
        if isinstance(sigma, int | float):
            fixed = tuple(float(sigma) for _ in channels)
        elif sigma != "estimate":  # a table: its channels checked by check_sigma_table
            fixed = tuple(float(sigma[c]) for c in channels)
        return PairedOutputError(
            noise_m_s2,
            runs[0].sample_rate_hz,
            tuple(int(run.accelerations_m_s2.shape[-1]) for run in runs),
            spec.spectrum,
            fixed,
        )
    if sigma == "estimate":
        if measured.shape[0] < 2:
            raise StudyError(
                "output_error.sigma: 'estimate' needs at least 2 measured runs (found 1); "
                'give sigma as a number or a {channel = sigma} table, or model = "paired" '
                "(one run is enough when its track was measured), in the [output_error] "
                "section of a study .toml (the command line has no flag for them: see the "
                'README\'s "Scripted studies")'
            )
        estimated = estimate_output_error(measured)
        return OutputError(estimated.sigma, ell)
    if isinstance(sigma, int | float):
        return OutputError(tuple(float(sigma) for _ in channels), ell)
    return OutputError(tuple(float(sigma[c]) for c in channels), ell)  # check_sigma_table


def check_resume_budget(config: StudyConfig) -> None:
    """Refuses a resume whose budget is below the finished result's evaluations.

    A resume extends a study: with a smaller budget it would replace the folder's finished
    result (``result.json``, the draws, the figures) by one from fewer evaluations, and
    its check points, placed earlier, would cost new simulations. A folder without a
    readable result (an interrupted study) has nothing to replace.

    Raises:
        StudyError: naming --budget (``budget.max_evaluations``), the value, the finished
            result's count and what to do.
    """
    try:
        finished = json.loads((config.out / RESULT_NAME).read_text())
        done = int(finished["n_evaluations"])
    except (OSError, ValueError, TypeError, KeyError):
        return
    budget = config.budget.max_evaluations
    if budget < done:
        try:  # the budget it ran with (a study may stop before its budget, e.g. converged)
            ran = tomllib.loads((config.out / CONFIG_NAME).read_text(encoding="utf-8"))
            ran_with = int(ran["budget"]["max_evaluations"])
        except (OSError, ValueError, TypeError, KeyError):
            ran_with = None
        same = (
            f"{ran_with}, the budget it ran with, gives the same result again; any other "
            "budget changes the search and gives another result"
            if ran_with is not None and ran_with >= done
            else "a budget other than the one it ran with changes the search and gives "
            "another result"
        )
        raise StudyError(
            f"--budget (budget.max_evaluations): {budget} is below the {done} likelihood "
            f"evaluations of the finished result in {config.out / RESULT_NAME}; a resume only "
            f"extends a study: give {done} or more ({same}), or calibrate into another output "
            "folder to see what a smaller budget gives"
        )


def _slowest_speed(run: MeasuredRun) -> float:
    """The slowest speed (m/s) a simulation of ``run`` goes through: its speed profile from
    0 to the end of its accelerations (piecewise linear, so the samples and that end)."""
    end_s = record_end_s(run)
    speed = run.speed
    inside = np.asarray(speed.speed_m_s)[np.asarray(speed.time_s) <= end_s]
    return float(min(np.min(inside, initial=np.inf), float(speed.speed_at(end_s))))


def check_results_folder(config: StudyConfig, resume: bool) -> None:
    """Refuse, before any simulation, a results folder the study would spoil.

    A results file name held by a folder (found only when written, after the whole
    calibration: outside probe, session 29); a plain run beside a finished ``result.json``
    whose store is gone (it was overwritten); a resume below the finished result's
    evaluations (:func:`check_resume_budget`). Called by ``run_study`` and, for every
    campaign still to calibrate, by ``monitor`` before its first campaign runs.

    Raises:
        StudyError: naming the path and what to do; nothing is changed.
    """
    try:
        check_output_files(
            config.out, (RESULT_NAME, SAMPLES_NAME, CONFIG_NAME, LOG_NAME, *FIGURE_NAMES), "out"
        )
    except ValueError as error:
        raise StudyError(str(error)) from None
    if resume:
        check_resume_budget(config)
    elif (config.out / RESULT_NAME).exists():  # a finished result without its store
        raise StudyError(
            f"out: {config.out} already holds a result ({RESULT_NAME}) without its "
            f"{STORE_NAME}; it is left as it was: choose another output folder, or move the "
            "result away to calibrate into this one"
        )


def check_runs_have_tracks(config: StudyConfig, runs: tuple[MeasuredRun, ...]) -> None:
    """Refuse runs without track geometry under an output-error model that simulates every
    run on its own measured track (``unpaired``, ``paired``), before any simulation.

    ``track_statistics`` simulates synthetic tracks and accepts them.

    Raises:
        StudyError: naming the first run file without geometry (and how many more), what
            is missing and the two ways out.
    """
    model = config.output_error.model
    if model == "track_statistics":
        return
    names = run_names(runs, config.data)
    missing = [name for name, run in zip(names, runs) if run.geometry is None]
    if not missing:
        return
    more = (
        f" ({len(missing) - 1} more of the {len(runs)} runs "
        f"{'has' if len(missing) == 2 else 'have'} none: "
        f"{', '.join(missing[1:4])}{', …' if len(missing) > 4 else ''})"
        if len(missing) > 1
        else ""
    )
    raise StudyError(
        f"data: {config.data / missing[0]}: the run has no track geometry (its track was not "
        f"measured: no geometry/ group){more}; output_error.model = {model!r} simulates "
        "every run on its own measured track: calibrate runs on unmeasured track with "
        '[output_error] model = "track_statistics" in a study .toml (their tracks known '
        "only by their statistics), or add the measured track geometry to the run files "
        '(README, "Measured data format") (nothing was simulated)'
    )


def prepare_study(config: StudyConfig, resume: bool = False) -> PreparedStudy:
    """Check every input of a study and load its data (no simulation).

    Raises:
        StudyError: naming what is wrong (rig, parameters, data, output folder).
    """
    try:
        spec = load_rig_spec(config.rig)
        names = config.check_parameters(spec.calibration_names)
        check_output_folder(config.out, "out")
    except (FileNotFoundError, ValueError) as error:
        raise StudyError(str(error)) from error
    check_budget(config, len(names))
    check_sigma_table(config, spec)
    if config.out.resolve() == config.data.resolve():
        raise StudyError(
            f"out: {config.out} is the data folder; expected a results folder of its own (the "
            "study writes its store, results, figures and log there, and a results folder is "
            "something one deletes)"
        )
    store_path = config.out / STORE_NAME
    if store_path.exists() and not resume:
        raise StudyError(
            f"out: {config.out} already holds a study ({STORE_NAME}); resume it with --resume "
            "or choose another output folder"
        )
    if resume and not store_path.exists():
        raise StudyError(
            f"--resume: {store_path} does not exist; nothing to resume (a run stopped before "
            "it made its store left none): run without --resume"
        )
    try:
        runs = tuple(load_runs(config.data, channels=spec.channels))
        for name, run in zip(run_names(runs, config.data), runs):
            validate_run(
                run,
                spec.channels,
                spec.spectrum,
                axle_span_m=axle_span_m(spec),
                source=str(config.data / name),
            )
    except ValueError as error:
        raise StudyError(f"data: {error}{import_hint(config.data)}") from error
    check_runs_have_tracks(config, runs)
    check_runs_rig(runs, spec.name, config.data)
    slowest = {name: _slowest_speed(run) for name, run in zip(run_names(runs, config.data), runs)}
    name = min(slowest, key=slowest.__getitem__)  # the slowest run decides (probe, s. 29)
    problem = speed_problem(spec, slowest[name], speed_label=f"data: {config.data / name}")
    if problem is not None:  # every simulation of it would be refused, one by one
        raise StudyError(problem)
    noise = sensor_noise(config, runs)  # one sample rate, before the windows are compared
    files = [str(config.data / name) for name in run_names(runs, config.data)]
    try:  # the samples the simulation records, and the track it needs for them
        compared = tuple(compared_window(run, spec, file) for file, run in zip(files, runs))
        if config.output_error.model != "track_statistics":
            for file, run in zip(files, runs):
                check_track_covers_the_speed_record(run, spec, file)
    except RecordWindowError as error:
        raise StudyError(f"data: {error}") from None
    try:
        measured = measured_log_spectra(spec, compared)
    except ValueError as error:
        raise StudyError(f"data: {error}") from error
    all_names = spec.calibration_names
    columns = [all_names.index(name) for name in names]
    bounds = spec.calibration_bounds[:, columns]
    if config.output_error.model == "track_statistics":
        check_exchangeable_runs(runs, run_names(runs, config.data))
        if config.output_error.sensor_noise_m_s2 is None and any(
            "noise_m_s2" not in (run.metadata or {}) for run in runs
        ):
            raise StudyError(
                "output_error.sensor_noise_m_s2: not given, and the runs' metadata do not "
                "record it; model = 'track_statistics' draws the sensor noise into its pilot "
                "runs (its share of the summaries' covariance): give the accelerometers' "
                "noise in m/s^2 rms (0 if it is negligible)"
            )
        plan = plan_for(
            config.output_error.pilot_runs,
            len(names),
            len(runs),
            config.seeds.calibration,
            spec.simulation.track_quality,
        )
        tracks = model_tracks(runs, plan, spec)
        error: OutputError | PairedOutputError | TrackStatisticsPlan = plan
    else:
        tracks = tuple(
            TrackRun(
                f"run{index:03d}-{run.content_digest()[:16]}", run.geometry, run.speed, run.design
            )
            for index, run in enumerate(runs)
        )
        error = _output_error(config, measured, spec.channels, compared, spec, noise)
    return PreparedStudy(
        config=config,
        spec=spec,
        names=tuple(names),
        bounds=bounds,
        runs=runs,
        measured=measured,
        tracks=tracks,
        error=error,
        noise_m_s2=noise,
        reference=reference_parameters(runs, tuple(names)),
    )


def store_fingerprint(
    study: PreparedStudy, spec: RigSpec | None = None, names: tuple[str, ...] | None = None
) -> dict[str, str]:
    """What identifies the evaluations of ``study`` (or of ``spec``/``names`` on its data).

    With the summary likelihood the tracks are synthetic, so the runs' content digests are
    part of the data too (its pilot's second point is fitted to them). A run without
    geometry has a digest of its own (:meth:`MeasuredRun.content_digest`), and the
    realizations' length (:func:`.study_track_statistics.realization_length_m`) is a key of
    its own, ``realization_length_m``.

    Raises:
        ValueError: a study whose summary likelihood's pilot has run (fingerprint the study
            that ``prepare_study`` returned).
    """
    if isinstance(study.error, TrackStatisticsError):
        raise ValueError(
            "store_fingerprint: the study's pilot has run; take the fingerprint of the "
            "prepared study (its TrackStatisticsPlan)"
        )
    data = [t.track_id for t in study.tracks]
    realizations: dict[str, str] = {}
    if isinstance(study.error, TrackStatisticsPlan):
        data += [run.content_digest() for run in study.runs]
        # ids name a realization's seed, not its length: a store of session 34 (length
        # then taken from the runs' geometry) is refused, naming this key
        realizations = {"realization_length_m": repr(study.tracks[0].geometry.length_m)}
    return study_fingerprint(
        (spec or study.spec).fingerprint(),
        json.dumps(data),
        names or study.names,
        output_error=json.dumps(dataclasses.asdict(study.error)),
        output_error_model=study.config.output_error.model,
        sensor_noise_m_s2=repr(study.noise_m_s2),
        **realizations,
    )
