"""log L(w) from simulator runs: the ``evaluate`` function the calibration loop calls.

For a batch of parameter vectors ``W`` (b x q) the evaluator needs the spectra
``h(x_j, w)`` of every vector on every measured track stretch ``x_j``
(j = 1..μ). Each (w, x_j) pair is one simulator evaluation: it is looked up in
the study's :class:`~susp_bo.store.EvaluationStore` first (a resumed study
reuses what finished), the missing ones run together on the study's executor
(so an EGO batch fills every worker), and each is recorded in the store the
moment it completes. A vector whose evaluations all succeeded gets
``log L`` of eq. 4 against the measured spectra; a vector with a failed
evaluation (diverged simulation, crashed worker) gets NaN, which the
calibration loop treats as a failed point — the study goes on.
"""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass

import numpy as np

from susp_bo.calibration.likelihood import OutputError, log_likelihood
from susp_bo.calibration.paired_error import PairedOutputError, paired_log_likelihood
from susp_bo.calibration.track_statistics import (
    TrackStatisticsError,
    track_statistics_log_likelihood,
)
from susp_bo.execution import TaskOutcome, run_tasks
from susp_bo.rig.design import TrackDesign
from susp_bo.rig.simulator import Rig
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.spectra import with_noise_floor
from susp_bo.rig.track import SpeedProfile, TrackGeometry
from susp_bo.store import EvaluationStore


@dataclass(frozen=True)
class TrackRun:
    """One track stretch x_j: its geometry and the speed the train ran it at.

    Attributes:
        track_id: stable id (recorded in the store with every evaluation).
        geometry: track irregularities sampled in space.
        speed: speed record of the run.
        design: the line's design (curves, cant, gradient), None on tangent track.
    """

    track_id: str
    geometry: TrackGeometry
    speed: SpeedProfile
    design: TrackDesign | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.geometry, TrackGeometry):  # e.g. a run's geometry None
            raise ValueError(
                f"TrackRun {self.track_id!r}: geometry is {type(self.geometry).__name__}; "
                "expected a TrackGeometry (a run whose track was not measured has none: "
                'simulate it on synthetic tracks, [output_error] model = "track_statistics")'
            )


class _RigCache(threading.local):
    """One :class:`Rig` (one PyBullet client) per rig spec, per worker thread.

    Thread-local, because a Dask worker may run several tasks in threads of one
    process and a PyBullet client must not be stepped by two threads at once.
    """

    def __init__(self) -> None:
        self._rigs: dict[str, Rig] = {}

    def rig(self, spec: RigSpec) -> Rig:
        key = spec.fingerprint()
        if key not in self._rigs:
            self._rigs[key] = Rig(spec)
        return self._rigs[key]


_WORKER_RIGS = _RigCache()


def simulate_spectra(
    spec: RigSpec,
    parameters: Mapping[str, float],
    geometry: TrackGeometry,
    speed: SpeedProfile,
    design: TrackDesign | None = None,
) -> np.ndarray:
    """One simulator evaluation h(x, w): the rig's log-amplitude spectra (C x F).

    On a designed line the rig follows the design and the design's quasi-static
    specific force is removed before the spectra, as from the measured runs.

    A top-level function so that worker processes (and Dask workers) import it
    by name; each worker keeps its own rig (PyBullet client) between calls. The rig's
    BLAS products run on one thread, so the spectra are the same bits in a pool worker,
    in-process (``workers = 0``) and in a worker whose program loaded NumPy before the
    pool could limit its threads (:func:`susp_bo.numerics.one_blas_thread`).

    Raises:
        SimulationFailed: the simulation diverged (recorded as a failed evaluation).
    """
    spectra = _WORKER_RIGS.rig(spec).spectra(geometry, speed, dict(parameters), design=design)
    return np.asarray(spectra.log_amplitude, dtype=np.float64)


