"""Tests of susp_bo.data.measured: the MeasuredRun container and the HDF5 format."""

from __future__ import annotations

import dataclasses
import itertools
import re
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import susp_bo.data.measured as measured
from susp_bo.data.measured import (
    MeasuredDataError,
    MeasuredRun,
    load_run,
    load_runs,
    nan_runs,
    runs_channels,
    save_run,
)
from susp_bo.data.run_validation import validate_run
from susp_bo.rig.line_file import design_from_segments
from susp_bo.rig.spectra import SpectrumSettings, log_amplitude_spectra
from susp_bo.rig.track import GEOMETRY_COMPONENTS, SpeedProfile, TrackGeometry

# --- the container ------------------------------------------------------------------------


def test_run_properties_and_canonical_units(small_run: MeasuredRun) -> None:
    assert small_run.n_samples == 400 and small_run.duration_s == pytest.approx(4.0)
    np.testing.assert_allclose(small_run.time_s[:3], [0.0, 0.01, 0.02])
    assert not small_run.accelerations_m_s2.flags.writeable
    run = MeasuredRun(
        small_run.geometry,
        small_run.speed,
        ("a", "b"),
        np.ones((2, 10)),
        50.0,
        units=("m/s2", "G"),
        metadata={"k": np.float64(2.5), "n": np.int64(3), "v": np.arange(2)},
    )
    assert run.units == ("m/s^2", "g")
    assert run.metadata == {"k": 2.5, "n": 3, "v": [0, 1]}
    assert type(run.metadata["k"]) is float


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        ({"channels": ("a", "a")}, r"channels: duplicate names \['a'\]"),
        ({"channels": ("a", "")}, r"channels: need one or more non-empty names"),
        ({"channels": ("a",)}, r"accelerations_m_s2: shape \(2, 400\).*C = 1"),
        ({"accelerations_m_s2": np.zeros((2, 1))}, r"n_t >= 2"),
        ({"accelerations_m_s2": np.full((2, 5), np.inf)}, r"channel 'carbody_z' contains inf"),
        ({"accelerations_m_s2": [["x", "y"], ["z", "w"]]}, r"accelerations_m_s2: not numeric"),
        ({"accelerations_m_s2": np.ones((2, 5)) * (1 + 1j)}, r"accelerations_m_s2: complex"),
        ({"sample_rate_hz": -100.0}, r"sample_rate_hz: got -100.0 Hz; must be > 0 Hz"),
        ({"sample_rate_hz": float("nan")}, r"sample_rate_hz: got nan; must be finite"),
        ({"sample_rate_hz": "100"}, r"sample_rate_hz: got '100'; expected a real number"),
        ({"time_offset_s": -1.0}, r"time_offset_s: got -1.0 s; must be >= 0"),
        ({"units": ("m/s^2",)}, r"units: need one string per channel \(2\)"),
        ({"metadata": {"f": object()}}, r"metadata: must be JSON-compatible"),
        (  # None is a run whose track was not measured (test_untracked_runs.py)
            {"geometry": np.zeros(3)},
            r"geometry: expected a TrackGeometry or None \(track not measured\), got ndarray",
        ),
        ({"speed": 83.0}, r"speed: expected a SpeedProfile, got float"),
    ],
)
def test_run_validation_names_field_and_value(
    small_run: MeasuredRun, change: dict[str, object], pattern: str
) -> None:
    fields = {
        "geometry": small_run.geometry,
        "speed": small_run.speed,
        "channels": small_run.channels,
        "accelerations_m_s2": small_run.accelerations_m_s2,
        "sample_rate_hz": small_run.sample_rate_hz,
        "units": small_run.units,
        "metadata": small_run.metadata,
        **change,
    }
    with pytest.raises(MeasuredDataError, match=pattern):
        MeasuredRun(**fields)  # type: ignore[arg-type]


