"""A study's summary likelihood: its plan, the runs it accepts, model and pilot tracks (no
simulation)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from susp_bo.calibration.study import loop_start
from susp_bo.calibration.study_inputs import StudyError
from susp_bo.calibration.study_track_statistics import (
    TrackStatisticsPlan,
    check_exchangeable_runs,
    model_tracks,
    pilot_point,
    pilot_tracks,
    plan_for,
    realization_length_m,
)
from susp_bo.calibration.track_statistics_pilot import PilotRecord
from susp_bo.data.synthetic import synthesize_runs
from susp_bo.rig.spec import RigSpec, load_rig_spec
from susp_bo.rig.track import TrackGeometry


@pytest.fixture(scope="module")
def spec(fast_rig: Path) -> RigSpec:
    """The fast rig."""
    return load_rig_spec(fast_rig)


@pytest.fixture(scope="module")
def runs(spec: RigSpec) -> list:
    """Two runs of one experiment (speed, record, no design) on their own tracks."""
    return synthesize_runs(spec, nu=2, seed=3)


def test_the_plan_takes_the_defaults_and_refuses_a_pilot_too_small_for_q() -> None:
    plan = plan_for(None, q=3, n_measured=2, seed=5, track_quality="low")
    assert plan == TrackStatisticsPlan(100, 2, 2, 5, "low")
    assert plan.model == "track_statistics"
    assert plan_for(70, 7, 3, 0, "high").n_simulated == 3  # μ = ν
    with pytest.raises(StudyError, match=r"pilot_runs: 60 .* q = 7 .* at least 70"):
        plan_for(60, 7, 3, 0, "low")


def test_the_pilot_point_is_its_first_fit_in_physical_units() -> None:
    from susp_bo.calibration.track_statistics_pilot import PilotRecord

    bounds = np.array([[10.0, 0.5], [50.0, 8.0]])
    record = PilotRecord(first_fit=(0.0, 0.4), simulations=7, shrinkage=0.1)
    assert pilot_point(record, bounds).tolist() == [10.0, 0.5 + 0.4 * 7.5]


def test_runs_of_another_speed_or_record_are_refused_naming_the_run(
    fast_rig: Path, runs: list
) -> None:
    spec = load_rig_spec(fast_rig)
    names = ["a.h5", "b.h5", "c.h5"]
    check_exchangeable_runs(runs, names[:2])  # one experiment: accepted
    shorter = synthesize_runs(spec, nu=1, seed=4, duration_s=6.0)
    with pytest.raises(StudyError, match=r"data: c\.h5 differs from a\.h5 in its .*record"):
        check_exchangeable_runs([*runs, *shorter], names)
    slower = synthesize_runs(spec, nu=1, seed=4, speed_m_s=70.0)
    with pytest.raises(StudyError, match=r"c\.h5 differs from a\.h5 in its speed profile"):
        check_exchangeable_runs([*runs, *slower], names)


def test_model_and_pilot_tracks_are_seeded_realizations_under_the_runs_speed_and_length(
    runs: list, spec: RigSpec
) -> None:
    plan = plan_for(50, q=2, n_measured=2, seed=11, track_quality="low")
    tracks = model_tracks(runs, plan, spec)
    assert [t.track_id for t in tracks] == [f"model{j:03d}-seed11" for j in range(2)]
    for j, track in enumerate(tracks):
        template = runs[j]
        assert track.speed is runs[0].speed and track.design is runs[0].design
        assert track.geometry.length_m == pytest.approx(template.geometry.length_m, abs=0.25)
        assert not np.array_equal(
            track.geometry.vertical_m[:100], template.geometry.vertical_m[:100]
        )
    again = model_tracks(runs, plan, spec)  # deterministic: a resume finds the same tracks
    assert all(
        np.array_equal(a.geometry.vertical_m, b.geometry.vertical_m) for a, b in zip(tracks, again)
    )
    stage0, stage1 = pilot_tracks(runs, plan, spec, 0), pilot_tracks(runs, plan, spec, 1)
    assert len(stage0) == len(stage1) == 50
    ids = {t.track_id for t in (*tracks, *stage0, *stage1)}
    assert len(ids) == 2 + 100  # every realization its own key in the store
    verticals = [t.geometry.vertical_m[:200] for t in (*tracks, *stage0[:5], *stage1[:5])]
    assert len({v.tobytes() for v in verticals}) == len(verticals)  # all different draws
    # another seed, other realizations
    other = model_tracks(runs, plan_for(50, 2, 2, 12, "low"), spec)
    assert not np.array_equal(other[0].geometry.vertical_m, tracks[0].geometry.vertical_m)


def test_the_realizations_follow_the_rigs_track_psd(runs: list, spec: RigSpec) -> None:
    """The pilot's tracks are draws of the PSD the plan names: their rms matches a direct draw."""
    low = pilot_tracks(runs, plan_for(50, 1, 2, 0, "low"), spec, 0)
    high = pilot_tracks(runs, plan_for(50, 1, 2, 0, "high"), spec, 0)
    rms_low = np.sqrt(np.mean([np.mean(t.geometry.vertical_m**2) for t in low]))
    rms_high = np.sqrt(np.mean([np.mean(t.geometry.vertical_m**2) for t in high]))
    reference = np.sqrt(
        np.mean(
            [
                np.mean(
                    TrackGeometry.synthetic("low", runs[0].geometry.length_m, seed=s).vertical_m
                    ** 2
                )
                for s in range(50)
            ]
        )
    )
    assert rms_low == pytest.approx(reference, rel=0.25)
    assert rms_high > 1.25 * rms_low  # "high" is the PSD of high disturbance


