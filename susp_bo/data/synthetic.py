"""Synthetic measured runs: a rig with known ("true") parameters on random track.

This is how the tool is validated end to end: the truth is known, so a
calibration of the synthetic runs can be scored against it. Each run gets its
own seeded track realization (German PSD of the rig's track quality), the rig
is simulated at the true parameters, and optional Gaussian sensor noise is
added to the accelerations. The result is in the measured-data format
(:class:`susp_bo.data.measured.MeasuredRun`), so a synthetic data set and a
real one go through exactly the same path.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping

import numpy as np

from susp_bo.data.measured import MeasuredRun
from susp_bo.rig.design import TrackDesign
from susp_bo.rig.simulator import Rig, synthetic_track, synthetic_track_length_m
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.track import SpeedProfile


def track_seed(seed: int, run_index: int) -> int:
    """Seed of run ``run_index``'s track realization (independent streams per run)."""
    return int(np.random.SeedSequence([seed, run_index, 1]).generate_state(1)[0])


MAX_RUNS = 1000
"""Most runs one synthesis makes: a measurement campaign has a handful, and each run is a
full PyBullet simulation (≈ 1 s), so more is a typo (outside probe, session 29: 100 000)."""
MAX_NOISE_M_S2 = 100.0
"""Largest sensor noise (m/s² rms, ≈ 10 g): ten times a bogie's own accelerations, so the
spectra would show nothing but noise (the probe: 1e9 was accepted)."""


def check_synthesis(nu: object, seed: object, noise_m_s2: object) -> None:
    """Refuse what :func:`synthesize_runs` cannot synthesise, before any simulation.

    Raises:
        ValueError: ``nu`` not an integer in 1 … :data:`MAX_RUNS`, ``seed`` not an integer
            >= 0, or ``noise_m_s2`` not a finite real in 0 … :data:`MAX_NOISE_M_S2` (m/s²),
            naming the argument and value.
    """
    if isinstance(nu, bool) or not isinstance(nu, int) or not 1 <= nu <= MAX_RUNS:
        raise ValueError(f"nu: got {nu!r}; expected an integer in 1 … {MAX_RUNS}")
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise ValueError(f"seed: got {seed!r}; expected an integer >= 0")
    real = isinstance(noise_m_s2, numbers.Real) and not isinstance(noise_m_s2, bool)
    if not (real and math.isfinite(noise_m_s2) and 0.0 <= noise_m_s2 <= MAX_NOISE_M_S2):
        raise ValueError(
            f"noise_m_s2: got {noise_m_s2!r}; expected a finite value in 0 … "
            f"{MAX_NOISE_M_S2:g} m/s^2"
        )


def synthesize_runs(
    spec: RigSpec,
    truth: Mapping[str, float] | None = None,
    *,
    nu: int = 3,
    seed: int = 0,
    noise_m_s2: float = 0.0,
    speed_m_s: float | None = None,
    duration_s: float | None = None,
    design: TrackDesign | None = None,
) -> list[MeasuredRun]:
    """Simulate ``nu`` measured runs of ``spec`` at the true parameters.

    Args:
        spec: the rig; its switched-on effects are part of the "true" physics.
        truth: true parameter values (any named parameter of the rig); None keeps
            the rig file's values.
        nu: number of runs (independent track stretches), >= 1.
        seed: master seed, an integer >= 0; run ``i`` uses :func:`track_seed(seed, i)`.
        noise_m_s2: standard deviation of white sensor noise added to every
            channel (m/s²), >= 0.
        speed_m_s: constant speed (m/s); None takes the rig's default.
        duration_s: recorded time after warm-up (s); None takes the rig's default.
        design: the line (curves, cant, gradient) every run follows, with its own
            irregularities; stored in the runs. None is tangent track.

    Returns:
        ``nu`` runs, with the truth, seed, noise and rig name in their metadata.

    Raises:
        ValueError: bad ``nu``, ``seed``, ``noise_m_s2``, speed or duration, a truth the
            rig refuses, or a design that does not cover the runs — all before any
            simulation runs.
    """
    check_synthesis(nu, seed, noise_m_s2)
    changes: dict[str, float] = {}
    if speed_m_s is not None:
        changes["speed_m_s"] = speed_m_s
    if duration_s is not None:
        changes["duration_s"] = duration_s
    if changes:
        spec = spec.with_simulation(**changes)
    true_spec = spec.with_parameters(dict(truth or {}))
    settings = true_spec.simulation
    total_s = settings.warm_up_s + settings.duration_s
    speed = SpeedProfile.constant(settings.speed_m_s, total_s)
    true_values = {name: true_spec.parameter_values()[name] for name in spec.calibration_names}
    if design is not None:
        design.check_covers(0.0, synthetic_track_length_m(true_spec), "the synthetic track")
    runs: list[MeasuredRun] = []
    with Rig(true_spec) as rig:
        for index in range(nu):
            geometry = synthetic_track(true_spec, seed=track_seed(seed, index))
            response = rig.simulate(geometry, speed, design=design)
            accelerations = np.array(response.accelerations_m_s2, dtype=np.float64)
            if noise_m_s2 > 0.0:
                noise_rng = np.random.default_rng([seed, index, 2])
                accelerations = accelerations + noise_rng.normal(
                    0.0, noise_m_s2, size=accelerations.shape
                )
            runs.append(
                MeasuredRun(
                    geometry=geometry,
                    speed=speed,
                    channels=tuple(response.channels),
                    accelerations_m_s2=accelerations,
                    sample_rate_hz=float(response.sample_rate_hz),
                    units=tuple("m/s^2" for _ in response.channels),
                    time_offset_s=float(response.time_s[0]),
                    design=design,
                    metadata={
                        "source": "synthetic",
                        "rig": spec.name,
                        "truth": true_values,
                        "effects": sorted(true_spec.effects),
                        "seed": seed,
                        "run_index": index,
                        "noise_m_s2": noise_m_s2,
                    },
                )
            )
    return runs
