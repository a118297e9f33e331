"""A study on runs whose track was not measured (run files without geometry): refused
before any simulation by the models that simulate each run on its own track, accepted by
``track_statistics`` with the very tracks the same runs with geometry get."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from susp_bo.calibration.study_inputs import StudyError, store_mismatch
from susp_bo.calibration.study_preparation import PreparedStudy, prepare_study, store_fingerprint
from susp_bo.calibration.study_track_statistics import TrackStatisticsPlan, pilot_tracks
from susp_bo.data.run_files import save_run
from susp_bo.data.synthetic import synthesize_runs
from susp_bo.rig.spec import load_rig_spec
from susp_bo.store import EvaluationStore, StoreMismatchError
from susp_bo.study_config import OutputErrorConfig, StudyConfig

PARAMETERS = ("secondary_vertical_damping", "yaw_damper_damping")


@pytest.fixture(scope="module")
def folders(fast_rig: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Two synthetic runs of the fast rig, saved with their geometry (``measured``), without
    it (``untracked``), and one of each (``mixed``)."""
    runs = synthesize_runs(load_rig_spec(fast_rig), nu=2, seed=7, noise_m_s2=0.005)
    folders = {name: tmp_path_factory.mktemp(name) for name in ("measured", "untracked", "mixed")}
    for index, run in enumerate(runs):
        bare = dataclasses.replace(run, geometry=None)
        save_run(run, folders["measured"] / f"run_{index:03d}.h5")
        save_run(bare, folders["untracked"] / f"run_{index:03d}.h5")
        save_run(bare if index == 1 else run, folders["mixed"] / f"run_{index:03d}.h5")
    return folders


def _config(rig: Path, data: Path, out: Path, model: str) -> StudyConfig:
    return StudyConfig(
        rig=str(rig),
        data=data,
        out=out,
        parameters=PARAMETERS,
        output_error=OutputErrorConfig(
            model=model, pilot_runs=50 if model == "track_statistics" else None
        ),
    )


@pytest.mark.parametrize("model", ["unpaired", "paired"])
def test_models_on_the_runs_own_tracks_refuse_runs_without_geometry_naming_the_file(
    fast_rig: Path, folders: dict[str, Path], tmp_path: Path, model: str
) -> None:
    untracked = folders["untracked"]
    with pytest.raises(StudyError) as info:
        prepare_study(_config(fast_rig, untracked, tmp_path / "out", model))
    assert str(info.value) == (
        f"data: {untracked / 'run_000.h5'}: the run has no track geometry (its track was not "
        "measured: no geometry/ group) (1 more of the 2 runs has none: run_001.h5); "
        f"output_error.model = '{model}' simulates every run on its own measured track: "
        'calibrate runs on unmeasured track with [output_error] model = "track_statistics" '
        "in a study .toml (their tracks known only by their statistics), or add the "
        'measured track geometry to the run files (README, "Measured data format") '
        "(nothing was simulated)"
    )
    assert not (tmp_path / "out").exists()  # refused before the results folder is made
    mixed = folders["mixed"]
    with pytest.raises(StudyError, match=rf"data: {mixed / 'run_001.h5'}: the run has no track"):
        prepare_study(_config(fast_rig, mixed, tmp_path / "out", model))
    assert isinstance(
        prepare_study(_config(fast_rig, folders["measured"], tmp_path / "out", model)),
        PreparedStudy,
    )


def test_track_statistics_takes_runs_without_geometry_with_the_same_tracks(
    fast_rig: Path, folders: dict[str, Path], tmp_path: Path
) -> None:
    """The model and pilot tracks never read a geometry: with or without it, the same ids
    and arrays, so the same study result; the store fingerprints differ by the data only."""
    studies = [
        prepare_study(_config(fast_rig, folders[name], tmp_path / name, "track_statistics"))
        for name in ("measured", "untracked", "mixed")
    ]
    measured, untracked, mixed = studies
    assert untracked.runs[0].geometry is None and measured.runs[0].geometry is not None
    assert isinstance(untracked.error, TrackStatisticsPlan) and untracked.error == measured.error
    np.testing.assert_array_equal(untracked.measured, measured.measured)
    for study in (untracked, mixed):
        tracks = [
            study.tracks,
            *(pilot_tracks(study.runs, study.error, study.spec, stage) for stage in (0, 1)),
        ]
        expected = [
            measured.tracks,
            *(pilot_tracks(measured.runs, measured.error, measured.spec, s) for s in (0, 1)),
        ]
        for got, want in zip(tracks, expected, strict=True):
            assert [t.track_id for t in got] == [t.track_id for t in want]
            for a, b in zip(got, want, strict=True):
                assert a.geometry.spacing_m == b.geometry.spacing_m
                np.testing.assert_array_equal(a.geometry.stacked(), b.geometry.stacked())
                assert a.speed is study.runs[0].speed and a.design == b.design
    assert [t.track_id for t in measured.tracks] == ["model000-seed0", "model001-seed0"]
    assert measured.tracks[0].geometry.length_m == 780.0  # the runs' own track length
    fingerprints = [store_fingerprint(study) for study in studies]
    for other in fingerprints[1:]:  # other files: other content digests
        assert {k for k in other if other[k] != fingerprints[0][k]} == {"data"}
    # the realizations' length is a key of its own: a store of session 34 (no such key)
    # is refused naming it, not as "the measured data changed"
    assert fingerprints[0]["realization_length_m"] == "780.0"
    old = {k: v for k, v in fingerprints[0].items() if k != "realization_length_m"}
    EvaluationStore(tmp_path / "old.sqlite", old, create=True).close()
    with pytest.raises(StoreMismatchError) as refused:
        EvaluationStore(tmp_path / "old.sqlite", fingerprints[0], create=False)
    assert refused.value.key == "realization_length_m"
    message = str(store_mismatch(tmp_path, refused.value))
    assert "the length of the model's synthetic track realizations" in message