def test_the_realizations_are_as_long_as_the_runs_need_with_or_without_geometry(
    runs: list, spec: RigSpec
) -> None:
    """One rule from the speed record and the axle span, never from a geometry: the same
    runs without geometry get the same tracks, bit for bit; for synthetic runs these are the
    tracks the longest geometry gave before (780.0 m on the fast rig, 3121 samples)."""
    assert realization_length_m(runs, spec) == pytest.approx(83.33 * 9.0 + 20.0 + 10.0)
    bare = [dataclasses.replace(run, geometry=None) for run in runs]
    check_exchangeable_runs(bare, ["a.h5", "b.h5"])
    check_exchangeable_runs([runs[0], bare[1]], ["a.h5", "b.h5"])  # a mixed folder
    plan = plan_for(50, q=2, n_measured=2, seed=11, track_quality="low")
    for make in (
        lambda r: model_tracks(r, plan, spec),
        lambda r: pilot_tracks(r, plan, spec, 1)[:3],
    ):
        with_geometry, without = make(runs), make(bare)
        assert [t.track_id for t in with_geometry] == [t.track_id for t in without]
        for a, b in zip(with_geometry, without):
            np.testing.assert_array_equal(a.geometry.stacked(), b.geometry.stacked())
            assert a.geometry.spacing_m == b.geometry.spacing_m == 0.25
            assert a.geometry.length_m == runs[0].geometry.length_m == 780.0


def test_the_loop_starts_from_the_pilots_fit_cold_or_warm() -> None:
    """Cold: the fit replaces one space-filling point (``initial_points``). Warm (a
    monitoring campaign's design, centred on the previous posterior): the fit is one more
    point after that design, which is kept whole. Without a pilot nothing is added."""
    bounds = np.array([[1.0, 10.0], [3.0, 30.0]])
    record = PilotRecord(first_fit=(0.25, 0.5), simulations=0, shrinkage=0.1)
    study = SimpleNamespace(pilot=record, bounds=bounds)
    fit = np.array([[1.5, 20.0]])  # the fit in physical units
    design, points = loop_start(study, None)
    assert design is None and np.array_equal(points, fit)
    warm = np.array([[2.0, 15.0], [2.1, 16.0], [1.2, 28.0]])
    design, points = loop_start(study, warm)
    assert points is None and np.array_equal(design, np.vstack([warm, fit]))
    cold = SimpleNamespace(pilot=None, bounds=bounds)
    assert loop_start(cold, None) == (None, None)
    design, points = loop_start(cold, warm)
    assert design is warm and points is None


def test_a_pilot_fit_on_an_upper_face_stays_inside_c_w() -> None:
    """A fit at a face (unit coordinate 1.0) can round one step past the upper bound in
    physical units (bounds (0.001, 0.01): 0.001 + 1.0 x 0.009 > 0.01); a warm design
    holding it would be refused by calibrate (second review, session 36)."""
    bounds = np.array([[0.001, 1.0], [0.01, 3.0]])
    assert bounds[0, 0] + 1.0 * (bounds[1, 0] - bounds[0, 0]) > bounds[1, 0]  # the rounding
    record = PilotRecord(first_fit=(1.0, 0.0), simulations=0, shrinkage=0.1)
    point = pilot_point(record, bounds)
    assert point.tolist() == [0.01, 1.0]
    design, _ = loop_start(SimpleNamespace(pilot=record, bounds=bounds), np.array([[0.005, 2.0]]))
    assert np.all((bounds[0] <= design) & (design <= bounds[1]))
