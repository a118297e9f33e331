"""Hidden-effect data sets: the effect on in the generator, off in the model being calibrated.

A scenario is the maintainer's base rig (:func:`~.effects.maintainer_base`)
with a worn parameter state (the truth), ν measured runs on independent seeded
tracks at one speed with white sensor noise, and optionally one library effect
switched on in the generator only. Generators:

* ``linear`` — the linearised rig's time response (fast; tests and benchmark);
* ``pybullet`` — the PyBullet rig as :func:`susp_bo.data.synthetic.synthesize_runs`
  runs it (nonlinear elements);
* ``pybullet_linear`` — PyBullet with every element at its slope, the time-domain
  counterpart of the fast path (PyBullet data for the fast-path workflow).

The band is widened to 0.3–40 Hz (:func:`scenario_spec`): polygonal wheels show
at n·V/(πD), 30.8 Hz for order 1 at 300 km/h, beyond the rig file's 20 Hz.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from susp_bo.calibration.evaluation import TrackRun
from susp_bo.calibration.likelihood import estimate_output_error
from susp_bo.calibration.paired_error import PairedOutputError
from susp_bo.data.synthetic import track_seed
from susp_bo.discrepancy.effects import maintainer_base, with_effect
from susp_bo.discrepancy.out_of_library import get_modification
from susp_bo.discrepancy.problem import DiagnosisProblem
from susp_bo.rig.linear import LinearisedRig
from susp_bo.rig.simulator import Rig, synthetic_track
from susp_bo.rig.spec import RigSpec, load_rig_spec
from susp_bo.rig.spectra import log_amplitude_spectra
from susp_bo.rig.track import SpeedProfile

WORN_TRUTH = {
    "primary_vertical_damping": 10.0e3,
    "secondary_vertical_damping": 30.0e3,
    "secondary_lateral_damping": 45.0e3,
    "yaw_damper_damping": 3.5e6,
}
"""A worn state (the truth of the scenarios): dampers 15–30 % below nominal."""


def scenario_spec(
    rig: str = "hst_trailer",
    duration_s: float = 24.0,
    warm_up_s: float = 4.0,
    f_max_hz: float = 40.0,
) -> RigSpec:
    """The maintainer's base rig with the scenario record length and band (0.3–f_max Hz)."""
    spec = maintainer_base(load_rig_spec(rig)).with_simulation(
        duration_s=duration_s, warm_up_s=warm_up_s
    )
    ratio = (spec.spectrum.f_max_hz / spec.spectrum.f_min_hz) ** (1 / spec.spectrum.n_frequencies)
    n_frequencies = round(np.log(f_max_hz / spec.spectrum.f_min_hz) / np.log(ratio))
    spectrum = dataclasses.replace(spec.spectrum, f_max_hz=f_max_hz, n_frequencies=n_frequencies)
    return dataclasses.replace(spec, spectrum=spectrum)


def synthesize_problem(
    spec: RigSpec,
    effect: tuple[str, Mapping[str, float]] | None = None,
    *,
    truth: Mapping[str, float] | None = None,
    nu: int = 3,
    seed: int = 0,
    noise_m_s2: float = 0.0,
    speed_m_s: float | None = None,
    generator: str = "linear",
    modification: str | None = None,
    output_error: str = "unpaired",
) -> DiagnosisProblem:
    """Measured spectra with a hidden effect, paired with their tracks, for the base ``spec``.

    Args:
        spec: the base rig (the model being calibrated: effect off).
        effect: ``(name, values)`` switched on in the generator only, or None (null case).
        truth: true base parameters (default :data:`WORN_TRUTH`).
        nu: number of runs (>= 2: σ_B is estimated from their scatter, as a study does).
        seed: master seed (tracks and noise).
        noise_m_s2: white sensor noise (m/s² rms); also the model's known noise floor.
        speed_m_s: constant speed (default: the rig's).
        generator: ``linear``, ``pybullet`` or ``pybullet_linear``.
        modification: an out-of-library change of the generator
            (:data:`~.out_of_library.MODIFICATIONS`), or None.
        output_error: ``unpaired`` (the checks judge residuals on σ_B, the scatter between
            runs: what ``susp-bo diagnose`` does) or ``paired`` (each run against its own
            track on the sensor-noise scale plus a robust model error,
            :func:`~.detection_scale.paired_scale`: only for data the simulator reproduces
            up to sensor noise, see that module).
    """
    if nu < 2:
        raise ValueError(f"nu: got {nu}; need >= 2 runs to estimate σ_B")
    if output_error not in ("paired", "unpaired"):
        raise ValueError(f"output_error: got {output_error!r}; allowed 'paired', 'unpaired'")
    truth = dict(WORN_TRUTH if truth is None else truth)
    speed = spec.simulation.speed_m_s if speed_m_s is None else float(speed_m_s)
    spec = spec.with_simulation(speed_m_s=speed)
    true_spec = spec.with_parameters(truth)
    reference = {n: true_spec.parameters[n] for n in spec.calibration_names}
    if effect is not None:
        true_spec = with_effect(true_spec, effect[0], effect[1])
        reference.update(
            {k: v for k, v in true_spec.parameters.items() if k.startswith(f"{effect[0]}_")}
        )
    change = get_modification(modification) if modification is not None else None
    if change is not None:
        true_spec = change.apply_spec(true_spec)
        reference.update(change.parameters)
    sim = spec.simulation
    total = sim.warm_up_s + sim.duration_s
    profile = SpeedProfile.constant(speed, total)
    measured, tracks, n_samples = [], [], []
    rig = Rig(true_spec, linear_elements=generator == "pybullet_linear")
    try:
        for index in range(nu):
            geometry = synthetic_track(true_spec, seed=track_seed(seed, index))
            if generator == "linear":
                response = LinearisedRig(true_spec).response(
                    geometry, speed, time_step_s=1.0 / sim.sample_rate_hz
                )
            elif generator in ("pybullet", "pybullet_linear"):
                response = rig.simulate(geometry, profile)
            else:
                raise ValueError(
                    f"generator: got {generator!r}; allowed linear, pybullet, pybullet_linear"
                )
            signals = np.array(response.accelerations_m_s2, dtype=np.float64)
            if change is not None:
                signals = change.apply_signals(
                    signals, tuple(response.channels), response.sample_rate_hz
                )
            if noise_m_s2 > 0:
                signals += np.random.default_rng([seed, index, 2]).normal(
                    0.0, noise_m_s2, signals.shape
                )
            spectra = log_amplitude_spectra(
                signals, response.sample_rate_hz, response.channels, spec.spectrum
            )
            measured.append(spectra.log_amplitude)
            n_samples.append(int(signals.shape[-1]))
            tracks.append(TrackRun(f"run{index:03d}", geometry, profile))
    finally:
        rig.close()
    measured_array = np.stack(measured)
    return DiagnosisProblem(
        spec=spec,
        names=spec.calibration_names,
        bounds=spec.calibration_bounds,
        measured=measured_array,
        tracks=tuple(tracks),
        error=estimate_output_error(measured_array),
        noise_m_s2=noise_m_s2,
        reference=reference,
        paired=PairedOutputError(noise_m_s2, sim.sample_rate_hz, tuple(n_samples), spec.spectrum)
        if output_error == "paired"
        else None,
    )
