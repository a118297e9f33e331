"""What the discrepancy workflow works on: measured spectra, their tracks, a rig, a simulator.

A :class:`DiagnosisProblem` pairs every measured run ``y_i`` with the track it
was measured on ``x_i`` (μ = ν, as in a study), so that simulated and measured
spectra are compared run by run. Two simulators give ``h(x_i, w)``:

* :class:`LinearSimulator` — the linearised rig's time response on the measured
  track (:meth:`~susp_bo.rig.linear.LinearisedRig.response`, one FFT solve,
  ≈10 ms a run at the sample rate): the fast path for refits;
* :class:`PyBulletSimulator` — the PyBullet rig (what a study calibrates with).

A known sensor noise floor (white, ``noise_m_s2`` rms) is added to every
simulated spectrum, so that a quiet band of the data is not read as missing
physics.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from susp_bo.calibration.evaluation import TrackRun, simulate_spectra
from susp_bo.calibration.likelihood import OutputError
from susp_bo.calibration.paired_error import PairedOutputError
from susp_bo.discrepancy.detection_scale import DetectionScale, paired_scale, unpaired_scale
from susp_bo.rig.linear import LinearisedRig
from susp_bo.rig.linear_curving import LinearModelNotApplicable
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.spectra import with_noise_floor

FloatArray = np.ndarray


class Simulator(Protocol):
    """``h(x, w)``: log-amplitude spectra (C x F) of a rig on one track."""

    name: str

    def spectra(
        self, spec: RigSpec, parameters: Mapping[str, float], track: TrackRun
    ) -> FloatArray: ...


MAX_SPEED_VARIATION = 0.05
"""Largest (max − min) / mean speed of a run the linearised rig stands for: it runs at the
run's mean speed, and a speed sweep of 70 → 95 m/s made its spectra disagree with
linear-element PyBullet data in bands no effect explains."""


def linear_model_problem(track: TrackRun) -> str:
    """Why the linearised rig cannot stand for ``track`` ("" when it can): a designed line
    with curves, cant or gradient, or a speed varying by more than
    :data:`MAX_SPEED_VARIATION` of its mean."""
    if track.design is not None and not track.design.is_tangent():
        return (
            f"track {track.track_id} follows a track design with curves, cant or gradient, "
            "which the linearised time response does not (the PyBullet rig does)"
        )
    speeds = track.speed.speed_at(np.linspace(0.0, track.speed.duration_s, 256))
    variation = float((np.max(speeds) - np.min(speeds)) / np.mean(speeds))
    if variation > MAX_SPEED_VARIATION:
        return (
            f"track {track.track_id}: the speed varies by {variation:.0%} of its mean "
            f"({np.min(speeds):.4g}–{np.max(speeds):.4g} m/s); the linearised rig runs at "
            f"one speed, which stands for a run only within {MAX_SPEED_VARIATION:.0%}"
        )
    return ""


class LinearSimulator:
    """The linearised rig on the measured track, at the output sample rate (fast path)."""

    name = "linear"

    def __init__(self) -> None:
        self._rigs: dict[str, tuple[RigSpec, LinearisedRig]] = {}

    def _rig(self, spec: RigSpec) -> LinearisedRig:
        key = spec.fingerprint()
        if key not in self._rigs:
            self._rigs[key] = (spec, LinearisedRig(spec))
        return self._rigs[key][1]

    def spectra(
        self, spec: RigSpec, parameters: Mapping[str, float], track: TrackRun
    ) -> FloatArray:
        """Spectra (C x F) of ``spec`` at ``parameters`` on ``track`` (constant mean speed).

        Raises:
            LinearModelNotApplicable: the track has a curved design or its speed varies by
                more than :data:`MAX_SPEED_VARIATION` (:func:`linear_model_problem`).
        """
        problem = linear_model_problem(track)
        if problem:
            raise LinearModelNotApplicable(problem)
        sim = spec.simulation
        speed = float(np.mean(track.speed.speed_at(np.linspace(0, track.speed.duration_s, 64))))
        response = self._rig(spec).response(
            track.geometry,
            speed,
            dict(parameters),
            duration_s=track.speed.duration_s - sim.warm_up_s,
            time_step_s=1.0 / sim.sample_rate_hz,
        )
        return np.asarray(response.spectra(spec.spectrum).log_amplitude, dtype=np.float64)


class PyBulletSimulator:
    """The PyBullet rig (the study's simulator), one client per thread."""

    name = "pybullet"

    def spectra(
        self, spec: RigSpec, parameters: Mapping[str, float], track: TrackRun
    ) -> FloatArray:
        """Spectra (C x F) of ``spec`` at ``parameters`` on ``track``."""
        return simulate_spectra(spec, parameters, track.geometry, track.speed, track.design)


def make_simulator(kind: str) -> Simulator:
    """``linear`` or ``pybullet``."""
    if kind == "linear":
        return LinearSimulator()
    if kind == "pybullet":
        return PyBulletSimulator()
    raise ValueError(f"simulator: got {kind!r}; allowed 'linear', 'pybullet'")


@dataclass(frozen=True)
class DiagnosisProblem:
    """Measured data, their tracks and the model being checked.

    Attributes:
        spec: the rig being calibrated (the base model, effects off).
        names: calibrated parameter names (q,).
        bounds: (2 x q) admissible set.
        measured: (ν x C x F) measured log-amplitude spectra.
        tracks: the ν tracks, ``tracks[i]`` is where ``measured[i]`` was taken.
        error: the unpaired output error (σ_B per channel, the scatter between runs): the
            metric of the refits' least squares and of the ranking's eq. 4 scores.
        noise_m_s2: known sensor noise (m/s² rms), 0 when negligible or unknown.
        reference: true parameter values by name when the data are synthetic, else None.
        paired: the paired output error of these runs (each with its own measured track),
            or None: when given, the checks judge residuals on its scale
            (:func:`~.detection_scale.paired_scale`) and the refits' Laplace posteriors
            use it; else on σ_B (:func:`~.detection_scale.unpaired_scale`).
    """

    spec: RigSpec
    names: tuple[str, ...]
    bounds: FloatArray
    measured: FloatArray
    tracks: tuple[TrackRun, ...]
    error: OutputError
    noise_m_s2: float = 0.0
    reference: Mapping[str, float] | None = None
    paired: PairedOutputError | None = None

    def __post_init__(self) -> None:
        measured = np.asarray(self.measured, dtype=np.float64)
        if measured.ndim != 3 or measured.shape[0] != len(self.tracks):
            raise ValueError(
                f"measured: shape {measured.shape}; expected (ν x C x F) with ν = "
                f"{len(self.tracks)} tracks"
            )
        if measured.shape[1] != len(self.spec.channels):
            raise ValueError(
                f"measured: {measured.shape[1]} channels, the rig has {len(self.spec.channels)}"
            )
        bins = len(self.spec.spectrum.band_edges_hz()) - 1
        if measured.shape[2] != bins:  # else a broadcasting error deep in the first check
            raise ValueError(
                f"measured: {measured.shape[2]} frequencies, the rig's spectrum has {bins} bands"
            )
        if not np.all(np.isfinite(measured)):
            raise ValueError("measured: non-finite log-amplitudes; expected finite spectra")
        bounds = np.asarray(self.bounds, dtype=np.float64)
        if bounds.shape != (2, len(self.names)):
            raise ValueError(f"bounds: shape {bounds.shape}; expected (2 x {len(self.names)})")
        inverted = [n for n, lo, hi in zip(self.names, *bounds, strict=True) if not lo < hi]
        if inverted:  # also NaN
            raise ValueError(
                f"bounds: lower >= upper (or NaN) for {', '.join(map(str, inverted))}; expected "
                "rows (lower, upper) with lower < upper"
            )
        if not (math.isfinite(self.noise_m_s2) and self.noise_m_s2 >= 0):
            raise ValueError(f"noise_m_s2: got {self.noise_m_s2}; must be a finite value >= 0 m/s²")
        if self.paired is not None:
            if not isinstance(self.paired, PairedOutputError):
                raise ValueError(
                    f"paired: got {type(self.paired).__name__}; expected a PairedOutputError "
                    "or None"
                )
            if len(self.paired.n_samples) != measured.shape[0]:
                raise ValueError(
                    f"paired: an error model of {len(self.paired.n_samples)} runs for "
                    f"{measured.shape[0]} measured runs"
                )
        object.__setattr__(self, "measured", measured)
        object.__setattr__(self, "bounds", bounds)
        object.__setattr__(self, "names", tuple(self.names))

    @property
    def frequencies_hz(self) -> FloatArray:
        """(F,) the frequency grid."""
        return self.spec.spectrum.frequencies_hz()

    @property
    def sigma(self) -> FloatArray:
        """(C,) σ_B per channel."""
        return np.asarray(self.error.sigma, dtype=np.float64)

    def detection_scale(self, predicted: FloatArray) -> DetectionScale:
        """B's expected residual and variance (ν x C x F) around ``predicted`` (ν x C x F):
        paired when :attr:`paired` is given, else σ_B."""
        if self.paired is not None:
            return paired_scale(self.measured, predicted, self.paired)
        return unpaired_scale(self.sigma, self.measured.shape)

    def simulate(
        self,
        simulator: Simulator,
        spec: RigSpec,
        names: Sequence[str],
        w: FloatArray,
    ) -> FloatArray:
        """``h(x_i, w)`` on every track, noise floor included: (ν x C x F)."""
        parameters = dict(zip(names, (float(v) for v in w)))
        out = np.stack([simulator.spectra(spec, parameters, track) for track in self.tracks])
        return with_noise_floor(out, self.noise_m_s2, spec.simulation.sample_rate_hz)