def test_select_to_si_and_spectra(small_run: MeasuredRun) -> None:
    swapped = small_run.select(["bogie_y", "carbody_z"])
    np.testing.assert_array_equal(swapped.channel("carbody_z"), small_run.channel("carbody_z"))
    assert swapped.channels == ("bogie_y", "carbody_z")
    with pytest.raises(MeasuredDataError, match=r"missing channel\(s\) \['x'\]"):
        small_run.select(["x"])
    in_g = MeasuredRun(
        small_run.geometry, small_run.speed, ("a",), np.full((1, 4), 0.5), 10.0, ("g",)
    )
    np.testing.assert_allclose(in_g.to_si().accelerations_m_s2, 0.5 * 9.80665)
    assert in_g.to_si().units == ("m/s^2",)
    odd = MeasuredRun(small_run.geometry, small_run.speed, ("a",), np.ones((1, 4)), 10.0, ("V",))
    with pytest.raises(MeasuredDataError, match=r"cannot convert \[\('a', 'V'\)\]"):
        odd.to_si()
    spectrum = SpectrumSettings(f_min_hz=1.0, f_max_hz=20.0, n_frequencies=8, segment_s=2.0)
    direct = log_amplitude_spectra(
        small_run.accelerations_m_s2, 100.0, small_run.channels, spectrum
    )
    np.testing.assert_array_equal(small_run.spectra(spectrum).log_amplitude, direct.log_amplitude)
    with pytest.raises(MeasuredDataError, match=r"unit mismatch: 'a' in 'g'"):
        in_g.spectra(spectrum)


@settings(max_examples=60, deadline=None)
@given(mask=st.lists(st.booleans(), min_size=1, max_size=60))
def test_nan_runs_reconstruct_the_mask(mask: list[bool]) -> None:
    values = np.where(mask, np.nan, 1.0)
    rebuilt = np.zeros(len(mask), dtype=bool)
    runs = nan_runs(values)
    for start, length in runs:
        assert length >= 1
        rebuilt[start : start + length] = True
    np.testing.assert_array_equal(rebuilt, mask)
    # runs are maximal: separated by at least one valid sample
    assert all(b[0] > a[0] + a[1] for a, b in itertools.pairwise(runs))


# --- HDF5 -----------------------------------------------------------------------------------


def _assert_same_run(a: MeasuredRun, b: MeasuredRun) -> None:
    for name in GEOMETRY_COMPONENTS:
        assert getattr(a.geometry, name).tobytes() == getattr(b.geometry, name).tobytes()
    assert a.geometry.spacing_m == b.geometry.spacing_m
    assert a.speed.time_s.tobytes() == b.speed.time_s.tobytes()
    assert a.speed.speed_m_s.tobytes() == b.speed.speed_m_s.tobytes()
    assert a.accelerations_m_s2.tobytes() == b.accelerations_m_s2.tobytes()
    assert (a.channels, a.units, a.sample_rate_hz, a.time_offset_s, a.metadata) == (
        b.channels,
        b.units,
        b.sample_rate_hz,
        b.time_offset_s,
        b.metadata,
    )


def test_save_load_round_trip_is_exact(small_run: MeasuredRun, tmp_path: Path) -> None:
    path = save_run(small_run, tmp_path / "sub" / "run.h5")
    loaded = load_run(path)
    _assert_same_run(small_run, loaded)
    assert loaded.content_digest() == small_run.content_digest()
    assert [p.name for p in path.parent.iterdir()] == ["run.h5"]  # no temporary left behind
    plain = tmp_path / "plain"
    plain.write_bytes(b"")  # a file made the ordinary way: mode 0666 less the umask
    assert path.stat().st_mode & 0o777 == plain.stat().st_mode & 0o777  # was 0600


def test_file_layout_matches_the_documentation(small_run: MeasuredRun, tmp_path: Path) -> None:
    path = save_run(small_run, tmp_path / "run.h5")
    items: list[str] = []
    with h5py.File(path, "r") as file:
        file.visit(items.append)
        assert file.attrs["format"] == "susp_bo.measured_run"
        assert file.attrs["format_version"] == 2
        assert file["geometry"].attrs["spacing_m"] == small_run.geometry.spacing_m
        assert file["geometry/cross_level_rad"].attrs["units"] == "rad"
        assert file["accelerations/data"].shape == (2, 400)
        assert list(file["accelerations/channels"].asstr()[()]) == ["carbody_z", "bogie_y"]
    documentation = measured.__doc__ or ""
    for item in items:  # every group and dataset written is documented
        assert item.rsplit("/", 1)[-1] in documentation, item


