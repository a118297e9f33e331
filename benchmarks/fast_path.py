"""The linearised fast path shared by the SBC and the localisation benchmarks.

:class:`FastPathProblem`: ν synthetic runs of one truth on the linearised rig (seeded
German-PSD tracks, white sensor noise) and ``evaluate(W) -> log L`` under the paired or
the unpaired output-error model, with the spectra exposed for the local phase.
:class:`Options` and :func:`demo_settings`: the SBC run's options and the demo's
calibration settings seeded per experiment. Used by ``coverage.py`` and
``component_localisation.py`` (``from fast_path import ...``: a script's own folder is
on ``sys.path``).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from susp_bo.calibration.evaluation import TrackRun
from susp_bo.calibration.likelihood import OutputError, estimate_output_error, log_likelihood
from susp_bo.calibration.loop import CalibrationSettings
from susp_bo.calibration.paired_error import PairedOutputError, paired_log_likelihood
from susp_bo.calibration.study import calibration_settings
from susp_bo.calibration.track_statistics import (
    TrackStatisticsError,
    track_statistics_log_likelihood,
)
from susp_bo.commands.demo import demo_config
from susp_bo.data.synthetic import track_seed
from susp_bo.discrepancy.problem import LinearSimulator
from susp_bo.rig.linear import LinearisedRig
from susp_bo.rig.simulator import synthetic_track
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.spectra import log_amplitude_spectra, with_noise_floor
from susp_bo.rig.track import SpeedProfile


@dataclasses.dataclass(frozen=True)
class Options:
    """What an SBC run is (stored in ``OUT/config.json``; a resume must match)."""

    nu: int
    noise: float
    seed: int
    error: str
    budget: int | None
    smoke: bool
    reference_only: bool = False
    zoom: bool = False
    trust_region: bool = False
    local_search: bool = False
    surrogate_mean: str = "auto"
    half_width_sd: float = 8.0
    unknown_tracks: bool = False
    kernel_switch: bool = True


def demo_settings(options: Options, experiment: int) -> CalibrationSettings:
    """The demo's calibration settings, seeded per experiment (and shrunk with --smoke)."""
    config = demo_config(Path("/nonexistent"), smoke=False, seed=0)
    settings = calibration_settings(config)
    seed = int(np.random.SeedSequence([options.seed, experiment, 7]).generate_state(1)[0] >> 1)
    settings = dataclasses.replace(
        settings,
        seed=seed,
        mcmc_seed=seed + 1,
        trust_region=options.trust_region,
        local_search=options.local_search,
        surrogate=dataclasses.replace(settings.surrogate, mean=options.surrogate_mean),
        trust_region_half_width_sd=options.half_width_sd,
        kernel_switch=options.kernel_switch,
    )
    if options.budget is not None:
        settings = dataclasses.replace(
            settings,
            max_evaluations=options.budget,
            initial_design_size=min(settings.initial_design_size or 40, options.budget - 2),
        )
    if options.smoke:
        settings = dataclasses.replace(
            settings,
            max_evaluations=14,
            initial_design_size=10,
            check_points=2,
            batch_size=2,
            mcmc_chains=16,
            mcmc_warmup=100,
            mcmc_samples=200,
            allow_small_budget=True,
        )
    return settings


def sbc_draw(seed: int, experiment: int, q: int) -> tuple[np.ndarray, int]:
    """Experiment ``experiment`` of ``coverage.py --seed seed``: (u_true (q,), data seed).

    u_true is the truth in the unit cube of C_w; the data seed seeds the runs' tracks and
    sensor noise (:class:`FastPathProblem`).
    """
    u_true = np.random.default_rng([seed, experiment, 11]).uniform(size=q)
    data_seed = int(np.random.SeedSequence([seed, experiment, 13]).generate_state(1)[0])
    return u_true, data_seed


