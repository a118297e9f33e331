"""A study on runs with a track design: measured spectra lose the design's quasi-static part."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from susp_bo.calibration.study_inputs import design_removal
from susp_bo.calibration.study_preparation import prepare_study
from susp_bo.data.measured import MeasuredRun, save_run
from susp_bo.rig.assembly import build_assembly
from susp_bo.rig.curving import reference_specific_force
from susp_bo.rig.line_file import design_from_segments
from susp_bo.rig.simulator import synthetic_track
from susp_bo.rig.spec import load_rig_spec
from susp_bo.rig.track import SpeedProfile
from susp_bo.study_config import StudyConfig


def test_designed_runs_feed_the_study_with_the_quasi_static_part_removed(tmp_path: Path) -> None:
    spec = load_rig_spec("hst_trailer")
    sim = spec.simulation
    total = sim.warm_up_s + sim.duration_s
    speed = SpeedProfile.constant(sim.speed_m_s, total)
    design = design_from_segments(
        [
            {"type": "tangent", "length_m": 500.0},
            {"type": "transition", "length_m": 300.0},
            {
                "type": "curve",
                "length_m": 3000.0,
                "radius_m": 4000.0,
                "cant_mm": 100.0,
                "direction": "right",
            },
        ]
    )
    rng = np.random.default_rng(0)
    time = sim.warm_up_s + np.arange(round(sim.duration_s * sim.sample_rate_hz)) / 100.0
    dynamic = rng.normal(0.0, 0.05, size=(len(spec.channels), time.size))
    quasi_static = reference_specific_force(build_assembly(spec), spec.sensors, design, speed, time)
    assert np.max(np.abs(quasi_static)) > 0.5  # V²/R − g φ ≈ 1.08 m/s² in the curve
    for index in range(2):
        run = MeasuredRun(
            geometry=synthetic_track(spec, seed=index),
            speed=speed,
            channels=spec.channels,
            accelerations_m_s2=dynamic + quasi_static,
            sample_rate_hz=sim.sample_rate_hz,
            time_offset_s=float(time[0]),
            design=design,
        )
        save_run(run, tmp_path / "data" / f"run_{index:03d}.h5")
    study = prepare_study(
        StudyConfig(rig="hst_trailer", data=tmp_path / "data", out=tmp_path / "out")
    )
    assert all(track.design is not None for track in study.tracks)
    np.testing.assert_allclose(design_removal(spec, study.runs[0]), quasi_static, atol=1e-12)
    # the measured spectra are those of the dynamic part alone
    plain = MeasuredRun(
        study.runs[0].geometry,
        speed,
        spec.channels,
        dynamic,
        sim.sample_rate_hz,
        time_offset_s=float(time[0]),
    )
    np.testing.assert_allclose(
        study.measured[0], plain.spectra(spec.spectrum).log_amplitude, atol=1e-9
    )
