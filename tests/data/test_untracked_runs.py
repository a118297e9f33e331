"""Runs whose track was not measured (``MeasuredRun.geometry`` None): HDF5 version 3, MAT
and CSV without geometry, validation, digests; and runs with geometry unchanged (version 2,
the same digests and file layout as before version 3 existed)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io

from susp_bo.data.importers import read_csv_run, read_mat_run, write_csv_run, write_mat_run
from susp_bo.data.measured import MeasuredDataError, MeasuredRun, load_run, load_runs, save_run
from susp_bo.data.run_validation import track_needed_m, validate_run
from susp_bo.rig.design import DESIGN_COMPONENTS, TrackDesign
from susp_bo.rig.spectra import SpectrumSettings
from susp_bo.rig.track import GEOMETRY_COMPONENTS, SpeedProfile, TrackGeometry

FIXTURES = Path(__file__).parent / "fixtures"
PINNED_DIGEST = "2911892ee371483730657e8030f81b71218fa05e7488c5ab5e0adb085778d53c"
"""content_digest of :func:`pinned_run` (no design), computed before runs could lack a
geometry (main at f510405); run_v2.h5 was written by that version's save_run."""
PINNED_DESIGN_DIGEST = "1fbe05551820e7128b5abf8b676ae66d7d3da733897a2579334ec18981d52e83"
"""The same for ``pinned_run(design=True)``."""


def pinned_run(design: bool = False) -> MeasuredRun:
    """A run of exactly representable arithmetic (no random draw, no FFT, no libm), so its
    digest is the same bits on every machine: 100 m of track at 0.25 m, 4 s at 20–22 m/s."""
    s = np.arange(401, dtype=np.float64)
    geometry = TrackGeometry(
        spacing_m=0.25,
        vertical_m=(s % 7 - 3) * 0.001,
        alignment_m=(s % 5 - 2) * 0.0005,
        cross_level_rad=(s % 3 - 1) * 0.0002,
        gauge_m=(s % 11 - 5) * 0.0001,
    )
    line = None
    if design:
        line = TrackDesign(
            chainage_m=np.array([0.0, 40.0, 100.0]),
            curvature_1_m=np.array([0.0, 0.0005, 0.0005]),
            cant_m=np.array([0.0, 0.05, 0.05]),
            gradient=np.array([0.0, 0.002, 0.002]),
        )
    return MeasuredRun(
        geometry=geometry,
        speed=SpeedProfile(np.array([0.0, 2.0, 4.0]), np.array([20.0, 22.0, 21.0])),
        channels=("carbody_z", "bogie_y"),
        accelerations_m_s2=((np.arange(800, dtype=np.float64).reshape(2, 400) % 17) - 8) * 0.01,
        sample_rate_hz=100.0,
        units=("m/s^2", "m/s^2"),
        metadata={"rig": "hst_trailer", "seed": 1},
        time_offset_s=0.5,
        design=line,
    )


def untracked(run: MeasuredRun) -> MeasuredRun:
    """``run`` with its track not measured."""
    return dataclasses.replace(run, geometry=None)


def _tree(path: Path) -> dict[str, object]:
    """Every attribute and dataset of an HDF5 file: name -> value (arrays as lists)."""
    items: dict[str, object] = {}
    with h5py.File(path, "r") as file:

        def visit(name: str, obj: h5py.HLObject) -> None:
            for key, value in obj.attrs.items():
                items[f"{name}:{key}"] = np.asarray(value).tolist()
            if isinstance(obj, h5py.Dataset):
                items[name] = (str(obj.dtype), obj.chunks is not None, obj.fletcher32)
                items[f"{name}[]"] = np.asarray(obj[()]).tolist()

        visit("/", file)
        file.visititems(visit)
    return items


# --- digests ------------------------------------------------------------------------------


def test_runs_with_geometry_keep_their_digest_and_without_get_another() -> None:
    assert pinned_run().content_digest() == PINNED_DIGEST
    assert pinned_run(design=True).content_digest() == PINNED_DESIGN_DIGEST
    digests = {
        pinned_run().content_digest(),
        pinned_run(design=True).content_digest(),
        untracked(pinned_run()).content_digest(),
        untracked(pinned_run(design=True)).content_digest(),
    }
    assert len(digests) == 4  # with and without geometry, with and without design
    assert untracked(pinned_run()).content_digest() == untracked(pinned_run()).content_digest()


def test_a_geometry_of_the_wrong_type_is_refused_naming_what_is_allowed() -> None:
    with pytest.raises(MeasuredDataError, match=r"geometry: expected a TrackGeometry or None"):
        dataclasses.replace(pinned_run(), geometry=np.zeros(4))