def simulate_noisy_spectra(
    spec: RigSpec,
    parameters: Mapping[str, float],
    geometry: TrackGeometry,
    speed: SpeedProfile,
    design: TrackDesign | None,
    noise_m_s2: float,
    noise_seed: int | Sequence[int],
) -> np.ndarray:
    """One run as it would be measured: the rig's accelerations plus white sensor noise
    (``noise_m_s2`` m/s² rms, drawn by ``numpy.random.default_rng(noise_seed)``), then its
    log-amplitude spectra (C x F) — a pilot run of the summary likelihood
    (:mod:`.study_track_statistics`).

    The noise is drawn, not a floor (:func:`simulate_spectra`'s spectra take the floor in
    :meth:`LikelihoodEvaluator.spectra`): the pilot measures how one measured run's
    spectrum scatters, the sensor's share included.

    Raises:
        SimulationFailed: the simulation diverged (recorded as a failed evaluation).
    """
    response = _WORKER_RIGS.rig(spec).simulate(geometry, speed, dict(parameters), design=design)
    accelerations = response.accelerations_m_s2
    if noise_m_s2 > 0.0:
        noise = np.random.default_rng(noise_seed).normal(0.0, noise_m_s2, accelerations.shape)
        response = dataclasses.replace(response, accelerations_m_s2=accelerations + noise)
    return np.asarray(response.spectra().log_amplitude, dtype=np.float64)