def test_load_runs_sorted_and_channel_consistent(tmp_path: Path, run_factory: Callable) -> None:
    save_run(run_factory(2, ("a", "b")), tmp_path / "run_b.h5")
    save_run(run_factory(1, ("b", "a")), tmp_path / "run_a.hdf5")
    (tmp_path / "notes.txt").write_text("not a run")
    runs = load_runs(tmp_path)
    assert [r.metadata["seed"] for r in runs] == [1, 2]
    assert runs_channels(runs) == ("b", "a")
    np.testing.assert_array_equal(runs[1].channel("a"), run_factory(2, ("a", "b")).channel("a"))
    assert [r.channels for r in load_runs(tmp_path, channels=["a"])] == [("a",), ("a",)]
    with pytest.raises(MeasuredDataError, match=r"run_a.hdf5: missing channel\(s\) \['c'\]"):
        load_runs(tmp_path, channels=["a", "c"])
    save_run(run_factory(3, ("a", "c")), tmp_path / "run_c.h5")
    with pytest.raises(MeasuredDataError, match=r"run_c.h5: channel set differs.*\['b'\].*\['c'\]"):
        load_runs(tmp_path)


def test_save_run_refuses_a_folder_and_a_suffix_load_runs_skips(
    small_run: MeasuredRun, tmp_path: Path
) -> None:
    """A folder gave an IsADirectoryError quoting a temporary path; a .txt file was written
    and then silently ignored by load_runs."""
    with pytest.raises(MeasuredDataError, match=f"path: {re.escape(str(tmp_path))} is a folder"):
        save_run(small_run, tmp_path)
    with pytest.raises(MeasuredDataError, match=r"suffix '\.txt'.*\['\.h5', '\.hdf5'\]"):
        save_run(small_run, tmp_path / "run.txt")
    assert list(tmp_path.iterdir()) == []  # nothing written, no temporary left


def test_an_entry_named_like_a_run_that_is_no_file_is_named_not_skipped(
    small_run: MeasuredRun, tmp_path: Path
) -> None:
    """Outside probe, session 29: a folder or a broken link named run_000.h5 was skipped,
    and the study said it "needs at least 2 measured runs (found 1)"."""
    save_run(small_run, tmp_path / "run_001.h5")
    (tmp_path / "run_000.h5").mkdir()
    with pytest.raises(
        MeasuredDataError, match=r"run_000\.h5: named like a measured run but a folder"
    ):
        load_runs(tmp_path)
    (tmp_path / "run_000.h5").rmdir()
    (tmp_path / "run_000.h5").symlink_to(tmp_path / "gone.h5")
    with pytest.raises(MeasuredDataError, match=r"run_000\.h5: .* but a link to nothing"):
        load_runs(tmp_path)
    (tmp_path / "run_000.h5").unlink()
    assert len(load_runs(tmp_path)) == 1


def test_load_runs_refuses_a_str_or_empty_channel_list(
    small_run: MeasuredRun, tmp_path: Path
) -> None:
    """A str was split into one-letter channel names."""
    save_run(small_run, tmp_path / "run.h5")
    with pytest.raises(MeasuredDataError, match=r"channels: 'carbody_z' is not allowed.*\["):
        load_runs(tmp_path, channels="carbody_z")
    with pytest.raises(MeasuredDataError, match=r"channels: \[\] is not allowed"):
        load_runs(tmp_path, channels=[])
    with pytest.raises(MeasuredDataError, match=r"channels: 'bogie_y' is not allowed"):
        small_run.select("bogie_y")
    assert load_runs(tmp_path, channels=iter(["bogie_y"]))[0].channels == ("bogie_y",)


def test_load_errors_for_missing_places(tmp_path: Path) -> None:
    with pytest.raises(MeasuredDataError, match=r"holds no measured runs"):
        load_runs(tmp_path)
    with pytest.raises(MeasuredDataError, match=r"not a folder"):
        load_runs(tmp_path / "absent")
    with pytest.raises(MeasuredDataError, match=r"no such file"):
        load_run(tmp_path / "absent.h5")