def laplace_at_truth(
    problem: FastPathProblem, bounds: np.ndarray, u_true: np.ndarray, step: float = 1e-4
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spectra at u_true ± step e_k and B's Fisher information there (unit-cube coordinates,
    :func:`~susp_bo.calibration.paired_error.paired_fisher_information`); paired model only.

    A truth within ``step`` of a face of the unit cube is differenced one-sidedly on that
    side (the shifted point is the face), so no spectrum is asked for outside C_w.

    Returns ``(shifted, information, width)``: (2q x ν x C x F) spectra (plus steps first,
    then minus), the (q x q) information matrix and the (q,) distance between each plus
    and minus point (2 step, less at a face): a difference quotient divides by it.
    """
    from susp_bo.calibration.paired_error import paired_fisher_information

    q = len(u_true)
    span = bounds[1] - bounds[0]
    plus = np.minimum(u_true + step, 1.0)
    minus = np.maximum(u_true - step, 0.0)
    interior = (u_true + step <= 1.0) & (u_true - step >= 0.0)
    width = np.where(interior, 2 * step, plus - minus)  # 2 step exactly, as before
    eye = np.eye(q, dtype=bool)
    points = np.vstack([np.where(eye, plus[None, :], u_true[None, :]),
                        np.where(eye, minus[None, :], u_true[None, :])])  # fmt: skip
    shifted = problem.spectra(bounds[0] + points * span)
    h = problem.spectra((bounds[0] + u_true * span)[None])[0]
    assert isinstance(problem.error, PairedOutputError)
    jacobian = (shifted[:q] - shifted[q:]) / width.reshape((q,) + (1,) * (shifted.ndim - 1))
    information = paired_fisher_information(h, jacobian, problem.error)
    return shifted, information, width


def linear_run(
    rig: LinearisedRig,
    spec: RigSpec,
    geometry,
    noise_m_s2: float,
    noise_key: list[int],
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """One measured run on the linearised rig at the spec's speed and sampling rate.

    Returns ``(spectra, clean, channels)``: the (C x F) log-amplitude spectra of the
    accelerations plus white sensor noise of ``noise_m_s2`` m/s² rms (drawn from
    ``default_rng(noise_key)``; none at 0), the noise-free (C x n_t) accelerations (m/s²)
    and the channel names.
    """
    sim = spec.simulation
    response = rig.response(geometry, sim.speed_m_s, time_step_s=1.0 / sim.sample_rate_hz)
    clean = np.array(response.accelerations_m_s2, dtype=np.float64)
    signals = clean
    if noise_m_s2 > 0:
        signals = clean + np.random.default_rng(noise_key).normal(0.0, noise_m_s2, clean.shape)
    spectra = log_amplitude_spectra(signals, sim.sample_rate_hz, response.channels, spec.spectrum)
    return spectra.log_amplitude, clean, tuple(response.channels)


class FastPathProblem:
    """Synthetic runs of one truth and ``evaluate(W) -> log L`` on the linearised rig.

    The model simulates run i on run i's own track (``tracks`` = ``measured_tracks``),
    or, with ``options.unknown_tracks``, on ν other realizations of the same track
    process (the unpaired model's setting: the tracks were not measured).
    """

    def __init__(self, spec: RigSpec, truth: dict[str, float], options: Options, seed: int):
        self.spec = spec
        self.names = spec.calibration_names
        self.options = options
        sim = spec.simulation
        self.rate = sim.sample_rate_hz
        true_spec = spec.with_parameters(truth)
        rig = LinearisedRig(true_spec)
        profile = SpeedProfile.constant(sim.speed_m_s, sim.warm_up_s + sim.duration_s)
        measured, tracks, n_samples, clean = [], [], [], []
        for index in range(options.nu):
            geometry = synthetic_track(true_spec, seed=track_seed(seed, index))
            spectra, signals, channels = linear_run(
                rig, spec, geometry, options.noise, [seed, index, 2]
            )
            clean.append(signals)
            measured.append(spectra)
            tracks.append(TrackRun(f"run{index:03d}", geometry, profile))
            n_samples.append(signals.shape[1])
        self.measured = np.stack(measured)
        self.clean_signals = tuple(clean)  # (ν,) noise-free (C x n_t) m/s², run i on track i
        self.channels = channels
        self.measured_tracks = tuple(tracks)
        if options.unknown_tracks:  # the unpaired model's own setting: only the track's
            # statistics are known, so the model simulates ν other realizations of them
            tracks = [
                TrackRun(
                    f"sim{index:03d}",
                    synthetic_track(spec, seed=track_seed(seed, options.nu + index)),
                    profile,
                )
                for index in range(options.nu)
            ]
        self.tracks = tuple(tracks)  # what the model simulates: the measured tracks or not
        self.error: PairedOutputError | OutputError | TrackStatisticsError
        self.simulator = LinearSimulator()
        self.evaluations = 0
        self.pilot = None
        if options.error == "paired":
            self.error = PairedOutputError(
                options.noise, self.rate, tuple(n_samples), spec.spectrum
            )
        elif options.error == "statistics":  # the summary likelihood, its pilot first
            from track_statistics_pilot import two_stage_error

            self.error, self.pilot = two_stage_error(self, seed)
        else:
            self.error = estimate_output_error(self.measured)

    def simulated(self, w: np.ndarray) -> np.ndarray:
        """(ν x C x F) simulated spectra with the noise floor, run i on track i."""
        parameters = dict(zip(self.names, np.asarray(w, dtype=float).tolist()))
        spectra = [self.simulator.spectra(self.spec, parameters, t) for t in self.tracks]
        return with_noise_floor(np.stack(spectra), self.options.noise, self.rate)

    def log_l(self, w: np.ndarray) -> float:
        """log L at one parameter vector (physical units)."""
        return float(self.log_likelihood_of(self.simulated(w)[None])[0])

    def spectra(self, W: np.ndarray) -> np.ndarray:
        """(b x ν x C x F) simulated spectra of the rows of W (the local phase's input)."""
        self.evaluations += len(np.atleast_2d(W))
        return np.stack([self.simulated(w) for w in np.atleast_2d(W)])

    def log_likelihood_of(self, H: np.ndarray, exact: bool = False) -> np.ndarray:
        """(b,) log L of (b x ν x C x F) spectra, no simulation."""
        if isinstance(self.error, PairedOutputError):
            value = paired_log_likelihood(self.measured, H, self.error, exact=exact)
        elif isinstance(self.error, TrackStatisticsError):
            value = track_statistics_log_likelihood(self.measured, H, self.error)
        else:
            value = log_likelihood(self.measured, H, self.error)
        return np.atleast_1d(np.asarray(value, dtype=np.float64))

    def __call__(self, W: np.ndarray) -> np.ndarray:
        self.evaluations += len(W)
        out = []
        for w in np.atleast_2d(W):
            try:
                out.append(self.log_l(w))
            except (ValueError, np.linalg.LinAlgError):
                out.append(math.nan)
        return np.asarray(out, dtype=np.float64)