# --- HDF5 ---------------------------------------------------------------------------------


def test_a_run_with_geometry_is_still_written_as_version_2(tmp_path: Path) -> None:
    """The file written before version 3 existed loads with its pinned digest, and saving
    the run again gives the same file: same groups, datasets, attributes and values."""
    old = load_run(FIXTURES / "run_v2.h5")
    assert old.content_digest() == PINNED_DIGEST
    again = save_run(pinned_run(), tmp_path / "run.h5")
    assert _tree(again) == _tree(FIXTURES / "run_v2.h5")
    with h5py.File(again, "r") as file:
        assert file.attrs["format_version"] == 2 and "geometry" in file


def test_a_run_without_geometry_round_trips_as_version_3(tmp_path: Path) -> None:
    for run in (untracked(pinned_run()), untracked(pinned_run(design=True))):
        path = save_run(run, tmp_path / "run.h5")
        with h5py.File(path, "r") as file:
            assert file.attrs["format_version"] == 3
            assert "geometry" not in file and "speed" in file
            assert file.attrs["content_sha256"] == run.content_digest()
        loaded = load_run(path)
        assert loaded.geometry is None
        assert loaded.content_digest() == run.content_digest()
        np.testing.assert_array_equal(loaded.accelerations_m_s2, run.accelerations_m_s2)
        np.testing.assert_array_equal(loaded.speed.speed_m_s, run.speed.speed_m_s)
        assert (loaded.design is None) == (run.design is None)
        if run.design is not None:
            for name in ("chainage_m", *DESIGN_COMPONENTS):
                np.testing.assert_array_equal(
                    getattr(loaded.design, name), getattr(run.design, name)
                )
    save_run(pinned_run(), tmp_path / "with.h5")  # one folder may mix both
    assert [r.geometry is None for r in load_runs(tmp_path)] == [True, False]


def _unsealed(path: Path) -> Path:
    """``path`` as another tool would leave it after an edit: no user block checksum, no
    content checksum."""
    with open(path, "r+b") as handle:
        handle.write(b"\0" * 512)
    with h5py.File(path, "r+") as file:
        del file.attrs["content_sha256"]
    return path


def test_geometry_is_required_below_version_3_and_checked_whenever_present(
    tmp_path: Path,
) -> None:
    path = _unsealed(save_run(pinned_run(), tmp_path / "v2.h5"))
    with h5py.File(path, "r+") as file:
        del file["geometry"]
    with pytest.raises(
        MeasuredDataError,
        match=r"v2\.h5: missing group /geometry: format_version 2 requires it .*written as "
        r"format_version 3, without /geometry",
    ):
        load_run(path)
    path = _unsealed(save_run(untracked(pinned_run()), tmp_path / "v3.h5"))
    with h5py.File(path, "r+") as file:  # a version-3 file may hold a geometry …
        group = file.create_group("geometry")
        group.attrs["spacing_m"] = 0.25
        for name in GEOMETRY_COMPONENTS:
            group.create_dataset(name, data=getattr(pinned_run().geometry, name))
            group[name].attrs["units"] = "rad" if name.endswith("_rad") else "m"
    assert load_run(path).content_digest() == PINNED_DIGEST
    with h5py.File(path, "r+") as file:  # … checked as in version 2
        file["geometry/gauge_m"].attrs["units"] = "mm"
    with pytest.raises(MeasuredDataError, match=r"v3\.h5: unit mismatch: /geometry/gauge_m"):
        load_run(path)
    with h5py.File(path, "r+") as file:
        del file["geometry"]
        file.create_dataset("geometry", data=np.zeros(3))
    with pytest.raises(MeasuredDataError, match=r"v3\.h5: /geometry must be a group"):
        load_run(path)
    with h5py.File(path, "r+") as file:
        del file["geometry"]
        file.attrs["format_version"] = 4
    with pytest.raises(MeasuredDataError, match=r"format_version = 4; this reader knows 1, 2, 3"):
        load_run(path)


# --- validation ---------------------------------------------------------------------------