def test_nan_dropouts_load_only_when_allowed(small_run: MeasuredRun, tmp_path: Path) -> None:
    data = np.array(small_run.accelerations_m_s2)
    data[1, 50:60] = np.nan
    run = MeasuredRun(small_run.geometry, small_run.speed, small_run.channels, data, 100.0)
    path = save_run(run, tmp_path / "run.h5")
    with pytest.raises(MeasuredDataError, match=r"run.h5: channel 'bogie_y' has NaN runs: 1 run"):
        load_run(path)
    assert np.isnan(load_run(path, allow_nan=True).channel("bogie_y")[55])


def test_geometry_and_speed_survive_variable_speed(tmp_path: Path) -> None:
    geometry = TrackGeometry(0.5, np.arange(5.0), np.zeros(5), np.zeros(5), np.ones(5))
    speed = SpeedProfile(np.array([0.0, 0.05, 0.1]), np.array([10.0, 12.0, 11.0]))
    run = MeasuredRun(geometry, speed, ("x",), np.ones((1, 11)), 100.0, time_offset_s=0.0)
    loaded = load_run(save_run(run, tmp_path / "r.h5"))
    _assert_same_run(run, loaded)
    assert loaded.speed.distance_m(0.1) == pytest.approx(0.05 * 11 + 0.05 * 11.5)


FIXTURES = Path(__file__).parent / "fixtures"


def test_a_version_1_file_still_loads(run_factory: Callable) -> None:
    """run_v1.h5 was written by the version-1 writer (main at 079b3c4, make_run(seed=5, 3 s))."""
    run = load_run(FIXTURES / "run_v1.h5")
    expected = run_factory(seed=5, duration_s=3.0)
    _assert_same_run(expected, run)
    assert run.design is None
    assert run.content_digest() == expected.content_digest()  # the v1 checksum still verifies
    with h5py.File(FIXTURES / "run_v1.h5", "r") as file:
        assert file.attrs["format_version"] == 1


def _designed(run: MeasuredRun) -> MeasuredRun:
    design = design_from_segments(
        [
            {"type": "tangent", "length_m": 30.0},
            {"type": "transition", "length_m": 30.0},
            {
                "type": "curve",
                "length_m": 60.0,
                "radius_m": 3000.0,
                "cant_mm": 90.0,
                "direction": "right",
                "gradient_permille": 3.0,
            },
        ]
    )
    return dataclasses.replace(run, design=design)


def test_design_round_trip_and_layout(small_run: MeasuredRun, tmp_path: Path) -> None:
    run = _designed(small_run)
    assert run.content_digest() != small_run.content_digest()
    loaded = load_run(save_run(run, tmp_path / "run.h5"))
    _assert_same_run(run, loaded)
    for name in ("chainage_m", "curvature_1_m", "cant_m", "gradient"):
        np.testing.assert_array_equal(getattr(loaded.design, name), getattr(run.design, name))
    assert loaded.content_digest() == run.content_digest()
    with h5py.File(tmp_path / "run.h5", "r") as file:
        assert file["design/curvature_1_m"].attrs["units"] == "1/m"
        assert file["design/cant_m"].attrs["units"] == "m"
    validate_run(loaded)


def test_bad_designs_in_files_are_refused_naming_the_file(
    small_run: MeasuredRun, tmp_path: Path
) -> None:
    path = save_run(_designed(small_run), tmp_path / "run.h5")
    with open(path, "r+b") as handle:  # unseal: edited by another tool
        handle.write(b"\0" * 512)
    with h5py.File(path, "r+") as file:
        del file.attrs["content_sha256"]
        file["design/cant_m"][...] = file["design/cant_m"][()] * 1000.0  # mm written as m
    with pytest.raises(MeasuredDataError, match=r"run.h5:/design.cant_m.*suggests millimetres"):
        load_run(path)
    with h5py.File(path, "r+") as file:
        file["design/cant_m"][...] = file["design/cant_m"][()] / 1000.0
        file.attrs["format_version"] = 1
    with pytest.raises(MeasuredDataError, match=r"run.h5: /design needs format_version >= 2"):
        load_run(path)


def test_validate_flags_a_design_that_does_not_cover_the_run(small_run: MeasuredRun) -> None:
    short = design_from_segments([{"type": "tangent", "length_m": 50.0}])
    with pytest.raises(MeasuredDataError, match=r"design record does not cover the run"):
        validate_run(dataclasses.replace(small_run, design=short), source="run")
