"""A study on tracks known only by their statistics (``[output_error] model = "track_statistics"``).

The measured runs went over track stretches that were not measured (their run files may
omit the geometry, and any geometry they hold is not used): only the track process is
known, the rig's ``simulation.track_quality`` PSD
(:meth:`~susp_bo.rig.track.TrackGeometry.synthetic`). The study then

1. simulates every w on μ = ν synthetic realizations of that process
   (:func:`model_tracks`: fixed, seeded by ``seeds.calibration``, under the runs' speed
   profile and line design, as long as :func:`realization_length_m` says — from the
   speed record and the rig, never from a geometry —; the runs must share them and
   their record, :func:`check_exchangeable_runs`);
2. before the calibration, runs the summary likelihood's two-stage pilot
   (:mod:`.track_statistics_pilot`): M runs at the middle of C_w on fresh realizations
   with drawn sensor noise (:func:`~susp_bo.calibration.evaluation.simulate_noisy_spectra`),
   a Gauss–Newton fit of the q
   summaries on the model tracks, then M runs again at that fit (:func:`run_pilot`);
3. calibrates with the resulting :class:`~.track_statistics.TrackStatisticsError`.

Every pilot run and every model-track run goes through the study's store and executor
(keyed by the pilot point and the run's track id, which names its stage, index and seed),
so a resumed study replays the pilot from the store bit for bit and reaches the same error.
The pilot's simulations are outside the budget; ``result.json["output_error"]`` records
them (:func:`pilot_payload`: the distinct simulator runs it needed).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from susp_bo.calibration.evaluation import (
    LikelihoodEvaluator,
    TrackRun,
    simulate_noisy_spectra,
)
from susp_bo.calibration.record_window import simulated_track_m
from susp_bo.calibration.study_inputs import StudyError
from susp_bo.calibration.summary_misfit import group_labels
from susp_bo.calibration.track_statistics import TrackStatisticsError, minimum_pilot_runs
from susp_bo.calibration.track_statistics_pilot import PILOT_RUNS, PilotRecord, two_stage_error
from susp_bo.data.measured import MeasuredRun
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.track import TrackGeometry

MODEL_TRACKS_TAG = 7001
"""Mixed into the seed of the model's track realizations."""
PILOT_TRACKS_TAG = 7002
"""Mixed into the seeds of the pilot's track realizations and sensor noise."""
REALIZATION_MARGIN_M = 10.0
"""Track (m) a realization has beyond what the simulation reaches: the spare of
:func:`susp_bo.rig.simulator.synthetic_track_length_m`, which made the synthetic runs."""


@dataclass(frozen=True)
class TrackStatisticsPlan:
    """The summary likelihood before its pilot has run: what the pilot will do.

    A prepared study holds it as its output error (the store's fingerprint records it);
    :func:`run_pilot` turns it into the :class:`~.track_statistics.TrackStatisticsError`.

    Attributes:
        pilot_runs: M runs per stage.
        n_measured: ν.
        n_simulated: μ.
        seed: the seed of the model's and the pilot's track realizations.
        track_quality: the PSD the realizations are drawn from.
    """

    pilot_runs: int
    n_measured: int
    n_simulated: int
    seed: int
    track_quality: str
    model: str = field(default="track_statistics", init=False)


def plan_for(
    pilot_runs: int | None,
    q: int,
    n_measured: int,
    seed: int,
    track_quality: str,
) -> TrackStatisticsPlan:
    """The plan a study's ``[output_error]`` asks for, checked against q (μ = ν: the lack
    of fit between the runs compares run i with model track i, :mod:`.lack_of_fit`).

    Raises:
        StudyError: ``pilot_runs`` below :func:`.track_statistics.minimum_pilot_runs` (q).
    """
    runs = PILOT_RUNS if pilot_runs is None else pilot_runs
    need = minimum_pilot_runs(q)
    if runs < need:
        raise StudyError(
            f"output_error.pilot_runs: {runs} is not allowed for q = {q} calibrated "
            f"parameters; expected at least {need} (max(10 q, 50): the pilot's covariance of "
            "the q summaries needs them)"
        )
    return TrackStatisticsPlan(runs, n_measured, n_measured, seed, track_quality)


def _design_arrays(run: MeasuredRun) -> tuple[np.ndarray, ...] | None:
    design = run.design
    if design is None:
        return None
    return (design.chainage_m, design.curvature_1_m, design.cant_m, design.gradient)


