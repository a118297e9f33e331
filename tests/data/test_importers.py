"""Tests of susp_bo.data.importers: CSV and MATLAB .mat round trips and clear errors."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from susp_bo.data.importers import read_csv_run, read_mat_run, write_csv_run, write_mat_run
from susp_bo.data.measured import MeasuredDataError, MeasuredRun
from susp_bo.rig.line_file import design_from_segments
from susp_bo.rig.track import GEOMETRY_COMPONENTS


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _geometry_csv(path: Path, start: float = 0.0) -> Path:
    rows = ["s_m,vertical_m,alignment_m,cross_level_rad,gauge_m"]
    rows += [f"{start + 0.5 * i},{0.001 * i},0,0,0" for i in range(41)]
    return _write(path, "\n".join(rows) + "\n")


def test_csv_round_trip_is_exact(small_run: MeasuredRun, tmp_path: Path) -> None:
    files = [tmp_path / name for name in ("acc.csv", "geo.csv", "speed.csv")]
    write_csv_run(small_run, *files)
    run = read_csv_run(*files, metadata={"line": "LGV Est"})
    np.testing.assert_array_equal(run.accelerations_m_s2, small_run.accelerations_m_s2)
    for name in GEOMETRY_COMPONENTS:
        np.testing.assert_array_equal(
            getattr(run.geometry, name), getattr(small_run.geometry, name)
        )
    np.testing.assert_array_equal(run.speed.speed_m_s, small_run.speed.speed_m_s)
    assert run.sample_rate_hz == pytest.approx(100.0, rel=1e-12)
    assert run.channels == small_run.channels and run.units == ("m/s^2", "m/s^2")
    assert run.metadata == {"source": "csv:acc.csv", "line": "LGV Est", "geometry_start_m": 0.0}


def test_csv_written_by_a_spreadsheet_with_a_byte_order_mark(
    small_run: MeasuredRun, tmp_path: Path
) -> None:
    # Excel's "CSV UTF-8" starts with a BOM; it was read into the first column's name
    files = [tmp_path / name for name in ("acc.csv", "geo.csv", "speed.csv")]
    write_csv_run(small_run, *files)
    for file in files:
        file.write_bytes(b"\xef\xbb\xbf" + file.read_bytes())
    run = read_csv_run(*files)
    np.testing.assert_array_equal(run.accelerations_m_s2, small_run.accelerations_m_s2)
    np.testing.assert_array_equal(run.geometry.vertical_m, small_run.geometry.vertical_m)


def test_csv_layout_by_hand(tmp_path: Path) -> None:
    """Units in brackets, chainage offset, speed column, clock from the first sample."""
    acc = _write(
        tmp_path / "acc.csv",
        "# exported by the IRIS 320 recorder\n"
        "time_s,carbody_z [g],bogie_y,speed_m_s\n"
        + "".join(
            f"{10 + 0.01 * i:.2f},{0.01 * (i % 3)},{0.1},{80 + 0.1 * i}\n" for i in range(50)
        ),
    )
    geo = _geometry_csv(tmp_path / "geo.csv", start=1234.5)
    run = read_csv_run(acc, geo)
    assert run.channels == ("carbody_z", "bogie_y") and run.units == ("g", "m/s^2")
    assert run.sample_rate_hz == pytest.approx(100.0) and run.time_offset_s == 0.0
    assert run.speed.speed_at(0.49) == pytest.approx(84.9)
    assert run.geometry.spacing_m == pytest.approx(0.5) and run.geometry.length_m == 20.0
    assert run.metadata["geometry_start_m"] == 1234.5
    np.testing.assert_allclose(run.to_si().channel("carbody_z")[:3], [0.0, 0.0980665, 0.196133])
    constant = read_csv_run(acc, geo, speed=83.0)
    assert constant.speed.duration_s == pytest.approx(0.49)
    assert constant.speed.speed_at(0.2) == 83.0


@pytest.mark.parametrize(
    ("acc_text", "pattern"),
    [
        ("t,a\n0,1\n1,2\n", r"first column must be 'time_s'; got 't'"),
        ("time_s,a\n0,1\n0.01,2\n0.03,3\n", r"'time_s' must increase in equal steps"),
        ("time_s,a\n0,1\n0.01,x\n0.02,3\n", r"line 3, column 'a': 'x' is not a number"),
        ("time_s,a\n0,1\n0.01\n0.02,3\n", r"line 3 has 1 cells; the header has 2"),
        ("time_s,a,a\n0,1,1\n0.01,2,2\n", r"column names must be unique"),
        ("time_s\n0\n0.01\n0.02\n", r"no acceleration channel columns"),
        ("time_s,a\n0,1\n", r"needs a header row and at least 2 data rows"),
        (
            "time_s,a,speed_m_s\n0,1,80\n0.01,,80\n0.02,3,80\n",
            r"channel 'a' has NaN runs \(1 run\(s\), 1 samples\)",
        ),
        ("time_s,a,speed_m_s\n0,1,80\n0.01,1,-1\n0.02,3,80\n", r"speed_m_s.*> 0 m/s"),
        ("time_s,a\n0,1\n0.01,1\n0.02,3\n", r"no speed: give speed="),
    ],
)
def test_csv_errors_name_file_line_and_column(acc_text: str, pattern: str, tmp_path: Path) -> None:
    acc = _write(tmp_path / "acc.csv", acc_text)
    geo = _geometry_csv(tmp_path / "geo.csv")
    with pytest.raises(MeasuredDataError, match=r"acc\.csv: .*" + pattern):
        read_csv_run(acc, geo)


def test_csv_geometry_and_speed_file_errors(tmp_path: Path) -> None:
    acc = _write(tmp_path / "acc.csv", "time_s,a\n0,1\n0.01,2\n0.02,3\n")
    rows = ["s_m,vertical_m,alignment_m,cross_level_rad,gauge_m"]
    rows += [f"{0.5 * i},0,{4.0 * (i % 5)},0,0" for i in range(41)]  # alignment in mm
    geo = _write(tmp_path / "geo_mm.csv", "\n".join(rows) + "\n")
    with pytest.raises(MeasuredDataError, match=r"geo_mm\.csv: alignment_m deviates up to 8 m"):
        read_csv_run(acc, geo, speed=80.0)
    acc = _write(tmp_path / "acc.csv", "time_s,a\n5,1\n5.01,2\n5.02,3\n")
    geo = _write(tmp_path / "geo.csv", "s_m,vertical_m,alignment_m,gauge_m\n0,0,0,0\n1,0,0,0\n")
    with pytest.raises(MeasuredDataError, match=r"geo\.csv: columns must be .*missing \['cross"):
        read_csv_run(acc, geo, speed=80.0)
    geo = _geometry_csv(tmp_path / "geo2.csv")
    speed = _write(tmp_path / "speed.csv", "time_s,speed_m_s\n6,80\n7,81\n8,80\n")
    with pytest.raises(
        MeasuredDataError, match=r"accelerations start at t = 5 s, before the speed"
    ):
        read_csv_run(acc, geo, speed=speed)
    speed = _write(tmp_path / "speed2.csv", "time,v\n0,80\n7,81\n")
    with pytest.raises(MeasuredDataError, match=r"speed2\.csv: columns must be 'time_s', 'speed_m"):
        read_csv_run(acc, geo, speed=speed)
    with pytest.raises(MeasuredDataError, match=r"absent\.csv: cannot read CSV"):
        read_csv_run(tmp_path / "absent.csv", geo, speed=80.0)


def test_an_out_of_order_speed_file_is_reported_with_its_own_times(tmp_path: Path) -> None:
    # the times were reported shifted to the record's start (time_s[1] = -9.0 s)
    acc = _write(tmp_path / "acc.csv", "time_s,a\n9,1\n9.01,2\n9.02,3\n")
    geo = _geometry_csv(tmp_path / "geo.csv")
    speed = _write(tmp_path / "speed.csv", "time_s,speed_m_s\n9.0,83.33\n0.0,83.33\n")
    with pytest.raises(MeasuredDataError) as error:
        read_csv_run(acc, geo, speed=speed)
    message = str(error.value)
    assert message.startswith(f"{speed}: column 'time_s' must be strictly increasing")
    assert "data row 2 has time_s = 0 s, not after data row 1 (9 s)" in message
    assert "-9" not in message[len(str(speed)) :]
    speed = _write(tmp_path / "gap.csv", "time_s,speed_m_s\n0,80\n,80\n2,80\n")
    with pytest.raises(MeasuredDataError, match=r"gap\.csv: column 'time_s': data row 2 is empty"):
        read_csv_run(acc, geo, speed=speed)


def test_mat_round_trip(small_run: MeasuredRun, tmp_path: Path) -> None:
    path = tmp_path / "run.mat"
    write_mat_run(small_run, path)
    run = read_mat_run(path)
    np.testing.assert_array_equal(run.accelerations_m_s2, small_run.accelerations_m_s2)
    np.testing.assert_array_equal(run.speed.time_s, small_run.speed.time_s)
    np.testing.assert_array_equal(run.geometry.gauge_m, small_run.geometry.gauge_m)
    assert run.channels == small_run.channels and run.sample_rate_hz == 100.0
    assert run.metadata["truth"] == {"secondary_kz": 190000.0}


def _matlab_style(tmp_path: Path, **changes: object) -> Path:
    """A .mat file as a MATLAB user would write it (n_t x C, constant speed)."""
    variables: dict[str, object] = {
        "accelerations": np.random.default_rng(0).normal(size=(300, 2)),
        "channels": np.array(["carbody_z", "bogie_y"], dtype=object),
        "sample_rate_hz": 100.0,
        "spacing_m": 0.25,
        "speed_m_s": 25.0,
        **{name: np.zeros(400) for name in GEOMETRY_COMPONENTS},
    }
    variables.update(changes)
    variables = {k: v for k, v in variables.items() if v is not None}
    path = tmp_path / "matlab.mat"
    scipy.io.savemat(path, variables)
    return path


def test_mat_written_by_hand(tmp_path: Path) -> None:
    run = read_mat_run(_matlab_style(tmp_path))
    assert run.channels == ("carbody_z", "bogie_y") and run.accelerations_m_s2.shape == (2, 300)
    assert run.units == ("m/s^2", "m/s^2") and run.speed.duration_s == pytest.approx(2.99)
    single = read_mat_run(_matlab_style(tmp_path, channels="x", accelerations=np.ones(50)))
    assert single.channels == ("x",) and single.accelerations_m_s2.shape == (1, 50)


@pytest.mark.parametrize(
    ("changes", "pattern"),
    [
        ({"channels": None}, r"missing variable 'channels'"),
        ({"sample_rate_hz": None}, r"missing variable 'sample_rate_hz'"),
        ({"accelerations": np.ones((300, 3))}, r"'accelerations' has shape \(300, 3\)"),
        ({"accelerations": np.array(["a", "b"])}, r"'accelerations' must be real numbers"),
        ({"sample_rate_hz": -5.0}, r"sample_rate_hz: got -5.0 Hz; must be > 0"),
        ({"vertical_m": np.zeros(10)}, r"vertical_m has 400 samples|alignment_m: has 400"),
        ({"gauge_m": np.full(400, np.nan)}, r"gauge_m: 400 non-finite"),
        (  # millimetres under a metre variable: 5 m of irregularity was taken
            {"vertical_m": 5.0 * np.sin(np.arange(400) / 7.0)},
            r"vertical_m deviates up to 5\.0\d* m from its median; .*was it written in mm\?",
        ),
        (
            {"cross_level_rad": np.linspace(0.0, 3.0, 400)},
            r"cross_level_rad deviates up to 1.5 rad .*was it written in mrad\?",
        ),
        ({"speed_m_s": np.array([20.0, 21.0])}, r"missing variable 'speed_time_s'"),
        ({"units": np.array(["m/s^2"], dtype=object)}, r"units: need one string per channel"),
        ({"metadata_json": "{oops"}, r"'metadata_json' is not JSON"),
    ],
)
def test_mat_errors(tmp_path: Path, changes: dict[str, object], pattern: str) -> None:
    with pytest.raises(MeasuredDataError, match=r"matlab\.mat: .*" + pattern):
        read_mat_run(_matlab_style(tmp_path, **changes))


def test_mat_unreadable(tmp_path: Path) -> None:
    path = tmp_path / "bad.mat"
    path.write_bytes(b"MATLAB 7.3 MAT-file" + bytes(200))
    with pytest.raises(MeasuredDataError, match=r"bad\.mat: "):
        read_mat_run(path)


@pytest.mark.parametrize(
    ("content", "why"),
    [(b"", r"an empty file"), (b"0123456789", r".*truncated; the file has 10 bytes")],
)
def test_empty_or_short_mat_is_named(tmp_path: Path, content: bytes, why: str) -> None:
    path = tmp_path / "short.mat"
    path.write_bytes(content)
    with pytest.raises(MeasuredDataError, match=r"short\.mat: not a readable \.mat file \(" + why):
        read_mat_run(path)


def test_a_mat_file_cut_anywhere_is_refused_naming_it(
    small_run: MeasuredRun, tmp_path: Path
) -> None:
    whole = tmp_path / "whole.mat"
    write_mat_run(small_run, whole)
    data = whole.read_bytes()
    cut = tmp_path / "cut.mat"
    for length in range(0, len(data), max(1, len(data) // 97)):
        cut.write_bytes(data[:length])
        with pytest.raises(MeasuredDataError, match=r"cut\.mat: "):
            read_mat_run(cut)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(text=st.text(alphabet=st.sampled_from("0123456789.,-e\nabn_ [];#"), max_size=200))
def test_random_csv_text_never_crashes(text: str) -> None:
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        acc = _write(Path(folder) / "acc.csv", text)
        geo = _geometry_csv(Path(folder) / "geo.csv")
        try:
            run = read_csv_run(acc, geo, speed=80.0)
        except MeasuredDataError:
            return
        assert isinstance(run, MeasuredRun) and run.n_samples >= 2


def _with_design(run: MeasuredRun) -> MeasuredRun:
    design = design_from_segments(
        [
            {"type": "tangent", "length_m": 20.0},
            {"type": "transition", "length_m": 40.0},
            {
                "type": "curve",
                "length_m": 60.0,
                "radius_m": 2500.0,
                "cant_mm": 110.0,
                "direction": "left",
                "gradient_permille": 6.0,
            },
        ]
    )
    return dataclasses.replace(run, design=design)


def test_csv_design_columns_round_trip(small_run: MeasuredRun, tmp_path: Path) -> None:
    run = _with_design(small_run)
    files = [tmp_path / name for name in ("acc.csv", "geo.csv", "speed.csv")]
    write_csv_run(run, *files)
    assert "curvature_1_m,cant_m,gradient" in files[1].read_text().splitlines()[0]
    loaded = read_csv_run(*files)
    s = run.geometry.position_m  # the design comes back sampled on the geometry's rows
    np.testing.assert_allclose(loaded.design.curvature(s), run.design.curvature(s), atol=1e-15)
    np.testing.assert_allclose(loaded.design.cant(s), run.design.cant(s), atol=1e-15)
    np.testing.assert_allclose(loaded.design.grade(s)[0], run.design.grade(s)[0], atol=1e-15)
    text = files[1].read_text().replace(",gradient\n", ",slope\n", 1)
    _write(files[1], text)
    with pytest.raises(MeasuredDataError, match=r"geo\.csv: columns must be .*missing \['gradient"):
        read_csv_run(*files)


def test_mat_design_variables_round_trip_and_units(small_run: MeasuredRun, tmp_path: Path) -> None:
    run = _with_design(small_run)
    path = tmp_path / "run.mat"
    write_mat_run(run, path)
    loaded = read_mat_run(path)
    np.testing.assert_array_equal(loaded.design.chainage_m, run.design.chainage_m)
    np.testing.assert_array_equal(loaded.design.cant_m, run.design.cant_m)
    variables = scipy.io.loadmat(path)
    variables["design_cant_m"] = variables["design_cant_m"] * 1000.0  # mm written as m
    scipy.io.savemat(path, {k: v for k, v in variables.items() if not k.startswith("__")})
    with pytest.raises(MeasuredDataError, match=r"run\.mat\.cant_m.*suggests millimetres"):
        read_mat_run(path)
