"""A pilot run (:func:`simulate_noisy_spectra`) is a measured run: same spectra, same noise;
a track stretch without geometry is refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from susp_bo.calibration.evaluation import TrackRun, simulate_noisy_spectra, simulate_spectra
from susp_bo.calibration.study_inputs import measured_log_spectra
from susp_bo.data.synthetic import synthesize_runs
from susp_bo.rig.spec import load_rig_spec

TRUTH = {"secondary_vertical_damping": 30.0e3, "yaw_damper_damping": 3.5e6}


def test_a_noisy_simulation_gives_the_spectra_of_the_synthetic_run_with_that_noise(
    fast_rig: Path,
) -> None:
    spec = load_rig_spec(fast_rig)
    run = synthesize_runs(spec, TRUTH, nu=1, seed=7, noise_m_s2=0.02)[0]
    measured = measured_log_spectra(spec, [run])[0]
    # synthesize_runs draws run 0's noise from default_rng([seed, 0, 2])
    pilot = simulate_noisy_spectra(spec, TRUTH, run.geometry, run.speed, None, 0.02, [7, 0, 2])
    np.testing.assert_allclose(pilot, measured, rtol=0.0, atol=1e-9)
    quiet = simulate_noisy_spectra(spec, TRUTH, run.geometry, run.speed, None, 0.0, 0)
    np.testing.assert_array_equal(quiet, simulate_spectra(spec, TRUTH, run.geometry, run.speed))
    other = simulate_noisy_spectra(spec, TRUTH, run.geometry, run.speed, None, 0.02, [7, 0, 3])
    assert np.max(np.abs(other - measured)) > 1e-3  # another draw of the noise


def test_a_track_run_without_geometry_is_refused_naming_it() -> None:
    from susp_bo.rig.track import SpeedProfile

    with pytest.raises(ValueError, match=r"TrackRun 'run007': geometry is NoneType; expected"):
        TrackRun("run007", None, SpeedProfile.constant(20.0, 10.0))  # type: ignore[arg-type]