def check_exchangeable_runs(runs: Sequence[MeasuredRun], names: Sequence[str]) -> None:
    """Refuse runs that are not draws of one experiment: the summary likelihood's ȳ, h̄ and
    pilot treat every run as the same speed profile, record and line design on another
    realization of the track process (κ = 1/ν + 1/μ; C from runs of one template).

    The runs' geometry (present or not) is not compared: the model never reads it.

    Args:
        runs: the ν measured runs.
        names: their file names, for the message.

    Raises:
        StudyError: naming the first run that differs from the first one and in what.
    """
    first = runs[0]
    for name, run in zip(names[1:], runs[1:]):
        differs = []
        if not (
            np.array_equal(run.speed.time_s, first.speed.time_s)
            and np.array_equal(run.speed.speed_m_s, first.speed.speed_m_s)
        ):
            differs.append("speed profile")
        if run.n_samples != first.n_samples or run.time_offset_s != first.time_offset_s:
            differs.append(
                f"record ({run.n_samples} samples from {run.time_offset_s:g} s against "
                f"{first.n_samples} from {first.time_offset_s:g} s)"
            )
        a, b = _design_arrays(run), _design_arrays(first)
        if (a is None) != (b is None) or (
            a is not None and not all(np.array_equal(x, y) for x, y in zip(a, b or ()))
        ):
            differs.append("line design")
        if differs:
            raise StudyError(
                f"data: {name} differs from {names[0]} in its {', '.join(differs)}; "
                "output_error.model = 'track_statistics' compares the mean spectrum of runs "
                "of one speed profile, record length and line design on different track "
                "realizations: calibrate such runs as separate studies, cut them to one "
                "record, or use another output-error model"
            )


def _synthetic_run(
    template: MeasuredRun, length_m: float, track_id: str, quality: str, seed: Sequence[int]
) -> TrackRun:
    """A realization of the track process, ``length_m`` long, under ``template``'s speed
    profile and line design."""
    track_seed = int(np.random.SeedSequence(list(seed)).generate_state(1)[0])
    geometry = TrackGeometry.synthetic(
        quality=quality,  # type: ignore[arg-type]
        length_m=length_m,
        seed=track_seed,
    )
    return TrackRun(track_id, geometry, template.speed, template.design)


def realization_length_m(runs: Sequence[MeasuredRun], spec: RigSpec) -> float:
    """Length (m) of every model and pilot track: what the longest run needs, one rule for
    runs with geometry and without (a run's own geometry is never read).

    A simulation of a run covers its whole speed record (warm-up included,
    :meth:`susp_bo.rig.simulator.Rig.simulate`), so a run needs the distance of its speed
    record plus the axle span — at least :func:`~susp_bo.data.run_validation.track_needed_m`,
    which stops at the last acceleration sample — and the realization has
    :data:`REALIZATION_MARGIN_M` more. For runs made by
    :func:`~susp_bo.data.synthetic.synthesize_runs` this is the length of their own
    tracks, to the sample, which the realizations had when they took the longest run's
    geometry length (the test suite's fast rig: 780.0 m either way).

    Args:
        runs: the ν measured runs.
        spec: the rig (its axle span, m).
    """
    return max(simulated_track_m(run, spec) for run in runs) + REALIZATION_MARGIN_M


def _realizations(
    runs: Sequence[MeasuredRun],
    plan: TrackStatisticsPlan,
    spec: RigSpec,
    name: str,
    key: tuple[int, ...],
    count: int,
) -> tuple[TrackRun, ...]:
    """``count`` realizations under the first run's speed profile and line design,
    :func:`realization_length_m` long, named ``{name}{i:03d}-seed{seed}`` and seeded by
    (seed, *key, i)."""
    length = realization_length_m(runs, spec)
    return tuple(
        _synthetic_run(
            runs[0],
            length,
            f"{name}{i:03d}-seed{plan.seed}",
            plan.track_quality,
            (plan.seed, *key, i),
        )
        for i in range(count)
    )


def model_tracks(
    runs: Sequence[MeasuredRun], plan: TrackStatisticsPlan, spec: RigSpec
) -> tuple[TrackRun, ...]:
    """The μ synthetic track realizations the model simulates at every w (module docstring)."""
    return _realizations(runs, plan, spec, "model", (MODEL_TRACKS_TAG,), plan.n_simulated)


def pilot_tracks(
    runs: Sequence[MeasuredRun], plan: TrackStatisticsPlan, spec: RigSpec, stage: int
) -> tuple[TrackRun, ...]:
    """The M fresh realizations of one pilot stage (0 or 1)."""
    return _realizations(
        runs, plan, spec, f"pilot{stage}-", (PILOT_TRACKS_TAG, stage), plan.pilot_runs
    )


def _noise_seed(plan: TrackStatisticsPlan, stage: int, m: int) -> int:
    return int(
        np.random.SeedSequence([plan.seed, PILOT_TRACKS_TAG, stage, m, 1]).generate_state(1)[0]
    )