class LikelihoodEvaluator:
    """``evaluate(W) -> log L`` for the calibration loop, backed by the store and an executor.

    Args:
        spec: the rig being calibrated (its non-calibrated parameters stay fixed).
        names: calibration parameter names, in the order of the columns of W.
        tracks: the μ measured track stretches x_j.
        measured: (ν x C x F) measured log-amplitude spectra.
        error: the output error model B: paired (run i against track i only), the
            unpaired mixture of eq. 4, or the summary likelihood (tracks known only by
            their statistics, :mod:`.track_statistics`; a study sets it after its pilot).
        store: where every evaluation is recorded and looked up.
        executor: where simulations run.
        frequencies_hz: (F,) grid of the spectra.
        progress: show a progress bar per batch of simulations (susp_bo.progress).
        noise_m_s2: sensor noise (m/s² rms) added to the simulated spectra as a
            floor before the comparison (the measurement model); 0 = none.
        sample_rate_hz: sampling rate of the measurements (Hz), for the floor.
    """

    def __init__(
        self,
        spec: RigSpec,
        names: Sequence[str],
        tracks: Sequence[TrackRun],
        measured: np.ndarray,
        error: OutputError | PairedOutputError | TrackStatisticsError,
        store: EvaluationStore,
        executor: Executor,
        frequencies_hz: np.ndarray,
        progress: bool = True,
        noise_m_s2: float = 0.0,
        sample_rate_hz: float = 1.0,
    ) -> None:
        self.spec = spec
        self.names = tuple(names)
        self.tracks = tuple(tracks)
        self.measured = np.asarray(measured, dtype=np.float64)
        self.error = error
        self.store = store
        self.executor = executor
        self.frequencies_hz = np.asarray(frequencies_hz, dtype=np.float64)
        self.progress = progress
        self.noise_m_s2 = float(noise_m_s2)
        self.sample_rate_hz = float(sample_rate_hz)
        self.simulations_run = 0
        self.simulations_reused = 0
        self.failures: list[str] = []

    def spectra_of(self, W: np.ndarray) -> list[list[np.ndarray | None]]:
        """Spectra of every row of ``W`` on every track, running only what is missing.

        Args:
            W: (b x q) parameter vectors, physical units.

        Returns:
            ``b`` lists of ``μ`` arrays (C x F), None where the evaluation failed.
        """
        W = np.atleast_2d(np.asarray(W, dtype=np.float64))
        items = [
            (
                w,
                track.track_id,
                (
                    self.spec,
                    dict(zip(self.names, w.tolist())),
                    track.geometry,
                    track.speed,
                    track.design,
                ),
            )
            for w in W
            for track in self.tracks
        ]
        found = self.stored_runs(items, simulate_spectra)
        mu = len(self.tracks)
        return [found[row * mu : (row + 1) * mu] for row in range(len(W))]

    def stored_runs(
        self,
        items: Sequence[tuple[np.ndarray, str, tuple]],
        simulate: Callable[..., np.ndarray],
        desc: str = "simulations",
    ) -> list[np.ndarray | None]:
        """Simulator results keyed by (parameters, track id): the store's, else run.

        Args:
            items: ``(w, track_id, arguments)``: w (q,) physical units and the track id
                that key the store, ``simulate(*arguments)`` what runs when it misses.
            simulate: a picklable top-level function returning (C x F) spectra.
            desc: the progress bar's label.

        Returns:
            One (C x F) array per item, None where the evaluation failed.
        """
        found: dict[int, np.ndarray | None] = {}
        missing: list[int] = []
        for index, (w, track_id, _) in enumerate(items):
            recorded = self.store.lookup(w, track_id)
            if recorded is None:
                missing.append(index)
            else:
                found[index] = recorded.spectra if recorded.ok else None
        self.simulations_reused += len(found)
        if missing:

            def record(outcome: TaskOutcome) -> None:
                w, track_id, _ = items[missing[outcome.index]]
                if outcome.ok:
                    self.store.record_ok(w, track_id, outcome.value, outcome.seconds)
                else:
                    self.store.record_failure(
                        w,
                        track_id,
                        outcome.reason or "unknown failure",
                        outcome.seconds,
                        kind=outcome.failure_kind or "error",
                    )
                    self.failures.append(f"{dict(zip(self.names, w))}: {outcome.reason}")

            outcomes = run_tasks(
                self.executor,
                simulate,
                [items[index][2] for index in missing],
                on_result=record,
                desc=desc,
                progress=self.progress,
            )
            self.simulations_run += len(missing)
            for index, outcome in zip(missing, outcomes):
                found[index] = np.asarray(outcome.value) if outcome.ok else None
        return [found[index] for index in range(len(items))]

    def spectra(self, W: np.ndarray) -> np.ndarray:
        """(b x μ x C x F) simulated spectra of the rows of W, noise floor included; a row
        with a failed evaluation is all NaN (:class:`.local_search.SpectraEvaluator`)."""
        rows = []
        for spectra in self.spectra_of(W):
            if any(s is None for s in spectra):
                rows.append(None)
                continue
            rows.append(
                with_noise_floor(
                    np.stack([np.asarray(s) for s in spectra]), self.noise_m_s2, self.sample_rate_hz
                )
            )
        shape = next((r.shape for r in rows if r is not None), None)
        if shape is None:
            c, f = self.measured.shape[1:]
            shape = (len(self.tracks), c, f)
        return np.stack([np.full(shape, np.nan) if r is None else r for r in rows])

    def log_likelihood_of(self, H: np.ndarray, exact: bool = False) -> np.ndarray:
        """(b,) log L of eq. 4 (or the paired model) of (b x μ x C x F) spectra, no
        simulation; ``exact`` skips the paired model's rounding (for derivatives)."""
        H = np.asarray(H, dtype=np.float64)
        if getattr(self.error, "model", None) == "track_statistics" and not isinstance(
            self.error, TrackStatisticsError
        ):
            raise ValueError(
                "error: the summary likelihood's plan, whose pilot has not run; run_study "
                "runs it first (susp_bo.calibration.study.with_pilot)"
            )
        if isinstance(self.error, PairedOutputError):
            value = paired_log_likelihood(self.measured, H, self.error, exact=exact)
        elif isinstance(self.error, TrackStatisticsError):
            value = track_statistics_log_likelihood(self.measured, H, self.error)
        else:
            value = log_likelihood(self.measured, H, self.error, self.frequencies_hz)
        return np.atleast_1d(np.asarray(value, dtype=np.float64))

    def __call__(self, W: np.ndarray) -> np.ndarray:
        """log L of eq. 4 for each row of W (b,), NaN where an evaluation failed."""
        H = self.spectra(W)
        ok = np.all(np.isfinite(H.reshape(len(H), -1)), axis=1)
        values = np.full(len(H), np.nan)
        for row in np.flatnonzero(ok):
            values[row] = float(self.log_likelihood_of(H[row][None])[0])
        return values
