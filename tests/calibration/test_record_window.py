"""The measured samples a study compares are the ones the simulation records: an imported
run starting at t = 0 loses its first warm-up seconds, and what cannot be aligned is
refused (checked against the rig's own record and against the physics of a shifted clock)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from susp_bo.calibration.evaluation import simulate_spectra
from susp_bo.calibration.record_window import (
    RecordWindowError,
    check_track_covers_the_speed_record,
    compared_window,
)
from susp_bo.calibration.study_inputs import StudyError, measured_log_spectra
from susp_bo.calibration.study_preparation import prepare_study
from susp_bo.data.measured import MeasuredRun
from susp_bo.data.run_files import save_run
from susp_bo.data.run_validation import validate_run
from susp_bo.data.synthetic import synthesize_runs
from susp_bo.rig.simulator import Rig, axle_span_m, recorded_samples, synthetic_track
from susp_bo.rig.spec import load_rig_spec
from susp_bo.rig.track import SpeedProfile, TrackGeometry
from susp_bo.study_config import OutputErrorConfig, StudyConfig

TRUTH = {"secondary_vertical_damping": 30.0e3, "yaw_damper_damping": 3.5e6}
CLOCK_S = 2.5
"""The imported run's clock starts this long after the physical run's (a whole number of
track samples at the fast rig's speed)."""


def _shifted(geometry: TrackGeometry, metres: float) -> TrackGeometry:
    k = round(metres / geometry.spacing_m)
    assert abs(k * geometry.spacing_m - metres) < 1e-9
    return TrackGeometry(
        geometry.spacing_m,
        geometry.vertical_m[k:],
        geometry.alignment_m[k:],
        geometry.cross_level_rad[k:],
        geometry.gauge_m[k:],
    )


def _speed_record_to(run: MeasuredRun, end_s: float) -> MeasuredRun:
    """``run`` with its (constant) speed record ending at ``end_s``."""
    return dataclasses.replace(run, speed=SpeedProfile.constant(run.speed.speed_m_s[0], end_s))


@pytest.fixture(scope="module")
def imported(fast_rig: Path) -> tuple[MeasuredRun, TrackGeometry]:
    """A run as an importer makes it: the physical run (3 s warm-up, 6 s recorded, no
    noise) on a clock that starts 2.5 s in, its first sample at 0.505 s, a speed record
    ending half a sample after the last one, and the track from the new clock's origin (80 m/s)."""
    spec = load_rig_spec(fast_rig)
    speed_m_s = 80.0  # 2.5 s of it: 800 track samples of 0.25 m
    physical = spec.with_simulation(warm_up_s=3.0, duration_s=6.0, speed_m_s=speed_m_s)
    track = synthetic_track(physical, seed=11)
    with Rig(physical) as rig:
        response = rig.simulate(track, SpeedProfile.constant(speed_m_s, 9.0), TRUTH)
    run = MeasuredRun(
        geometry=_shifted(track, speed_m_s * CLOCK_S),
        speed=SpeedProfile.constant(speed_m_s, 9.0 - CLOCK_S),
        channels=tuple(response.channels),
        accelerations_m_s2=np.asarray(response.accelerations_m_s2),
        sample_rate_hz=float(response.sample_rate_hz),
        time_offset_s=float(response.time_s[0]) - CLOCK_S,
    )
    return run, run.geometry


def test_recorded_samples_are_what_the_rig_records(fast_rig: Path) -> None:
    base = load_rig_spec(fast_rig)
    track = synthetic_track(base, seed=1)
    speed = base.simulation.speed_m_s
    # warm-ups on and off the 10 ms record grid; speed records on the step grid, off it
    # rounding down, and off it rounding up (the step count must not pass the record)
    for spec in (base, base.with_simulation(warm_up_s=1.013)):
        with Rig(spec) as rig:
            for total_s in (9.0, 6.497, 6.4985):
                response = rig.simulate(track, SpeedProfile.constant(speed, total_s))
                first_s, n, interval_s = recorded_samples(spec, total_s)
                assert n == len(response.time_s), (spec.simulation.warm_up_s, total_s)
                assert first_s == pytest.approx(response.time_s[0], abs=1e-12)
                assert interval_s == pytest.approx(np.diff(response.time_s).mean(), rel=1e-12)


def test_a_synthetic_run_is_compared_whole_and_unchanged(fast_rig: Path) -> None:
    spec = load_rig_spec(fast_rig)
    (run,) = synthesize_runs(spec, TRUTH, nu=1, seed=3)
    assert compared_window(run, spec, "run_000.h5") is run
    # the same record labelled at its intervals' starts (as a logger writes it), not their
    # centres (as the rig does): the same samples, compared whole
    starts = dataclasses.replace(run, time_offset_s=run.time_offset_s - 0.5 / run.sample_rate_hz)
    assert compared_window(starts, spec, "run_000.h5") is starts


def test_an_imported_run_loses_its_first_warm_up_seconds_and_then_matches_the_simulation(
    fast_rig: Path, imported: tuple[MeasuredRun, TrackGeometry]
) -> None:
    spec = load_rig_spec(fast_rig)  # warm-up 1 s: records 1.005 … 6.495 s of the new clock
    run, geometry = imported
    window = compared_window(run, spec, "run_000.h5")
    assert window.n_samples == 550 and run.n_samples == 600
    assert window.time_offset_s == pytest.approx(1.005, abs=1e-9)
    np.testing.assert_array_equal(window.accelerations_m_s2, run.accelerations_m_s2[:, 50:])
    simulated = simulate_spectra(spec, TRUTH, geometry, run.speed)
    compared, whole = measured_log_spectra(spec, [window, run])
    aligned = float(np.sqrt(np.mean((compared - simulated) ** 2)))
    misaligned = float(np.sqrt(np.mean((whole - simulated) ** 2)))
    # same physics on the same stretch of track: only the simulation's start from rest
    # differs (0.020 of log amplitude here); the whole record holds 0.5 s the simulation
    # never recorded (0.33: sixteen times that)
    assert aligned < 0.04, aligned
    assert misaligned > 8 * aligned, (aligned, misaligned)


def test_a_run_sampled_faster_than_the_rig_keeps_the_same_stretch_of_track(
    fast_rig: Path, imported: tuple[MeasuredRun, TrackGeometry]
) -> None:
    """The same record at 1000 Hz (each 10 ms sample held for ten 1 ms samples, labelled
    at their centres): the window holds the same stretch, ten times the samples."""
    spec = load_rig_spec(fast_rig)
    run, _ = imported
    fine = dataclasses.replace(
        run,
        accelerations_m_s2=np.repeat(run.accelerations_m_s2, 10, axis=1),
        sample_rate_hz=10 * run.sample_rate_hz,
        time_offset_s=run.time_offset_s - 0.0045,  # the first 1 ms sample's centre
    )
    window = compared_window(fine, spec, "run_000.h5")
    coarse = compared_window(run, spec, "run_000.h5")
    np.testing.assert_array_equal(
        window.accelerations_m_s2, np.repeat(coarse.accelerations_m_s2, 10, axis=1)
    )


def test_what_cannot_be_aligned_is_refused_naming_the_file_and_both_windows(
    fast_rig: Path, imported: tuple[MeasuredRun, TrackGeometry]
) -> None:
    spec = load_rig_spec(fast_rig)
    run, _ = imported
    late = spec.with_simulation(warm_up_s=0.25)  # records from 0.2525 s: before the data
    with pytest.raises(RecordWindowError, match=r"run_000\.h5: its accelerations cover 0\.505"):
        compared_window(run, late, "run_000.h5")
    with pytest.raises(RecordWindowError, match=r"set the rig's simulation\.warm_up_s to 0\.505"):
        compared_window(run, late, "run_000.h5")
    longer = _speed_record_to(run, 7.0)  # 0.5 s past the last sample
    with pytest.raises(RecordWindowError, match=r"cut it to end at the last sample \(6\.495 s\)"):
        compared_window(longer, spec, "run_000.h5")
    check_track_covers_the_speed_record(run, spec, "run_000.h5")  # long enough
    geometry = run.geometry
    short = dataclasses.replace(  # 539.75 m: the accelerations need 539.6 m, the record 540
        run,
        geometry=TrackGeometry(
            geometry.spacing_m,
            *(getattr(geometry, c)[:2160] for c in ("vertical_m", "alignment_m")),
            *(getattr(geometry, c)[:2160] for c in ("cross_level_rad", "gauge_m")),
        ),
    )
    validate_run(short, axle_span_m=axle_span_m(spec))  # long enough for the accelerations
    with pytest.raises(RecordWindowError, match=r"track shorter than its simulation"):
        check_track_covers_the_speed_record(short, spec, "run_000.h5")
    long_warm_up = spec.with_simulation(warm_up_s=3.0)  # 3.5 s left: under a 4 s segment
    with pytest.raises(RecordWindowError, match=r"after the warm-up \(3\.5 s\) is too short"):
        compared_window(run, long_warm_up, "run_000.h5")
    past_the_record = spec.with_simulation(warm_up_s=7.0)  # the record lasts 6.5 s
    with pytest.raises(RecordWindowError, match=r"ends before the warm-up leaves 2 samples"):
        compared_window(run, past_the_record, "run_000.h5")


def test_a_study_refuses_a_run_it_cannot_align_before_any_simulation(
    fast_rig: Path, imported: tuple[MeasuredRun, TrackGeometry], tmp_path: Path
) -> None:
    run, _ = imported
    data = tmp_path / "data"
    data.mkdir()
    longer = _speed_record_to(run, 7.0)  # 0.5 s past the last sample
    save_run(run, data / "run_000.h5")
    save_run(longer, data / "run_001.h5")
    config = StudyConfig(
        rig=str(fast_rig),
        data=data,
        out=tmp_path / "out",
        parameters=tuple(TRUTH),
        output_error=OutputErrorConfig(model="paired", sensor_noise_m_s2=0.005),
    )
    with pytest.raises(StudyError, match=r"data: .*run_001\.h5: its accelerations cover"):
        prepare_study(config)
    assert not (tmp_path / "out").exists()
    (data / "run_001.h5").unlink()
    study = prepare_study(config)  # run 0 alone: compared over the simulated record
    assert study.error.n_samples == (550,)
