"""Tests of susp_bo.data.run_validation: every problem of a run named at once."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from susp_bo.data.measured import MeasuredDataError, MeasuredRun
from susp_bo.data.run_validation import validate_run
from susp_bo.rig.spectra import SpectrumSettings
from susp_bo.rig.track import SpeedProfile


def test_validate_accepts_a_good_run(small_run: MeasuredRun) -> None:
    spectrum = SpectrumSettings(f_min_hz=1.0, f_max_hz=20.0, n_frequencies=8, segment_s=2.0)
    validate_run(small_run, ["carbody_z"], spectrum, axle_span_m=17.5)


def test_validate_lists_every_problem(small_run: MeasuredRun) -> None:
    data = np.array(small_run.accelerations_m_s2)
    data[0, 100:120] = np.nan
    data[0, 300] = np.nan
    broken = MeasuredRun(
        small_run.geometry,
        small_run.speed,
        small_run.channels,
        data,
        small_run.sample_rate_hz,
        units=("m/s^2", "g"),
    )
    spectrum = SpectrumSettings(f_min_hz=1.0, f_max_hz=60.0, n_frequencies=8, segment_s=2.0)
    with pytest.raises(MeasuredDataError) as info:
        validate_run(
            broken, ["carbody_z", "bogie_y", "axle_z"], spectrum, axle_span_m=30.0, source="r.h5"
        )
    message = str(info.value)
    assert message.startswith("r.h5: ")
    assert "missing channel(s) ['axle_z']" in message
    assert "unit mismatch: 'bogie_y' in 'g'; expected m/s^2" in message
    assert "'carbody_z' has NaN runs: 2 run(s), 21 samples; longest 0.2 s at t = 1 s" in message
    assert "Nyquist 50 Hz is not above f_max_hz = 60 Hz" in message
    assert "track shorter than the run: the geometry covers 100 m" in message


def test_validate_record_and_speed_lengths(small_run: MeasuredRun) -> None:
    spectrum = SpectrumSettings(f_min_hz=0.5, f_max_hz=20.0, n_frequencies=8, segment_s=8.0)
    with pytest.raises(MeasuredDataError, match=r"duration_s: got 4 s, shorter than one Welch"):
        validate_run(small_run, settings=spectrum)
    short_speed = MeasuredRun(
        small_run.geometry,
        SpeedProfile.constant(20.0, 2.0),
        small_run.channels,
        small_run.accelerations_m_s2,
        100.0,
    )
    with pytest.raises(MeasuredDataError, match=r"speed record too short: it covers 0 … 2 s"):
        validate_run(short_speed)


def test_track_irregularities_written_in_mm_are_named(small_run: MeasuredRun) -> None:
    """Outside probe, session 29: an HDF5 run whose vertical profile was in mm passed, every
    design simulation ran, and then "every log L evaluation failed" named no file."""
    geometry = small_run.geometry
    in_mm = dataclasses.replace(
        geometry, vertical_m=1000.0 * (np.asarray(geometry.vertical_m) + 0.05)
    )
    vertical = np.asarray(in_mm.vertical_m)
    assert float(np.max(np.abs(vertical - np.median(vertical)))) > 0.1  # not plausible in m
    run = dataclasses.replace(small_run, geometry=in_mm)
    with pytest.raises(MeasuredDataError, match=r"r\.h5: vertical_m deviates up to .* m from"):
        validate_run(run, source="r.h5")
    with pytest.raises(MeasuredDataError, match=r"was it written in mm\?"):
        validate_run(run)
    validate_run(small_run)  # the run in metres passes