def run_pilot(
    plan: TrackStatisticsPlan,
    runs: Sequence[MeasuredRun],
    measured: np.ndarray,
    bounds: np.ndarray,
    evaluator: LikelihoodEvaluator,
    spec: RigSpec,
    noise_m_s2: float,
) -> tuple[TrackStatisticsError, PilotRecord]:
    """The two-stage pilot of a study, through its store and executor (module docstring).

    Args:
        plan: what the study's ``[output_error]`` asked for.
        runs: the ν measured runs (speed and design of the realizations, and with the
            rig their length, :func:`realization_length_m`).
        measured: (ν x C x F) their spectra.
        bounds: (2 x q) C_w.
        evaluator: the study's evaluator on the μ model tracks (its store and executor).
        spec: the rig.
        noise_m_s2: sensor noise (m/s² rms) drawn into every pilot run.

    Raises:
        StudyError: a simulation of the pilot failed, or the pilot's spectra cannot give
            the summaries (a parameter without effect at the pilot point), naming it; the
            finished simulations stay in the store.
    """
    names = evaluator.names

    touched: set[tuple[bytes, str]] = set()

    def spectra(W: np.ndarray) -> np.ndarray:
        W = np.atleast_2d(np.asarray(W, dtype=np.float64))
        touched.update((w.tobytes(), t.track_id) for w in W for t in evaluator.tracks)
        H = evaluator.spectra(W)
        bad = np.flatnonzero(~np.all(np.isfinite(H.reshape(len(H), -1)), axis=1))
        if bad.size:
            point = dict(zip(names, np.atleast_2d(W)[bad[0]].tolist()))
            raise StudyError(
                f"output_error.model = 'track_statistics': the pilot's simulation at {point} "
                f"failed ({'; '.join(evaluator.failures[-1:]) or 'see the log'}); the "
                "summary likelihood needs every run of its pilot: narrow C_w in the rig file "
                "or use another output-error model"
            )
        return H

    def pilot_runs(w: np.ndarray, stage: int) -> np.ndarray:
        parameters = dict(zip(names, w.tolist()))
        items = [
            (
                w,
                track.track_id,
                (
                    spec,
                    parameters,
                    track.geometry,
                    track.speed,
                    track.design,
                    noise_m_s2,
                    _noise_seed(plan, stage, m),
                ),
            )
            for m, track in enumerate(pilot_tracks(runs, plan, spec, stage))
        ]
        touched.update((np.asarray(w).tobytes(), track_id) for w, track_id, _ in items)
        found = evaluator.stored_runs(
            items, simulate_noisy_spectra, desc=f"pilot stage {stage + 1}"
        )
        if any(f is None for f in found):
            failed = sum(f is None for f in found)
            raise StudyError(
                f"output_error.model = 'track_statistics': {failed} of the {len(found)} "
                f"pilot runs of stage {stage + 1} at {parameters} failed "
                f"({'; '.join(evaluator.failures[-1:]) or 'see the log'}); the summary "
                "likelihood needs every run of its pilot"
            )
        return np.stack([np.asarray(f) for f in found])

    try:
        error, record = two_stage_error(spectra, pilot_runs, measured, bounds, plan.n_simulated)
    except StudyError:
        raise
    except ValueError as error:
        raise StudyError(f"output_error.model = 'track_statistics': the pilot: {error}") from None
    if error.misfit is not None:  # its summaries named by the rig's channels and bands
        labels = group_labels(error.misfit, spec.channels, spec.spectrum.frequencies_hz())
        error = dataclasses.replace(error, misfit=dataclasses.replace(error.misfit, labels=labels))
    # a point the fit and the Jacobian share is one stored run: count the distinct ones
    return error, dataclasses.replace(record, simulations=len(touched))


def pilot_point(record: PilotRecord, bounds: np.ndarray) -> np.ndarray:
    """(q,) the pilot's fit of the summaries, its second point, in physical units, inside
    C_w (a fit at a face, unit coordinate 1.0, can round one step past the upper bound:
    a warm design holding it would be refused, second review of session 36)."""
    point = bounds[0] + np.asarray(record.first_fit) * (bounds[1] - bounds[0])
    return np.clip(point, bounds[0], bounds[1])


def pilot_payload(
    error: TrackStatisticsError, record: PilotRecord, bounds: np.ndarray, names: Sequence[str]
) -> dict[str, object]:
    """``result.json["output_error"]``'s pilot fields (physical units); ``misfit_summaries``
    is k, the summaries of the goodness-of-fit test (:mod:`.summary_misfit`; null: none)."""
    point = pilot_point(record, bounds)
    return {
        "pilot_runs": int(error.pilot_runs),
        "pilot_simulations": int(record.simulations),
        "pilot_point": dict(zip(names, point.tolist())),
        "pilot_fit_converged": bool(record.converged),
        "shrinkage": float(error.shrinkage),
        "summary_covariance": np.asarray(error.covariance).tolist(),
        "misfit_summaries": None if error.misfit is None else error.misfit.dof,
    }