def test_validate_run_without_geometry_skips_only_the_track_checks() -> None:
    spectrum = SpectrumSettings(f_min_hz=1.0, f_max_hz=20.0, n_frequencies=8, segment_s=2.0)
    run = dataclasses.replace(untracked(pinned_run()), time_offset_s=0.0)  # to 3.99 s
    validate_run(run, ["carbody_z"], spectrum, axle_span_m=500.0)  # no track to be short
    assert track_needed_m(run, 20.0) == pytest.approx(float(run.speed.distance_m(3.99)) + 20.0)
    short_speed = dataclasses.replace(run, speed=SpeedProfile.constant(20.0, 2.0))
    with pytest.raises(MeasuredDataError, match=r"r\.h5: speed record too short: .* 0 … 2 s"):
        validate_run(short_speed, source="r.h5")
    with pytest.raises(MeasuredDataError, match=r"speed record too short: .* t = 4\.49 s"):
        validate_run(untracked(pinned_run()))  # its record starts 0.5 s in: past the speed
    designed = dataclasses.replace(run, design=pinned_run(design=True).design)  # 0 … 100 m
    validate_run(designed, axle_span_m=10.0)
    with pytest.raises(
        MeasuredDataError, match=r"design record does not cover the run: .* needs 0 … 1.*m"
    ):
        validate_run(designed, axle_span_m=30.0)


# --- MAT and CSV --------------------------------------------------------------------------


def test_mat_without_geometry_round_trips_and_a_partial_geometry_is_refused(
    tmp_path: Path,
) -> None:
    run = untracked(pinned_run(design=True))
    path = tmp_path / "run.mat"
    write_mat_run(run, path)
    variables = scipy.io.loadmat(path)
    assert not {"spacing_m", *GEOMETRY_COMPONENTS} & set(variables)
    loaded = read_mat_run(path)
    assert loaded.geometry is None
    np.testing.assert_array_equal(loaded.accelerations_m_s2, run.accelerations_m_s2)
    np.testing.assert_array_equal(loaded.design.cant_m, run.design.cant_m)
    variables["vertical_m"] = np.zeros(10)
    scipy.io.savemat(path, {k: v for k, v in variables.items() if not k.startswith("__")})
    with pytest.raises(
        MeasuredDataError,
        match=r"run\.mat: geometry variables must come together: found \['vertical_m'\], "
        r"missing \['spacing_m', 'alignment_m', .*or none of them when the track",
    ):
        read_mat_run(path)


def test_a_mat_run_with_misnamed_geometry_is_refused_not_read_as_an_unmeasured_track(
    tmp_path: Path,
) -> None:
    path = tmp_path / "run.mat"
    write_mat_run(pinned_run(), path)
    variables = {k: v for k, v in scipy.io.loadmat(path).items() if not k.startswith("__")}
    geometry = {"spacing_m", *GEOMETRY_COMPONENTS}
    renamed = {k: v for k, v in variables.items() if k not in geometry} | {
        k.removesuffix("_m").removesuffix("_rad"): variables[k] for k in geometry
    }  # spacing, vertical, ...: the geometry under names the layout does not know
    scipy.io.savemat(path, renamed)
    with pytest.raises(
        MeasuredDataError,
        match=r"run\.mat: no geometry variables, and variables the layout does not name: "
        r"\['alignment', 'cross_level', 'gauge', 'spacing', 'vertical'\]",
    ):
        read_mat_run(path)


def test_csv_without_irregularities_or_without_a_geometry_file(tmp_path: Path) -> None:
    for run in (untracked(pinned_run()), untracked(pinned_run(design=True))):
        files = [tmp_path / name for name in ("acc.csv", "geo.csv", "speed.csv")]
        write_csv_run(run, *files)
        header = files[1].read_text().splitlines()[0].split(",")
        assert header == ["s_m", *(DESIGN_COMPONENTS if run.design else ())]
        loaded = read_csv_run(*files)
        assert loaded.geometry is None and loaded.metadata["geometry_start_m"] == 0.0
        np.testing.assert_array_equal(loaded.accelerations_m_s2, run.accelerations_m_s2)
        if run.design is not None:  # sampled on the s_m rows: the same line at the rows
            s = np.linspace(0.0, 100.0, 401)
            np.testing.assert_allclose(loaded.design.cant(s), run.design.cant(s), atol=1e-15)
        else:
            assert loaded.design is None
    bare = read_csv_run(files[0], None, files[2])
    assert bare.geometry is None and bare.design is None
    assert "geometry_start_m" not in bare.metadata
    (tmp_path / "half.csv").write_text("s_m,vertical_m,gauge_m\n0,0,0\n1,0,0\n")
    with pytest.raises(
        MeasuredDataError,
        match=r"half\.csv: columns must be 's_m', all of .*\(or none of them: the track not "
        r"measured\).*missing \['alignment_m', 'cross_level_rad'\]",
    ):
        read_csv_run(files[0], tmp_path / "half.csv", files[2])
